// The WebGL2 renderer: the paper's forward mapping on the GPU (DESIGN §5), following the
// CPU reference renderer (inkwarp-core `render`) element for element.
//
// Every pixel of a layer is a vertex placed at its displaced position (the vertex shader
// reads the field from a float texture). A block of four pixels joined by all four links
// is a quad, coloured by the bilinear mix of its pixels' premultiplied RGBA; in any other
// block (the border, a cut, a hole) each drawn pixel owns a skirt quarter, so the identity
// field covers every pixel exactly and the two sides of a missing link separate when the
// field pulls them apart. Where the mesh folds, the part from further down the rest image
// (within a block row, further right) is in front: each element's depth is its block's
// place in that order (a fragment of a draft's or fast frame's element of many blocks: the
// block of its rest position), skirt quarters included.
// Layers are composited back to front with premultiplied "over" into a 4× multisampled
// target (coverage antialiasing), resolved into the canvas.
//
// Where it differs from the CPU renderer (stated tolerances in the browser test): each
// quad is drawn as two triangles (affine, not the exact inverse bilinear map), coverage is
// four samples rather than exact area, a skirt's centre point is the parallelogram
// completion from its own pixel, and where a translucent part is folded over another the
// one behind, if drawn after it, does not show through.

import type { DraftGeometry, DraftHandle, DraftLayer, Engine, FieldData } from './engine';
import { DRAFT_TARGET_PX } from './options';
import { type PackedField, proxySize, unpackAt } from './proxy';

// Quads: vertex k is pixel (k % W, k / W); the index buffer lists the two triangles of
// every block whose four links exist, each triangle's last (provoking) vertex being the
// block's top-left pixel, so the fragment shader knows its block.
/** Texels per row of a layer's sparse draft values. */
const SPARSE_ROW = 1024;

// A layer's field at pixel p: from the full-resolution texture, or (a sparse draft, see
// \`draftPixels\`) from the values of the selected pixels, found through their index.
const FIELD_AT = `
uniform highp sampler2D uField;
uniform highp usampler2D uSparseIndex;
uniform highp sampler2D uSparseValues;
uniform int uSparse;
vec2 fieldAt(ivec2 p) {
  if (uSparse == 1) {
    uint k = texelFetch(uSparseIndex, p, 0).r;
    return texelFetch(uSparseValues, ivec2(int(k % ${SPARSE_ROW}u), int(k / ${SPARSE_ROW}u)), 0).rg;
  }
  return texelFetch(uField, p, 0).rg;
}
`;

// Where the mesh folds, the element from further down the rest image (and within a block
// row, further right) is in front, as the CPU renderer draws them in that order: its block's
// place in that order, as a depth that only a later element passes (quads are drawn before
// the skirt quarters, so the draw order alone put every quarter in front).
const ORDER = `
float order(ivec2 block) {
  return float((block.y + 1) * (uSize.x + 1) + block.x + 1) / float((uSize.y + 1) * (uSize.x + 1));
}
`;

const VERT = `#version 300 es
precision highp float;
precision highp int;
${FIELD_AT}
uniform ivec2 uSize;
uniform vec2 uCanvas;
uniform vec2 uOffset;
// The side of the quads drawn (1; the draft's largest block, a loose clamp for its
// smaller ones, which is enough as drafts are not multisampled: every fragment centre lies
// inside its triangle).
uniform float uBlock;
// Drafts (1) draw no skirt quarters along the layer's border: its vertices there move out
// by half a pixel instead, so the draft still covers the border pixels' outer halves.
uniform float uEdge;
// Fast full frames (adaptiveTriangles) clamp nothing: their fans' last vertex is a
// block's centre, and they are not multisampled (every fragment centre lies inside its
// triangle).
uniform float uLoose;
out vec2 vRest;
flat out vec4 vClamp;
flat out float vOrder;
${ORDER}
void main() {
  ivec2 p = ivec2(gl_VertexID % uSize.x, gl_VertexID / uSize.x);
  vOrder = order(p);
  vec2 rest = vec2(p);
  vec2 d = fieldAt(p);
  vec2 out_ = uEdge * 0.5 * vec2(p.x == 0 ? -1.0 : p.x == uSize.x - 1 ? 1.0 : 0.0, p.y == 0 ? -1.0 : p.y == uSize.y - 1 ? 1.0 : 0.0);
  vec2 q = rest + out_ + d + uOffset;
  vRest = rest + out_;
  vClamp = vec4(rest - uLoose, rest + uBlock + uLoose);
  gl_Position = vec4((q.x + 0.5) / uCanvas.x * 2.0 - 1.0, 1.0 - (q.y + 0.5) / uCanvas.y * 2.0, 0.0, 1.0);
}
`;

// Skirt quarters: in a block that is not a whole quad, each drawn pixel owns the quarter
// of the block nearest to it: the pixel, the points half way to its horizontal and vertical
// neighbours (the link's midpoint where linked, otherwise half a pixel along the pixel's
// displaced frame), and their parallelogram completion. Colour blends only along links.
const SKIRT_VERT = `#version 300 es
precision highp float;
precision highp int;
precision highp usampler2D;
${FIELD_AT}
uniform usampler2D uLinks;
uniform ivec2 uSize;
uniform vec2 uCanvas;
uniform vec2 uOffset;
in vec4 aQuarter;   // pixel x, y, and the block's side sx, sy (±1)
in vec2 aCorner;    // (0|1, 0|1) along x and y
out vec2 vRest;
flat out vec4 vClamp;
flat out float vOrder;
${ORDER}
vec2 pos(ivec2 p) { return vec2(p) + fieldAt(p); }
uint links(ivec2 p) { return texelFetch(uLinks, p, 0).r; }
bool right(ivec2 p) { return p.x >= 0 && p.x < uSize.x - 1 && (links(p) & 2u) != 0u; }
bool down(ivec2 p) { return p.y >= 0 && p.y < uSize.y - 1 && (links(p) & 4u) != 0u; }

void main() {
  ivec2 p = ivec2(aQuarter.xy);
  float sx = aQuarter.z;
  float sy = aQuarter.w;
  vOrder = order(p - ivec2(sx < 0.0 ? 1 : 0, sy < 0.0 ? 1 : 0));
  vec2 P = pos(p);
  bool rx = right(p), lx = right(p - ivec2(1, 0));
  bool dy = down(p), uy = down(p - ivec2(0, 1));
  vec2 ex = rx ? pos(p + ivec2(1, 0)) - P : lx ? P - pos(p - ivec2(1, 0)) : vec2(0.0);
  vec2 ey = dy ? pos(p + ivec2(0, 1)) - P : uy ? P - pos(p - ivec2(0, 1)) : vec2(0.0);
  if (ex == vec2(0.0)) ex = ey == vec2(0.0) ? vec2(1.0, 0.0) : vec2(ey.y, -ey.x);
  if (ey == vec2(0.0)) ey = vec2(-ex.y, ex.x);
  bool linkX = sx > 0.0 ? rx : lx;
  bool linkY = sy > 0.0 ? dy : uy;
  // Past the picture's edge, a pixel near its rest place across it reaches out to the frame's
  // edge (the CPU renderer's rule: a held edge stays on the frame however squeezed).
  vec2 moved = abs(P - vec2(p));
  if (!linkX && (p.x + int(sx) < 0 || p.x + int(sx) >= uSize.x) && ex.x > 0.0) ex.x = max(ex.x, clamp(1.0 - moved.x / 0.5, 0.0, 1.0));
  if (!linkY && (p.y + int(sy) < 0 || p.y + int(sy) >= uSize.y) && ey.y > 0.0) ey.y = max(ey.y, clamp(1.0 - moved.y / 0.5, 0.0, 1.0));
  vec2 q = P + 0.5 * (aCorner.x * sx * ex + aCorner.y * sy * ey) + uOffset;
  vec2 rest = vec2(p);
  vec2 far = rest + 0.5 * vec2(linkX ? sx : 0.0, linkY ? sy : 0.0);
  vRest = rest + 0.5 * vec2(aCorner.x * (linkX ? sx : 0.0), aCorner.y * (linkY ? sy : 0.0));
  vClamp = vec4(min(rest, far), max(rest, far));
  gl_Position = vec4((q.x + 0.5) / uCanvas.x * 2.0 - 1.0, 1.0 - (q.y + 0.5) / uCanvas.y * 2.0, 0.0, 1.0);
}
`;

