//! A region of a frame drawn for a view: at the picture's own resolution, or a whole
//! factor smaller from a box-filtered level of every layer (see [`draw_view`]).

use super::{check_layer, draw_frame, premultiply, unpremultiply, PreparedLayer, RenderError, RgbaImage};
use crate::{Field, Grid};

/// One layer of a view ([`draw_view`]): its picture, its field (read, not taken: a view
/// is drawn again as it is zoomed and panned), its grid and its offset (frame pixels).
#[derive(Clone, Copy, Debug)]
pub struct ViewLayer<'a> {
    pub image: &'a RgbaImage,
    pub field: &'a Field,
    pub grid: &'a Grid,
    pub offset: [f64; 2],
}

/// The size of a `width × height` frame drawn `shrink` times smaller: every pixel stands
/// for a `shrink × shrink` block of the frame (the last ones clipped).
pub fn view_size(width: usize, height: usize, shrink: usize) -> (usize, usize) {
    let k = shrink.max(1);
    (width.div_ceil(k), height.div_ceil(k))
}

/// A layer a whole factor `k` smaller, pixel `(i, j)` standing for the block of pixels
/// `k·i … k·i + k − 1`, `k·j … k·j + k − 1` (clipped at the layer's right and bottom):
///
/// - its colour is the block's premultiplied mean (a box filter), as the draft's level;
/// - its displaced position is the mean of the block's drawn pixels' displaced positions,
///   in the smaller frame's pixels (a frame position `p` is `(p + ½)/k − ½` there), so a
///   smooth field places it where the block's pixels land; a block with no drawn pixel is
///   not drawn;
/// - it is active when one of its pixels is, and linked to its right (lower) neighbour
///   when every link across their shared side is and neither block has a broken link in
///   that direction inside it, so a cut or a hole's edge through a block tears the level
///   there too.
fn level(image: &RgbaImage, field: &Field, grid: &Grid, k: usize) -> (RgbaImage, Field, Grid) {
    let (w, h) = (image.width, image.height);
    let (lw, lh) = view_size(w, h, k);
    let n = lw * lh;
    let mut data = vec![0u8; 4 * n];
    let (mut dx, mut dy) = (vec![f32::NAN; n], vec![f32::NAN; n]);
    let mut active = vec![false; n];
    // Per level pixel: every link in that direction inside the block is present.
    let (mut whole_right, mut whole_down) = (vec![true; n], vec![true; n]);
    // Per level pixel of the row: the sums of its block's colours and drawn positions.
    let (mut col, mut pos, mut count) = (vec![[0f64; 4]; lw], vec![[0f64; 3]; lw], vec![0u32; lw]);
    for j in 0..lh {
        col.iter_mut().for_each(|c| *c = [0.0; 4]);
        pos.iter_mut().for_each(|p| *p = [0.0; 3]);
        count.iter_mut().for_each(|c| *c = 0);
        let rows = j * k..((j + 1) * k).min(h);
        for y in rows.clone() {
            for x in 0..w {
                let i = (x / k, y * w + x);
                let (li, p) = (j * lw + i.0, i.1);
                let rgba: [u8; 4] = image.data[4 * p..4 * p + 4].try_into().expect("four channels");
                let pm = premultiply(rgba);
                col[i.0].iter_mut().zip(pm).for_each(|(c, v)| *c += v as f64);
                count[i.0] += 1;
                let on = grid.active[p];
                active[li] |= on;
                let drawn = on || rgba[3] > 0;
                let at = [x as f32 + field.dx[p], y as f32 + field.dy[p]];
                if drawn && at[0].is_finite() && at[1].is_finite() {
                    let q = &mut pos[i.0];
                    q[0] += at[0] as f64;
                    q[1] += at[1] as f64;
                    q[2] += 1.0;
                }
                // Links inside the block (not across its right or lower side).
                whole_right[li] &= x % k == k - 1 || x + 1 >= w || grid.link_right[p];
                whole_down[li] &= y % k == k - 1 || y + 1 >= h || grid.link_down[p];
            }
        }
        for i in 0..lw {
            let li = j * lw + i;
            let inv = 1.0 / count[i].max(1) as f64;
            data[4 * li..4 * li + 4].copy_from_slice(&unpremultiply(col[i].map(|v| (v * inv) as f32)));
            let q = pos[i];
            if q[2] > 0.0 {
                let kf = k as f64;
                dx[li] = (((q[0] / q[2]) + 0.5) / kf - 0.5 - i as f64) as f32;
                dy[li] = (((q[1] / q[2]) + 0.5) / kf - 0.5 - j as f64) as f32;
            }
        }
    }
    let (mut link_right, mut link_down) = (vec![false; n], vec![false; n]);
    for j in 0..lh {
        for i in 0..lw {
            let li = j * lw + i;
            if i + 1 < lw && active[li] && active[li + 1] && whole_right[li] && whole_right[li + 1] {
                // Every link across the side between the two blocks.
                let x = (i + 1) * k - 1;
                link_right[li] = (j * k..((j + 1) * k).min(h)).all(|y| grid.link_right[y * w + x]);
            }
            if j + 1 < lh && active[li] && active[li + lw] && whole_down[li] && whole_down[li + lw] {
                let y = (j + 1) * k - 1;
                link_down[li] = (i * k..((i + 1) * k).min(w)).all(|x| grid.link_down[y * w + x]);
            }
        }
    }
    // An undrawn level pixel (no drawn pixel in its block) has no position: the renderer
    // leaves a pixel with a non-finite position out.
    (
        RgbaImage { width: lw, height: lh, data },
        Field { width: lw, height: lh, dx, dy },
        Grid { width: lw, height: lh, active, link_right, link_down },
    )
}

