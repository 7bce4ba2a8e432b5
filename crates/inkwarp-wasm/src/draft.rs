//! Draft frames drawn on the CPU, for the editor on a software GPU: the WebGL2 draft's
//! triangles, positions and colours (the editor's `web/src/gl.ts`), rasterised here; and
//! the same for the fast full frame after a settle (its adaptive triangles, every skirt
//! quarter, every pixel's value).
//!
//! A draft layer is the layer's premultiplied pixels, its mesh (triangles over pixel
//! vertices), the skirt quarters it draws, its links, and the place of each pixel in the
//! values of its field (a sparse draft's, or every pixel's). A frame composites layers over a background with
//! premultiplied "over", rounding to 8 bits at each layer as a GPU's RGBA8 target does.
//! Where a layer folds, its fragments keep the full frame's order ([`rank`], the editor's
//! `ORDER`): a triangle's fragment is ranked by the block its rest position lies in (the
//! full mesh's quad there), a skirt quarter's by the quarter's block, and a fragment is
//! drawn only over one of no higher rank, as the GPU's depth test draws them. (Drawn in
//! the order given, the quarters along a cut, drawn after every triangle, showed through
//! the other side where the drawing pushed one side of the cut under the other.)
//! Colours are the bilinear mix of the 8-bit premultiplied pixels with 8-bit weights, as
//! the draft elements' texture unit filters; the skirt quarters' shader premultiplies and
//! mixes in floating point, which this rounds differently by at most a level.

use std::cell::RefCell;

use crate::{fail, insert, release, slot_mut, view, view_mut};

/// One layer's draft geometry and pixels (see the module docs).
#[derive(Debug)]
struct DraftLayer {
    width: usize,
    height: usize,
    /// Premultiplied RGBA8, one little-endian word a pixel (R in the low byte).
    pixels: Vec<u32>,
    /// The mesh's triangles, as pixel indices.
    coarse: Vec<u32>,
    /// The skirt quarters' vertices (a draft's: those along cuts and holes): (x, y, sx,
    /// sy, u, v), six vertices a quarter.
    skirts: Vec<f32>,
    /// Per pixel: bit 0 active, bit 1 linked right, bit 2 linked down.
    links: Vec<u8>,
    /// Per pixel, its place in the sparse draft's values.
    index: Vec<u32>,
    /// How many pixels the sparse draft holds.
    reads: usize,
    /// Whether the mesh's vertices on the layer's border move out by half a pixel (a draft:
    /// its skirts along the border are not drawn), or stay (a fast full frame, whose skirt
    /// quarters cover the border).
    push_border: bool,
    /// The pixels box-filtered by a whole factor, for frames drawn smaller (see
    /// [`iw_draft_draw`]): the factor, the level's size and its premultiplied words. Made
    /// at the first such frame and kept.
    level: Option<(usize, usize, usize, Vec<u32>)>,
}

impl DraftLayer {
    /// Makes the pixels a frame drawn `shrink` times smaller samples ([`Self::sampled`]),
    /// unless they are made already: the mean of each `shrink × shrink` block (the blocks
    /// along the right and bottom edges as far as the layer goes).
    fn make_level(&mut self, shrink: usize) {
        if shrink > 1 && self.level.as_ref().map(|l| l.0) != Some(shrink) {
            let (w, h) = (self.width.div_ceil(shrink), self.height.div_ceil(shrink));
            let mut out = Vec::with_capacity(w * h);
            for j in 0..h {
                let rows = j * shrink..((j + 1) * shrink).min(self.height);
                for i in 0..w {
                    let cols = i * shrink..((i + 1) * shrink).min(self.width);
                    let mut sum = [0u32; 4];
                    for y in rows.clone() {
                        for &px in
                            &self.pixels[y * self.width + cols.start..y * self.width + cols.end]
                        {
                            for (c, s) in sum.iter_mut().enumerate() {
                                *s += (px >> (8 * c)) & 255;
                            }
                        }
                    }
                    let n = (rows.len() * cols.len()) as u32;
                    out.push(
                        sum.iter()
                            .enumerate()
                            .fold(0u32, |acc, (c, &s)| acc | ((s + n / 2) / n) << (8 * c)),
                    );
                }
            }
            self.level = Some((shrink, w, h, out));
        }
    }

    /// The pixels (and their size) a frame drawn `shrink` times smaller samples: the
    /// layer's own for 1, else the level [`Self::make_level`] made.
    fn sampled(&self, shrink: usize) -> (&[u32], usize, usize) {
        match &self.level {
            Some((s, w, h, px)) if shrink > 1 && *s == shrink => (px, *w, *h),
            _ => (&self.pixels, self.width, self.height),
        }
    }
}

thread_local! {
    static DRAFTS: RefCell<Vec<Option<DraftLayer>>> = const { RefCell::new(Vec::new()) };
}

