"""`inkwarp.thin_plate`: arguments, results, and the messages for bad input."""

from __future__ import annotations

import dataclasses
import threading
import warnings

import numpy as np
import pytest
from scipy import ndimage

import inkwarp
from test_solver_oracle import Problem, oracle

PTS = [[2.0, 3.0], [20.0, 4.0], [10.0, 15.0]]
DISP = [[1.0, 0.0], [0.0, 1.0], [-1.0, 2.0]]
SHAPE = (18, 24)
# Four points whose displacements no affine map fits: the solve iterates (three points,
# or displacements an affine map fits, take that map with no cycle).
PTS4 = PTS + [[16.0, 12.0]]
DISP4 = DISP + [[2.0, -1.0]]


def test_returns_float32_height_width_2():
    field = inkwarp.thin_plate(PTS, DISP, SHAPE)
    assert field.shape == (18, 24, 2) and field.dtype == np.float32
    # constrained nodes hold their displacements exactly
    assert np.array_equal(field[3, 2], np.float32([1.0, 0.0]))
    assert np.array_equal(field[15, 10], np.float32([-1.0, 2.0]))


def test_report_is_a_frozen_dataclass_with_the_counts():
    pts = PTS4 + [[-5.0, 1.0], [2.4, 3.3]]  # one outside, one on the same node as the first
    disp = DISP4 + [[9.0, 9.0], [3.0, 0.0]]
    field, report = inkwarp.thin_plate_report(pts, disp, SHAPE)
    assert isinstance(report, inkwarp.SolveReport)
    assert (report.constrained_nodes, report.constrained_samples, report.dropped_samples) == (4, 5, 1)
    assert np.array_equal(field[3, 2], np.float32([2.0, 0.0]))  # averaged
    assert report.converged and report.cycles >= 1 and report.seconds > 0
    assert report.final_change <= 0.01 and report.residual >= 0
    with pytest.raises(dataclasses.FrozenInstanceError):
        report.cycles = 3  # type: ignore[misc]


def test_mask_zero_pixels_do_not_move_and_samples_there_are_dropped():
    mask = np.ones(SHAPE, bool)
    mask[:, 12] = False
    field, report = inkwarp.thin_plate_report(PTS + [[12, 5]], DISP + [[5, 5]], SHAPE, mask=mask)
    assert np.all(field[:, 12] == 0)
    assert report.dropped_samples == 1


def test_a_grid_without_mask_or_cuts_is_the_same_whatever_came_before():
    # The binding keeps the last open grid by shape: solves with a mask, a cut or another
    # shape in between must leave it as it was.
    first = inkwarp.thin_plate(PTS4, DISP4, SHAPE)
    mask = np.ones(SHAPE, bool)
    mask[:, 12] = False
    torn = inkwarp.thin_plate(PTS4, DISP4, SHAPE, mask=mask, cuts=[[[5.5, -1], [5.5, 9]]])
    assert not np.array_equal(torn, first)
    inkwarp.thin_plate(PTS4, DISP4, (SHAPE[0] + 3, SHAPE[1]))
    assert np.array_equal(inkwarp.thin_plate(PTS4, DISP4, SHAPE), first)
    cut = inkwarp.thin_plate(PTS4, DISP4, SHAPE, cuts=[[[5.5, -1], [5.5, 9]]])
    assert np.array_equal(inkwarp.thin_plate(PTS4, DISP4, SHAPE), first)
    assert not np.array_equal(cut, first)


def test_accepts_numpy_and_lists_and_integer_types():
    a = inkwarp.thin_plate(np.array(PTS, np.float32), np.array(DISP, np.int64), (np.int64(18), 24))
    b = inkwarp.thin_plate(PTS, DISP, SHAPE)
    assert np.array_equal(a, b)


def test_southwell_and_grid_step_and_max_cycles_run():
    f1, r1 = inkwarp.thin_plate_report(PTS4, DISP4, SHAPE, method="southwell")
    f2, r2 = inkwarp.thin_plate_report(PTS4, DISP4, SHAPE, grid_step=3)
    f3, r3 = inkwarp.thin_plate_report(PTS4, DISP4, SHAPE, max_cycles=1, tolerance=0.0)
    assert r3.cycles == 1 and not r3.converged
    for f in (f1, f2, f3):
        assert f.shape == (18, 24, 2) and np.all(np.isfinite(f))


