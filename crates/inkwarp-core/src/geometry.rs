//! Features and their sampling into (rest position, displacement) pairs (DESIGN §3).

use serde::{Deserialize, Serialize};

/// A position `(x, y)` in pixels: pixel centres at integer coordinates, y down.
pub type Point = [f64; 2];

/// One constraint taken from a drawing: a point on the rest geometry and how far its
/// partner on the posed geometry has moved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub rest: Point,
    pub displacement: Point,
}

/// The five feature kinds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    Point,
    Polyline,
    Spline,
    Region,
    Cut,
}
