// The WebGL2 renderer: the paper's forward mapping on the GPU (DESIGN §5).
//
// Every pixel of a layer is a vertex of a mesh placed at its displaced position (read in the
// vertex shader from a float texture holding the field); every 2×2 block of linked pixels is
// a quad whose colour is the bilinear mix of its four pixels' premultiplied RGBA; a quad
// with a missing link is dropped (moved outside the clip volume), so holes and cuts open.
// The mesh is extended by half a pixel beyond the layer's border with the border pixels'
// colour and displacement ("clamp to edge"), so the identity field covers every pixel fully.
// Quads are drawn row by row, top to bottom, left to right; where the mesh folds over
// itself a later quad is composited over an earlier one. Layers are composited back to
// front with premultiplied "over" into a multisampled target (coverage antialiasing), which
// is resolved into the canvas.

import type { FieldData } from './engine';

const VERT = `#version 300 es
precision highp float;
precision highp int;
uniform highp sampler2D uField;
uniform ivec2 uSize;
uniform vec2 uCanvas;
uniform vec2 uOffset;
out vec2 vRest;

// Vertex k of the extended mesh: node (i, j) with i in [-1, W], j in [-1, H]; the nodes
// beyond the border are the half-pixel skirt (rest position clamped to -0.5 / W - 0.5,
// displacement and colour of the border node).
void main() {
  int cols = uSize.x + 2;
  int i = gl_VertexID % cols - 1;
  int j = gl_VertexID / cols - 1;
  vec2 rest = vec2(clamp(float(i), -0.5, float(uSize.x) - 0.5), clamp(float(j), -0.5, float(uSize.y) - 0.5));
  vec2 d = texelFetch(uField, ivec2(clamp(i, 0, uSize.x - 1), clamp(j, 0, uSize.y - 1)), 0).rg;
  vec2 p = rest + d + uOffset;
  vRest = rest;
  gl_Position = vec4((p.x + 0.5) / uCanvas.x * 2.0 - 1.0, 1.0 - (p.y + 0.5) / uCanvas.y * 2.0, 0.0, 1.0);
}
`;

const FRAG = `#version 300 es
precision highp float;
precision highp int;
uniform highp sampler2D uImage;
uniform ivec2 uSize;
uniform float uOpacity;
in vec2 vRest;
out vec4 outColor;

vec4 px(int i, int j) {
  vec4 c = texelFetch(uImage, ivec2(clamp(i, 0, uSize.x - 1), clamp(j, 0, uSize.y - 1)), 0);
  return vec4(c.rgb * c.a, c.a);
}

// The bilinear mix of the quad's four premultiplied pixels at this rest position.
void main() {
  vec2 q = floor(vRest);
  vec2 f = vRest - q;
  int i = int(q.x);
  int j = int(q.y);
  vec4 top = mix(px(i, j), px(i + 1, j), f.x);
  vec4 bottom = mix(px(i, j + 1), px(i + 1, j + 1), f.x);
  outColor = mix(top, bottom, f.y) * uOpacity;
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

function program(gl: WebGL2RenderingContext, vs: string, fs: string): WebGLProgram {
  const p = gl.createProgram()!;
  gl.attachShader(p, compile(gl, gl.VERTEX_SHADER, vs));
  gl.attachShader(p, compile(gl, gl.FRAGMENT_SHADER, fs));
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(`Shader failed to link: ${gl.getProgramInfoLog(p)}`);
  return p;
}

/** One layer's GPU resources. */
export class GlLayer {
  image: WebGLTexture;
  field: WebGLTexture;
  /** Indices of the triangles of every quad whose four links exist. */
  indices: WebGLBuffer;
  count = 0;
  constructor(
    private r: GlRenderer,
    readonly width: number,
    readonly height: number,
  ) {
    const gl = r.gl;
    this.image = r.texture();
    this.field = r.texture();
    this.indices = gl.createBuffer()!;
    gl.bindTexture(gl.TEXTURE_2D, this.field);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RG32F, width, height, 0, gl.RG, gl.FLOAT, new Float32Array(2 * width * height));
    this.setLinks(null);
  }

  /** Straight RGBA8 pixels of the layer. */
  setImage(rgba: Uint8Array | Uint8ClampedArray): void {
    const gl = this.r.gl;
    gl.bindTexture(gl.TEXTURE_2D, this.image);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, this.width, this.height, 0, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(rgba.buffer, rgba.byteOffset, rgba.byteLength));
  }

  /**
   * The mesh from the grid's links (per node: bit 0 active, bit 1 linked right, bit 2
   * linked down; null: everything linked). A quad is drawn when its four edges are links;
   * the skirt beyond the border joins a border node to itself, linked when it is active.
   */
  setLinks(links: Uint8Array | null): void {
    const { width: w, height: h } = this;
    const at = (i: number, j: number) => (links ? links[Math.min(h - 1, Math.max(0, j)) * w + Math.min(w - 1, Math.max(0, i))] : 7);
    const right = (i: number, j: number) => ((i < 0 || i >= w - 1 ? at(i, j) & 1 : at(i, j) & 2) !== 0);
    const down = (i: number, j: number) => ((j < 0 || j >= h - 1 ? at(i, j) & 1 : at(i, j) & 4) !== 0);
    const cols = w + 2;
    const out = new Uint32Array(6 * (w + 1) * (h + 1));
    let n = 0;
    for (let j = -1; j < h; j++) {
      for (let i = -1; i < w; i++) {
        if (!(right(i, j) && right(i, j + 1) && down(i, j) && down(i + 1, j))) continue;
        const k = (j + 1) * cols + (i + 1);
        out[n++] = k;
        out[n++] = k + 1;
        out[n++] = k + cols;
        out[n++] = k + cols;
        out[n++] = k + 1;
        out[n++] = k + cols + 1;
      }
    }
    const gl = this.r.gl;
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.indices);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, out.subarray(0, n), gl.STATIC_DRAW);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, null);
    this.count = n;
  }

  setField(field: FieldData | null): void {
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
  }

  dispose(): void {
    const gl = this.r.gl;
    gl.deleteTexture(this.image);
    gl.deleteTexture(this.field);
    gl.deleteBuffer(this.indices);
  }
}

export interface DrawLayer {
  layer: GlLayer;
  offset: [number, number];
  opacity?: number;
}

export class GlRenderer {
  readonly gl: WebGL2RenderingContext;
  private mesh: WebGLProgram;
  private blit: WebGLProgram;
  private vao: WebGLVertexArrayObject;
  private msaaFbo: WebGLFramebuffer | null = null;
  private msaaRb: WebGLRenderbuffer | null = null;
  private resolveFbo: WebGLFramebuffer | null = null;
  private resolveTex: WebGLTexture | null = null;
  private width = 0;
  private height = 0;
  readonly samples: number;

  constructor(readonly canvas: HTMLCanvasElement | OffscreenCanvas) {
    const gl = canvas.getContext('webgl2', { antialias: false, premultipliedAlpha: true, preserveDrawingBuffer: true, alpha: true }) as WebGL2RenderingContext | null;
    if (!gl) throw new Error('This browser has no WebGL2; the editor needs it to draw the warped picture.');
    this.gl = gl;
    this.mesh = program(gl, VERT, FRAG);
    this.blit = program(gl, BLIT_VERT, `#version 300 es