/// A draft layer of `width × height` from its premultiplied RGBA8 (`4·w·h` bytes), its
/// draft mesh's triangles (`coarse_len` indices), its inner skirt quarters' vertices
/// (`skirts_len` floats, 6 a vertex), its links and its sparse index (`w·h` each: the
/// place of each pixel among the `reads` pixels its sparse drafts hold). Every pixel the
/// triangles and quarters read must have a place. `push_border` (nonzero) moves the
/// triangles' vertices on the layer's border out by half a pixel, as the WebGL2 draft does
/// where it draws no skirts along the border; a fast full frame passes every skirt quarter
/// and 0. Returns a handle ≥ 1, or 0 with the error in the result buffer.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub extern "C" fn iw_draft_new(
    width: usize,
    height: usize,
    pixels_ptr: *const u8,
    coarse_ptr: *const u32,
    coarse_len: usize,
    skirts_ptr: *const f32,
    skirts_len: usize,
    links_ptr: *const u8,
    index_ptr: *const u32,
    reads: usize,
    push_border: u32,
) -> u32 {
    let n = width * height;
    if n == 0
        || coarse_len % 3 != 0
        || skirts_len % 36 != 0
        || pixels_ptr.is_null()
        || links_ptr.is_null()
        || index_ptr.is_null()
    {
        fail(format!(
            "A draft layer needs a size, whole triangles, whole skirt quarters, its pixels, links and index (got {width}×{height}, {coarse_len} indices, {skirts_len} skirt floats)."
        ));
        return 0;
    }
    let index = view(index_ptr, n).to_vec();
    let coarse = view(coarse_ptr, coarse_len).to_vec();
    let skirts = view(skirts_ptr, skirts_len).to_vec();
    if let Err(e) = check_triangles(&coarse, width, height, &index, reads)
        .and_then(|()| check_quarters(&skirts, width, height, &index, reads))
    {
        fail(e);
        return 0;
    }
    let pixels = view(pixels_ptr, 4 * n)
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    let layer = DraftLayer {
        width,
        height,
        pixels,
        coarse,
        skirts,
        links: view(links_ptr, n).to_vec(),
        index,
        reads,
        push_border: push_border != 0,
        level: None,
    };
    DRAFTS.with(|d| insert(&mut d.borrow_mut(), layer))
}

/// Replaces a draft layer's triangles (`coarse_len` pixel indices, checked as
/// [`iw_draft_new`] checks them), keeping its pixels, skirts, links and index: a fast full
/// frame's triangles follow its field, the rest of the layer does not. Status 0/1.
#[no_mangle]
pub extern "C" fn iw_draft_set_triangles(
    handle: u32,
    coarse_ptr: *const u32,
    coarse_len: usize,
) -> i32 {
    let coarse = view(coarse_ptr, coarse_len);
    let set = DRAFTS.with(|d| {
        let mut store = d.borrow_mut();
        let Some(layer) = slot_mut(&mut store, handle) else {
            return Err(format!("There is no draft layer with handle {handle}."));
        };
        if coarse_len % 3 != 0 {
            return Err(format!(
                "Draft triangles need whole triangles (got {coarse_len} indices)."
            ));
        }
        check_triangles(coarse, layer.width, layer.height, &layer.index, layer.reads)?;
        layer.coarse = coarse.to_vec();
        Ok(())
    });
    match set {
        Ok(()) => 0,
        Err(e) => fail(e),
    }
}

/// Every triangle corner is a pixel of the `width × height` layer with a place among the
/// `reads` pixels of its values.
fn check_triangles(
    coarse: &[u32],
    width: usize,
    height: usize,
    index: &[u32],
    reads: usize,
) -> Result<(), String> {
    for &v in coarse {
        let Some(&place) = index.get(v as usize) else {
            return Err(format!(
                "A draft triangle refers to pixel {v} of a {width}×{height} layer."
            ));
        };
        if place as usize >= reads {
            return Err(format!(
                "Pixel {v} of the draft mesh has no place among the {reads} pixels of its values."
            ));
        }
    }
    Ok(())
}

/// Every skirt quarter sits on a pixel of the layer, and it and its linked neighbours have
/// a place among the `reads` pixels of its values.
fn check_quarters(
    skirts: &[f32],
    width: usize,
    height: usize,
    index: &[u32],
    reads: usize,
) -> Result<(), String> {
    for quarter in skirts.chunks_exact(36) {
        let (x, y) = (quarter[0], quarter[1]);
        if !(x >= 0.0
            && y >= 0.0
            && (x as usize) < width
            && (y as usize) < height
            && x.fract() == 0.0
            && y.fract() == 0.0)
        {
            return Err(format!(
                "A skirt quarter at ({x}, {y}) is off the {width}×{height} layer."
            ));
        }
        let (i, j) = (x as usize, y as usize);
        let p = j * width + i;
        let around = [
            Some(p),
            (i + 1 < width).then(|| p + 1),
            (i > 0).then(|| p - 1),
            (j + 1 < height).then(|| p + width),
            (j > 0).then(|| p - width),
        ];
        if let Some(q) = around
            .into_iter()
            .flatten()
            .find(|&q| index[q] as usize >= reads)
        {
            return Err(format!(
                "Pixel {q} of the draft mesh has no place among the {reads} pixels of its values."
            ));
        }
    }
    Ok(())
}