const FRAG = `#version 300 es
precision highp float;
precision highp int;
uniform highp sampler2D uImage;
uniform ivec2 uSize;
uniform float uOpacity;
// Fast full frames' elements (see VERT) span many blocks: a fragment takes the order of the
// block its rest position lies in.
uniform float uLoose;
in vec2 vRest;
flat in vec4 vClamp;
flat in float vOrder;
out vec4 outColor;
${ORDER}

vec4 px(int i, int j) {
  vec4 c = texelFetch(uImage, ivec2(clamp(i, 0, uSize.x - 1), clamp(j, 0, uSize.y - 1)), 0);
  return vec4(c.rgb * c.a, c.a);
}

// The bilinear mix of the block's premultiplied pixels at this rest position (clamped to
// the element, as a pixel centre just outside an edge takes the edge's colour).
void main() {
  vec2 r = clamp(vRest, vClamp.xy, vClamp.zw);
  vec2 q = min(floor(r), vec2(uSize - 1));
  vec2 f = r - q;
  int i = int(q.x);
  int j = int(q.y);
  vec4 top = mix(px(i, j), px(i + 1, j), f.x);
  vec4 bottom = mix(px(i, j + 1), px(i + 1, j + 1), f.x);
  outColor = mix(top, bottom, f.y) * uOpacity;
  // (A see-through part adds nothing, and must not hide what is behind it.)
  if (outColor.a == 0.0) discard;
  gl_FragDepth = uLoose > 0.0 ? order(ivec2(floor(vRest))) : vOrder;
}
`;

// Drafts: one filtered fetch from the premultiplied copy of the image, the same bilinear
// mix of premultiplied pixels as FRAG up to the texture unit's 8-bit weights (the draft
// mesh has no skirt quarters to clamp to: its quads are whole), each fragment in the order
// of the block its rest position lies in (an element spans many).
const DRAFT_FRAG = `#version 300 es
precision highp float;
precision highp int;
uniform highp sampler2D uPremultiplied;
uniform ivec2 uSize;
uniform float uOpacity;
in vec2 vRest;
out vec4 outColor;
${ORDER}

void main() {
  outColor = texture(uPremultiplied, (vRest + 0.5) / vec2(uSize)) * uOpacity;
  if (outColor.a == 0.0) discard;
  gl_FragDepth = order(ivec2(floor(vRest)));
}
`;

const BLIT_VERT = `#version 300 es
out vec2 vPos;
void main() {
  vec2 p = vec2(float((gl_VertexID & 1) * 2), float((gl_VertexID >> 1) * 2));
  vPos = p;
  gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
`;

function compile(gl: WebGL2RenderingContext, type: number, src: string): WebGLShader {
  const s = gl.createShader(type)!;
  gl.shaderSource(s, src);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(`Shader failed to compile: ${gl.getShaderInfoLog(s)}`);
  return s;
}

function program(gl: WebGL2RenderingContext, vs: string, fs: string, attributes: string[] = []): WebGLProgram {
  const p = gl.createProgram()!;
  attributes.forEach((a, i) => gl.bindAttribLocation(p, i, a));
  gl.attachShader(p, compile(gl, gl.VERTEX_SHADER, vs));
  gl.attachShader(p, compile(gl, gl.FRAGMENT_SHADER, fs));
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(`Shader failed to link: ${gl.getProgramInfoLog(p)}`);
  return p;
}

/** Straight RGBA8 pixels premultiplied by their alpha (rounded), as drafts read them. */
export function premultiply(rgba: Uint8Array | Uint8ClampedArray): Uint8Array {
  const out = new Uint8Array(rgba.length);
  for (let i = 0; i < rgba.length; i += 4) {
    const a = rgba[i + 3];
    out[i] = Math.round((rgba[i] * a) / 255);
    out[i + 1] = Math.round((rgba[i + 1] * a) / 255);
    out[i + 2] = Math.round((rgba[i + 2] * a) / 255);
    out[i + 3] = a;
  }
  return out;
}

/**
 * The mesh of a `w × h` layer from its grid's links (per node: bit 0 active, bit 1 linked
 * right, bit 2 linked down; null: everything linked) and its RGBA (a pixel is drawn when
 * it is active or visible): triangle indices of the whole quads, of the draft mesh (see
 * `draftQuads`), the skirt quarters' vertices (x, y, sx, sy, u, v), and the links as given
 * (or all).
 */
export function buildMesh(w: number, h: number, links: Uint8Array | null, rgba: Uint8Array | null, block = DRAFT_BLOCK): { quads: Uint32Array; coarse: Uint32Array; skirts: Float32Array; innerSkirts: number; links: Uint8Array } {
  const at = (i: number, j: number) => (links ? links[j * w + i] : i + 1 < w ? (j + 1 < h ? 7 : 3) : j + 1 < h ? 5 : 1);
  const drawn = (i: number, j: number) => i >= 0 && j >= 0 && i < w && j < h && ((at(i, j) & 1) !== 0 || (rgba !== null && rgba[4 * (j * w + i) + 3] > 0));
  const quads = new Uint32Array(6 * Math.max(0, (w - 1) * (h - 1)));
  // Skirts of blocks inside the layer (cuts, holes) first, then those along its border.
  const skirts: number[] = [];
  const border: number[] = [];
  let n = 0;
  for (let j = -1; j < h; j++) {
    for (let i = -1; i < w; i++) {
      const whole = i >= 0 && j >= 0 && i + 1 < w && j + 1 < h && (at(i, j) & 6) === 6 && (at(i, j + 1) & 2) !== 0 && (at(i + 1, j) & 4) !== 0;
      if (whole) {
        const k = j * w + i;
        // Both triangles end on the block's top-left pixel (the provoking vertex).
        quads.set([k + 1, k + w + 1, k, k + w + 1, k + w, k], n);
        n += 6;
        continue;
      }
      const to = i < 0 || j < 0 || i + 1 >= w || j + 1 >= h ? border : skirts;
      for (const [ci, cj, sx, sy] of [[i, j, 1, 1], [i + 1, j, -1, 1], [i, j + 1, 1, -1], [i + 1, j + 1, -1, -1]]) {
        if (!drawn(ci, cj)) continue;
        for (const [u, v] of [[0, 0], [1, 0], [0, 1], [0, 1], [1, 0], [1, 1]]) to.push(ci, cj, sx, sy, u, v);
      }
    }
  }
  const all = new Uint8Array(w * h);
  for (let j = 0; j < h; j++) for (let i = 0; i < w; i++) all[j * w + i] = at(i, j);
  const innerSkirts = skirts.length / 6;
  for (const v of border) skirts.push(v);
  return { quads: quads.slice(0, n), coarse: draftQuads(w, h, all, block), skirts: new Float32Array(skirts), innerSkirts, links: all };
}

/**
 * Largest block side (pixels, a power of two) of the draft mesh: where the surface is
 * whole, one vertex every `DRAFT_BLOCK` pixels. The draft field is solved on a grid about
 * 64 nodes across and interpolated, so at 512 × 512 this places a vertex on every draft node.
 */
export const DRAFT_BLOCK = 8;

/**
 * The draft mesh's block side for a `w × h` layer: about the draft solve grid's spacing
 * (the layer's larger side over `DRAFT_TARGET_PX`), a power of two from `DRAFT_BLOCK` to
 * 16. A large picture's proxy (1000 × 750: a draft node every 16 pixels) takes blocks of
 * 16, a quarter of the elements (and of the pixels a sparse draft is solved at) that
 * blocks of 8 would have; 512 × 512 and smaller keep 8.
 */
export function draftBlock(w: number, h: number): number {
  const spacing = Math.ceil(Math.max(w, h) / DRAFT_TARGET_PX);
  return spacing >= 16 ? 16 : DRAFT_BLOCK;
}