precision highp float;
uniform sampler2D uTex;
in vec2 vPos;
out vec4 o;
void main() { o = texture(uTex, vPos); }`);
    this.vao = gl.createVertexArray()!;
    this.samples = Math.min(4, gl.getParameter(gl.MAX_SAMPLES) as number);
  }

  texture(): WebGLTexture {
    const gl = this.gl;
    const t = gl.createTexture()!;
    gl.bindTexture(gl.TEXTURE_2D, t);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
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
    if (this.resolveFbo) gl.deleteFramebuffer(this.resolveFbo);
    if (this.resolveTex) gl.deleteTexture(this.resolveTex);
    this.msaaRb = gl.createRenderbuffer();
    gl.bindRenderbuffer(gl.RENDERBUFFER, this.msaaRb);
    gl.renderbufferStorageMultisample(gl.RENDERBUFFER, this.samples, gl.RGBA8, width, height);
    this.msaaFbo = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, this.msaaFbo);
    gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.RENDERBUFFER, this.msaaRb);
    this.resolveTex = this.texture();
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, width, height, 0, gl.RGBA, gl.UNSIGNED_BYTE, null);
    this.resolveFbo = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, this.resolveFbo);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, this.resolveTex, 0);
  }

  /**
   * Renders a frame: the background (straight RGBA8) then each layer, back to front.
   * The result stays in the resolve target (for `readPixels`) and is shown on the canvas.
   */
  render(width: number, height: number, background: [number, number, number, number], layers: DrawLayer[]): void {
    const gl = this.gl;
    this.ensureTargets(width, height);
    gl.bindFramebuffer(gl.FRAMEBUFFER, this.msaaFbo);
    gl.viewport(0, 0, width, height);
    const a = background[3] / 255;
    gl.clearColor((background[0] / 255) * a, (background[1] / 255) * a, (background[2] / 255) * a, a);
    gl.clear(gl.COLOR_BUFFER_BIT);
    gl.enable(gl.BLEND);
    gl.blendFunc(gl.ONE, gl.ONE_MINUS_SRC_ALPHA);
    gl.useProgram(this.mesh);
    gl.bindVertexArray(this.vao);
    const u = (n: string) => gl.getUniformLocation(this.mesh, n);
    gl.uniform1i(u('uField'), 0);
    gl.uniform1i(u('uImage'), 2);
    gl.uniform2f(u('uCanvas'), width, height);
    for (const { layer, offset, opacity } of layers) {
      gl.activeTexture(gl.TEXTURE0);
      gl.bindTexture(gl.TEXTURE_2D, layer.field);
      gl.activeTexture(gl.TEXTURE2);
      gl.bindTexture(gl.TEXTURE_2D, layer.image);
      gl.uniform2i(u('uSize'), layer.width, layer.height);
      gl.uniform2f(u('uOffset'), offset[0], offset[1]);
      gl.uniform1f(u('uOpacity'), opacity ?? 1);
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, layer.indices);
      gl.drawElements(gl.TRIANGLES, layer.count, gl.UNSIGNED_INT, 0);
    }
    gl.bindVertexArray(null);
    gl.disable(gl.BLEND);
    // Resolve the samples, then show the frame on the canvas.
    gl.bindFramebuffer(gl.READ_FRAMEBUFFER, this.msaaFbo);
    gl.bindFramebuffer(gl.DRAW_FRAMEBUFFER, this.resolveFbo);
    gl.blitFramebuffer(0, 0, width, height, 0, 0, width, height, gl.COLOR_BUFFER_BIT, gl.NEAREST);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.useProgram(this.blit);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, this.resolveTex);
    gl.uniform1i(gl.getUniformLocation(this.blit, 'uTex'), 0);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
  }

  /** The last frame as straight RGBA8, rows top to bottom (for tests and PNG export). */
  readPixels(): Uint8Array {
    const gl = this.gl;
    const { width, height } = this;
    const px = new Uint8Array(4 * width * height);
    gl.bindFramebuffer(gl.FRAMEBUFFER, this.resolveFbo);
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