/// Frees a draft layer.
#[no_mangle]
pub extern "C" fn iw_draft_free(handle: u32) {
    DRAFTS.with(|d| release(&mut d.borrow_mut(), handle));
}

/// Draws a draft frame of `width × height` into `out_ptr` (straight RGBA8, rows top to
/// bottom): the background (straight RGBA8), then `count` layers back to front, each six
/// numbers at `layers_ptr`: its handle, a pointer to its sparse draft's (dx, dy) pairs and
/// their count of floats, its offset (x, y) and its opacity. Status 0/1.
///
/// With `shrink` above 1 the frame is drawn that many times smaller, `⌈width / shrink⌉ ×
/// ⌈height / shrink⌉` pixels, for a large picture while dragging: the same triangles with
/// every position (x, y) at ((x + ½) / shrink − ½, (y + ½) / shrink − ½), the pixel
/// centres of the smaller frame, coloured from the layer's pixels box-filtered by the same
/// factor (made at the first such frame and kept), so each pixel is about the mean of the
/// `shrink × shrink` pixels it stands for.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub extern "C" fn iw_draft_draw(
    out_ptr: *mut u8,
    width: usize,
    height: usize,
    shrink: usize,
    r: u8,
    g: u8,
    b: u8,
    a: u8,
    layers_ptr: *const f64,
    count: usize,
) -> i32 {
    let shrink = shrink.max(1);
    let (width, height) = (width.div_ceil(shrink), height.div_ceil(shrink));
    let args = view(layers_ptr, 6 * count);
    let out = view_mut(out_ptr, 4 * width * height);
    if out.len() != 4 * width * height {
        return fail("No room for the draft frame.");
    }
    let premultiply = |c: u8| ((c as u32 * a as u32 + 127) / 255) as u8;
    let background = u32::from_le_bytes([premultiply(r), premultiply(g), premultiply(b), a]);
    let mut frame = vec![background; width * height];
    let mut ranks = vec![0u32; width * height];
    let drawn = DRAFTS.with(|d| {
        let mut store = d.borrow_mut();
        for arg in args.chunks_exact(6) {
            let Some(layer) = slot_mut(&mut store, arg[0] as u32) else {
                return Err(format!("There is no draft layer with handle {}.", arg[0]));
            };
            layer.make_level(shrink);
            let layer = &*layer;
            let values = view(arg[1] as usize as *const f32, arg[2] as usize);
            let needed = 2 * layer.reads;
            if values.len() < needed {
                return Err(format!(
                    "A sparse draft of {} values for a layer that reads {needed}.",
                    values.len()
                ));
            }
            ranks.fill(0);
            let target = Target {
                frame: &mut frame,
                ranks: &mut ranks,
                width,
                height,
            };
            draw_layer(target, layer, values, [arg[3], arg[4]], arg[5], shrink);
        }
        Ok(())
    });
    if let Err(e) = drawn {
        return fail(e);
    }
    for (px, o) in frame.iter().zip(out.chunks_exact_mut(4)) {
        let [r, g, b, a] = px.to_le_bytes();
        if a == 255 || a == 0 {
            o.copy_from_slice(&[r, g, b, a]);
        } else {
            let s = 255.0 / a as f32;
            let un = |c: u8| (c as f32 * s + 0.5).min(255.0) as u8;
            o.copy_from_slice(&[un(r), un(g), un(b), a]);
        }
    }
    0
}

/// The frame being drawn: premultiplied RGBA8 words, and per pixel the highest [`rank`]
/// the layer being drawn has put there (0 where it has put nothing).
struct Target<'a> {
    frame: &'a mut [u32],
    ranks: &'a mut [u32],
    width: usize,
    height: usize,
}

/// The place of block (`i`, `j`) (the unit square right of and below pixel (`i`, `j`); −1
/// for those beyond the top and left edges) of a `width × height` layer in the full
/// frame's drawing order, from 0: further down, then further right, is in front.
fn rank(i: i64, j: i64, width: usize, height: usize) -> u32 {
    let (i, j) = (i.clamp(-1, width as i64), j.clamp(-1, height as i64));
    ((j + 1) * (width as i64 + 1) + i + 1) as u32
}

/// How a fragment is ranked in the full frame's order ([`rank`]).
#[derive(Clone, Copy)]
enum Rank {
    /// A skirt quarter's fragments: its block's.
    Block(u32),
    /// A triangle's: the block of the fragment's rest position, on a `width × height` layer
    /// whose positions are drawn `shrink` times smaller (see [`iw_draft_draw`]).
    Rest {
        width: usize,
        height: usize,
        shrink: usize,
    },
}