/**
 * The draft mesh of a `w × h` layer from its links (as `buildMesh` returns them): triangles
 * over the pixel vertices. Each block of `block` × `block` pixel quads whose every quad is
 * whole (all four links) is one element through its corner pixels; every other pixel quad
 * (a cut, a hole, or a quad beside one) is drawn as the full mesh draws it, and a missing
 * pixel quad is dropped. So the draft covers exactly what the full mesh's whole quads
 * cover (the skirts are drawn as in the full mesh), with far fewer vertices where nothing
 * tears, and cuts and holes open at full resolution. An element is two triangles where
 * its neighbours are elements too; an edge it shares with pixel quads takes every pixel
 * along it (the element is then a fan from its centre pixel), so neighbours always share
 * their edges' vertices: no T-junction, no crack. Blocks at the right and bottom edges
 * are clipped to the layer (one element only where no edge needs every pixel).
 */
export function draftQuads(w: number, h: number, links: Uint8Array, block = DRAFT_BLOCK): Uint32Array {
  return blockMesh(w, h, links, block, null);
}

/**
 * The pixels a draft reads its field at (sorted): every vertex of the draft mesh
 * (`draftQuads`), and the pixel of every inner skirt quarter (the first `innerSkirts`
 * vertices of `skirts`, 6 floats each) with its four neighbours. On the built-in 512 × 512
 * example with its cut, 7.1 thousand of the 262 thousand, so a draft is solved, sent and uploaded for those
 * alone (see `GlLayer.setSparseField`).
 */
export function draftPixels(w: number, h: number, coarse: Uint32Array, skirts: Float32Array, innerSkirts: number): Uint32Array {
  const used = new Uint8Array(w * h);
  for (const v of coarse) used[v] = 1;
  for (let k = 0; k < innerSkirts; k++) {
    const x = skirts[6 * k];
    const y = skirts[6 * k + 1];
    for (const [dx, dy] of [[0, 0], [1, 0], [-1, 0], [0, 1], [0, -1]]) {
      const i = x + dx;
      const j = y + dy;
      if (i >= 0 && j >= 0 && i < w && j < h) used[j * w + i] = 1;
    }
  }
  let n = 0;
  for (const u of used) n += u;
  const out = new Uint32Array(n);
  for (let i = 0, k = 0; i < used.length; i++) if (used[i]) out[k++] = i;
  return out;
}

/**
 * Whether every pixel quad of a block (quads `i0..i1` × `j0..j1`) has its four links: a
 * summed-area table of the whole pixel quads answers any block in four lookups.
 */
function wholeBlocks(w: number, h: number, links: Uint8Array): (i0: number, j0: number, i1: number, j1: number) => boolean {
  const qw = Math.max(0, w - 1);
  const qh = Math.max(0, h - 1);
  const sums = new Uint32Array((qw + 1) * (qh + 1));
  for (let j = 0; j < qh; j++) {
    let row = 0;
    for (let i = 0; i < qw; i++) {
      const k = j * w + i;
      if ((links[k] & 6) === 6 && (links[k + w] & 2) !== 0 && (links[k + 1] & 4) !== 0) row++;
      sums[(j + 1) * (qw + 1) + i + 1] = sums[j * (qw + 1) + i + 1] + row;
    }
  }
  return (i0, j0, i1, j1) =>
    sums[j1 * (qw + 1) + i1] - sums[j0 * (qw + 1) + i1] - sums[j1 * (qw + 1) + i0] + sums[j0 * (qw + 1) + i0] === (i1 - i0) * (j1 - j0);
}

/** Side (pixel quads) of the elements of `adaptiveTriangles`. */
export const FAN_BLOCK = 8;

/**
 * How far (pixels) the field may stray inside an element of `adaptiveTriangles` from the
 * element's own (piecewise affine) interpolation.
 */
export const ADAPTIVE_TOLERANCE = 0.05;

/**
 * The triangles of a fast full frame for `field` (single-sampled: the frame a software GPU
 * shows first when the pointer rests): the mesh of `draftQuads` with blocks of
 * `FAN_BLOCK`, except that a block is one element only where, at every pixel of it, the
 * field is within `tolerance` pixels of the element's interpolation (the field affine on
 * each of its triangles). Elsewhere the pixel quads are drawn as the full mesh draws
 * them. So every pixel lands within `tolerance` of where the full mesh puts it, and every
 * fragment takes the colour of its rest position as in the full mesh (rest positions are
 * affine on every triangle of both), from a fraction of the triangles where the field is
 * smooth.
 */
export function adaptiveTriangles(w: number, h: number, links: Uint8Array, field: FieldData, tolerance = ADAPTIVE_TOLERANCE): Uint32Array {
  return blockMesh(w, h, links, FAN_BLOCK, { field, tolerance });
}

/**
 * The elements of `draftQuads` and `adaptiveTriangles`: blocks of `s` × `s` pixel quads,
 * each one element (two triangles, or a fan from its centre pixel where an edge faces
 * pixel quads) or its whole pixel quads. With `fit`, an element must also hold the field
 * within the tolerance, and blocks that do not are split, until every element does.
 */
