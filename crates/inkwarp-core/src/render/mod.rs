//! The forward-mapping renderer (DESIGN §5): every pixel of a layer is a vertex of a mesh
//! placed at its displaced position, `(x + Δx + offset_x, y + Δy + offset_y)` on the
//! canvas (pixel centres at integer coordinates, DESIGN §2), and the mesh is drawn onto a
//! premultiplied canvas.
//!
//! The rest plane is cut into *blocks*, the unit squares between pixel centres. A block
//! whose four pixels are joined by all four links of the [`Grid`] is one bilinear **quad**;
//! in any other block each drawn pixel owns the quarter of the block nearest to it, a
//! **skirt quarter**, so pieces are watertight and a missing link (a hole, a cut, the
//! image border) lets its two sides separate. A pixel is drawn when it is active in the
//! grid or has nonzero alpha, and its displaced position is finite.
//!
//! Each canvas pixel gets the mesh's colour at its centre (where the mesh folds, the
//! element drawn last is in front, "over" the others: the part from further down, then
//! further right, in the rest image) times its coverage, the exact area of its square
//! inside the mesh, composited "over" the canvas. For a translation this is exactly the area-weighted (box-filtered)
//! image of the translated layer, edges included. `docs/concepts/forward-mapping.md`
//! states every rule exactly (the skirts' corners and colours, the tie rules, the colour
//! of pixels on an edge), with pictures.

mod mesh;
mod raster;
mod view;

pub use view::{draw_view, view_size, ViewLayer};

use crate::{Field, Grid};

/// Errors of the renderer: the inputs of a layer that do not fit together.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RenderError {
    /// An RGBA buffer whose length is not `width × height × 4`.
    #[error(
        "The RGBA data holds {actual} bytes, but a {width}×{height} RGBA image needs {expected} \
         (4 bytes per pixel, row-major)."
    )]
    ImageDataLength { width: usize, height: usize, expected: usize, actual: usize },
    /// A field or grid whose size differs from the layer image.
    #[error(
        "The {what} is {got_width}×{got_height}, but the layer image is {width}×{height}; \
         the image, its displacement field and its grid must be the same size."
    )]
    SizeMismatch { what: &'static str, got_width: usize, got_height: usize, width: usize, height: usize },
    /// An output buffer whose length does not fit the rows asked for.
    #[error(
        "The output buffer holds {actual} bytes, but rows {first}..{end} of a {width}-pixel-wide \
         frame need {expected} (4 bytes per pixel)."
    )]
    OutputLength { width: usize, first: usize, end: usize, expected: usize, actual: usize },
    /// A view's region ([`draw_view`]) outside its frame.
    #[error(
        "The region {region:?} (x0, y0, x1, y1) is not inside the {width}×{height} frame of \
         the view; ask for x0 ≤ x1 ≤ {width} and y0 ≤ y1 ≤ {height}."
    )]
    Region { region: [usize; 4], width: usize, height: usize },
    /// Rows asked for outside the frame.
    #[error("Rows {first}..{end} are not rows of a frame {height} pixels high.")]
    Rows { first: usize, end: usize, height: usize },
    /// A stop requested while drawing ([`crate::interrupt`]): the image is not whole.
    #[error("{}", crate::interrupt::STOPPED)]
    Interrupted,
}

/// An image with straight (not premultiplied) 8-bit RGBA, row-major, 4 bytes per pixel.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RgbaImage {
    pub width: usize,
    pub height: usize,
    /// `data[(y * width + x) * 4 + channel]`, channels R, G, B, A.
    pub data: Vec<u8>,
}

impl RgbaImage {
    /// A fully transparent image.
    pub fn new(width: usize, height: usize) -> Self { RgbaImage { width, height, data: vec![0; width * height * 4] } }

    /// An image from raw RGBA bytes.
    ///
    /// ```
    /// use inkwarp_core::render::RgbaImage;
    /// let image = RgbaImage::from_raw(2, 1, vec![255, 0, 0, 255, 0, 0, 255, 128]).unwrap();
    /// assert_eq!(image.pixel(1, 0), [0, 0, 255, 128]);
    /// assert!(RgbaImage::from_raw(2, 2, vec![0; 3]).is_err());
    /// ```
    pub fn from_raw(width: usize, height: usize, data: Vec<u8>) -> Result<Self, RenderError> {
        let expected = width * height * 4;
        if data.len() != expected {
            return Err(RenderError::ImageDataLength { width, height, expected, actual: data.len() });
        }
        Ok(RgbaImage { width, height, data })
    }

    /// The RGBA value of pixel `(x, y)`.
    ///
    /// # Panics
    /// If `(x, y)` is outside the image.
    pub fn pixel(&self, x: usize, y: usize) -> [u8; 4] {
        assert!(x < self.width && y < self.height, "pixel ({x}, {y}) is outside the image");
        let i = (y * self.width + x) * 4;
        self.data[i..i + 4].try_into().expect("four channels")
    }
}

