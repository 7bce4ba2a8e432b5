//! A layer's held border: its outer edge as samples that do not move.

use super::Sample;

/// Samples with zero displacement around the edge of a `width × height` grid: every node
/// on the outer rows and columns (`x = 0`, `x = width − 1`, `y = 0`, `y = height − 1`),
/// at most `spacing_px` apart along each edge, the corners always included, each node
/// once. A grid without nodes gives none; `spacing_px` below 1 is taken as 1.
///
/// ```
/// use inkwarp_core::geometry::border_samples;
/// let samples = border_samples(5, 4, 1.0);
/// assert_eq!(samples.len(), 2 * 5 + 2 * 4 - 4);
/// assert!(samples.iter().all(|s| s.displacement == [0.0, 0.0]));
/// assert!(samples.iter().any(|s| s.rest == [4.0, 3.0]));
/// ```
pub fn border_samples(width: usize, height: usize, spacing_px: f64) -> Vec<Sample> {
    if width == 0 || height == 0 {
        return Vec::new();
    }
    let (right, bottom) = ((width - 1) as f64, (height - 1) as f64);
    let step = spacing_px.max(1.0);
    // positions 0, step, 2·step, … along an edge of length `len`, its far end included
    let along = |len: f64| -> Vec<f64> {
        let count = (len / step).ceil() as usize;
        (0..count).map(|k| (k as f64 * step).min(len)).chain([len]).collect()
    };
    let at = |x: f64, y: f64| Sample { rest: [x, y], displacement: [0.0, 0.0] };
    let mut out = Vec::new();
    for x in along(right) {
        out.push(at(x, 0.0));
        out.extend((bottom > 0.0).then(|| at(x, bottom)));
    }
    // the columns without their end nodes (the rows above have them)
    for y in along(bottom).into_iter().filter(|&y| y > 0.0 && y < bottom) {
        out.push(at(0.0, y));
        out.extend((right > 0.0).then(|| at(right, y)));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_edge_node_once_at_spacing_one() {
        let s = border_samples(7, 3, 1.0);
        let mut nodes: Vec<(i64, i64)> = s.iter().map(|s| (s.rest[0] as i64, s.rest[1] as i64)).collect();
        nodes.sort_unstable();
        nodes.dedup();
        assert_eq!(nodes.len(), s.len());
        assert_eq!(s.len(), 2 * 7 + 2 * 3 - 4);
    }

    #[test]
    fn coarser_spacing_keeps_the_corners() {
        let s = border_samples(10, 10, 4.0);
        for corner in [[0.0, 0.0], [9.0, 0.0], [0.0, 9.0], [9.0, 9.0]] {
            assert!(s.iter().any(|s| s.rest == corner), "{corner:?}");
        }
        // 0, 4, 8, 9 on each edge: 4 per edge, corners shared
        assert_eq!(s.len(), 4 * 4 - 4);
    }

    #[test]
    fn degenerate_grids() {
        assert!(border_samples(0, 5, 1.0).is_empty());
        assert_eq!(border_samples(1, 1, 1.0).len(), 1);
        assert_eq!(border_samples(3, 1, 1.0).len(), 3);
        assert_eq!(border_samples(1, 3, 1.0).len(), 3);
    }
}