def test_a_report_says_why_its_solve_stopped():
    # Recorded by the solve, not inferred: converged exactly when "converged".
    rng = np.random.default_rng(0)
    pts, disp = rng.uniform(0, 256, (10, 2)), rng.normal(0, 3, (10, 2))
    cases = [
        ({}, "converged"),
        ({"max_cycles": 1}, "max_cycles"),
        ({"method": "southwell", "southwell_sweeps": 1}, "budget"),
        ({"method": "southwell", "southwell_sweeps": 3, "max_cycles": 2}, "max_cycles"),
        ({"tolerance": 1e-9}, "precision"),
        # No number of cycles meets that tolerance: the reason, though the cycles ran out too.
        ({"tolerance": 1e-9, "max_cycles": 3}, "precision"),
        # None allowed: the start comes back, and why is that, not its size (it said "precision").
        ({"max_cycles": 0}, "max_cycles"),
        ({"max_cycles": 0, "initial": np.full((257, 257, 2), 1e30, np.float32)}, "max_cycles"),
    ]
    for kwargs, stop in cases:
        _, report = inkwarp.thin_plate_report(pts, disp, (257, 257), **kwargs)
        assert report.stop == stop and report.converged == (stop == "converged"), (kwargs, report)


def test_grid_step_samples_go_to_their_nearest_coarse_node():
    # The last coarse row and column sit on the border, so the last cell may be shorter
    # than the step: a sample in it goes to the coarse node nearest to it, which keeps
    # its displacement (Catmull-Rom keeps the coarse values). They used to go by x / step,
    # so at a step above the grid's size every sample fell on the first node.
    pts = [[0.0, 0.0], [0.0, 8.0], [8.9, 4.0]]
    field, report = inkwarp.thin_plate_report(pts, [[0, 0], [0, 0], [2.0, 1.0]], (9, 10), grid_step=4)
    assert report.constrained_nodes == 3
    assert np.allclose(field[4, 9], [2.0, 1.0], atol=1e-5)
    field, report = inkwarp.thin_plate_report([[5, 5], [25, 5], [15, 25]], [[1, 0], [0, 1], [1, 1]], (32, 32), grid_step=1000)
    assert report.constrained_nodes == 3
    for (row, col), value in (((0, 0), [1, 0]), ((0, 31), [0, 1]), ((31, 0), [1, 1])):
        assert np.allclose(field[row, col], value, atol=1e-5), (row, col, field[row, col])


@pytest.mark.parametrize("width", [6, 8, 10])
def test_a_turned_limb_keeps_its_shape_at_grid_step_4(width):
    # A limb of the matte a few steps wide, every pixel of it turned by 60 degrees (a region
    # dragged round), held still far away. Each coarse node takes its nearest sample (the
    # mean of the 16 that round to it stood 0.7 px off), and a pixel whose cubic window the
    # limb's edges cut short still gives the turn (renormalised alone, the limb's edges
    # came out as beads up to 3.6 px off).
    shape, c, turn = (200, 240), np.array([86.0, 110.0]), np.radians(60)
    ys, xs = np.mgrid[0 : shape[0], 0 : shape[1]].astype(float)
    along = np.array([np.cos(np.radians(-146)), np.sin(np.radians(-146))])
    rel = np.stack([xs - c[0], ys - c[1]], axis=-1)
    t, n = rel @ along, rel @ np.array([-along[1], along[0]])
    limb = (t > 0) & (t < 60) & (np.abs(n) < width / 2)
    mask = limb | (ys > 150)
    rot = np.array([[np.cos(turn) - 1, -np.sin(turn)], [np.sin(turn), np.cos(turn) - 1]])
    pts = np.stack([xs[limb], ys[limb]], axis=-1)
    held = np.array([[30.0, 190.0], [220.0, 190.0], [120.0, 170.0]])
    field = inkwarp.thin_plate(
        np.vstack([pts, held]), np.vstack([(pts - c) @ rot.T, np.zeros((3, 2))]), shape, mask=mask, grid_step=4
    )
    error = np.hypot(*(field[limb] - (pts - c) @ rot.T).T)
    # (A few pixels at the limb's ends and corners reach no coarse node inside their window:
    # they take their nearest neighbour's value along the links, a pixel's turn off.)
    assert np.median(error) < 0.01 and np.mean(error < 0.1) > 0.95, (np.median(error), np.mean(error < 0.1))