/// Straight 8-bit RGBA → premultiplied RGBA in `[0, 1]`.
#[inline]
pub fn premultiply(rgba: [u8; 4]) -> [f32; 4] {
    // The integer products are exact in f32; one rounding each.
    const INV: f32 = 1.0 / (255.0 * 255.0);
    let a = rgba[3] as f32;
    [rgba[0] as f32 * a * INV, rgba[1] as f32 * a * INV, rgba[2] as f32 * a * INV, a * (1.0 / 255.0)]
}

/// Premultiplied RGBA in `[0, 1]` → straight 8-bit RGBA, rounding to nearest.
///
/// A pixel whose alpha rounds to 0 becomes `[0, 0, 0, 0]`: fully transparent pixels carry
/// no colour in a premultiplied pipeline.
#[inline]
pub fn unpremultiply(p: [f32; 4]) -> [u8; 4] {
    // `x + 0.5` truncated rounds non-negative values to nearest without a libm call.
    let a = p[3].clamp(0.0, 1.0);
    let a8 = (a * 255.0 + 0.5) as u8;
    if a8 == 0 {
        return [0; 4];
    }
    let scale = 255.0 / a;
    let c = |v: f32| ((v * scale).clamp(0.0, 255.0) + 0.5) as u8;
    [c(p[0]), c(p[1]), c(p[2]), a8]
}

/// A drawing surface of premultiplied RGBA `f32` pixels in `[0, 1]`, onto which layers are
/// forward-mapped and composited back to front.
#[derive(Clone, Debug, PartialEq)]
pub struct Canvas {
    pub width: usize,
    pub height: usize,
    /// Premultiplied RGBA, `data[y * width + x]`.
    pub data: Vec<[f32; 4]>,
}

impl Canvas {
    /// A canvas filled with `background` (straight RGBA8).
    pub fn new(width: usize, height: usize, background: [u8; 4]) -> Self {
        Canvas { width, height, data: vec![premultiply(background); width * height] }
    }

    /// Forward-maps `image` by `field` over the mesh of `grid`'s links, shifted by `offset`
    /// (canvas pixels), and composites it "over" what the canvas holds.
    ///
    /// The output is the same for any number of threads.
    ///
    /// ```
    /// use inkwarp_core::render::{Canvas, RgbaImage};
    /// use inkwarp_core::{Field, Grid};
    /// let image = RgbaImage::from_raw(1, 1, vec![200, 100, 0, 255]).unwrap();
    /// let mut canvas = Canvas::new(3, 1, [0, 0, 255, 255]);
    /// canvas.draw_layer(&image, &Field::zeros(1, 1), &Grid::new(1, 1), [1.0, 0.0]);
    /// let out = canvas.to_rgba8();
    /// assert_eq!(out.pixel(0, 0), [0, 0, 255, 255]);
    /// assert_eq!(out.pixel(1, 0), [200, 100, 0, 255]);
    /// ```
    ///
    /// # Panics
    /// If the field or the grid is not the size of the image (see [`Canvas::try_draw_layer`]).
    pub fn draw_layer(&mut self, image: &RgbaImage, field: &Field, grid: &Grid, offset: [f64; 2]) {
        self.try_draw_layer(image, field, grid, offset).unwrap_or_else(|e| panic!("{e}"))
    }

    /// [`Canvas::draw_layer`], with an error instead of a panic when the sizes differ.
    pub fn try_draw_layer(&mut self, image: &RgbaImage, field: &Field, grid: &Grid, offset: [f64; 2]) -> Result<(), RenderError> {
        check_layer(image, field, grid)?;
        raster::draw_layer(self, image, field, grid, offset);
        Ok(())
    }

    /// The canvas as straight RGBA8 (see [`unpremultiply`]).
    pub fn to_rgba8(&self) -> RgbaImage {
        use rayon::prelude::*;
        const CHUNK: usize = 1 << 14;
        let mut data = vec![0u8; self.data.len() * 4];
        data.par_chunks_mut(4 * CHUNK).zip(self.data.par_chunks(CHUNK)).for_each(|(out, pixels)| {
            out.chunks_exact_mut(4).zip(pixels).for_each(|(o, &p)| o.copy_from_slice(&unpremultiply(p)));
        });
        RgbaImage { width: self.width, height: self.height, data }
    }
}

/// A layer ready for [`draw_frame`]: its picture (borrowed), placed by its field, which it
/// takes (the field's two planes become the pixels' canvas positions, in place), and its
/// mesh's plan. It holds 10 bytes a pixel besides the picture (the field's 8 and two
/// bytes of links and plan), where a [`Canvas`] of the frame holds 16 bytes a pixel.
pub struct PreparedLayer<'a> {
    layer: mesh::Layer<'a>,
    plan: mesh::Plan,
}