/// Draws the region `region = [x0, y0, x1, y1]` (pixels of the smaller frame, end
/// exclusive) of the frame of `layers` over `background` drawn `shrink` times smaller
/// ([`view_size`]), as straight RGBA8 in `out` (`4 × (x1 − x0) × (y1 − y0)` bytes), for an
/// editor's view of a large picture: the stage shows a 4000 × 3000 photograph at about
/// 1000 × 750 screen pixels, so its frame drawn 4 times smaller is all the stage can show.
///
/// At `shrink` 1 the bytes are those of [`draw_frame`]'s frame in the region, bit for bit.
/// Above 1 each layer is drawn from its level ([`level`]: colours box-filtered, positions
/// the blocks' mean displaced positions), so a pixel is about the mean of the `shrink ×
/// shrink` pixels of the full frame it stands for.
pub fn draw_view(
    width: usize,
    height: usize,
    background: [u8; 4],
    layers: &[ViewLayer<'_>],
    shrink: usize,
    region: [usize; 4],
    out: &mut [u8],
) -> Result<(), RenderError> {
    let k = shrink.max(1);
    let (vw, vh) = view_size(width, height, k);
    let [x0, y0, x1, y1] = region;
    if x0 > x1 || x1 > vw || y0 > y1 || y1 > vh {
        return Err(RenderError::Region { region, width: vw, height: vh });
    }
    let expected = 4 * (x1 - x0) * (y1 - y0);
    if out.len() != expected {
        return Err(RenderError::OutputLength { width: x1 - x0, first: y0, end: y1, expected, actual: out.len() });
    }
    layers.iter().try_for_each(|l| check_layer(l.image, l.field, l.grid))?;
    // Above 1, each layer's level: its picture and grid (borrowed by the prepared layer)
    // and its field (taken).
    let levels = layers.iter().filter(|_| k > 1).map(|l| level(l.image, l.field, l.grid, k));
    let (levels, fields): (Vec<_>, Vec<_>) = levels.map(|(image, field, grid)| ((image, grid), field)).unzip();
    let prepared = if k == 1 {
        layers.iter().map(|l| PreparedLayer::new(l.image, l.field.clone(), l.grid, l.offset)).collect::<Result<Vec<_>, _>>()?
    } else {
        let kf = k as f64;
        let levelled = layers.iter().zip(&levels).zip(fields);
        let prepared = levelled.map(|((l, (image, grid)), field)| PreparedLayer::new(image, field, grid, l.offset.map(|o| o / kf)));
        prepared.collect::<Result<Vec<_>, _>>()?
    };
    if x0 == 0 && x1 == vw {
        return draw_frame(vw, vh, background, &prepared, y0..y1, out);
    }
    let mut rows = vec![0u8; 4 * vw * (y1 - y0)];
    draw_frame(vw, vh, background, &prepared, y0..y1, &mut rows)?;
    out.chunks_exact_mut(4 * (x1 - x0)).zip(rows.chunks_exact(4 * vw)).for_each(|(o, r)| o.copy_from_slice(&r[4 * x0..4 * x1]));
    Ok(())
}