impl Rank {
    /// The rank of a fragment at rest position (`x`, `y`) in the frame drawn.
    fn at(self, x: f64, y: f64) -> u32 {
        self.of(|shrink| [x, y].map(|v| ((v + 0.5) * shrink as f64 - 0.5).floor() as i64))
    }

    /// [`Rank::at`] a rest position in 16.16 fixed point.
    fn at_fixed(self, x: i32, y: i32) -> u32 {
        self.of(|shrink| [x, y].map(|v| ((v as i64 + 32768) * shrink as i64 - 32768) >> 16))
    }

    /// The rank of the layer pixel `pixel(shrink)` gives (the draft's rest position taken to the layer's pixels).
    fn of(self, pixel: impl FnOnce(usize) -> [i64; 2]) -> u32 {
        match self {
            Rank::Block(order) => order,
            Rank::Rest { width, height, shrink } => {
                let [x, y] = pixel(shrink);
                rank(x, y, width, height)
            }
        }
    }
}

/// A triangle's corners: screen and rest positions.
#[derive(Clone, Copy, Default)]
struct Corner {
    x: f64,
    y: f64,
    rx: f64,
    ry: f64,
}

/// How a triangle's fragments take their colour.
struct Shade<'a> {
    /// The pixels sampled (the layer's, or its level for a smaller frame) and their size.
    pixels: &'a [u32],
    width: usize,
    height: usize,
    /// Opacity in 256ths.
    opacity: u32,
    /// A skirt quarter's rest box (min x, min y, max x, max y); none for draft elements.
    clamp: Option<[f64; 4]>,
    /// The fragments' place in the full frame's order.
    rank: Rank,
}

fn draw_layer(
    mut t: Target,
    layer: &DraftLayer,
    values: &[f32],
    offset: [f64; 2],
    opacity: f64,
    shrink: usize,
) {
    let (w, h) = (layer.width, layer.height);
    let (pixels, lw, lh) = layer.sampled(shrink);
    // A position on the layer or the frame, in the frame drawn (see `iw_draft_draw`).
    let inv = 1.0 / shrink as f64;
    let at = |v: f64| if shrink > 1 { (v + 0.5) * inv - 0.5 } else { v };
    let place = |c: Corner| Corner {
        x: at(c.x),
        y: at(c.y),
        rx: at(c.rx),
        ry: at(c.ry),
    };
    let field = |p: usize| {
        let k = 2 * layer.index[p] as usize;
        (values[k] as f64, values[k + 1] as f64)
    };
    let opacity = (opacity.clamp(0.0, 1.0) * 256.0).round() as u32;
    let element = Shade {
        pixels,
        width: lw,
        height: lh,
        opacity,
        clamp: None,
        rank: Rank::Rest {
            width: w,
            height: h,
            shrink,
        },
    };
    // The mesh: for a draft, the border's vertices pushed out by half a pixel.
    let push = if layer.push_border { 0.5 } else { 0.0 };
    for tri in layer.coarse.chunks_exact(3) {
        let mut c = [Corner::default(); 3];
        for (corner, &p) in c.iter_mut().zip(tri) {
            let p = p as usize;
            let (i, j) = (p % w, p / w);
            let out = |k: usize, n: usize| {
                if k == 0 {
                    -push
                } else if k == n - 1 {
                    push
                } else {
                    0.0
                }
            };
            let (rx, ry) = (i as f64 + out(i, w), j as f64 + out(j, h));
            let (dx, dy) = field(p);
            *corner = place(Corner {
                x: rx + dx + offset[0],
                y: ry + dy + offset[1],
                rx,
                ry,
            });
        }
        fill(&mut t, &c, &element);
    }
    // The skirt quarters (see `SKIRT_VERT` in the editor's gl.ts).
    let linked = |i: i64, j: i64, bit: u8| {
        i >= 0
            && j >= 0
            && (i as usize) < w
            && (j as usize) < h
            && layer.links[j as usize * w + i as usize] & bit != 0
    };
    let right = |i: i64, j: i64| (i as usize) < w - 1 && linked(i, j, 2);
    let down = |i: i64, j: i64| (j as usize) < h - 1 && linked(i, j, 4);
    for quarter in layer.skirts.chunks_exact(36) {
        let (i, j, sx, sy) = (
            quarter[0] as i64,
            quarter[1] as i64,
            quarter[2] as f64,
            quarter[3] as f64,
        );
        let p = j as usize * w + i as usize;
        let order = rank(i - (sx < 0.0) as i64, j - (sy < 0.0) as i64, w, h);
        let (dx, dy) = field(p);
        let (px, py) = (i as f64 + dx, j as f64 + dy);
        let pos = |q: usize, qi: i64, qj: i64| {
            let (dx, dy) = field(q);
            (qi as f64 + dx, qj as f64 + dy)
        };
        let (rx, lx, dw, uy) = (right(i, j), right(i - 1, j), down(i, j), down(i, j - 1));
        let mut ex = if rx {
            let q = pos(p + 1, i + 1, j);
            (q.0 - px, q.1 - py)
        } else if lx {
            let q = pos(p - 1, i - 1, j);
            (px - q.0, py - q.1)
        } else {
            (0.0, 0.0)
        };
        let mut ey = if dw {
            let q = pos(p + w, i, j + 1);
            (q.0 - px, q.1 - py)
        } else if uy {
            let q = pos(p - w, i, j - 1);
            (px - q.0, py - q.1)
        } else {
            (0.0, 0.0)
        };
        if ex == (0.0, 0.0) {
            ex = if ey == (0.0, 0.0) {
                (1.0, 0.0)
            } else {
                (ey.1, -ey.0)
            };
        }
        if ey == (0.0, 0.0) {
            ey = (-ex.1, ex.0);
        }
        let link_x = if sx > 0.0 { rx } else { lx };
        let link_y = if sy > 0.0 { dw } else { uy };
        let (kx, ky) = (if link_x { sx } else { 0.0 }, if link_y { sy } else { 0.0 });
        let (far_x, far_y) = (i as f64 + 0.5 * kx, j as f64 + 0.5 * ky);
        let shade = Shade {
            pixels,
            width: lw,
            height: lh,
            opacity,
            clamp: Some([
                at((i as f64).min(far_x)),
                at((j as f64).min(far_y)),
                at((i as f64).max(far_x)),
                at((j as f64).max(far_y)),
            ]),
            rank: Rank::Block(order),
        };
        for half in quarter.chunks_exact(18) {
            let mut c = [Corner::default(); 3];
            for (corner, v) in c.iter_mut().zip(half.chunks_exact(6)) {
                let (u, s) = (v[4] as f64, v[5] as f64);
                *corner = place(Corner {
                    x: px + 0.5 * (u * sx * ex.0 + s * sy * ey.0) + offset[0],
                    y: py + 0.5 * (u * sx * ex.1 + s * sy * ey.1) + offset[1],
                    rx: i as f64 + 0.5 * u * kx,
                    ry: j as f64 + 0.5 * s * ky,
                });
            }
            fill(&mut t, &c, &shade);
        }
    }
}

