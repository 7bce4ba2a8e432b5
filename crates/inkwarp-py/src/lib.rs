//! The PyO3 adapter: converts between NumPy/Python values and `inkwarp-core`, and maps
//! core errors to Python exceptions. No engine logic lives here.

use pyo3::prelude::*;

mod errors;
mod limits;
mod geometry;
mod methods;
mod scene;
mod render;
mod solve;

/// mimalloc, with large blocks staggered within the page (`inkwarp_core::alloc`): the solver's vectors on
/// large grids no longer alias one another's offsets.
#[global_allocator]
static ALLOCATOR: inkwarp_core::alloc::Staggered<mimalloc::MiMalloc> = inkwarp_core::alloc::Staggered(mimalloc::MiMalloc);

/// The compiled core of the `inkwarp` Python package.
#[pymodule]
fn _inkwarp(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    errors::register(m)?;
    geometry::register(m)?;
    methods::register(m)?;
    scene::register(m)?;
    render::register(m)?;
    solve::register(m)?;
    Ok(())
}