@pytest.mark.parametrize("seed", range(6))
def test_grid_step_keeps_an_affine_motion_affine_beside_holes(seed):
    # An affine motion pinned at every active coarse node, holes in the matte. A pixel on a
    # coarse row or column fitted its window's plane along that line alone: where a hole
    # took the nearer node, it took the farther one's value, a streak one pixel wide up to
    # 2.1 px off between exact rows (step 8, a disc of radius 9.5 at (47.3, 21.6)).
    rng = np.random.default_rng(seed)
    step = int(rng.choice([4, 8, 16]))
    h, w = (step * int(n) + 1 for n in rng.integers(5, 9, 2))  # (side - 1) a multiple of the step
    ys, xs = np.mgrid[0:h, 0:w]
    mask = np.ones((h, w), bool)
    for _ in range(3):
        cx, cy, r = rng.uniform(0, w), rng.uniform(0, h), rng.uniform(0.6, 1.4) * step
        mask &= (xs - cx) ** 2 + (ys - cy) ** 2 >= r * r
    if seed == 0:
        step, mask = 8, ((xs - 47.3) ** 2 + (ys - 21.6) ** 2 >= 9.5**2)[:65, :65]
        h = w = 65
        ys, xs = np.mgrid[0:h, 0:w]
    a, b = np.array([[0.3, -0.2], [0.1, 0.4]]), np.array([2.0, -1.5])
    nodes = np.stack(np.meshgrid(np.arange(0, w, step), np.arange(0, h, step)), -1).reshape(-1, 2)
    pts = nodes[mask[nodes[:, 1], nodes[:, 0]]].astype(float)
    field, report = inkwarp.thin_plate_report(pts, pts @ a.T + b, (h, w), mask=mask, grid_step=step)
    exact = np.stack([xs, ys], -1) @ a.T + b
    # (on the pieces the points hold: a piece no point holds does not move)
    labels, _ = ndimage.label(mask)
    held = np.isin(labels, labels[pts[:, 1].astype(int), pts[:, 0].astype(int)])
    error = np.where(held, np.abs(field - exact).max(-1), 0)
    assert report.converged and error.max() < 1e-3, (step, error.max(), np.argwhere(error > 1e-3)[:5])


def test_grid_step_takes_a_coarse_row_whose_nodes_are_holes_from_the_rows_beside():
    # Row 32 of a step-16 grid runs between holes on its coarse nodes (16, 32), (32, 32) and
    # (48, 32): a pixel on it between them has none of its own row's nodes to use, and took
    # a neighbour's value along the links, one row off (0.4 px for this motion).
    h = w = 65
    ys, xs = np.mgrid[0:h, 0:w]
    mask = np.ones((h, w), bool)
    for x in (16, 32, 48):
        mask[31:34, x - 1 : x + 2] = False
    a, b = np.array([[0.3, -0.2], [0.1, 0.4]]), np.array([2.0, -1.5])
    nodes = np.stack(np.meshgrid(np.arange(0, w, 16), np.arange(0, h, 16)), -1).reshape(-1, 2)
    pts = nodes[mask[nodes[:, 1], nodes[:, 0]]].astype(float)
    field = inkwarp.thin_plate(pts, pts @ a.T + b, (h, w), mask=mask, grid_step=16)
    error = np.where(mask, np.abs(field - (np.stack([xs, ys], -1) @ a.T + b)).max(-1), 0)
    assert error.max() < 1e-3, (error.max(), np.argwhere(error > 1e-3)[:5])


