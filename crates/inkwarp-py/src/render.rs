//! `warp_image`: NumPy arrays in, the forward-mapped RGBA image out.

use inkwarp_core::render::{try_warp_image, RgbaImage};
use inkwarp_core::{Field, Grid};
use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray3, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::errors::input_error;

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(warp_image, m)?)?;
    m.add_function(wrap_pyfunction!(decode_picture, m)?)?;
    Ok(())
}

/// Forward-maps an RGBA image by a displacement field (see `inkwarp.warp_image`, which
/// checks and converts its arguments before calling this).
///
/// `image`: uint8 (H, W, 4) straight RGBA; `field`: float32 (H, W, 2); `matte`: uint8
/// (H, W), nonzero = connected; `cuts`: float64 (K, 2) polylines whose crossed links are
/// removed. All C-contiguous. Returns uint8 (H, W, 4).
#[pyfunction]
#[pyo3(signature = (image, field, matte, cuts))]
fn warp_image<'py>(
    py: Python<'py>,
    image: PyReadonlyArray3<'py, u8>,
    field: PyReadonlyArray3<'py, f32>,
    matte: PyReadonlyArray2<'py, u8>,
    cuts: Vec<PyReadonlyArray2<'py, f64>>,
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let shape = image.shape();
    let (h, w) = (shape[0], shape[1]);
    if shape[2] != 4 {
        return Err(input_error(format!(
            "image must have 4 channels (RGBA), got {}",
            shape[2]
        )));
    }
    if field.shape() != [h, w, 2] {
        return Err(input_error(format!(
            "field must have shape ({h}, {w}, 2) to match the image, got {:?}",
            field.shape()
        )));
    }
    if matte.shape() != [h, w] {
        return Err(input_error(format!(
            "matte must have shape ({h}, {w}) to match the image, got {:?}",
            matte.shape()
        )));
    }
    let contiguous = |name: &str| input_error(format!("{name} must be C-contiguous"));
    let pixels = image.as_slice().map_err(|_| contiguous("image"))?;
    let displacement = field.as_slice().map_err(|_| contiguous("field"))?;
    let matte = matte.as_slice().map_err(|_| contiguous("matte"))?;
    let polylines = crate::limits::cuts_of(&cuts)?;
    let out = crate::errors::run_engine(py, || {
        let image = RgbaImage::from_raw(w, h, pixels.to_vec())?;
        let field = Field::from_interleaved(w, h, displacement);
        let mut grid = Grid::from_matte(w, h, matte);
        polylines.iter().for_each(|p| grid.add_cut(p));
        try_warp_image(&image, &field, &grid)
    })?;
    let out = out.map_err(input_error)?;
    let array = Array3::from_shape_vec((h, w, 4), out.data)
        .expect("the renderer returns an image of the input's size");
    Ok(array.into_pyarray(py))
}

/// A PNG or JPEG file's bytes decoded as the engine decodes a scene's pictures: straight RGBA
/// (H, W, 4), upright by the EXIF orientation the engine reads. A `ValueError` says why not.
#[pyfunction]
fn decode_picture<'py>(py: Python<'py>, data: &[u8]) -> PyResult<Bound<'py, PyArray3<u8>>> {
    if crate::scene::jpeg_cut_short(data) {
        return Err(input_error("a JPEG that ends before its end-of-image marker: the file is cut short \
                                           (copied or synced only in part); copy or save it again"));
    }
    let image = py.detach(|| inkwarp_core::scene::images::decode_image(data)).map_err(input_error)?;
    let array = Array3::from_shape_vec((image.height, image.width, 4), image.data).expect("RGBA8 of its size");
    Ok(array.into_pyarray(py))
}