/// The edge function of a → b as `E(p) = A·x + B·y + C`, its coefficients computed from the
/// lexicographically smaller end: the two triangles sharing an edge see exactly opposite
/// values at every pixel centre, so a centre on it is drawn by exactly one of them.
fn edge(a: (f64, f64), b: (f64, f64)) -> [f64; 3] {
    let flip = !(a.0 < b.0 || (a.0 == b.0 && a.1 < b.1));
    let (p, q, s) = if flip { (b, a, -1.0) } else { (a, b, 1.0) };
    [
        -(q.1 - p.1) * s,
        (q.0 - p.0) * s,
        ((q.1 - p.1) * p.0 - (q.0 - p.0) * p.1) * s,
    ]
}

/// Whether a pixel centre exactly on edge a → b (of a triangle of positive area) is drawn.
fn owns(a: (f64, f64), b: (f64, f64)) -> bool {
    let dy = b.1 - a.1;
    dy > 0.0 || (dy == 0.0 && b.0 < a.0)
}

/// Shades the pixel centres inside a triangle where the layer has drawn nothing of a
/// higher rank ([`Shade::rank`]); a fragment with no alpha adds nothing and keeps its
/// pixel's rank (the GPU discards it).
fn fill(t: &mut Target, c: &[Corner; 3], shade: &Shade) {
    let cross = (c[1].x - c[0].x) * (c[2].y - c[0].y) - (c[1].y - c[0].y) * (c[2].x - c[0].x);
    if cross == 0.0 || !cross.is_finite() {
        return;
    }
    let (v0, v1, v2) = if cross > 0.0 {
        (c[0], c[1], c[2])
    } else {
        (c[0], c[2], c[1])
    };
    let (p0, p1, p2) = ((v0.x, v0.y), (v1.x, v1.y), (v2.x, v2.y));
    let (e0, e1, e2) = (edge(p1, p2), edge(p2, p0), edge(p0, p1));
    let area = e0[0] * p0.0 + e0[1] * p0.1 + e0[2];
    if area.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return;
    }
    let (o0, o1, o2) = (owns(p1, p2), owns(p2, p0), owns(p0, p1));
    let min_x = p0.0.min(p1.0).min(p2.0).ceil().max(0.0);
    let max_x = p0.0.max(p1.0).max(p2.0).floor().min(t.width as f64 - 1.0);
    let min_y = p0.1.min(p1.1).min(p2.1).ceil().max(0.0);
    let max_y = p0.1.max(p1.1).max(p2.1).floor().min(t.height as f64 - 1.0);
    if min_x > max_x || min_y > max_y {
        return;
    }
    // The rest position as an affine function of the pixel centre.
    let inv = 1.0 / area;
    let affine = |r0: f64, r1: f64, r2: f64| {
        [
            (e0[0] * r0 + e1[0] * r1 + e2[0] * r2) * inv,
            (e0[1] * r0 + e1[1] * r1 + e2[1] * r2) * inv,
            (e0[2] * r0 + e1[2] * r1 + e2[2] * r2) * inv,
        ]
    };
    let rx = affine(v0.rx, v1.rx, v2.rx);
    let ry = affine(v0.ry, v1.ry, v2.ry);
    let owned = |e: f64, owns: bool| e > 0.0 || (e == 0.0 && owns);
    let (w, h, pixels) = (shade.width, shade.height, shade.pixels);
    // Each edge's crossing of a row is −c/a: its reciprocal once (the exact edge values at
    // the crossing decide which centres it keeps).
    let minus_inv = [e0[0], e1[0], e2[0]].map(|a| if a != 0.0 { -1.0 / a } else { 0.0 });
    for y in min_y as usize..=max_y as usize {
        let yf = y as f64;
        let (c0, c1, c2) = (e0[1] * yf + e0[2], e1[1] * yf + e1[2], e2[1] * yf + e2[2]);
        // The row's span: each edge bounds it on one side at its crossing of the row
        // (rounded to the pixel centres it keeps, the crossing's own centre decided by
        // the exact edge value there and the tie rule); a horizontal edge keeps or drops
        // the whole row. The pixels inside a triangle form one run per row.
        let (mut lo, mut hi) = (min_x, max_x);
        let mut empty = false;
        for ((a, c, owns), inv) in [(e0[0], c0, o0), (e1[0], c1, o1), (e2[0], c2, o2)]
            .into_iter()
            .zip(minus_inv)
        {
            let keeps = |x: f64| owned(a * x + c, owns);
            if a > 0.0 {
                let mut x = (c * inv).ceil();
                if !keeps(x) {
                    x += 1.0;
                } else if keeps(x - 1.0) {
                    x -= 1.0;
                }
                lo = lo.max(x);
            } else if a < 0.0 {
                let mut x = (c * inv).floor();
                if !keeps(x) {
                    x -= 1.0;
                } else if keeps(x + 1.0) {
                    x += 1.0;
                }
                hi = hi.min(x);
            } else if !owned(c, owns) {
                empty = true;
            }
        }
        if empty || lo > hi {
            continue;
        }
        let row = &mut t.frame[y * t.width..][..t.width];
        let run = &mut row[lo as usize..=hi as usize];
        let ranks = &mut t.ranks[y * t.width..][lo as usize..=hi as usize];
        // A fragment of rank `order` over what the layer put there of no higher rank.
        let put = |dst: &mut u32, seen: &mut u32, order: u32, src: u32| {
            if src >> 24 != 0 {
                *seen = order;
                *dst = over(src, *dst);
            }
        };
        let n = run.len() as f64;
        let (sx, sy) = (
            rx[0] * lo + rx[1] * yf + rx[2],
            ry[0] * lo + ry[1] * yf + ry[2],
        );
        if let Some(b) = shade.clamp {
            // A skirt quarter (a few pixels): its rest box clamps every sample.
            let order = shade.rank.at(sx, sy);
            for (k, (dst, seen)) in run.iter_mut().zip(ranks).enumerate() {
                if *seen <= order {
                    let x = (sx + rx[0] * k as f64).clamp(b[0], b[2]);
                    let y = (sy + ry[0] * k as f64).clamp(b[1], b[3]);
                    put(
                        dst,
                        seen,
                        order,
                        bilinear(pixels, w, h, x, y, shade.opacity),
                    );
                }
            }
        } else if [sx, sy, sx + rx[0] * n, sy + ry[0] * n]
            .iter()
            .all(|v| v.abs() < FIXED_MAX)
        {
            // A draft element: its rest position steps in 16.16 fixed point along the run.
            let fixed = |v: f64| (v * 65536.0).round_ties_even() as i32;
            let (mut fx, mut fy, dfx, dfy) = (fixed(sx), fixed(sy), fixed(rx[0]), fixed(ry[0]));
            for (dst, seen) in run.iter_mut().zip(ranks) {
                let order = shade.rank.at_fixed(fx, fy);
                if *seen <= order {
                    let src = bilinear_fixed(pixels, w, h, fx, fy, shade.opacity);
                    put(dst, seen, order, src);
                }
                fx = fx.wrapping_add(dfx);
                fy = fy.wrapping_add(dfy);
            }
        } else {
            // A sliver folded over (its rest position races along the run) or a huge layer.
            for (k, (dst, seen)) in run.iter_mut().zip(ranks).enumerate() {
                let (x, y) = (sx + rx[0] * k as f64, sy + ry[0] * k as f64);
                let order = shade.rank.at(x, y);
                if *seen <= order {
                    put(
                        dst,
                        seen,
                        order,
                        bilinear(pixels, w, h, x, y, shade.opacity),
                    );
                }
            }
        }
    }
}

