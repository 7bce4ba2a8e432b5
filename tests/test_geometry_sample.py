"""inkwarp.sample: spacing, vertices, partners, closed curves, regions, errors.

Regions are checked against independent oracles: matplotlib's point-in-polygon test for
which nodes are inside, and a NumPy implementation of Hormann & Floater's mean value
coordinates for their displacements.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from matplotlib.path import Path

import inkwarp

coords = st.floats(-40.0, 140.0, allow_nan=False)
point_lists = st.lists(st.tuples(coords, coords), min_size=2, max_size=6)


def star(radii, center=(32.3, 31.7)):
    n = len(radii)
    a = 2 * np.pi * (np.arange(n) + 0.3) / n
    r = np.asarray(radii, dtype=float)
    return np.stack([center[0] + r * np.cos(a), center[1] + r * np.sin(a)], axis=1)


def mvc_oracle(poly, values, x):
    """Mean value interpolation at the points x (K, 2) of values at a closed polygon."""
    s = poly[None, :, :] - x[:, None, :]  # (K, M, 2)
    r = np.linalg.norm(s, axis=2)
    s1 = np.roll(s, -1, axis=1)
    r1 = np.roll(r, -1, axis=1)
    det = s[..., 0] * s1[..., 1] - s[..., 1] * s1[..., 0]
    dot = (s * s1).sum(axis=2)
    tan_half = np.tan(np.arctan2(det, dot) / 2)  # the signed angle, directly
    w = (np.roll(tan_half, 1, axis=1) + tan_half) / r
    return (w @ values) / w.sum(axis=1, keepdims=True)


@settings(max_examples=60, deadline=None)
@given(rest=point_lists, closed=st.booleans(), kind=st.sampled_from(["polyline", "spline"]),
       spacing=st.floats(0.3, 5.0))
def test_samples_are_no_further_apart_than_the_spacing_and_keep_every_vertex(rest, closed, kind, spacing):
    rest = np.asarray(rest)
    points, moves = inkwarp.sample(kind, rest, rest, closed=closed, spacing=spacing)
    assert points.dtype == np.float64 and points.shape == moves.shape and points.shape[1] == 2
    # chords never exceed arcs, so this bounds the arc length from below; the Rust tests
    # measure the arc length itself
    gaps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    assert (gaps <= spacing * (1 + 1e-9)).all()
    if closed:
        assert np.linalg.norm(points[-1] - points[0]) <= spacing * (1 + 1e-9)
    for v in rest:  # exactly: a spline passes through its control points
        assert ((points == v).all(axis=1)).any()
    assert (points[0] == rest[0]).all()
    if not closed:
        assert (points[-1] == rest[-1]).all()
    assert (moves == 0).all()


def test_the_midpoint_of_a_segment_moves_to_the_midpoint_of_the_posed_segment():
    rest = [[0, 0], [10, 0], [10, 6]]
    pose = [[5, 5], [5, 25], [-1, 25]]
    points, moves = inkwarp.sample("polyline", rest, pose)
    partners = points + moves
    i = np.flatnonzero((points == [5, 0]).all(axis=1))[0]
    assert partners[i].tolist() == [5.0, 15.0]
    j = np.flatnonzero((points == [10, 3]).all(axis=1))[0]
    assert partners[j].tolist() == [2.0, 25.0]


@settings(max_examples=40, deadline=None)
@given(rest=point_lists, offsets=st.lists(st.tuples(coords, coords), min_size=6, max_size=6),
       closed=st.booleans())
def test_polyline_partners_are_at_the_same_fraction_of_their_segment(rest, offsets, closed):
    rest = np.asarray(rest)
    pose = rest + 0.3 * np.asarray(offsets)[: len(rest)]
    points, moves = inkwarp.sample("polyline", rest, pose, closed=closed, spacing=2.0)
    partners = points + moves
    ring = np.vstack([rest, rest[:1]]) if closed else rest
    ring_pose = np.vstack([pose, pose[:1]]) if closed else pose
    # each sample lies on some rest segment at fraction u; its partner is at u on the
    # posed segment
    for p, q in zip(points, partners):
        found = False
        for a, b, a2, b2 in zip(ring[:-1], ring[1:], ring_pose[:-1], ring_pose[1:]):
            d = b - a
            L2 = d @ d
            # a zero-length rest segment has samples at both of its ends
            us = [0.0, 1.0] if L2 == 0 else [float(np.clip((p - a) @ d / L2, 0, 1))]
            for u in us:
                if np.linalg.norm(a + u * d - p) < 1e-7 and np.linalg.norm(a2 + u * (b2 - a2) - q) < 1e-7:
                    found = True
        assert found


def test_a_closed_curve_wraps_without_repeating_its_first_point():
    square = [[0, 0], [4, 0], [4, 4], [0, 4]]
    open_pts, _ = inkwarp.sample("polyline", square, square)
    closed_pts, _ = inkwarp.sample("polyline", square, square, closed=True)
    assert len(open_pts) == 13 and open_pts[-1].tolist() == [0.0, 4.0]
    assert len(closed_pts) == 16 and closed_pts[-1].tolist() == [0.0, 1.0]
    spline, _ = inkwarp.sample("spline", square, square, closed=True)
    assert not (spline[1:] == spline[0]).all(axis=1).any()


def test_point_and_cut():
    points, moves = inkwarp.sample("point", [[3.5, 2.0]], [[4.0, 0.0]])
    assert points.tolist() == [[3.5, 2.0]] and moves.tolist() == [[0.5, -2.0]]
    points, moves = inkwarp.sample("cut", [[0, 0], [9, 9]], [[0, 0], [9, 9]])
    assert points.shape == (0, 2) and moves.shape == (0, 2)


@settings(max_examples=40, deadline=None)
@given(radii=st.lists(st.floats(8, 30), min_size=3, max_size=8),
       a=st.floats(0.5, 1.5), b=st.floats(-0.5, 0.5), c=st.floats(-0.5, 0.5), d=st.floats(0.5, 1.5),
       tx=st.floats(-10, 10), ty=st.floats(-10, 10))
def test_a_polyline_region_follows_any_affine_map(radii, a, b, c, d, tx, ty):
    rest = star(radii)
    A = np.array([[a, b], [c, d]])
    pose = rest @ A.T + [tx, ty]
    points, moves = inkwarp.sample("region", rest, pose, shape=(64, 64))
    np.testing.assert_allclose(points + moves, points @ A.T + [tx, ty], atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(radii=st.lists(st.floats(8, 30), min_size=3, max_size=8), angle=st.floats(-3, 3),
       scale=st.floats(0.5, 2), tx=st.floats(-10, 10), ty=st.floats(-10, 10))
def test_a_spline_region_follows_a_similarity(radii, angle, scale, tx, ty):
    rest = star(radii)
    c, s = scale * np.cos(angle), scale * np.sin(angle)
    A = np.array([[c, -s], [s, c]])
    pose = rest @ A.T + [tx, ty]
    points, moves = inkwarp.sample("region", rest, pose, shape=(64, 64), curve="spline")
    np.testing.assert_allclose(points + moves, points @ A.T + [tx, ty], atol=1e-8)


def test_region_interior_nodes_and_displacements_match_independent_oracles():
    rest = star([20, 28, 17, 30, 24, 26, 15], center=(40.37, 38.61))
    pose = rest + np.stack([3 * np.sin(rest[:, 1] / 7), 0.02 * (rest[:, 0] - 40) ** 2], axis=1)
    mask = np.ones((80, 90), dtype=bool)
    mask[30:36, 20:70] = False  # a slot the region straddles
    for curve in ("polyline", "spline"):
        points, moves = inkwarp.sample("region", rest, pose, shape=(80, 90), curve=curve, mask=mask)
        # the outline samples come first (a region's outline is sampled like the closed
        # curve), then the interior nodes row by row
        outline_count = len(inkwarp.sample(curve, rest, pose, closed=True)[0])
        interior = points[outline_count:]
        outline_pts = points[:outline_count]
        # which nodes: every node strictly inside the outline where the mask is set
        ys, xs = np.mgrid[0:80, 0:90]
        nodes = np.stack([xs.ravel(), ys.ravel()], axis=1).astype(float)
        inside = Path(outline_pts).contains_points(nodes) & mask.ravel()
        assert sorted(map(tuple, interior.tolist())) == sorted(map(tuple, nodes[inside].tolist()))
        assert interior[:, ::-1].tolist() == sorted(interior[:, ::-1].tolist())  # row-major
        # how they move: mean value interpolation of the outline samples' displacements
        want = mvc_oracle(outline_pts, moves[:outline_count], interior)
        np.testing.assert_allclose(moves[outline_count:], want, atol=1e-9)


@pytest.mark.parametrize(
    ("args", "kwargs", "match"),
    [
        (("blob", [[0, 0]], [[0, 0]]), {}, "unknown feature kind 'blob'; the kinds are point, polyline"),
        (("polyline", [1, 2], [1, 2]), {}, r"rest must be an \(N, 2\) array .* write \[\[x, y\]\]"),
        (("polyline", [[0, 0, 0]], [[0, 0, 0]]), {}, r"got shape \(1, 3\)"),
        (("polyline", np.zeros((0, 2)), np.zeros((0, 2))), {}, "rest is empty"),
        (("polyline", [["a", "b"]], [[0, 0]]), {}, "could not be read as numbers"),
        (("polyline", [[0, 0], [1, np.nan]], [[0, 0], [1, 1]]), {}, r"rest\[1\] is \(0?1.0, nan\); every coordinate"),
        (("polyline", [[0, 0], [1, 1]], [[0, 0], [np.inf, 1]]), {}, r"pose\[1\] is \(inf, 1.0\)"),
        (("polyline", [[0, 0], [1, 1]], [[0, 0]]), {}, "pose has 1 point but rest has 2 points"),
        (("polyline", [[0, 0]], [[0, 0]]), {}, "A polyline needs at least 2 control points"),
        (("region", [[0, 0], [1, 0]], [[0, 0], [1, 0]]), {"shape": (4, 4)}, "A region needs at least 3"),
        (("point", [[0, 0], [1, 1]], [[0, 0], [1, 1]]), {}, "exactly one position"),
        (("polyline", [[0, 0], [1, 1]], [[0, 0], [1, 1]]), {"spacing": 0}, "spacing must be a positive"),
        (("polyline", [[0, 0], [1, 1]], [[0, 0], [1, 1]]), {"spacing": float("nan")}, "spacing must be"),
        (("polyline", [[0, 0], [1, 1]], [[0, 0], [1, 1]]), {"spacing": "1"}, "spacing must be a positive, finite number"),
        (("polyline", [[0, 0], [1, 1]], [[0, 0], [1, 1]]), {"spacing": True}, "spacing must be a positive, finite number"),
        (("region", [[0, 0], [4, 0], [0, 4]], [[0, 0], [4, 0], [0, 4]]), {}, r"a region needs shape=\(H, W\)"),
        (("region", [[0, 0], [4, 0], [0, 4]], [[0, 0], [4, 0], [0, 4]]), {"shape": (0, 4)}, r"shape must be at least \(1, 1\)"),
        # As thin_plate takes them (a float shape was cut, a NaN mask and closed="no" taken).
        (("region", [[0, 0], [4, 0], [0, 4]], [[0, 0], [4, 0], [0, 4]]), {"shape": (8.5, 8.7)}, r"shape must be \(H, W\)"),
        (("region", [[0, 0], [4, 0], [0, 4]], [[0, 0], [4, 0], [0, 4]]), {"shape": (8, 8), "mask": np.full((8, 8), np.nan)},
         "mask has NaN or infinite values"),
        (("region", [[0, 0], [4, 0], [0, 4]], [[0, 0], [4, 0], [0, 4]]), {"shape": (8, 8), "mask": np.ones((8, 8, 4))},
         r"a picture's alpha is mask\[\.\.\., 3\]"),
        (("polyline", [[0, 0], [1, 1]], [[0, 0], [1, 1]]), {"closed": "no"}, "closed must be True or False"),
        (("polyline", [[0, 0], [1, 1]], [[0, 0], [1, 1]]), {"spacing": 10**400}, "spacing must be a positive"),
        (("region", [[0, 0], [4, 0], [0, 4]], [[0, 0], [4, 0], [0, 4]]), {"shape": (4, 4), "mask": np.ones((3, 4))},
         r"mask has shape \(3, 4\) but shape is \(4, 4\)"),
        (("polyline", [[0, 0], [1, 1]], [[0, 0], [1, 1]]), {"mask": np.ones((3, 4))}, "mask needs shape"),
        (("spline", [[0, 0], [1, 1]], [[0, 0], [1, 1]]), {"curve": "spline"}, "for region outlines only"),
        (("region", [[0, 0], [4, 0], [0, 4]], [[0, 0], [4, 0], [0, 4]]), {"curve": "bezier"}, "unknown curve 'bezier'"),
    ],
)
def test_bad_input_says_what_and_how_to_fix(args, kwargs, match):
    with pytest.raises(ValueError, match=match):
        inkwarp.sample(*args, **kwargs)


def test_curve_polyline_of_a_closed_spline_returns_to_its_start():
    square = np.array([[0, 0], [10, 0], [10, 10], [0, 10]], dtype=float)
    line = inkwarp._inkwarp.curve_polyline("spline", square, closed=True, spacing=0.5)
    assert (line[0] == line[-1]).all()
    assert (np.linalg.norm(np.diff(line, axis=0), axis=1) <= 0.5 + 1e-12).all()


def test_the_documented_examples_run():
    import doctest
    from pathlib import Path as FilePath

    import inkwarp.drawing

    result = doctest.testmod(inkwarp.drawing)
    assert result.attempted > 0 and result.failed == 0
    page = FilePath(__file__).resolve().parents[1] / "docs" / "concepts" / "drawings.md"
    result = doctest.testfile(str(page), module_relative=False)
    assert result.attempted > 0 and result.failed == 0