impl std::fmt::Debug for PreparedLayer<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result { f.debug_struct("PreparedLayer").field("width", &self.layer.w).field("height", &self.layer.h).finish_non_exhaustive() }
}

impl<'a> PreparedLayer<'a> {
    /// `image` displaced by `field` over `grid`'s mesh, shifted by `offset` (canvas pixels).
    pub fn new(image: &'a RgbaImage, field: Field, grid: &Grid, offset: [f64; 2]) -> Result<Self, RenderError> {
        check_layer(image, &field, grid)?;
        let layer = mesh::Layer::prepare(image, field.dx, field.dy, grid, offset);
        Ok(PreparedLayer { plan: layer.plan(), layer })
    }
}

/// Draws `layers` back to front over `background` (straight RGBA8) into rows `rows` of a
/// frame `width` pixels wide and `height` high, as straight RGBA8 in `out`
/// (`4 × width × rows.len()` bytes), without a [`Canvas`] of the frame: the rows are
/// composited band by band in a small buffer and written out. The bytes are those of
/// [`Canvas::new`], [`Canvas::draw_layer`] for each layer, then [`Canvas::to_rgba8`] (the
/// rows of it), for any rows and any number of threads, so two workers can each draw
/// a part of one frame.
///
/// ```
/// use inkwarp_core::render::{draw_frame, Canvas, PreparedLayer, RgbaImage};
/// use inkwarp_core::{Field, Grid};
/// let image = RgbaImage::from_raw(2, 2, (0..16).map(|v| v as u8 * 15 + 5).collect()).unwrap();
/// let (field, grid) = (Field::zeros(2, 2), Grid::new(2, 2));
/// let mut canvas = Canvas::new(4, 3, [0, 0, 255, 255]);
/// canvas.draw_layer(&image, &field, &grid, [1.5, 0.5]);
/// let layer = PreparedLayer::new(&image, field, &grid, [1.5, 0.5]).unwrap();
/// let mut out = vec![0; 4 * 4 * 2];
/// draw_frame(4, 3, [0, 0, 255, 255], &[layer], 1..3, &mut out).unwrap();
/// assert_eq!(out, canvas.to_rgba8().data[4 * 4..]);
/// ```
pub fn draw_frame(
    width: usize,
    height: usize,
    background: [u8; 4],
    layers: &[PreparedLayer<'_>],
    rows: std::ops::Range<usize>,
    out: &mut [u8],
) -> Result<(), RenderError> {
    let (first, end) = (rows.start, rows.end);
    if first > end || end > height {
        return Err(RenderError::Rows { first, end, height });
    }
    let expected = 4 * width * rows.len();
    if out.len() != expected {
        return Err(RenderError::OutputLength { width, first, end, expected, actual: out.len() });
    }
    let pairs: Vec<(&mesh::Layer<'_>, &mesh::Plan)> = layers.iter().map(|l| (&l.layer, &l.plan)).collect();
    raster::draw_frame(width, premultiply(background), &pairs, rows.start, out);
    crate::interrupt::unless_requested((), RenderError::Interrupted)
}

fn check_layer(image: &RgbaImage, field: &Field, grid: &Grid) -> Result<(), RenderError> {
    let (width, height) = (image.width, image.height);
    if image.data.len() != width * height * 4 {
        return Err(RenderError::ImageDataLength { width, height, expected: width * height * 4, actual: image.data.len() });
    }
    let mismatch = |what, got_width, got_height| RenderError::SizeMismatch { what, got_width, got_height, width, height };
    let n = width * height;
    if (field.width, field.height) != (width, height) || field.dx.len() != n || field.dy.len() != n {
        return Err(mismatch("displacement field", field.width, field.height));
    }
    if (grid.width, grid.height) != (width, height) || [&grid.active, &grid.link_right, &grid.link_down].iter().any(|v| v.len() != n) {
        return Err(mismatch("grid", grid.width, grid.height));
    }
    Ok(())
}

/// Forward-maps `image` by `field` over `grid`'s mesh onto a transparent canvas of the
/// image's size; an error when the field or the grid is not the size of the image.
///
/// ```
/// use inkwarp_core::render::{try_warp_image, RgbaImage};
/// use inkwarp_core::{Field, Grid};
/// let image = RgbaImage::from_raw(2, 2, (0..16).map(|v| v as u8 * 10 + 5).collect()).unwrap();
/// // The identity field reproduces the image exactly.
/// assert_eq!(try_warp_image(&image, &Field::zeros(2, 2), &Grid::new(2, 2)).unwrap(), image);
/// ```
pub fn try_warp_image(image: &RgbaImage, field: &Field, grid: &Grid) -> Result<RgbaImage, RenderError> {
    let mut canvas = Canvas::new(image.width, image.height, [0; 4]);
    canvas.try_draw_layer(image, field, grid, [0.0, 0.0])?;
    crate::interrupt::unless_requested(canvas.to_rgba8(), RenderError::Interrupted)
}

#[cfg(test)]
mod tests;