/// Rest positions stepped in 16.16 fixed point stay below this (pixels) in magnitude.
const FIXED_MAX: f64 = 30_000.0;

/// [`bilinear`] at (x, y) in 16.16 fixed point.
#[inline]
fn bilinear_fixed(pixels: &[u32], w: usize, h: usize, x: i32, y: i32, opacity: u32) -> u32 {
    let (i, j) = ((x >> 16) as i64, (y >> 16) as i64);
    let (ux, uy) = (
        (((x & 0xffff) + 128) >> 8) as u32,
        (((y & 0xffff) + 128) >> 8) as u32,
    );
    mix(pixels, w, h, i, j, ux, uy, opacity)
}

/// The bilinear mix of premultiplied pixels at (x, y) (pixel centres at integers, the edge
/// pixels repeated beyond), with 8-bit weights as a GPU's texture unit filters, times the
/// opacity (in 256ths).
#[inline]
fn bilinear(pixels: &[u32], w: usize, h: usize, x: f64, y: f64, opacity: u32) -> u32 {
    let (fx, fy) = (x.floor(), y.floor());
    let (ux, uy) = (
        ((x - fx) * 256.0 + 0.5) as u32,
        ((y - fy) * 256.0 + 0.5) as u32,
    );
    mix(pixels, w, h, fx as i64, fy as i64, ux, uy, opacity)
}

