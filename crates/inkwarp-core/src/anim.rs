//! Time: a feature's control points at any time from its keys (DESIGN §3, "Time").
//!
//! A key is the feature's drawing at one time. Between two keys the control points move
//! by the first key's [`Interpolation`]; before the first key the feature holds the first
//! key, after the last key the last one, and a feature without keys stays at rest.
//!
//! `Smooth` is a cubic Hermite curve in time through the keys, its velocity at each key
//! (the tangent rule) matching the motion on the key's other side: between two smooth
//! spans the Catmull-Rom tangent for non-uniform times, `m_i = (Δ⁺·v⁻ + Δ⁻·v⁺) / (Δ⁻ + Δ⁺)`
//! (`v⁻`, `v⁺` the slopes of the chords before and after the key, `Δ⁻`, `Δ⁺` their
//! durations), clamped coordinate by coordinate so that a span between two such keys never passes them:
//! zero where `v⁻` and `v⁺` differ in sign or one is zero (a key at a turn is the extreme,
//! equal keys hold still), at most `3·min(|v⁻|, |v⁺|)` (Fritsch–Carlson); next to a straight
//! span that span's velocity at the key; next to a hold, and at the first and last key,
//! zero. So smooth motion is C¹ in time except where a hold jumps (docs/concepts/drawings.md,
//! "Time", has the details).
//!
//! The eased spans move along the straight line between their keys with a set timing,
//! `u` being the fraction of the span's time gone by: `EaseIn` as `u²` (starts at rest,
//! arrives at twice the average speed), `EaseOut` as `1 − (1 − u)²` (the reverse) and
//! `EaseInOut` as `3u² − 2u³` (at rest at both ends). A smooth span next to an eased one
//! takes the eased span's velocity at the key they share, so motion stays C¹ there too.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::geometry::{hermite_basis, Point};

/// How control points move from a key to the next one.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum Interpolation {
    /// A C¹ cubic in time through the keys (see docs/concepts/drawings.md, "Time").
    #[default]
    Smooth,
    /// Straight lines at constant speed.
    Linear,
    /// Stay at this key until the next one.
    Hold,
    /// Straight lines, starting at rest and speeding up: `u²` of the way at the fraction
    /// `u` of the time to the next key.
    EaseIn,
    /// Straight lines, slowing down to rest at the next key: `1 − (1 − u)²` of the way.
    EaseOut,
    /// Straight lines, at rest at both keys: `3u² − 2u³` of the way.
    EaseInOut,
}

impl Interpolation {
    /// The fraction of the way from a key to the next one at the fraction `u` of the
    /// time between them, for the spans that move along the straight line (`None` for
    /// `Smooth` and `Hold`, which do not).
    ///
    /// ```
    /// use inkwarp_core::anim::Interpolation;
    /// assert_eq!(Interpolation::EaseIn.progress(0.5), Some(0.25));
    /// assert_eq!(Interpolation::EaseOut.progress(0.5), Some(0.75));
    /// assert_eq!(Interpolation::EaseInOut.progress(0.5), Some(0.5));
    /// ```
    pub fn progress(self, u: f64) -> Option<f64> {
        match self {
            Interpolation::Linear => Some(u),
            Interpolation::EaseIn => Some(u * u),
            Interpolation::EaseOut => Some(1.0 - (1.0 - u) * (1.0 - u)),
            Interpolation::EaseInOut => Some(u * u * (3.0 - 2.0 * u)),
            Interpolation::Smooth | Interpolation::Hold => None,
        }
    }

    /// The span's speed at its start and at its end as multiples of its average speed
    /// (the derivative of [`Interpolation::progress`] at 0 and at 1).
    fn end_speeds(self) -> (f64, f64) {
        match self {
            Interpolation::Linear => (1.0, 1.0),
            Interpolation::EaseIn => (0.0, 2.0),
            Interpolation::EaseOut => (2.0, 0.0),
            Interpolation::EaseInOut | Interpolation::Hold | Interpolation::Smooth => (0.0, 0.0),
        }
    }
}