function blockMesh(w: number, h: number, links: Uint8Array, s: number, fit: { field: FieldData; tolerance: number } | null): Uint32Array {
  const qw = Math.max(0, w - 1);
  const qh = Math.max(0, h - 1);
  const whole = wholeBlocks(w, h, links);
  const bw = Math.ceil(qw / s);
  const bh = Math.ceil(qh / s);
  const half = s / 2;
  // The quads of block (bi, bj), clipped to the layer.
  const span = (bi: number, bj: number) => [bi * s, bj * s, Math.min(bi * s + s, qw), Math.min(bj * s + s, qh)];
  const element = new Uint8Array(bw * bh);
  for (let bj = 0; bj < bh; bj++) {
    for (let bi = 0; bi < bw; bi++) {
      const [i0, j0, i1, j1] = span(bi, bj);
      element[bj * bw + bi] = whole(i0, j0, i1, j1) ? 1 : 0;
    }
  }
  // An element's edges that take every pixel: those facing a block inside the layer that
  // is not an element (top, right, bottom, left).
  const split = (bi: number, bj: number) => bi >= 0 && bj >= 0 && bi < bw && bj < bh && element[bj * bw + bi] === 0;
  const edges = (bi: number, bj: number) => [split(bi, bj - 1), split(bi + 1, bj), split(bi, bj + 1), split(bi - 1, bj)];
  const clipped = (bi: number, bj: number) => (bi + 1) * s > qw || (bj + 1) * s > qh;
  // Whether the element of block (bi, bj) holds the field (every pixel of it placed within
  // the tolerance by its triangles).
  const holds = (bi: number, bj: number): boolean => {
    if (!fit) return true;
    const [i0, j0, i1, j1] = span(bi, bj);
    const [ft, fr, fb, fl] = edges(bi, bj);
    const fan = ft || fr || fb || fl;
    const tol = fit.tolerance;
    for (let comp = 0; comp < 2; comp++) {
      const f = comp === 0 ? fit.field.dx : fit.field.dy;
      const a = f[j0 * w + i0], b = f[j0 * w + i1], c = f[j1 * w + i0], d = f[j1 * w + i1];
      if (!fan) {
        const iw = 1 / (i1 - i0), ih = 1 / (j1 - j0);
        for (let y = j0; y <= j1; y++) {
          const t = (y - j0) * ih;
          for (let x = i0; x <= i1; x++) {
            const u = (x - i0) * iw;
            const v = u >= t ? a + u * (b - a) + t * (d - b) : a + t * (c - a) + u * (d - c);
            if (Math.abs(f[y * w + x] - v) > tol) return false;
          }
        }
        continue;
      }
      const fc = f[(j0 + half) * w + i0 + half];
      // The edge from pixel index `p0`, `s` pixels of index step `step`, at `u` (0..1) of
      // it: between its pixels where it takes every one, else between its two corners.
      const onEdge = (full: boolean, p0: number, step: number, u: number): number => {
        const x = u * s;
        if (!full) return f[p0] + u * (f[p0 + s * step] - f[p0]);
        const k = Math.floor(x);
        const r = x - k;
        return r > 0 ? (1 - r) * f[p0 + k * step] + r * f[p0 + (k + 1) * step] : f[p0 + k * step];
      };
      for (let dy = -half; dy <= half; dy++) {
        for (let dx = -half; dx <= half; dx++) {
          const m = Math.max(Math.abs(dx), Math.abs(dy));
          if (m === 0) continue;
          // Where the ray from the centre through the pixel leaves the block; the fan is
          // affine along the ray.
          const qx = (dx * half) / m, qy = (dy * half) / m;
          const u = (qx + half) / s, t = (qy + half) / s;
          const edge =
            qy === -half ? onEdge(ft, j0 * w + i0, 1, u)
            : qx === half ? onEdge(fr, j0 * w + i1, w, t)
            : qy === half ? onEdge(fb, j1 * w + i0, 1, u)
            : onEdge(fl, j0 * w + i0, w, t);
          const v = fc + (m / half) * (edge - fc);
          if (Math.abs(f[(j0 + half + dy) * w + i0 + half + dx] - v) > tol) return false;
        }
      }
    }
    return true;
  };
  // Split the elements that cannot be drawn as one (a clipped or odd-sized block with an
  // edge that takes every pixel has no centre pixel to fan from) or do not hold the field,
  // until none is left. A split changes its neighbours' edges, so they are checked again.
  const fails = (bi: number, bj: number) => ((clipped(bi, bj) || s % 2 === 1) && edges(bi, bj).some(Boolean)) || !holds(bi, bj);
  const check: number[] = [];
  for (let b = 0; b < bw * bh; b++) if (element[b]) check.push(b);
  while (check.length) {
    const b = check.pop()!;
    const [bi, bj] = [b % bw, Math.floor(b / bw)];
    if (!element[b] || !fails(bi, bj)) continue;
    element[b] = 0;
    for (const [ni, nj] of [[bi, bj - 1], [bi + 1, bj], [bi, bj + 1], [bi - 1, bj]]) {
      if (ni >= 0 && nj >= 0 && ni < bw && nj < bh && element[nj * bw + ni]) check.push(nj * bw + ni);
    }
  }
  // At most two triangles a pixel quad.
  const out = new Uint32Array(6 * qw * qh);
  let n = 0;
  const tri = (p: number, q: number, r: number) => {
    out[n++] = p;
    out[n++] = q;
    out[n++] = r;
  };
  for (let bj = 0; bj < bh; bj++) {
    for (let bi = 0; bi < bw; bi++) {
      const [i0, j0, i1, j1] = span(bi, bj);
      if (element[bj * bw + bi]) {
        const [ft, fr, fb, fl] = edges(bi, bj);
        const [k, right, down, across] = [j0 * w + i0, j0 * w + i1, j1 * w + i0, j1 * w + i1];
        if (!(ft || fr || fb || fl)) {
          // Both triangles end on the block's top-left pixel (the provoking vertex).
          tri(right, across, k);
          tri(across, down, k);
          continue;
        }
        const ring: number[] = [k];
        if (ft) for (let t = 1; t < s; t++) ring.push(k + t);
        ring.push(right);
        if (fr) for (let t = 1; t < s; t++) ring.push(right + t * w);
        ring.push(across);
        if (fb) for (let t = 1; t < s; t++) ring.push(across - t);
        ring.push(down);
        if (fl) for (let t = 1; t < s; t++) ring.push(down - t * w);
        const c = (j0 + half) * w + i0 + half;
        for (let t = 0; t < ring.length; t++) tri(ring[t], ring[(t + 1) % ring.length], c);
        continue;
      }
      for (let j = j0; j < j1; j++) {
        for (let i = i0; i < i1; i++) {
          if (!whole(i, j, i + 1, j + 1)) continue;
          const k = j * w + i;
          tri(k + 1, k + w + 1, k);
          tri(k + w + 1, k + w, k);
        }
      }
    }
  }
  return out.slice(0, n);
}

let layerSerial = 0;