def test_solves_run_in_parallel_threads():
    # The GIL is released during the solve: threads finish with correct results.
    results = {}

    def work(k):
        results[k] = inkwarp.thin_plate(PTS, np.asarray(DISP) * k, (64, 64))

    threads = [threading.Thread(target=work, args=(k,)) for k in (1, 2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert np.allclose(results[2], 2 * results[1], atol=0.05)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"points": [[1, 2, 3]]}, r"points must have shape \(N, 2\)"),
        ({"points": [[1, np.nan]], "displacements": [[0, 0]]},
         r"points has a value that is not a finite number \(NaN, None or infinite\) in row 0"),
        ({"displacements": [[0, np.inf]] * 3}, "displacements has a value that is not a finite number"),
        ({"points": [[None, 1]], "displacements": [[0, 0]]}, r"\(NaN, None or infinite\) in row 0"),
        ({"points": np.zeros((0, 2)), "displacements": np.zeros((0, 2))}, "points is empty"),
        ({"displacements": [[0, 0]]}, "points has 3 rows but displacements has 1"),
        ({"points": "abc"}, "points must be an"),
        ({"shape": (0, 5)}, r"shape must be \(height, width\)"),
        ({"shape": (5,)}, r"shape must be \(height, width\)"),
        ({"shape": (5.5, 3)}, r"shape must be \(height, width\)"),
        ({"mask": np.ones((3, 3))}, r"mask has shape \(3, 3\)"),
        ({"mask": np.full(SHAPE, np.nan)}, "mask has NaN"),
        ({"mask": np.ones((*SHAPE, 4))}, r"a picture's channels; pass one of them, an \(H, W\) array \(a picture's alpha is mask\[\.\.\., 3\]\)"),
        ({"cuts": [[[1, 1]]]}, r"cuts\[0\] has 1 point"),
        ({"cuts": np.zeros((3, 2))}, "wrap a single cut in a list"),
        # (They said "got shape (); reshape it, e.g. np.asarray(points).reshape(-1, 2)", which fails on None.)
        ({"points": None}, r"points must be an \(N, 2\) array with one \(x, y\) pair per row, got None"),
        ({"cuts": [10, 0, 10, 31]}, r"got a list of numbers \[10, 0, 10, 31\]; give each cut's points as pairs"),
        ({"cuts": [[0, 20], [60, 20]]}, "wrap a single cut in a list"),  # pointed at a reshape to one point
        ({"cuts": [[[1, 1], [np.nan, 2]]]}, r"cuts\[0\] has a value that is not a finite number"),
        # A ragged cut named (numpy's "inhomogeneous shape" came up from a check of all cuts).
        ({"cuts": [[[1, 2], [3]]]}, r"cuts\[0\] must be an \(N, 2\) array of numbers"),
        ({"tension": -1.0}, "tension must be a finite number >= 0"),
        ({"tension": np.inf}, "tension must be a finite number >= 0"),
        ({"tolerance": -0.1}, "tolerance must be a finite number >= 0"),
        ({"grid_step": 0}, "grid_step must be an integer from 1 to 32768"),
        ({"grid_step": 1.5}, "grid_step must be an integer from 1 to 32768"),
        ({"grid_step": 10**20}, "grid_step must be an integer from 1 to 32768"),
        ({"max_cycles": -1}, r"max_cycles must be None \(the default cap, 300\) or an integer from 0 to 4,294,967,295"),
        # Past the engine's integers: a ValueError naming it, not numpy's or Rust's OverflowError.
        ({"max_cycles": 10**20}, "max_cycles must be None .* from 0 to 4,294,967,295, got 100000000000000000000"),
        ({"mask": "head.png"}, r"mask must be an \(H, W\) array, got the path 'head.png'"),
        ({"method": "jacobi"}, "method must be one of"),
        ({"initial": np.zeros((2, 2, 2))}, r"initial has shape \(2, 2, 2\) but must be \(18, 24, 2\)"),
        ({"initial": np.full((18, 24, 2), np.nan)}, "initial has NaN"),
        # Cut points within the coordinate limit, as points are (one at 1e308 dropped the cut).
        ({"cuts": [[[-1e308, 5.5], [1e308, 5.5]]]}, r"cuts\[0\] must be finite numbers of pixels within ±1e6, found -1e308"),
        ({"cuts": [[[0, 5.5], [1e7, 5.5]]]}, r"cuts\[0\] must be finite numbers of pixels within ±1e6, found 1e7"),
        # Python integers past any float, and other wrong types: ValueErrors naming the argument.
        ({"points": [[10**400, 1]], "displacements": [[1, 1]]}, r"points holds a number too large for a float; every value must be a finite number"),
        ({"cuts": [[[0, 0], [10**400, 1]]]}, r"cuts\[0\] holds a number too large for a float"),
        ({"initial": [[[10**400, 0]]]}, r"initial holds a number too large for a float"),
        ({"initial": "abc"}, r"initial must be an \(H, W, 2\) array of numbers"),
        ({"tension": 10**400}, "tension must be a finite number >= 0, got an integer of 401 digits"),
        ({"tolerance": 10**400}, "tolerance must be a finite number >= 0, got an integer of 401 digits"),
        ({"southwell_sweeps": 10**400}, "southwell_sweeps must be a finite number >= 0, got an integer of 401 digits"),
        ({"tension": 1000001}, r"tension must be a number from 0 to 1e6 .*, got 1000001\.$"),
        ({"tension": np.float64(2e6)}, r"tension must be a number from 0 to 1e6 .*, got 2000000\.0\.$"),
        # A whole float is shown as the float it is: "an integer ..., got 2" misread it.
        ({"grid_step": 2.0}, r"grid_step must be an integer from 1 to 32768 .*, got 2\.0\.$"),
        ({"max_cycles": 5.0}, r"max_cycles must be None .*, got 5\.0\.$"),
        ({"tension": -(10**5000)}, "tension must be a finite number >= 0, got a negative integer of about 5000 digits"),
        ({"cuts": np.array(5)}, r"cuts must be a list of \(K, 2\) polylines, got array\(5\)"),
        ({"cuts": 5}, r"cuts must be a list of \(K, 2\) polylines, got 5"),
        ({"mask": [[1, 2], [3]]}, r"mask must be an \(H, W\) array of numbers"),
        ({"points": np.array(PTS) + 1j}, "points holds complex numbers"),
        ({"displacements": np.array(DISP, complex)}, "displacements holds complex numbers"),
        ({"initial": np.zeros((18, 24, 2), complex)}, "initial holds complex numbers"),
    ],
)
def test_bad_arguments_say_what_to_fix(kwargs, match):
    args = {"points": PTS, "displacements": DISP, "shape": SHAPE}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        inkwarp.thin_plate_report(args.pop("points"), args.pop("displacements"), args.pop("shape"), **args)


