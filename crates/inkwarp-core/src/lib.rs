//! The inkwarp engine: animating an image by animating a drawing traced over it.
//!
//! Litwinowicz & Williams, "Animating Images with Drawings" (SIGGRAPH '94), as a pure
//! Rust library. Data flows through the modules in this order:
//!
//! `scene` (the file format) → `anim` (the drawing at time t) → `geometry` (features
//! sampled into rest positions and displacements) → `grid` (matte, links, cuts,
//! nearest-node constraints) → `solve` (the discrete thin plate by multigrid) → `field`
//! (the displacement field) → `render` (forward-mapped mesh, compositing).
//! `methods` holds the other interpolants the paper compares against and `transfer` the
//! paper's animation transfer. Nothing here knows about Python, the browser or files.

pub mod alloc;
pub mod anim;
mod clock;
pub mod field;
pub mod geometry;
pub mod grid;
pub mod interrupt;
pub mod limits;
pub mod methods;
pub mod render;
pub mod scene;
pub mod solve;
pub mod transfer;

pub use field::{Field, FieldView};
pub use geometry::{Kind, Point, Sample};
pub use grid::Grid;