/** One layer's GPU resources. */
export class GlLayer {
  /** Tells layers apart, and (`version`) each state of one: the image, mesh or field set. */
  readonly serial = ++layerSerial;
  version = 0;
  image: WebGLTexture;
  /** The image premultiplied, bilinearly filtered: drafts sample it once a fragment. */
  premultiplied: WebGLTexture;
  field: WebGLTexture;
  /** Indices of the triangles of every quad whose four links exist. */
  indices: WebGLBuffer;
  count = 0;
  /** Drafts: the triangles of `draftQuads` (whole blocks of `DRAFT_BLOCK`² quads as one element). */
  coarse: WebGLBuffer;
  coarseCount = 0;
  /** Fast full frames: the triangles of `adaptiveTriangles` for the field (built when first drawn). */
  adaptive: WebGLBuffer;
  adaptiveCount = 0;
  private adaptiveFor = -1;
  private fieldData: FieldData | null = null;
  private givenTriangles: Uint32Array | null = null;
  private allLinks: Uint8Array = new Uint8Array(0);
  links: WebGLTexture;
  /** The skirt quarters: 6 vertices each of (x, y, sx, sy, u, v). */
  skirts: WebGLBuffer;
  skirtVao: WebGLVertexArrayObject;
  skirtCount = 0;
  /** The skirt vertices of blocks inside the layer (the rest run along its border). */
  innerSkirtCount = 0;
  /** The draft mesh's block side (see `draftBlock`). */
  block = DRAFT_BLOCK;
  /** The pixels a draft reads its field at (`draftPixels`), for sparse drafts. */
  draftPixels: Uint32Array = new Uint32Array(0);
  /** Per pixel, its place in `draftPixels` (R32UI). */
  sparseIndex: WebGLTexture;
  /** A sparse draft's (dx, dy) at `draftPixels`, `SPARSE_ROW` a row (RG32F). */
  sparseValues: WebGLTexture;
  /** Whether the field is a sparse draft (`setSparseField`): it can only be drawn as a draft. */
  sparse = false;
  /**
   * What a draft drawn by the CPU reads (see `cpuDraft`): the premultiplied image, the draft
   * mesh, the sparse draft. Kept on a software GPU only (about 9 bytes a pixel).
   */
  private premultipliedBytes: Uint8Array = new Uint8Array(0);
  private draftGeometry: Omit<DraftGeometry, 'width' | 'height' | 'premultiplied'> | null = null;
  private sparseData: Float32Array = new Float32Array(0);
  /** `draftGeometry` and the image in the engine, made by the first draft the CPU draws. */
  private draftHandle: DraftHandle | null = null;
  /**
   * What a fast full frame drawn by the CPU reads besides (see `cpuFull`): every skirt
   * quarter, the field's (dx, dy) pairs, and the engine's copy of the layer with the
   * field's `adaptiveTriangles` (made for one `version`). Software GPU only.
   */
  private allSkirts: Float32Array | null = null;
  private fieldPairs: Float32Array | null = null;
  private fullHandle: { handle: DraftHandle; version: number } | null = null;
  /** Every pixel's place among a full field's values: itself (built once). */
  private identity: Uint32Array | null = null;
  constructor(
    private r: GlRenderer,
    readonly width: number,
    readonly height: number,
  ) {
    const gl = r.gl;
    this.image = r.texture();
    this.premultiplied = r.texture(true);
    this.field = r.texture();
    this.indices = gl.createBuffer()!;
    this.coarse = gl.createBuffer()!;
    this.adaptive = gl.createBuffer()!;
    this.links = r.texture();
    this.sparseIndex = r.texture();
    this.sparseValues = r.texture();
    this.skirts = gl.createBuffer()!;
    this.skirtVao = gl.createVertexArray()!;
    gl.bindVertexArray(this.skirtVao);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.skirts);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 4, gl.FLOAT, false, 24, 0);
    gl.enableVertexAttribArray(1);
    gl.vertexAttribPointer(1, 2, gl.FLOAT, false, 24, 16);
    gl.bindVertexArray(null);
    gl.bindBuffer(gl.ARRAY_BUFFER, null);
    gl.bindTexture(gl.TEXTURE_2D, this.field);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RG32F, width, height, 0, gl.RG, gl.FLOAT, new Float32Array(2 * width * height));
    this.setMesh(null, null);
  }

  /** Straight RGBA8 pixels of the layer. */
  setImage(rgba: Uint8Array | Uint8ClampedArray): void {
    this.version++;
    const gl = this.r.gl;
    gl.bindTexture(gl.TEXTURE_2D, this.image);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, this.width, this.height, 0, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(rgba.buffer, rgba.byteOffset, rgba.byteLength));
    const premultiplied = premultiply(rgba);
    gl.bindTexture(gl.TEXTURE_2D, this.premultiplied);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, this.width, this.height, 0, gl.RGBA, gl.UNSIGNED_BYTE, premultiplied);
    if (this.r.softwareGpu) this.premultipliedBytes = premultiplied;
    this.dropDraftHandle();
  }

  private dropDraftHandle(): void {
    this.draftHandle?.free();
    this.draftHandle = null;
    this.fullHandle?.handle.free();
    this.fullHandle = null;
  }

  /**
   * The mesh from the grid's links (per node: bit 0 active, bit 1 linked right, bit 2
   * linked down; null: everything linked) and the layer's alpha (a pixel is drawn when it
   * is active or visible). A block whose four links exist is a quad; in any other block
   * (at the border, along a cut, around a hole) each drawn pixel gets its skirt quarter.
   */
  setMesh(links: Uint8Array | null, rgba: Uint8Array | null): void {
    this.version++;
    const { width: w, height: h } = this;
    this.block = draftBlock(w, h);
    const { quads, coarse, skirts, innerSkirts, links: l } = buildMesh(w, h, links, rgba, this.block);
    const n = quads.length;
    const m = coarse.length;
    const gl = this.r.gl;
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.indices);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, quads, gl.STATIC_DRAW);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.coarse);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, coarse, gl.STATIC_DRAW);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, null);
    this.count = n;
    this.coarseCount = m;
    gl.bindBuffer(gl.ARRAY_BUFFER, this.skirts);
    gl.bufferData(gl.ARRAY_BUFFER, skirts, gl.STATIC_DRAW);
    gl.bindBuffer(gl.ARRAY_BUFFER, null);
    this.skirtCount = skirts.length / 6;
    this.innerSkirtCount = innerSkirts;
    this.allLinks = l;
    gl.bindTexture(gl.TEXTURE_2D, this.links);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.R8UI, w, h, 0, gl.RED_INTEGER, gl.UNSIGNED_BYTE, l);
    // A sparse field read at pixels of another mesh would be wrong: drop it.
    this.sparse = false;
    const pixels = draftPixels(w, h, coarse, skirts, innerSkirts);
    this.draftPixels = pixels;
    const index = new Uint32Array(w * h);
    for (let k = 0; k < pixels.length; k++) index[pixels[k]] = k;
    this.draftGeometry = this.r.softwareGpu ? { coarse, skirts: skirts.subarray(0, 6 * innerSkirts), links: l, index, reads: pixels.length } : null;
    this.allSkirts = this.r.softwareGpu ? skirts : null;
    this.dropDraftHandle();
    gl.bindTexture(gl.TEXTURE_2D, this.sparseIndex);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.R32UI, w, h, 0, gl.RED_INTEGER, gl.UNSIGNED_INT, index);
    gl.bindTexture(gl.TEXTURE_2D, this.sparseValues);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RG32F, SPARSE_ROW, Math.max(1, Math.ceil(pixels.length / SPARSE_ROW)), 0, gl.RG, gl.FLOAT, null);
  }

  /**
   * A draft's field at `draftPixels` only ((dx, dy) pairs in their order): what the draft
   * mesh reads, a few percent of the pixels to send and upload. Until the next `setField`
   * the layer is drawn as a draft.
   */
  setSparseField(values: Float32Array): void {
    const n = this.draftPixels.length;
    if (values.length !== 2 * n) throw new Error(`A sparse field of ${values.length / 2} pixels for a mesh that reads ${n}.`);
    this.version++;
    this.sparse = true;
    this.sparseData = values;
    this.fieldData = null;
    this.givenTriangles = null;
    const gl = this.r.gl;
    const rows = Math.floor(n / SPARSE_ROW);
    const rest = n - rows * SPARSE_ROW;
    gl.bindTexture(gl.TEXTURE_2D, this.sparseValues);
    if (rows) gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, SPARSE_ROW, rows, gl.RG, gl.FLOAT, values.subarray(0, 2 * rows * SPARSE_ROW));
    if (rest) gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, rows, rest, 1, gl.RG, gl.FLOAT, values.subarray(2 * rows * SPARSE_ROW));
  }

  /**
   * What drawing this layer's drafts on the CPU needs (see `cpuDraft`), for a worker that
   * draws them (`DraftDraw`): null off a software GPU.
   */
  get cpuDraftGeometry(): DraftGeometry | null {
    if (!this.draftGeometry || this.premultipliedBytes.length !== 4 * this.width * this.height) return null;
    return { width: this.width, height: this.height, premultiplied: this.premultipliedBytes, ...this.draftGeometry };
  }

  /** Whether the CPU can draw the layer's draft now (`cpuDraft`): a sparse draft, on a software GPU. */
  get onCpu(): boolean {
    return this.sparse && this.draftGeometry !== null;
  }

  /** The layer's sparse draft as `Engine.drawDraft` draws it, at `offset` with `opacity`. */
  cpuDraft(engine: Engine, offset: [number, number], opacity = 1): DraftLayer {
    if (!this.sparse || !this.draftGeometry) throw new Error('Only a sparse draft on a software GPU is drawn by the CPU.');
    const { width, height } = this;
    this.draftHandle ??= engine.draftLayer({ width, height, premultiplied: this.premultipliedBytes, ...this.draftGeometry });
    return { draft: this.draftHandle, values: this.sparseData, offset, opacity };
  }

  /** Whether the CPU can draw the layer's fast full frame now (`cpuFull`): a full field, on a software GPU. */
  get onCpuFull(): boolean {
    return !this.sparse && this.fieldPairs !== null && this.allSkirts !== null;
  }

  /**
   * The layer's fast full frame as `Engine.drawDraft` draws it, at `offset` with `opacity`:
   * the triangles of `adaptiveTriangles` and every skirt quarter, read at every pixel, as
   * the WebGL2 fast full frame draws them.
   */
  cpuFull(engine: Engine, offset: [number, number], opacity = 1): DraftLayer {
    if (!this.onCpuFull) throw new Error('Only a full field on a software GPU is drawn by the CPU.');
    if (this.fullHandle?.version !== this.version) {
      const coarse = this.fastTriangles();
      if (this.fullHandle) {
        // Only the field changed (a new image or mesh drops the handle): only the
        // triangles follow it.
        this.fullHandle.handle.setTriangles(coarse);
        this.fullHandle.version = this.version;
      } else {
        const { width: w, height: h } = this;
        this.identity ??= Uint32Array.from({ length: w * h }, (_, i) => i);
        const handle = engine.draftLayer({ width: w, height: h, premultiplied: this.premultipliedBytes, coarse, skirts: this.allSkirts!, links: this.allLinks, index: this.identity, reads: w * h, pushBorder: false });
        this.fullHandle = { handle, version: this.version };
      }
      this.adaptiveCount = coarse.length;
    }
    return { draft: this.fullHandle.handle, values: this.fieldPairs!, offset, opacity };
  }

  /** The field, and (`triangles`) its fast full frame's triangles when already built. */
  setField(field: FieldData | null, triangles: Uint32Array | null = null): void {
    this.version++;
    this.sparse = false;
    this.fieldData = field;
    this.givenTriangles = triangles;
    const gl = this.r.gl;
    const n = this.width * this.height;
    const rg = new Float32Array(2 * n);
    if (field) {
      for (let i = 0; i < n; i++) {
        rg[2 * i] = field.dx[i];
        rg[2 * i + 1] = field.dy[i];
      }
    }
    gl.bindTexture(gl.TEXTURE_2D, this.field);
    gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, this.width, this.height, gl.RG, gl.FLOAT, rg);
    this.fieldPairs = this.r.softwareGpu ? rg : null;
  }

  /** The triangles of the fast full frame of the current field and mesh: the worker's, or built here. */
  private fastTriangles(): Uint32Array {
    const { width: w, height: h } = this;
    return this.givenTriangles ?? adaptiveTriangles(w, h, this.allLinks, this.fieldData ?? { width: w, height: h, dx: new Float32Array(w * h), dy: new Float32Array(w * h) });
  }

  /** Makes `adaptive` the triangles of the current field and mesh (once per version). */
  useAdaptive(): void {
    if (this.adaptiveFor === this.version) return;
    const triangles = this.fastTriangles();
    const gl = this.r.gl;
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.adaptive);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, triangles, gl.DYNAMIC_DRAW);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, null);
    this.adaptiveCount = triangles.length;
    this.adaptiveFor = this.version;
  }

  dispose(): void {
    const gl = this.r.gl;
    gl.deleteBuffer(this.adaptive);
    gl.deleteTexture(this.image);
    gl.deleteTexture(this.premultiplied);
    gl.deleteTexture(this.field);
    gl.deleteBuffer(this.indices);
    gl.deleteBuffer(this.coarse);
    gl.deleteBuffer(this.skirts);
    gl.deleteTexture(this.links);
    gl.deleteTexture(this.sparseIndex);
    gl.deleteTexture(this.sparseValues);
    gl.deleteVertexArray(this.skirtVao);
    this.dropDraftHandle();
  }
}