def test_cuts_given_as_a_generator_are_read_once():
    # (A generator has no len(): "object of type 'generator' has no len()" came up.)
    cut = [[5.5, -1.0], [5.5, 40.0]]
    as_list, _ = inkwarp.thin_plate_report(PTS, DISP, SHAPE, cuts=[cut])
    as_generator, _ = inkwarp.thin_plate_report(PTS, DISP, SHAPE, cuts=(c for c in [cut]))
    uncut, _ = inkwarp.thin_plate_report(PTS, DISP, SHAPE)
    assert np.array_equal(as_list, as_generator) and np.abs(as_list - uncut).max() > 0.5


def test_southwell_stops_once_nothing_is_left_to_relax():
    # A budget far beyond what a small grid needs: it converges to rounding and returns.
    field, report = inkwarp.thin_plate_report(PTS, DISP, SHAPE, method="southwell", southwell_sweeps=1e5)
    exact = oracle(Problem(SHAPE, np.array(PTS), np.array(DISP)))[0]
    assert report.converged and np.abs(field - exact).max() < 1e-3


def test_warm_start_follows_an_animation_with_fewer_cycles_and_the_same_accuracy():
    pts = [[4, 4], [60, 6], [6, 44], [58, 42], [20, 20], [44, 30], [32, 10]]

    def disp(t):
        return [[0, 0]] * 4 + [[5 * np.sin(t), 3 * np.cos(t)], [-4 * np.cos(1.3 * t), 2 * np.sin(t)], [3 * t, -t]]

    warm = inkwarp.WarmStart()
    previous = None
    with_history, from_previous = 0, 0
    for frame in range(10):
        t = 0.2 * frame
        field, report = inkwarp.thin_plate_report(pts, disp(t), (48, 64), warm=warm)
        exact = oracle(Problem((48, 64), np.array(pts, float), np.array(disp(t), float)))[0]
        assert np.abs(field - exact).max() < 0.05
        _, plain = inkwarp.thin_plate_report(pts, disp(t), (48, 64), initial=previous)
        previous = field
        if frame >= 3:
            with_history += report.cycles
            from_previous += plain.cycles
    assert len(warm) == 3
    assert with_history < from_previous
    warm.clear()
    assert len(warm) == 0 and "0 earlier" in repr(warm)