/// The mix of pixels (i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1) with weights `ux`,
/// `uy` in 256ths (the edge pixels repeated beyond the layer), times the opacity.
#[inline]
#[allow(clippy::too_many_arguments)]
fn mix(pixels: &[u32], w: usize, h: usize, i: i64, j: i64, ux: u32, uy: u32, opacity: u32) -> u32 {
    let (a, b, c, d) = if i >= 0 && j >= 0 && (i as usize) + 1 < w && (j as usize) + 1 < h {
        let p = j as usize * w + i as usize;
        (pixels[p], pixels[p + 1], pixels[p + w], pixels[p + w + 1])
    } else {
        let at = |i: i64, j: i64| {
            pixels[j.clamp(0, h as i64 - 1) as usize * w + i.clamp(0, w as i64 - 1) as usize]
        };
        (at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1))
    };
    let wd = (ux * uy + 128) >> 8;
    let (wb, wc) = (ux - wd, uy - wd);
    let wa = 256 + wd - ux - uy;
    // Two channels to a multiply, rounded: red and blue, then green and alpha (each lane
    // stays below 2¹⁶: 255 × 256 + 128).
    const M: u32 = 0x00ff_00ff;
    const HALF: u32 = 0x0080_0080;
    let mut rb = (((a & M) * wa + (b & M) * wb + (c & M) * wc + (d & M) * wd + HALF) >> 8) & M;
    let mut ga = ((((a >> 8) & M) * wa
        + ((b >> 8) & M) * wb
        + ((c >> 8) & M) * wc
        + ((d >> 8) & M) * wd
        + HALF)
        >> 8)
        & M;
    if opacity < 256 {
        rb = ((rb * opacity + 0x0080_0080) >> 8) & 0x00ff_00ff;
        ga = ((ga * opacity + 0x0080_0080) >> 8) & 0x00ff_00ff;
    }
    rb | (ga << 8)
}