/// A feature's control points at one time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "KeyDoc")]
pub struct Key {
    /// Time in seconds, strictly increasing from key to key.
    #[serde(rename = "t")]
    pub time_s: f64,
    /// The control points at time `t`: as many as `rest` has, in the same order.
    pub points: Vec<Point>,
    /// How the points move from this key to the next: `smooth` (default), `linear`,
    /// `hold`, `ease-in`, `ease-out` or `ease-in-out`.
    #[serde(default, skip_serializing_if = "crate::scene::doc::is_default")]
    #[schemars(extend("default" = "smooth"))]
    pub interpolation: Interpolation,
}

/// A feature's control points at `time_s`.
///
/// `keys` must be sorted by time with distinct times, each with as many points as `rest`
/// (the scene validates both; points beyond the shortest of two neighbouring keys are
/// ignored). No keys: `rest`. At or before the first key's time: the first key; at or
/// after the last: the last. At a key's time: that key's points exactly. A NaN time is
/// taken as before the first key.
///
/// ```
/// use inkwarp_core::anim::{points_at, Interpolation, Key};
/// let rest = vec![[0.0, 0.0]];
/// let keys = vec![
///     Key { time_s: 1.0, points: vec![[0.0, 0.0]], interpolation: Interpolation::Linear },
///     Key { time_s: 3.0, points: vec![[10.0, 4.0]], interpolation: Interpolation::Linear },
/// ];
/// assert_eq!(points_at(&rest, &keys, 2.0), vec![[5.0, 2.0]]);
/// assert_eq!(points_at(&rest, &keys, 9.0), vec![[10.0, 4.0]]);
/// ```
pub fn points_at(rest: &[Point], keys: &[Key], time_s: f64) -> Vec<Point> {
    let (Some(first), Some(last)) = (keys.first(), keys.last()) else { return rest.to_vec() };
    if time_s.is_nan() || time_s <= first.time_s { return first.points.clone(); }
    if time_s >= last.time_s { return last.points.clone(); }
    // the span [keys[i], keys[i + 1]) holding time_s: t_i ≤ t < t_{i+1}
    let i = keys.partition_point(|k| k.time_s <= time_s) - 1;
    let (a, b) = (&keys[i], &keys[i + 1]);
    if time_s == a.time_s { return a.points.clone(); }
    let duration = b.time_s - a.time_s;
    let u = (time_s - a.time_s) / duration;
    let n = a.points.len().min(b.points.len());
    if a.interpolation == Interpolation::Hold { return a.points.clone(); }
    if let Some(w) = a.interpolation.progress(u) {
        return (0..n).map(|j| lerp(a.points[j], b.points[j], w)).collect();
    }
    // Smooth
    let [h00, h10, h11, h01] = hermite_basis(u);
    (0..n)
        .map(|j| {
            let m0 = velocity(keys, i, j, true);
            let m1 = velocity(keys, i + 1, j, false);
            let (p0, p1) = (a.points[j], b.points[j]);
            [0, 1].map(|c| h00 * p0[c] + h10 * duration * m0[c] + h01 * p1[c] + h11 * duration * m1[c])
        })
        .collect()
}

/// The velocity (units per second) of control point `j` at key `k`, by the tangent rule
/// of the module docs, for a smooth span that starts at the key (`starts`: the key's
/// other side is the span ending there) or ends there.
fn velocity(keys: &[Key], k: usize, j: usize, starts: bool) -> Point {
    // the span on the key's other side: (its start key index, its interpolation)
    let other = if starts {
        k.checked_sub(1).map(|s| (s, keys[s].interpolation))
    } else {
        (k + 1 < keys.len()).then(|| (k, keys[k].interpolation))
    };
    match other {
        None | Some((_, Interpolation::Hold)) => [0.0, 0.0],
        Some((s, eased)) if eased != Interpolation::Smooth => {
            // the straight span's own velocity at key k: its end (the span before) or start
            let (start, end) = eased.end_speeds();
            let factor = if starts { end } else { start };
            let v = slope(&keys[s], &keys[s + 1], j);
            [factor * v[0], factor * v[1]]
        }
        Some(_) => {
            // both neighbours exist: the parabola through keys k − 1, k, k + 1, clamped by
            // coordinate so that neither span passes a key (Fritsch–Carlson): zero where the
            // chords' slopes differ in sign or one is zero, at most three times the smaller
            let (prev, key, next) = (&keys[k - 1], &keys[k], &keys[k + 1]);
            let dm = key.time_s - prev.time_s;
            let dp = next.time_s - key.time_s;
            let vm = slope(prev, key, j);
            let vp = slope(key, next, j);
            [0, 1].map(|c| {
                let limit = if vm[c] * vp[c] > 0.0 { 3.0 * vm[c].abs().min(vp[c].abs()) } else { 0.0 };
                ((dp * vm[c] + dm * vp[c]) / (dm + dp)).clamp(-limit, limit)
            })
        }
    }
}