/**
 * A field's (dx, dy) pairs at `pixels` (a layer's `draftPixels`), as a sparse draft holds
 * them (`GlLayer.setSparseField`): from its floats, or from a field kept packed for playback
 * (`unpackAt`).
 */
export function sparseValuesAt(pixels: Uint32Array, field: FieldData | PackedField): Float32Array {
  if ('packed' in field) return unpackAt(field, pixels);
  const out = new Float32Array(2 * pixels.length);
  for (let k = 0; k < pixels.length; k++) {
    const i = pixels[k];
    out[2 * k] = field.dx[i];
    out[2 * k + 1] = field.dy[i];
  }
  return out;
}

/**
 * Whether a layer holds a sparse draft (`GlLayer.setSparseField`): its field is only known
 * at the draft mesh's pixels, so the frame can only be a single-sampled draft.
 */
export function holdsSparse(layers: DrawLayer[]): boolean {
  return layers.some(({ layer }) => layer.sparse);
}

/** Everything a frame depends on: its size, background and kind, and each layer's state. */
function frameKey(width: number, height: number, background: number[], layers: DrawLayer[], antialias: boolean, draft: boolean, fast: boolean): string {
  const parts = layers.map(({ layer, offset, opacity }) => `${layer.serial}.${layer.version}@${offset[0]},${offset[1]}*${opacity ?? 1}`);
  return `${width}x${height} ${background.join(',')} ${antialias ? 'aa' : '1'}${draft ? 'd' : fast ? 'a' : 'f'} ${parts.join(' ')}`;
}

export interface DrawLayer {
  layer: GlLayer;
  offset: [number, number];
  opacity?: number;
}

export class GlRenderer {
  readonly gl: WebGL2RenderingContext;
  private mesh: WebGLProgram;
  private draftMesh: WebGLProgram;
  private skirt: WebGLProgram;
  private blit: WebGLProgram;
  private vao: WebGLVertexArrayObject;
  private msaaFbo: WebGLFramebuffer | null = null;
  private msaaRb: WebGLRenderbuffer | null = null;
  private plainFbo: WebGLFramebuffer | null = null;
  private plainRb: WebGLRenderbuffer | null = null;
  /** The targets' depth (each element's place in the CPU renderer's order). */
  private depthRbs: WebGLRenderbuffer[] = [];
  private resolveFbo: WebGLFramebuffer | null = null;
  private resolveTex: WebGLTexture | null = null;
  /** What the last frame drew (see `frameKey`). */
  private lastFrame = '';
  /** Whether the GPU is a software one (SwiftShader, llvmpipe: the browser draws on the CPU). */
  readonly softwareGpu: boolean;
  /**
   * A 2D canvas stacked over the WebGL one, where sparse drafts and fast full frames are
   * drawn by the CPU (`Engine.drawDraft`) while `cpuDrafts` is on (see `useEngine`): the
   * page then shows them without waiting for the GPU, which a software GPU makes it do for
   * every WebGL frame it shows. Hidden while the WebGL canvas shows the frame. Null off the
   * page.
   */
  readonly draftCanvas: HTMLCanvasElement | null = null;
  cpuDrafts = false;
  /**
   * How many times smaller the CPU draws a draft (1: at the frame's size), set by the page
   * for a large frame while dragging (see `App.draftShrink`).
   */
  draftShrink = 1;
  /** Frames draw where a layer folds in the CPU renderer's order (a depth test, see ORDER); off only to measure its cost. */
  orderFolds = true;
  private engine: Engine | null = null;
  private cpuFrame: ImageData | null = null;
  private cpuShown = false;
  /** How many times smaller the frame on the CPU's canvas was drawn, and the frame's own size. */
  private cpuDrawn = { shrink: 1, width: 0, height: 0 };

  /** Whether `render` with these arguments (no fast frame) would draw the frame already drawn. */
  drawn(width: number, height: number, background: [number, number, number, number], layers: DrawLayer[], antialias = true, draft = false): boolean {
    if (holdsSparse(layers)) [draft, antialias] = [true, false];
    return this.lastFrame === this.keyOf(width, height, background, layers, antialias, draft, false);
  }

  /** Where the last frame can be read: the resolve target, or the canvas after a draft. */
  private shown: WebGLFramebuffer | null = null;
  private width = 0;
  private height = 0;
  readonly samples: number;
  /** Whether the canvas has a depth buffer: drafts drawn straight onto it keep the order of folds too. */
  private readonly canvasDepth: boolean;