def test_warm_start_starts_over_when_the_cuts_change():
    # The same grid size and points, another cut: the frames before it (another surface)
    # were kept, and the next three frames solved as from no start at all.
    rng = np.random.default_rng(0)
    pts, disp, shape = rng.uniform(0, 127, (25, 2)), rng.normal(0, 4, (25, 2)), (128, 128)
    cut_a, cut_b = [np.array([[10.5, 100], [120.5, 110]])], [np.array([[64.5, 0], [64.5, 80]])]
    warm = inkwarp.WarmStart()
    for k in (1.0, 0.9):
        inkwarp.thin_plate(pts, disp * k, shape, cuts=cut_a, warm=warm)
    assert len(warm) == 2
    inkwarp.thin_plate(pts, disp * 0.8, shape, cuts=cut_b, warm=warm)
    assert len(warm) == 1
    _, second = inkwarp.thin_plate_report(pts, disp * 0.7, shape, cuts=cut_b, warm=warm)
    _, cold = inkwarp.thin_plate_report(pts, disp * 0.7, shape, cuts=cut_b)
    assert second.cycles < cold.cycles, (second, cold)


def test_sizes_and_counts_are_whole_numbers_and_an_empty_list_is_empty():
    pts, disp = [[4, 4], [20, 4], [12, 12]], [[1, 0], [0, 1], [2, 2]]
    with pytest.raises(ValueError, match="max_samples must be a whole number"):
        inkwarp.interpolate(pts, disp, (16, 24), max_samples="x")
    with pytest.raises(ValueError, match="max_samples must be a whole number"):
        inkwarp.interpolate(pts, disp, (16, 24), max_samples=2.5)
    with pytest.raises(ValueError, match="shape must be"):
        inkwarp.interpolate(pts, disp, (16.7, 24))  # was cut to 16
    with pytest.raises(ValueError, match="points is empty"):
        inkwarp.thin_plate([], [], (16, 24))  # was "must have shape (N, 2)"


def test_warm_start_mistakes_say_what_to_do():
    with pytest.raises(ValueError, match="inkwarp.WarmStart"):
        inkwarp.thin_plate(PTS, DISP, SHAPE, warm="yes")
    with pytest.raises(ValueError, match="initial or warm, not both"):
        inkwarp.thin_plate(PTS, DISP, SHAPE, warm=inkwarp.WarmStart(), initial=np.zeros((*SHAPE, 2), np.float32))


def test_a_kept_solver_gives_a_fresh_solves_answer_on_torn_grids_and_other_grids():
    # Its coarse levels are reused for the same grid and points and rebuilt for others;
    # either way each answer is bit for bit the answer of a call without it (none of these
    # solves is slow enough to make the next keep its directions early).
    rng = np.random.default_rng(3)
    mask = np.ones((40, 48), np.uint8)
    mask[15:22, 20:30] = 0
    cuts = [np.array([[-1.0, 30.5], [30.0, 25.2]])]
    pts = np.column_stack([rng.uniform(0, 47, 12), rng.uniform(0, 39, 12)])
    solver = inkwarp.Solver()
    for k, (shape, m, c) in enumerate([((40, 48), mask, cuts), ((40, 48), mask, cuts), ((40, 48), None, None),
                                       ((33, 33), None, cuts), ((40, 48), mask, cuts)]):
        p = pts if shape == (40, 48) else pts * 0.6
        disp = rng.normal(0, 3, (12, 2))
        kept, rep = inkwarp.thin_plate_report(p, disp, shape, mask=m, cuts=c, solver=solver)
        fresh, fresh_rep = inkwarp.thin_plate_report(p, disp, shape, mask=m, cuts=c)
        assert rep.converged and rep.cycles == fresh_rep.cycles, k
        assert np.array_equal(kept, fresh), k
    assert repr(solver) == "Solver()"


def test_solver_mistakes_say_what_to_do():
    with pytest.raises(ValueError, match="inkwarp.Solver"):
        inkwarp.thin_plate(PTS, DISP, SHAPE, solver="yes")
    with pytest.raises(ValueError, match="solver or warm, not both"):
        inkwarp.thin_plate(PTS, DISP, SHAPE, solver=inkwarp.Solver(), warm=inkwarp.WarmStart())


def test_the_extension_stubs_are_valid_python():
    import ast
    from pathlib import Path

    ast.parse((Path(inkwarp.__file__).parent / "_inkwarp.pyi").read_text(encoding="utf-8"))