/// The constant velocity of control point `j` on the straight path from `a` to `b`.
fn slope(a: &Key, b: &Key, j: usize) -> Point {
    let (p, q) = (point(a, j), point(b, j));
    let dt = b.time_s - a.time_s;
    [(q[0] - p[0]) / dt, (q[1] - p[1]) / dt]
}

/// Point `j` of a key, or the key's last point if it has fewer (invalid input that the
/// scene rejects; this only keeps the arithmetic total).
fn point(k: &Key, j: usize) -> Point { k.points.get(j).or(k.points.last()).copied().unwrap_or([0.0, 0.0]) }

fn lerp(a: Point, b: Point, u: f64) -> Point { [a[0] + u * (b[0] - a[0]), a[1] + u * (b[1] - a[1])] }

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn key(time_s: f64, x: f64, interpolation: Interpolation) -> Key {
        Key {
            time_s,
            points: vec![[x, -2.0 * x]],
            interpolation,
        }
    }

    fn x_at(keys: &[Key], t: f64) -> f64 {
        points_at(&[[0.0, 0.0]], keys, t)[0][0]
    }

    /// One-sided derivatives in time of control point 0's x, by Richardson extrapolation
    /// of difference quotients (error O(h²)).
    fn dx_left(keys: &[Key], t: f64) -> f64 {
        let h = 1e-4;
        let d = |h: f64| (x_at(keys, t) - x_at(keys, t - h)) / h;
        2.0 * d(h / 2.0) - d(h)
    }
    fn dx_right(keys: &[Key], t: f64) -> f64 {
        let h = 1e-4;
        let d = |h: f64| (x_at(keys, t + h) - x_at(keys, t)) / h;
        2.0 * d(h / 2.0) - d(h)
    }

    #[test]
    fn no_keys_is_the_rest_drawing() {
        let rest = vec![[1.0, 2.0], [3.0, 4.0]];
        assert_eq!(points_at(&rest, &[], 5.0), rest);
    }

    #[test]
    fn holds_before_the_first_and_after_the_last_key() {
        let keys = [
            key(1.0, 3.0, Interpolation::Smooth),
            key(2.0, 7.0, Interpolation::Smooth),
        ];
        assert_eq!(points_at(&[[0.0, 0.0]], &keys, -4.0), vec![[3.0, -6.0]]);
        assert_eq!(points_at(&[[0.0, 0.0]], &keys, 1.0), vec![[3.0, -6.0]]);
        assert_eq!(points_at(&[[0.0, 0.0]], &keys, 2.0), vec![[7.0, -14.0]]);
        assert_eq!(points_at(&[[0.0, 0.0]], &keys, 100.0), vec![[7.0, -14.0]]);
        assert_eq!(points_at(&[[0.0, 0.0]], &keys, f64::NAN), vec![[3.0, -6.0]]);
    }

    #[test]
    fn hold_keeps_the_key_until_the_next_one() {
        let keys = [
            key(0.0, 1.0, Interpolation::Hold),
            key(1.0, 5.0, Interpolation::Hold),
        ];
        assert_eq!(x_at(&keys, 0.999_999), 1.0);
        assert_eq!(x_at(&keys, 1.0), 5.0);
    }

    #[test]
    fn linear_moves_at_constant_speed() {
        let keys = [
            key(0.0, 1.0, Interpolation::Linear),
            key(2.0, 5.0, Interpolation::Linear),
        ];
        for t in [0.25, 0.5, 1.0, 1.7] {
            assert!((x_at(&keys, t) - (1.0 + 2.0 * t)).abs() < 1e-12);
        }
    }

    #[test]
    fn smooth_between_two_keys_eases_in_and_out() {
        let keys = [
            key(0.0, 0.0, Interpolation::Smooth),
            key(1.0, 1.0, Interpolation::Smooth),
        ];
        // smoothstep: 3u² − 2u³
        for u in [0.1, 0.5, 0.8] {
            assert!((x_at(&keys, u) - (3.0 * u * u - 2.0 * u * u * u)).abs() < 1e-12);
        }
        assert!(dx_right(&keys, 0.0).abs() < 1e-5);
        assert!(dx_left(&keys, 1.0).abs() < 1e-5);
    }

    #[test]
    fn smooth_reproduces_a_parabola_at_interior_keys() {
        // keys on x = t² at uneven times: the tangent at an interior key is exact (2t)
        let times = [0.0, 0.4, 1.5, 1.9, 3.0];
        let keys: Vec<Key> = times
            .iter()
            .map(|&t| key(t, t * t, Interpolation::Smooth))
            .collect();
        for &t in &times[1..4] {
            assert!((dx_right(&keys, t) - 2.0 * t).abs() < 1e-4, "at {t}");
        }
    }

    #[test]
    fn smooth_holds_between_equal_keys_and_stops_at_the_last() {
        // A pose keyed twice is held; keys that only rise never rise past the last one.
        let keys = [
            key(0.0, 20.0, Interpolation::Smooth),
            key(0.2, 30.0, Interpolation::Smooth),
            key(1.0, 30.0, Interpolation::Smooth),
            key(1.2, 20.0, Interpolation::Smooth),
        ];
        for t in [0.3, 0.6, 0.9] {
            assert_eq!(x_at(&keys, t), 30.0);
        }
        let rising = [
            key(0.0, 0.0, Interpolation::Smooth),
            key(0.1, 10.0, Interpolation::Smooth),
            key(1.0, 12.0, Interpolation::Smooth),
        ];
        let peak = (0..=1000).map(|i| x_at(&rising, i as f64 / 1000.0)).fold(f64::MIN, f64::max);
        assert!(peak <= 12.0 + 1e-12, "{peak}");
    }

    #[test]
    fn smooth_joins_a_linear_span_with_its_slope() {
        let keys = [
            key(0.0, 0.0, Interpolation::Smooth),
            key(1.0, 2.0, Interpolation::Linear),
            key(3.0, 8.0, Interpolation::Smooth),
            key(4.0, 8.0, Interpolation::Smooth),
        ];
        assert!(
            (dx_left(&keys, 1.0) - 3.0).abs() < 1e-4 && (dx_right(&keys, 1.0) - 3.0).abs() < 1e-4
        );
        assert!(
            (dx_left(&keys, 3.0) - 3.0).abs() < 1e-4 && (dx_right(&keys, 3.0) - 3.0).abs() < 1e-4
        );
    }

    #[test]
    fn eased_spans_follow_their_curves() {
        for (kind, curve) in [
            (Interpolation::EaseIn, (|u: f64| u * u) as fn(f64) -> f64),
            (Interpolation::EaseOut, |u: f64| 1.0 - (1.0 - u) * (1.0 - u)),
            (Interpolation::EaseInOut, |u: f64| 3.0 * u * u - 2.0 * u * u * u),
        ] {
            let keys = [key(1.0, 2.0, kind), key(3.0, 10.0, Interpolation::Smooth)];
            for u in [0.1, 0.25, 0.5, 0.9] {
                let expect = 2.0 + 8.0 * curve(u);
                assert!((x_at(&keys, 1.0 + 2.0 * u) - expect).abs() < 1e-12, "{kind:?} at {u}");
            }
        }
    }

    #[test]
    fn smooth_spans_join_eased_ones_with_their_velocity() {
        // ease-in ends at twice its average speed (8 / 2 · 2 = 8), ease-out starts at it
        let keys = [
            key(0.0, 0.0, Interpolation::EaseIn),
            key(2.0, 8.0, Interpolation::Smooth),
            key(3.0, 9.0, Interpolation::EaseOut),
            key(5.0, 13.0, Interpolation::Smooth),
        ];
        for t in [2.0, 3.0] {
            let (l, r) = (dx_left(&keys, t), dx_right(&keys, t));
            assert!((l - r).abs() < 1e-4, "velocity {l} then {r} at {t}");
        }
        assert!((dx_left(&keys, 2.0) - 8.0).abs() < 1e-4);
        assert!(dx_right(&keys, 0.0).abs() < 1e-5);
    }

    fn interpolation() -> impl Strategy<Value = Interpolation> {
        prop_oneof![
            Just(Interpolation::Smooth),
            Just(Interpolation::Linear),
            Just(Interpolation::Hold),
            Just(Interpolation::EaseIn),
            Just(Interpolation::EaseOut),
            Just(Interpolation::EaseInOut)
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(128))]

        #[test]
        fn key_values_are_hit_exactly(
            steps in prop::collection::vec((0.05..2.0f64, -50.0..50.0f64, interpolation()), 1..7),
        ) {
            let mut t = -1.0;
            let keys: Vec<Key> = steps.iter().map(|&(dt, x, i)| { t += dt; Key { time_s: t, points: vec![[x, 1.0 - x], [2.0 * x, x]], interpolation: i } }).collect();
            for k in &keys {
                prop_assert_eq!(points_at(&[[0.0, 0.0], [0.0, 0.0]], &keys, k.time_s), k.points.clone());
            }
        }

        #[test]
        fn smooth_motion_is_c1_in_time(
            steps in prop::collection::vec((0.1..2.0f64, -50.0..50.0f64), 2..7),
            probe in 0.0..1.0f64,
        ) {
            let mut t = 0.0;
            let keys: Vec<Key> = steps.iter().map(|&(dt, x)| { t += dt; key(t, x, Interpolation::Smooth) }).collect();
            let (t0, t1) = (keys[0].time_s, keys[keys.len() - 1].time_s);
            // a velocity scale: the fastest chord
            let scale = keys.windows(2).map(|w| ((w[1].points[0][0] - w[0].points[0][0]) / (w[1].time_s - w[0].time_s)).abs()).fold(1.0, f64::max);
            // at every key, including the first and last (where the holds begin)
            for k in &keys {
                let (l, r) = (dx_left(&keys, k.time_s), dx_right(&keys, k.time_s));
                prop_assert!((l - r).abs() < 1e-4 * scale, "velocity {} then {} at {}", l, r, k.time_s);
            }
            // and continuous in value anywhere: over 1e-9 s it moves no more than a velocity
            // far above the fastest chord's allows
            let tp = t0 + probe * (t1 - t0);
            prop_assert!((x_at(&keys, tp + 1e-9) - x_at(&keys, tp)).abs() < 1e-7 * scale);
        }

        #[test]
        fn smooth_spans_never_pass_their_keys(
            steps in prop::collection::vec((0.05..2.0f64, -50.0..50.0f64), 2..8),
            probes in prop::collection::vec(0.0..1.0f64, 16),
        ) {
            // Unevenly timed keys, reversals and repeats included: each coordinate stays
            // between the values of the two keys around it (an animation curve's clamped
            // automatic tangents), so a key at a turn is the extreme and equal keys hold.
            let mut t = 0.0;
            let keys: Vec<Key> = steps.iter().map(|&(dt, x)| { t += dt; key(t, if x.abs() < 10.0 { 0.0 } else { x }, Interpolation::Smooth) }).collect();
            for w in keys.windows(2) {
                let (a, b) = (w[0].points[0][0], w[1].points[0][0]);
                for &u in &probes {
                    let x = x_at(&keys, w[0].time_s + u * (w[1].time_s - w[0].time_s));
                    prop_assert!(x >= a.min(b) - 1e-9 && x <= a.max(b) + 1e-9, "{} between {} and {}", x, a, b);
                }
            }
        }

        #[test]
        fn linear_stays_between_its_keys_and_hold_never_leaves_its_key(
            a in -50.0..50.0f64, b in -50.0..50.0f64, u in 0.0..1.0f64,
        ) {
            let lin = [key(0.0, a, Interpolation::Linear), key(1.0, b, Interpolation::Smooth)];
            let x = x_at(&lin, u);
            prop_assert!(x >= a.min(b) - 1e-12 && x <= a.max(b) + 1e-12);
            let hold = [key(0.0, a, Interpolation::Hold), key(1.0, b, Interpolation::Smooth)];
            prop_assert_eq!(x_at(&hold, u * 0.999), a);
        }
    }
}