  constructor(readonly canvas: HTMLCanvasElement | OffscreenCanvas) {
    const gl = canvas.getContext('webgl2', { antialias: false, premultipliedAlpha: true, preserveDrawingBuffer: true, alpha: true }) as WebGL2RenderingContext | null;
    if (!gl) throw new Error('This browser has no WebGL2; the editor needs it to draw the warped picture.');
    this.gl = gl;
    this.mesh = program(gl, VERT, FRAG);
    this.draftMesh = program(gl, VERT, DRAFT_FRAG);
    this.skirt = program(gl, SKIRT_VERT, FRAG, ['aQuarter', 'aCorner']);
    this.blit = program(gl, BLIT_VERT, `#version 300 es
precision highp float;
uniform sampler2D uTex;
in vec2 vPos;
out vec4 o;
void main() { o = texture(uTex, vPos); }`);
    this.vao = gl.createVertexArray()!;
    this.samples = Math.min(4, gl.getParameter(gl.MAX_SAMPLES) as number);
    this.canvasDepth = gl.getContextAttributes()?.depth === true;
    const info = gl.getExtension('WEBGL_debug_renderer_info');
    const name = String(gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER));
    this.softwareGpu = /SwiftShader|llvmpipe|softpipe|Software Rasterizer|Basic Render/i.test(name);
    if (typeof document !== 'undefined') {
      this.draftCanvas = document.createElement('canvas');
      this.draftCanvas.className = 'picture cpu-draft';
      this.draftCanvas.style.visibility = 'hidden';
    }
  }

  /** Draws sparse drafts and fast full frames with `engine` on the CPU where the GPU is a software one. */
  useEngine(engine: Engine): void {
    this.engine = engine;
    this.cpuDrafts = this.softwareGpu && this.draftCanvas !== null;
  }

  /** A texture clamped at its edges, sampled at the nearest texel or (`linear`) bilinearly. */
  texture(linear = false): WebGLTexture {
    const gl = this.gl;
    const t = gl.createTexture()!;
    const filter = linear ? gl.LINEAR : gl.NEAREST;
    gl.bindTexture(gl.TEXTURE_2D, t);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, filter);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, filter);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    return t;
  }

  layer(width: number, height: number): GlLayer {
    return new GlLayer(this, width, height);
  }

  private ensureTargets(width: number, height: number): void {
    if (this.width === width && this.height === height && this.msaaFbo) return;
    const gl = this.gl;
    this.width = width;
    this.height = height;
    if (this.canvas.width !== width) this.canvas.width = width;
    if (this.canvas.height !== height) this.canvas.height = height;
    if (this.msaaFbo) gl.deleteFramebuffer(this.msaaFbo);
    if (this.msaaRb) gl.deleteRenderbuffer(this.msaaRb);
    if (this.plainFbo) gl.deleteFramebuffer(this.plainFbo);
    if (this.plainRb) gl.deleteRenderbuffer(this.plainRb);
    for (const rb of this.depthRbs) gl.deleteRenderbuffer(rb);
    this.depthRbs = [];
    const depth = (samples: number) => {
      const rb = gl.createRenderbuffer()!;
      gl.bindRenderbuffer(gl.RENDERBUFFER, rb);
      if (samples) gl.renderbufferStorageMultisample(gl.RENDERBUFFER, samples, gl.DEPTH_COMPONENT32F, width, height);
      else gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH_COMPONENT32F, width, height);
      gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, rb);
      this.depthRbs.push(rb);
    };
    this.plainRb = gl.createRenderbuffer();
    gl.bindRenderbuffer(gl.RENDERBUFFER, this.plainRb);
    gl.renderbufferStorage(gl.RENDERBUFFER, gl.RGBA8, width, height);
    this.plainFbo = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, this.plainFbo);
    gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.RENDERBUFFER, this.plainRb);
    depth(0);
    if (this.resolveFbo) gl.deleteFramebuffer(this.resolveFbo);
    if (this.resolveTex) gl.deleteTexture(this.resolveTex);
    this.msaaRb = gl.createRenderbuffer();
    gl.bindRenderbuffer(gl.RENDERBUFFER, this.msaaRb);
    gl.renderbufferStorageMultisample(gl.RENDERBUFFER, this.samples, gl.RGBA8, width, height);
    this.msaaFbo = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, this.msaaFbo);
    gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.RENDERBUFFER, this.msaaRb);
    depth(this.samples);
    this.resolveTex = this.texture();
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, width, height, 0, gl.RGBA, gl.UNSIGNED_BYTE, null);
    this.resolveFbo = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, this.resolveFbo);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, this.resolveTex, 0);
  }

  /**
   * Renders a frame: the background (straight RGBA8) then each layer, back to front;
   * `antialias: false` samples once per pixel; `draft` draws the draft mesh (`draftQuads`:
   * a vertex every `DRAFT_BLOCK` pixels where the surface is whole) in place of one vertex
   * per pixel (both for fast frames during a drag on a software GPU, which pays per vertex,
   * per triangle and per sample). Colours are still the bilinear mix of the layer's
   * pixels at each fragment's rest position, so a draft differs from the full frame only
   * where the field bends inside a block, and along the layer's border (half a pixel
   * pushed out where the full frame draws skirt quarters; those of cuts and holes stay).
   * `adaptive` (single-sampled full frames only) draws the triangles of
   * `adaptiveTriangles`, which put every pixel within `ADAPTIVE_TOLERANCE` of the full
   * mesh, in place of two a pixel. A full frame stays in the resolve target (for `readPixels`) and is shown on the
   * canvas; a single-sampled draft is drawn on the canvas directly (a software GPU pays
   * for every pass over the pixels) and read from there.
   */
  render(width: number, height: number, background: [number, number, number, number], layers: DrawLayer[], antialias = true, draft = false, adaptive = false): void {
    if (holdsSparse(layers)) [draft, antialias] = [true, false];
    const fast = adaptive && !draft && !antialias;
    const key = this.keyOf(width, height, background, layers, antialias, draft, fast);
    if (this.cpuDrafts && this.engine && layers.length > 0) {
      // Drafts and fast full frames are drawn by the CPU where it can draw every layer's.
      const cpu = draft ? layers.every(({ layer }) => layer.onCpu) : fast && layers.every(({ layer }) => layer.onCpuFull);
      if (cpu) {
        const offered = this.offered;
        this.offered = null;
        this.renderCpu(width, height, background, layers, !draft, offered?.key === key ? offered.image : null);
        this.lastFrame = key;
        return;
      }
    }
    this.lastFrame = key;
    this.showCpu(false);
    const gl = this.gl;
    this.ensureTargets(width, height);
    // A draft draws straight onto the canvas; a full frame into a target of its own,
    // resolved into the texture that `readPixels` reads and then shown on the canvas.
    const direct = draft && !antialias;
    const target = direct ? null : antialias ? this.msaaFbo : this.plainFbo;
    this.shown = direct ? null : this.resolveFbo;
    gl.bindFramebuffer(gl.FRAMEBUFFER, target);
    gl.viewport(0, 0, width, height);
    const a = background[3] / 255;
    gl.clearColor((background[0] / 255) * a, (background[1] / 255) * a, (background[2] / 255) * a, a);
    gl.clear(gl.COLOR_BUFFER_BIT);
    gl.enable(gl.BLEND);
    gl.blendFunc(gl.ONE, gl.ONE_MINUS_SRC_ALPHA);
    // Every frame keeps the CPU renderer's order where a layer folds (see ORDER; a fragment
    // of a draft's or fast frame's element of many blocks by the block of its rest position).
    // Drawn in the order given, the skirt quarters along a cut (drawn after every quad) would
    // show through the side of the cut a drawing pushes over them.
    const ordered = this.orderFolds && (target !== null || this.canvasDepth);
    if (ordered) {
      gl.enable(gl.DEPTH_TEST);
      gl.depthFunc(gl.GEQUAL);
      gl.clearDepth(0);
    }
    for (const { layer, offset, opacity } of layers) {
      if (ordered) gl.clear(gl.DEPTH_BUFFER_BIT);
      if (fast) layer.useAdaptive();
      gl.activeTexture(gl.TEXTURE0);
      gl.bindTexture(gl.TEXTURE_2D, layer.field);
      gl.activeTexture(gl.TEXTURE1);
      gl.bindTexture(gl.TEXTURE_2D, layer.links);
      gl.activeTexture(gl.TEXTURE2);
      gl.bindTexture(gl.TEXTURE_2D, layer.image);
      gl.activeTexture(gl.TEXTURE3);
      gl.bindTexture(gl.TEXTURE_2D, layer.premultiplied);
      gl.activeTexture(gl.TEXTURE4);
      gl.bindTexture(gl.TEXTURE_2D, layer.sparseIndex);
      gl.activeTexture(gl.TEXTURE5);
      gl.bindTexture(gl.TEXTURE_2D, layer.sparseValues);
      for (const prog of [draft ? this.draftMesh : this.mesh, this.skirt]) {
        gl.useProgram(prog);
        const u = (n: string) => gl.getUniformLocation(prog, n);
        gl.uniform1i(u('uField'), 0);
        gl.uniform1i(u('uLinks'), 1);
        gl.uniform1i(u('uImage'), 2);
        gl.uniform1i(u('uPremultiplied'), 3);
        gl.uniform1i(u('uSparseIndex'), 4);
        gl.uniform1i(u('uSparseValues'), 5);
        gl.uniform1i(u('uSparse'), layer.sparse ? 1 : 0);
        gl.uniform2f(u('uCanvas'), width, height);
        gl.uniform2i(u('uSize'), layer.width, layer.height);
        gl.uniform2f(u('uOffset'), offset[0], offset[1]);
        gl.uniform1f(u('uOpacity'), opacity ?? 1);
        gl.uniform1f(u('uBlock'), draft ? layer.block : 1);
        gl.uniform1f(u('uEdge'), draft ? 1 : 0);
        gl.uniform1f(u('uLoose'), fast && prog !== this.skirt ? 2 * FAN_BLOCK : 0);
        if (prog !== this.skirt) {
          gl.bindVertexArray(this.vao);
          gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, draft ? layer.coarse : fast ? layer.adaptive : layer.indices);
          gl.drawElements(gl.TRIANGLES, draft ? layer.coarseCount : fast ? layer.adaptiveCount : layer.count, gl.UNSIGNED_INT, 0);
        } else if (draft ? layer.innerSkirtCount : layer.skirtCount) {
          gl.bindVertexArray(layer.skirtVao);
          gl.drawArrays(gl.TRIANGLES, 0, draft ? layer.innerSkirtCount : layer.skirtCount);
        }
      }
    }
    gl.bindVertexArray(null);
    gl.disable(gl.BLEND);
    gl.disable(gl.DEPTH_TEST);
    if (direct) return;
    // Resolve the samples, then show the frame on the canvas.
    gl.bindFramebuffer(gl.READ_FRAMEBUFFER, target);
    gl.bindFramebuffer(gl.DRAW_FRAMEBUFFER, this.resolveFbo);
    gl.blitFramebuffer(0, 0, width, height, 0, 0, width, height, gl.COLOR_BUFFER_BIT, gl.NEAREST);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.useProgram(this.blit);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, this.resolveTex);
    gl.uniform1i(gl.getUniformLocation(this.blit, 'uTex'), 0);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
  }

  /**
   * A sparse draft (or with `full`, a fast full frame) drawn by the CPU onto `draftCanvas`,
   * shown over the WebGL canvas.
   */
  private renderCpu(width: number, height: number, background: [number, number, number, number], layers: DrawLayer[], full = false, drawn: ImageData | null = null): void {
    const canvas = this.draftCanvas!;
    // A large frame's draft is drawn smaller and stretched over the frame (smoothly: its
    // pixels stand for blocks of the frame's), the full frame at its own size.
    const shrink = full ? 1 : Math.max(1, Math.floor(this.draftShrink));
    const { width: w, height: h } = proxySize(width, height, shrink);
    if (canvas.width !== w) canvas.width = w;
    if (canvas.height !== h) canvas.height = h;
    const was = this.cpuDrawn;
    if (was.shrink !== shrink || was.width !== width || was.height !== height) {
      // The last pixel column and row may stand for less than a block: the canvas reaches
      // past the frame by that much, hidden by the frame's edge.
      canvas.style.width = shrink > 1 ? `${(100 * w * shrink) / width}%` : '';
      canvas.style.height = shrink > 1 ? `${(100 * h * shrink) / height}%` : '';
      canvas.style.imageRendering = shrink > 1 ? 'auto' : '';
      this.cpuDrawn = { shrink, width, height };
    }
    if (drawn && drawn.width === w && drawn.height === h) {
      // Drawn already (by the draft worker): only put on the canvas. Its pixels may be
      // kept elsewhere (frames drawn ahead for playback): never drawn over.
      this.cpuFrame = drawn;
      this.cpuFrameBorrowed = true;
    } else {
      if (this.cpuFrameBorrowed || this.cpuFrame?.width !== w || this.cpuFrame.height !== h) this.cpuFrame = new ImageData(w, h);
      this.cpuFrameBorrowed = false;
      const engine = this.engine!;
      const what = layers.map(({ layer, offset, opacity }) => (full ? layer.cpuFull(engine, offset, opacity) : layer.cpuDraft(engine, offset, opacity)));
      engine.drawDraft(this.cpuFrame.data, width, height, background, what, shrink);
    }
    canvas.getContext('2d')!.putImageData(this.cpuFrame, 0, 0);
    this.showCpu(true);
  }

  /**
   * A draft frame drawn elsewhere (the draft worker, see `DraftDraw`), straight RGBA8 at
   * the size `draftShrink` gives: the next `render` of a draft of these layers, in the state
   * they are in now, puts these pixels on the CPU's canvas instead of drawing them. The
   * caller vouches that they are that draft.
   */
  offerDraft(pixels: Uint8ClampedArray, width: number, height: number, background: [number, number, number, number], layers: DrawLayer[]): void {
    const shrink = Math.max(1, Math.floor(this.draftShrink));
    const { width: w, height: h } = proxySize(width, height, shrink);
    if (pixels.length !== 4 * w * h) throw new Error(`A ${width} × ${height} draft at 1/${shrink} has ${4 * w * h} bytes, not ${pixels.length}.`);
    this.offered = { key: this.keyOf(width, height, background, layers, false, true, false), image: new ImageData(pixels as Uint8ClampedArray<ArrayBuffer>, w, h) };
  }

  private offered: { key: string; image: ImageData } | null = null;
  /** `cpuFrame` holds pixels offered by `offerDraft`, which a frame drawn here must not overwrite. */
  private cpuFrameBorrowed = false;

  /** `frameKey`, and how many times smaller a draft on the CPU is drawn. */
  private keyOf(width: number, height: number, background: [number, number, number, number], layers: DrawLayer[], antialias: boolean, draft: boolean, fast: boolean): string {
    const key = frameKey(width, height, background, layers, antialias, draft, fast);
    return draft && this.draftShrink > 1 ? `${key}|shrink ${this.draftShrink}` : key;
  }

  /** Shows the CPU's canvas or the WebGL one (never both: the one below would show through where a frame is transparent). */
  private showCpu(on: boolean): void {
    if (this.cpuShown === on || !this.draftCanvas) return;
    this.cpuShown = on;
    this.draftCanvas.style.visibility = on ? 'visible' : 'hidden';
    if ('style' in this.canvas) this.canvas.style.visibility = on ? 'hidden' : 'visible';
  }

  /**
   * Resolves with the time (performance.now()) the GPU finished the commands issued so
   * far: a fence polled between tasks, so nothing waits on the GPU (a software GPU draws
   * a frame long after the calls return). After a frame drawn by the CPU: now.
   */
  finished(): Promise<number> {
    // A frame drawn by the CPU is on its canvas already.
    if (this.cpuShown) return Promise.resolve(performance.now());
    const gl = this.gl;
    const sync = gl.fenceSync(gl.SYNC_GPU_COMMANDS_COMPLETE, 0);
    gl.flush();
    return new Promise((resolve) => {
      const poll = () => {
        if (!sync || gl.getSyncParameter(sync, gl.SYNC_STATUS) === gl.SIGNALED) {
          const t = performance.now();
          if (sync) gl.deleteSync(sync);
          resolve(t);
        } else setTimeout(poll, 1);
      };
      poll();
    });
  }

  /** The last frame as straight RGBA8, rows top to bottom (for tests and PNG export). */
  readPixels(): Uint8Array {
    if (this.cpuShown && this.cpuFrame) {
      const { shrink, width, height } = this.cpuDrawn;
      const src = this.cpuFrame;
      if (shrink === 1) return new Uint8Array(src.data);
      // A draft drawn smaller: each of its pixels over the block it stands for.
      const out = new Uint8Array(4 * width * height);
      const words = new Uint32Array(out.buffer);
      const from = new Uint32Array(src.data.buffer, src.data.byteOffset, src.width * src.height);
      for (let y = 0; y < height; y++) {
        const row = Math.floor(y / shrink) * src.width;
        for (let x = 0; x < width; x++) words[y * width + x] = from[row + Math.floor(x / shrink)];
      }
      return out;
    }
    const gl = this.gl;
    const { width, height } = this;
    const px = new Uint8Array(4 * width * height);
    gl.bindFramebuffer(gl.FRAMEBUFFER, this.shown);
    gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, px);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    // Rows come bottom-up and premultiplied: flip and unpremultiply.
    const out = new Uint8Array(px.length);
    const row = 4 * width;
    for (let y = 0; y < height; y++) {
      const src = (height - 1 - y) * row;
      for (let x = 0; x < row; x += 4) {
        const a = px[src + x + 3];
        const d = y * row + x;
        out[d + 3] = a;
        for (let c = 0; c < 3; c++) out[d + c] = a === 0 ? 0 : Math.min(255, Math.round((px[src + x + c] * 255) / a));
      }
    }
    return out;
  }
}