def test_the_ablation_switches_leave_the_answer_within_tolerance_and_refuse_unknown_names():
    # The benchmark's private keyword: a mechanism switched off changes the cycles, not the
    # answer; a name that is no switch is a clear error naming the switches.
    pts = np.array([[10.0, 10.0], [50.0, 12.0], [30.0, 40.0], [5.0, 44.0]])
    disp = np.array([[2.0, 0.0], [0.0, 1.0], [-1.0, 0.5], [0.0, 0.0]])
    base, _ = inkwarp.thin_plate_report(pts, disp, (48, 64))
    field, report = inkwarp.thin_plate_report(pts, disp, (48, 64), _off="kcycle")
    assert report.converged and np.abs(field - base).max() < 0.05
    with pytest.raises(ValueError, match="unknown mechanism .*second"):
        inkwarp.thin_plate_report(pts, disp, (48, 64), _off="held")


def test_three_points_and_affine_motions_take_their_map_exactly():
    # At tension 0 an affine map has no plate energy: three points, or any number whose
    # nodes' displacements one affine map fits (points on nodes turned together, or any
    # points translated together), are answered by it with no cycle.
    ys, xs = np.mgrid[0 : SHAPE[0], 0 : SHAPE[1]].astype(np.float64)
    grid_xy = np.stack([xs, ys], axis=-1)
    field, report = inkwarp.thin_plate_report(PTS, DISP, SHAPE)
    assert report.converged and report.cycles == 0
    coef = np.linalg.solve(np.column_stack([PTS, np.ones(3)]), DISP)
    assert np.abs(field - np.concatenate([grid_xy, np.ones_like(xs)[..., None]], axis=-1) @ coef).max() < 1e-5
    rng = np.random.default_rng(5)
    on_nodes = rng.integers(0, 17, (12, 2)).astype(float)
    turn = np.array([[0.0, -0.05], [0.05, 0.0]])  # a small rotation and a translation
    field, report = inkwarp.thin_plate_report(on_nodes, on_nodes @ turn.T + [1.5, -0.5], SHAPE)
    assert report.converged and report.cycles == 0
    assert np.abs(field - (grid_xy @ turn.T + [1.5, -0.5])).max() < 1e-5
    anywhere = rng.uniform(0, 17, (12, 2))
    field, report = inkwarp.thin_plate_report(anywhere, np.tile([0.7, -2.25], (12, 1)), SHAPE)
    assert report.converged and report.cycles == 0
    assert np.abs(field - [0.7, -2.25]).max() < 1e-6


@pytest.mark.parametrize("tension", [0.0, 0.3])
def test_a_piece_whose_points_move_together_translates_with_no_cycle(tension):
    # A rest frame (every displacement zero) or a piece dragged whole: the translation has
    # no energy of either kind, so it is the answer, on torn grids too, at once; a cycle
    # cap cannot make it unconverged.
    h, w = 40, 56
    ys, xs = np.mgrid[0:h, 0:w]
    mask = ((xs - 30) ** 2 + (ys - 20) ** 2 > 36).astype(np.uint8)
    cuts = [[[5.5, 30.5], [40.5, 25.5]]]
    pts = [[10, 10], [45, 8], [30, 35], [50, 30], [8, 36]]  # both sides of the cut
    for move in ([0.0, 0.0], [1.25, -3.5]):
        field, report = inkwarp.thin_plate_report(pts, [move] * len(pts), (h, w), mask=mask, cuts=cuts,
                                                  tension=tension, max_cycles=1)
        assert report.converged and report.cycles == 0, report
        assert np.array_equal(field[mask > 0], np.tile(np.float32(move), (int(mask.sum()), 1)))
        assert not field[mask == 0].any()
    # Displacements computed as pose - rest differ in their last bits: still a translation.
    rest = np.array(pts, float) * 1.37
    drag = (rest + [3.7, -0.3]) - rest
    assert len({tuple(d) for d in drag}) > 1  # not bit for bit equal
    field, report = inkwarp.thin_plate_report(pts, drag, (h, w), mask=mask, cuts=cuts, tension=tension, max_cycles=1)
    assert report.converged and report.cycles == 0 and np.abs(field[mask > 0] - [3.7, -0.3]).max() < 1e-6
    # A tolerance finer than the float32 field's resolution is not met, even by a translation.
    _, report = inkwarp.thin_plate_report(pts, [[0.1, 0.0]] * len(pts), (h, w), mask=mask, tolerance=1e-12)
    assert not report.converged