/// Premultiplied "over" in 8 bits: source + destination × (1 − source alpha), rounded.
#[inline]
fn over(src: u32, dst: u32) -> u32 {
    let keep = 255 - (src >> 24);
    if keep == 0 {
        return src;
    }
    let mut out = 0;
    for shift in [0, 8, 16, 24] {
        let t = ((dst >> shift) & 255) * keep + 128;
        let v = ((src >> shift) & 255) + ((t + (t >> 8)) >> 8);
        out |= v.min(255) << shift;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_triangle_whose_rest_positions_race_along_a_row_is_drawn_from_the_layer() {
        // Its rest position races along each row, by 100004 pixels per screen pixel (past
        // what 16.16 fixed point holds), from far off the layer at x = 0 back onto pixel
        // (4, 4) at x = 1; the layer's colour changes from pixel to pixel, so a rest
        // position gone wrong shows.
        let (w, h) = (9, 9);
        let pixels: Vec<u32> = (0..w * h)
            .map(|p| 0xff00_0000 | (20 * (p % w) as u32) | (20 * (p / w) as u32) << 8)
            .collect();
        let shade = Shade {
            pixels: &pixels,
            width: w,
            height: h,
            opacity: 256,
            clamp: None,
            rank: Rank::Rest {
                width: w,
                height: h,
                shrink: 1,
            },
        };
        let rest = |x: f64| -100_000.0 + 100_004.0 * x;
        let corner = |x, y| Corner {
            x,
            y,
            rx: rest(x),
            ry: 4.0,
        };
        // Over the pixel centres x = 0 and 1 of every row.
        let c = [corner(-0.5, -5.0), corner(3.0, -5.0), corner(-0.5, 10.0)];
        let mut frame = vec![0u32; 9];
        fill(
            &mut Target {
                frame: &mut frame,
                ranks: &mut [0; 9],
                width: 3,
                height: 3,
            },
            &c,
            &shade,
        );
        let (edge, inside) = (pixels[4 * w], pixels[4 * w + 4]);
        assert_eq!(frame, [edge, inside, 0, edge, inside, 0, edge, inside, 0]);
    }

    #[test]
    fn a_side_of_a_cut_pushed_under_the_other_stays_behind_it_skirts_included() {
        // A 12 × 6 layer, red left of a cut between columns 5 and 6, blue right of it; the
        // drawing pushes the left side 2.75 px right (and a quarter down) under the right
        // side, which stays. The full frame's order puts the right side in front wherever
        // they overlap (the same rows, further right), so no red shows right of x = 6: the
        // left side's skirt quarters along the cut, which the draft draws after its
        // triangles, are behind the right side as its own quads are. The right side is one
        // draft element, whose fragments rank as the full mesh's quads under them (ranked
        // by its top-left block, the left side's quads of every lower row would cover it).
        let (w, h, cut) = (12usize, 6usize, 5usize);
        let (red, blue) = ([255u8, 0, 0, 255], [0u8, 0, 255, 255]);
        let pixels: Vec<u8> = (0..w * h)
            .flat_map(|p| if p % w <= cut { red } else { blue })
            .collect();
        // Per pixel: bit 0 active, bit 1 linked right (not across the cut), bit 2 linked down.
        let links: Vec<u8> = (0..w * h)
            .map(|p| {
                let (i, j) = (p % w, p / w);
                1 | if i + 1 < w && i != cut { 2 } else { 0 } | if j + 1 < h { 4 } else { 0 }
            })
            .collect();
        // The left side's pixel quads (each triangle ending on its block's top-left pixel),
        // the right side's element, and the skirt quarters of the blocks along the cut, as
        // the editor's `buildMesh` lists them.
        let (w32, corner) = (w as u32, |i: usize, j: usize| (j * w + i) as u32);
        let (k, right) = (corner(cut + 1, 0), corner(w - 1, 0));
        let (down, across) = (corner(cut + 1, h - 1), corner(w - 1, h - 1));
        let mut triangles = Vec::new();
        let mut skirts = Vec::new();
        for j in 0..h - 1 {
            for i in 0..w - 1 {
                let k = corner(i, j);
                if i < cut {
                    triangles.extend([k + 1, k + w32 + 1, k, k + w32 + 1, k + w32, k]);
                    continue;
                } else if i > cut {
                    continue;
                }
                for (ci, cj, sx, sy) in [
                    (i, j, 1.0, 1.0),
                    (i + 1, j, -1.0, 1.0),
                    (i, j + 1, 1.0, -1.0),
                    (i + 1, j + 1, -1.0, -1.0),
                ] {
                    for (u, v) in [
                        (0.0, 0.0),
                        (1.0, 0.0),
                        (0.0, 1.0),
                        (0.0, 1.0),
                        (1.0, 0.0),
                        (1.0, 1.0),
                    ] {
                        skirts.extend([ci as f32, cj as f32, sx, sy, u, v]);
                    }
                }
            }
        }
        triangles.extend([right, across, k, across, down, k]);
        let index: Vec<u32> = (0..(w * h) as u32).collect();
        let values: Vec<f32> = (0..w * h)
            .flat_map(|p| {
                if p % w <= cut {
                    [2.75, 0.25]
                } else {
                    [0.0, 0.0]
                }
            })
            .collect();
        let handle = iw_draft_new(
            w,
            h,
            pixels.as_ptr(),
            triangles.as_ptr(),
            triangles.len(),
            skirts.as_ptr(),
            skirts.len(),
            links.as_ptr(),
            index.as_ptr(),
            w * h,
            0,
        );
        assert!(handle > 0);
        let layer = [
            handle as f64,
            values.as_ptr() as usize as f64,
            values.len() as f64,
            0.0,
            0.0,
            1.0,
        ];
        let mut out = vec![0u8; 4 * w * h];
        let status = iw_draft_draw(
            out.as_mut_ptr(),
            w,
            h,
            1,
            255,
            255,
            255,
            255,
            layer.as_ptr(),
            1,
        );
        iw_draft_free(handle);
        assert_eq!(status, 0);
        let at = |x: usize, y: usize| &out[4 * (y * w + x)..4 * (y * w + x) + 4];
        // Rows 1 to 4: every centre there lies inside both sides' meshes, none on their edges.
        for y in 1..h - 1 {
            assert_eq!(at(4, y), red, "the left side, moved, at (4, {y})");
            for x in 7..w {
                assert_eq!(at(x, y), blue, "the right side in front at ({x}, {y})");
            }
        }
    }

    #[test]
    fn over_blends_premultiplied_in_eight_bits() {
        // Opaque replaces; half-transparent black over white halves it; nothing over
        // anything keeps it.
        assert_eq!(over(0xff11_2233, 0xffff_ffff), 0xff11_2233);
        assert_eq!(over(0x8000_0000, 0xffff_ffff), 0xff7f_7f7f);
        assert_eq!(over(0, 0x8040_2010), 0x8040_2010);
    }
}