def test_complex_numbers_are_refused_everywhere_points_are_taken():
    pts = np.array([[1.0, 2.0], [5.0, 6.0], [3.0, 1.0]]) + 1j
    for call in (lambda: inkwarp.interpolate(pts, np.zeros((3, 2)), (8, 8), method="triangulation"),
                 lambda: inkwarp.sample("polyline", pts.real, pts)):
        with pytest.raises(ValueError, match="holds complex numbers"):
            call()


def test_no_cycle_returns_a_warm_start_as_it_is():
    # max_cycles=0 runs none and returns the start: a close but rough start (the answer
    # rounded to half pixels) came back with its coarse-to-fine correction, 7 px off.
    pts, disp, shape = [[20, 20], [100, 20], [20, 80], [100, 80], [64, 48]], [[0, 0]] * 4 + [[10, -6]], (96, 128)
    start = np.round(inkwarp.thin_plate(pts, disp, shape, tolerance=1e-5) * 2) / 2
    field, report = inkwarp.thin_plate_report(pts, disp, shape, initial=start, max_cycles=0)
    assert (report.cycles, report.converged, report.stop) == (0, False, "max_cycles")
    for (x, y), d in zip(pts, disp):  # the constrained nodes hold their displacements
        start[y, x] = d
    assert np.array_equal(field, start)


def test_a_start_past_float32_is_refused_without_numpy_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match="initial has NaN or infinite"):
            inkwarp.thin_plate(PTS, DISP, SHAPE, initial=np.full(SHAPE + (2,), 1e300))


def test_a_number_in_a_zero_dimensional_array_is_a_number():
    # tolerance=np.array(0.01) was refused where np.float32(0.5) was taken.
    pts, disp = [[4, 4], [40, 4], [20, 25]], [[1, 0], [0, 1], [2, 2]]
    np.testing.assert_array_equal(inkwarp.thin_plate(pts, disp, (32, 48), tolerance=np.array(0.01), tension=np.array(0.5)),
                                  inkwarp.thin_plate(pts, disp, (32, 48), tolerance=0.01, tension=0.5))


def test_thin_plate_warns_of_what_its_hidden_report_would_say():
    # thin_plate returns the field alone: a solve stopped short, or points that all miss the
    # grid (a field of zeros), are said in a warning; thin_plate_report says them in its report.
    rng = np.random.default_rng(0)
    pts, disp = rng.uniform(0, 255, (20, 2)), rng.normal(0, 3, (20, 2))
    # A ConvergenceWarning, as scenes warn, so that one filter catches both.
    with pytest.warns(inkwarp.ConvergenceWarning, match=r"did not converge \(stopped: max_cycles, after 1 cycle\)"):
        inkwarp.thin_plate(pts, disp, (256, 256), max_cycles=1)
    with pytest.warns(inkwarp.InkwarpWarning, match="all 2 points lie off the grid or on masked-out nodes, so the field is zero"):
        field = inkwarp.thin_plate([[100, 100], [200, 3]], [[5, 5], [1, 1]], (32, 32))
    assert not field.any()
    _, report = inkwarp.thin_plate_report([[100, 100], [200, 3]], [[5, 5], [1, 1]], (32, 32))  # no warning
    assert report.dropped_samples == 2 and report.constrained_samples == 0
    # Stops that are the settings' own doing say nothing (warnings are errors in this suite):
    # southwell's fixed budget, a tolerance of 0 (never converged by definition).
    inkwarp.thin_plate(pts, disp, (256, 256), method="southwell")
    inkwarp.thin_plate(pts, disp, (256, 256), tolerance=0, max_cycles=3)
    # interpolate_report's tps puts it in its report, not in a warning from inside inkwarp.
    _, said = inkwarp.interpolate_report([[100, 100], [200, 3]], [[5, 5], [1, 1]], (32, 32), method="tps")
    assert said["samples_used"] == 0 and said["dropped"] == 2
    _, said = inkwarp.interpolate_report(pts, disp, (256, 256), method="tps")
    assert said["samples_used"] == 20 and said["dropped"] == 0 and said["notes"] == []
