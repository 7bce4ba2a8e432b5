"""The multigrid thin plate on the hard families of DESIGN §4, against the direct solve.

Each family is a shape that real mattes are full of and that a grid solver finds hard:
pieces joined at one node (hinges), strands one or two pixels wide, thin closed rings,
antialiased character mattes (hair and a thin neck), combs with one-pixel gaps, many
random cuts, cuts through node centres, and warm starts from garbage. The oracle is the
sparse direct solve of `test_solver_oracle.py` (its own links with the documented cut tie
rule, tension -> 0+ by extrapolation where the plate minimiser is not unique).

The contract checked everywhere: the solve reports `converged=True` at default settings,
and then every node is within 0.05 px of the oracle. A `converged=True` far from the
oracle is reported as the worse failure (a wrong answer claimed right).
"""

from __future__ import annotations

import dataclasses
import functools
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import inkwarp
import test_solver_oracle
from test_solver_oracle import TOLERANCE_PX, Problem, links, oracle, piece_labels, solve

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from ratios import model_problem  # noqa: E402

DATA = Path(__file__).resolve().parent / "data"


def check_against_oracle(problem: Problem, what: str, **kwargs):
    """Solve, compare every active node with the oracle. A torn piece this small is solved
    whole by its banded factor, so the iteration that larger pieces take is checked too
    (`_off="whole"`); returns the larger max error and the report with more cycles."""
    exact, skipped, _degenerate = oracle(problem)
    assert not skipped.any(), f"{what}: the oracle could not solve {int(skipped.sum())} nodes"
    active, _, _ = links(problem)
    results = []
    for off in ("", "whole") if "_off" not in kwargs else (kwargs.pop("_off"),):
        field, report = solve(problem, _off=off, **kwargs)
        err = float(np.abs(field - exact)[active].max()) if active.any() else 0.0
        if report.converged:
            assert err < TOLERANCE_PX, (
                f"{what} (off {off!r}): reported converged, yet a node is {err:.4f} px from the direct "
                f"solve (contract {TOLERANCE_PX} px; {report})")
        else:
            raise AssertionError(f"{what} (off {off!r}): not converged at default settings, {err:.4f} px off ({report})")
        results.append((err, report))
    return max(e for e, _ in results), max((r for _, r in results), key=lambda r: r.cycles)


def disc(shape, cx, cy, r):
    ys, xs = np.mgrid[0 : shape[0], 0 : shape[1]]
    return (xs - cx) ** 2 + (ys - cy) ** 2 <= r * r


def antialiased_stroke(shape, p, q, width):
    """Coverage (0..1) of a stroke of `width` px from p to q, with a 1 px antialiased edge."""
    ys, xs = np.mgrid[0 : shape[0], 0 : shape[1]].astype(float)
    p, q = np.asarray(p, float), np.asarray(q, float)
    d = q - p
    t = np.clip(((xs - p[0]) * d[0] + (ys - p[1]) * d[1]) / (d @ d), 0, 1)
    dist = np.hypot(xs - (p[0] + t * d[0]), ys - (p[1] + t * d[1]))
    return np.clip(width / 2 + 0.5 - dist, 0, 1)


def random_points(rng, mask, n):
    """n points on active nodes of mask (x, y), with a sub-pixel jitter."""
    ys, xs = np.nonzero(mask)
    pick = rng.choice(len(xs), n, replace=False)
    return np.column_stack([xs[pick], ys[pick]]) + rng.uniform(-0.3, 0.3, (n, 2))


# --- hinges -------------------------------------------------------------------------------


def hinge_mask():
    m = np.zeros((14, 30), np.uint8)
    m[1:13, 1:13] = m[1:13, 14:26] = m[6, 13] = 1
    return m


def test_two_squares_joined_at_one_node_take_the_tension_limit():
    # Three points move the left square; the right square hangs on the one-node bridge
    # and must follow the tau -> 0+ rule (least membrane energy among the plate minimisers).
    problem = Problem((14, 30), np.array([[2.0, 2.0], [10.0, 3.0], [5.0, 11.0]]),
                      np.array([[1.0, 2.0], [-2.0, 0.5], [3.0, -1.5]]), mask=hinge_mask())
    check_against_oracle(problem, "hinge")


@pytest.mark.parametrize("seed", range(3))
def test_chains_of_hinged_blocks(seed):
    # Four blocks of random sizes in a row, each joined to the next by one bridge node in a
    # one-column gap; points in the first two blocks only.
    rng = np.random.default_rng(100 + seed)
    m = np.zeros((40, 64), np.uint8)
    x, blocks = 1, []
    for _ in range(4):
        size = int(rng.integers(6, 13))
        y0 = int(rng.integers(21 - size, 20))  # every block holds rows 20 and 21
        m[y0 : y0 + size, x : x + size] = 1
        blocks.append((x, size))
        x += size + 1
    for bx, size in blocks[:-1]:
        m[int(rng.integers(20, 22)), bx + size] = 1  # the bridge
    first_two = np.zeros_like(m)
    first_two[:, : blocks[1][0] + blocks[1][1]] = 1
    pts = random_points(rng, m & first_two, 5)
    problem = Problem(m.shape, pts, rng.normal(0, 4, (5, 2)), mask=m)
    check_against_oracle(problem, f"hinged chain {seed}")


# --- strands and rings --------------------------------------------------------------------


@pytest.mark.parametrize("width", [1, 2])
def test_strands_off_a_body(width):
    # A body with straight, bent and diagonal (staircase) strands of one or two pixels.
    m = np.zeros((48, 48), np.uint8)
    m[14:34, 14:34] = 1
    m[20 : 20 + width, 34:46] = 1  # straight, to the right
    m[20:44, 44 : 44 + min(width, 2)] = 1  # ... bending down
    m[2:14, 22 : 22 + width] = 1  # straight up
    for k in range(12):  # a staircase down-left off the corner
        m[34 + k, 14 - k : 14 - k + width + 1] = 1
    rng = np.random.default_rng(width)
    pts = random_points(rng, np.pad(np.ones((20, 20)), 14)[:48, :48] > 0, 7)
    problem = Problem(m.shape, pts, rng.normal(0, 5, (7, 2)), mask=m)
    check_against_oracle(problem, f"strands {width} px")


def test_a_piece_solved_directly_stops_once_exact():
    # A 6 x 3 block with cut links and a one-node staircase strand (the coarse grid of a
    # grid_step 3 draft of a 33 x 22 matte): few enough nodes for the banded factor alone.
    # Its steps after the first move rounding only, which kept the stopping rule going to
    # the cycle limit (converged=False, the answer exact) for these very values.
    mask = np.zeros((12, 8), np.uint8)
    mask[0:3, 0:6] = 1
    for y, x in [(3, 0), (4, 0), (4, 1), (5, 1), (5, 2), (6, 2), (6, 3), (7, 3)]:
        mask[y, x] = 1

    def tick(x, y, across_x):
        return np.array([[x - 0.25, y], [x + 0.25, y]] if across_x else [[x, y - 0.25], [x, y + 0.25]])

    cuts = [tick(2.5, 1, False), tick(1.5, 2, False), tick(3, 0.5, True), tick(4, 0.5, True), tick(2, 1.5, True)]
    points = np.array([[1.0, 1.0], [5.0, 2.0], [2.0, 5.0], [5.0, 2.0]])
    displacements = np.array([[-6.813091310057158, 4.5056356802303075], [1.1865053933077088, 1.0170445859197168],
                              [-4.325546916091786, 6.19639124202771], [-3.1358769010493774, -0.19587830171520082]])
    for scale in (1.0, 1.001):
        problem = Problem(mask.shape, points, displacements * scale, mask=mask, cuts=cuts)
        _, report = check_against_oracle(problem, f"directly solved piece, displacements x{scale}")
        assert report.cycles <= 2, report


def small_piece_problem(seed):
    """A matte of at most 17 x 17 pixels with holes, up to five short cuts and up to five
    points (so most of its pieces are solved by one level), at tension 0, 1e-6 or 0.5."""
    rng = np.random.default_rng(seed)
    h, w = (int(v) for v in rng.integers(4, 18, 2))
    m = (rng.random((h, w)) < rng.uniform(0.45, 0.8)).astype(np.uint8)
    cuts = []
    for _ in range(rng.integers(0, 6)):
        a = rng.uniform(-1, [w, h])
        cuts.append(np.array([a, a + rng.normal(0, 3, 2)]))
    act = np.argwhere(m > 0)
    k = int(rng.integers(1, 6))
    pts = act[rng.integers(0, len(act), k)][:, ::-1].astype(float) + rng.uniform(-0.3, 0.3, (k, 2))
    disp = rng.normal(0, 5, (k, 2)) * 10 ** rng.uniform(-2, 0)
    return Problem((h, w), pts, disp, mask=m, cuts=cuts, tension=[0.0, 1e-6, 0.5][seed % 3])


# Seeds that ran to the cycle limit before the one-level rule (12 of the first 1500), and
# others around them.
@pytest.mark.parametrize("seed", [465, 513, 591, 843, 894, 1184, 1294, 1452, 0, 1, 2, 3])
def test_small_pieces_converge_to_the_direct_solve(seed):
    check_against_oracle(small_piece_problem(seed), f"small pieces, seed {seed}")


@pytest.mark.parametrize("tension", [0.0, 1e-6])
def test_closed_ring(tension):
    # A ring 1.5 px wide (radius 20-21.5 on 64 x 64), six points around it.
    ys, xs = np.mgrid[0:64, 0:64]
    r = np.hypot(xs - 32, ys - 32)
    m = ((r >= 20) & (r <= 21.5)).astype(np.uint8)
    angles = np.arange(6) * np.pi / 3 + 0.2
    pts = np.column_stack([32 + 20.7 * np.cos(angles), 32 + 20.7 * np.sin(angles)])
    pts = np.array([p for p in pts if m[int(round(p[1])), int(round(p[0]))]])
    rng = np.random.default_rng(6)
    problem = Problem((64, 64), pts, rng.normal(0, 4, (len(pts), 2)), mask=m, tension=tension)
    assert len(pts) >= 5
    check_against_oracle(problem, f"ring tau={tension}")


@pytest.mark.parametrize("tension", [1e-12, 1e-10, 1e-8])
def test_concentric_thin_rings_with_bridges_at_small_tensions(tension):
    # Five rings 1.2 px wide joined by short bridges, three points: their free functions
    # form one block of more than 64, whose settled change was not judged (a dense
    # elimination a cycle), so the raw change, drifting along them, never fell to the
    # tolerance: right answers, not converged at 100 cycles (nor at 2,000).
    ys, xs = np.mgrid[0:64, 0:64]
    r = np.hypot(xs - 32, ys - 32)
    m = np.zeros((64, 64), np.uint8)
    for radius in (6, 12, 18, 24, 30):
        m[(r >= radius) & (r < radius + 1.2)] = 1
    for radius in (7, 13, 19, 25):
        m[32, 32 + radius : 37 + radius] = 1
    rng = np.random.default_rng(1)
    problem = Problem(m.shape, random_points(rng, m, 3), rng.normal(0, 5, (3, 2)), mask=m, tension=tension)
    field, report = solve(problem)
    assert report.converged and report.cycles <= 20, report
    limit, _, _ = oracle(dataclasses.replace(problem, tension=0.0))
    assert float(np.abs(field - limit).max()) < TOLERANCE_PX


# --- character-like antialiased mattes ----------------------------------------------------


def character_alpha(seed, scale=1, hair=True):
    """An antialiased character: an elliptic body, a head on a thin neck, hair strands and a
    thin arm, the alpha channel of a drawing (matte = alpha > 0); 72 x 64 at `scale` 1. At a
    larger scale the body grows and the hair grows longer and more numerous, but its
    strands keep their width (`benchmarks/strands.py`)."""
    s = scale
    rng = np.random.default_rng(seed)
    shape = (72 * s, 64 * s)
    ys, xs = np.mgrid[0 : shape[0], 0 : shape[1]].astype(float)
    body = np.clip((1 - np.hypot((xs - 32 * s) / (14 * s), (ys - 48 * s) / (18 * s))) * 14 * s + 0.5, 0, 1)
    head = np.clip(11 * s + 0.5 - np.hypot(xs - 32 * s, ys - 16 * s), 0, 1)
    alpha = np.maximum(body, head)
    neck = antialiased_stroke(shape, (32 * s, 26 * s), (32 * s, 31 * s), (1.2 + 0.4 * rng.random()) * s)
    alpha = np.maximum(alpha, neck)
    for k in range(int(rng.integers(4, 8)) * s if hair else 0):  # hair
        a = np.pi * (1.1 + 0.8 * rng.random())
        p = (32 * s + 10.5 * s * np.cos(a), 16 * s + 10.5 * s * np.sin(a))
        q = (p[0] + rng.uniform(6, 14) * s * np.cos(a), p[1] + rng.uniform(6, 14) * s * np.sin(a))
        alpha = np.maximum(alpha, antialiased_stroke(shape, p, q, rng.uniform(0.3, 1.6)))
    arm = antialiased_stroke(shape, (20 * s, 44 * s), (4 * s, (30 + 8 * rng.random()) * s), 1.5 * s)
    alpha = np.maximum(alpha, arm)
    return (alpha * 255).round().astype(np.uint8)


def character_problem(seed, scale=1):
    """The matte of `character_alpha`, 4 points on the body and 2 on the head (the hair, the
    arm and the head follow through their thin attachments) and their displacements."""
    s = scale
    m = (character_alpha(seed, scale) > 0).astype(np.uint8)
    rng = np.random.default_rng(seed)
    body = np.zeros_like(m)
    body[36 * s : 64 * s, 22 * s : 42 * s] = 1
    head = np.zeros_like(m)
    head[10 * s : 22 * s, 27 * s : 37 * s] = 1
    pts = np.vstack([random_points(rng, m & body, 4), random_points(rng, m & head, 2)])
    return m, pts, rng.normal(0, 5, (6, 2))


@pytest.mark.parametrize("seed", range(2))
def test_a_solid_character_matte_takes_the_open_grids_cycles(seed):
    # A character without hair (body, a head on a neck 5-6 px wide, an arm): every part at
    # least 5 px wide, so its prolongation runs across the nodes off the matte and its
    # edge costs no cycles. With the link-aware rows there (which extrapolate a constant
    # where the staircase leaves no room) it took 19-22 cycles.
    m = (character_alpha(seed, 4, hair=False) > 0).astype(np.uint8)
    rng = np.random.default_rng(seed)
    pts, disp = random_points(rng, m, 6), rng.normal(0, 5, (6, 2))
    _, report = check_against_oracle(Problem(m.shape, pts, disp, mask=m), f"solid character {seed}")
    _, open_report = solve(Problem(m.shape, pts, disp))
    assert report.cycles <= open_report.cycles + 2, (report, open_report)


@pytest.mark.parametrize("tension", [0.0, 1e-6])
def test_a_face_matte_with_a_mouth_cut_takes_the_open_grids_cycles(tension):
    # A cut inside a solid matte, away from its edge (a mouth, two brows), leaves it solid:
    # 19 cycles with the link-aware rows along the matte's edge.
    n = 160
    ys, xs = np.mgrid[0:n, 0:n]
    m = ((((xs - 0.5 * n) / (0.35 * n)) ** 2 + ((ys - 0.5 * n) / (0.42 * n)) ** 2) <= 1).astype(np.uint8)
    cuts = [np.array(c) * n for c in ([[0.35, 0.68], [0.5, 0.72], [0.65, 0.68]], [[0.3, 0.35], [0.42, 0.33]], [[0.58, 0.33], [0.7, 0.35]])]
    pts = np.array([[0.4, 0.6], [0.5, 0.76], [0.6, 0.6], [0.45, 0.3], [0.55, 0.45]]) * n
    disp = np.random.default_rng(3).normal(0, 4, pts.shape)
    _, report = check_against_oracle(Problem(m.shape, pts, disp, mask=m, cuts=cuts, tension=tension), "face with a mouth")
    _, open_report = solve(Problem(m.shape, pts, disp, tension=tension))
    assert report.cycles <= open_report.cycles + 2, (report, open_report)


@pytest.mark.parametrize("seed", range(3))
def test_antialiased_character_mattes(seed):
    m, pts, disp = character_problem(seed)
    problem = Problem(m.shape, pts, disp, mask=m)
    check_against_oracle(problem, f"character {seed}")


def test_a_hairy_character_at_four_times_matches_the_direct_solve():
    # 288 x 256, its hair's free bends a plate kernel of 132 functions (the direct solve
    # resolves them with more Lanczos vectors than a small kernel needs).
    m, pts, disp = character_problem(0, 4)
    _, report = check_against_oracle(Problem(m.shape, pts, disp, mask=m), "character 0 at 4x", _off="")
    assert report.cycles <= 30, report


def zigzag_strand(teeth: int, amplitude: int):
    """A body 12 px square and a 1 px strand off its right side: diagonal staircases down
    and up `teeth` times, `amplitude` rows each, joined by short runs along the bottom and
    the top. A staircase turns at every node, so nearly every strand node is a free function
    of the plate, and they all meet: one block of the least-membrane system."""
    path, (x, y) = [], (13, 2)
    for t in range(2 * teeth):
        down = t % 2 == 0
        for _ in range(amplitude):
            path += [(x, y), (x + 1, y)]
            x, y = x + 1, y + (1 if down else -1)
        path += [(x, y), (x + 1, y), (x + 2, y)]
        x += 3
    m = np.zeros((amplitude + 6, x + 3), np.uint8)
    m[2:14, 1:13] = 1
    for px, py in path:
        m[py, px] = 1
    return m, path


@pytest.mark.parametrize("tension", [0.0, 1e-6])
def test_a_long_staircase_strand_is_settled_whole(tension):
    # About 1,900 free functions in one block: past 1,500 the dense least-membrane solve was
    # refused and the solve never claimed convergence (a character with hair at 2304 x 2048
    # had a block of 2,722). The block is now factored in its envelope, its functions in
    # reverse Cuthill-McKee order along the strand.
    m, path = zigzag_strand(12, 40)
    assert len(path) > 1950
    pts = np.array([[2.0, 3.0], [11.0, 4.0], [5.0, 12.0], [float(path[-1][0]), float(path[-1][1])]])
    disp = np.random.default_rng(5).normal(0, 4, pts.shape)
    check_against_oracle(Problem(m.shape, pts, disp, mask=m, tension=tension), f"zigzag strand at {tension}")


def test_settling_rounds_below_the_fields_precision_say_so():
    # At a tension the settling alternates with cycles in rounds; at a tolerance below the
    # float32 field's resolution they never finish, and the report said max_cycles (whose
    # advice, more cycles, cannot help).
    m = comb_mask(2, 2)
    pts = np.array([[5.0, 4.0], [m.shape[1] / 2, 5.0], [m.shape[1] - 6.0, 3.0]])
    disp = np.random.default_rng(2).normal(0, 4, pts.shape)
    for max_cycles in (100, 1000):
        _, report = inkwarp.thin_plate_report(pts, disp, m.shape, mask=m, tension=1e-6, tolerance=1e-9, max_cycles=max_cycles)
        assert (report.converged, report.stop) == (False, "precision"), report


@pytest.mark.parametrize("seed", [2, 4])
def test_hair_at_a_small_tension_converges_in_few_cycles(seed):
    # At τ = 1e-6 the hair's free bends are the operator's smallest eigenvectors
    # (eigenvalues of order τ). The conjugate gradient had to find them one by one: these
    # characters at 4x stopped unconverged at 100 cycles (the 576 x 512 one at 400). The
    # iteration now keeps to settled answers, where they are solved exactly.
    m, pts, disp = character_problem(seed, 4)
    _, report = check_against_oracle(Problem(m.shape, pts, disp, mask=m, tension=1e-6), f"character {seed} at 4x")
    assert report.cycles <= 30, report


@pytest.mark.parametrize("tension", [1e-9, 1e-8, 1e-7])
def test_hair_at_tinier_tensions_matches_the_direct_solve(tension):
    # Below 1e-6 the LU pivots of P + τM fall to 6e-12 of the largest: the oracle refines
    # its direct solve with residuals in extended precision (with float64 ones it never
    # settled, and a tight solve was the reference). The cycles stay those of τ = 0.
    m, pts, disp = character_problem(1, 4)
    _, report = check_against_oracle(Problem(m.shape, pts, disp, mask=m, tension=tension), f"character 1 at 4x, tension {tension}")
    assert report.cycles <= 30, report


# --- combs --------------------------------------------------------------------------------


@pytest.mark.parametrize("tension", [0.0, 1e-6])
def test_a_short_cut_beside_an_arm(tension):
    # A cut of one link at the character's arm: a coarse level's operator was off symmetry
    # (a hanging node's row coded on the 2 x 2 corners), a thin set factored on it had
    # negative pivots, the relaxation pushed the wrong way, and the solve claimed
    # convergence 52 px off the direct solve.
    mask = character_problem(0)[0]
    points = np.array([[36, 51], [33, 29], [40, 61], [45, 50], [39, 35]], float)
    displacements = np.array([[4.8, -13.6], [0.2, -8.1], [5.5, 0.8], [2.7, -5.3], [9.1, 10.1]])
    problem = Problem(mask.shape, points, displacements, mask=mask, cuts=[np.array([[20.5, 30.0], [20.5, 39.0]])],
                      tension=tension)
    check_against_oracle(problem, f"a cut beside the arm, tension {tension}")


def comb_mask(tooth, scale=1):
    """A back bar and teeth `tooth` px wide separated by 1 px gaps, 40 x 64 at `scale` 1; at a
    larger scale the teeth grow longer and more numerous but keep their width."""
    h, w, bar = 40 * scale, 64 * scale, 6 * scale
    m = np.zeros((h, w), np.uint8)
    m[2 : 2 + bar, 2 : w - 2] = 1
    for x in range(2, w - 2, tooth + 1):
        m[2 + bar : h - 2, x : x + tooth] = 1
    return m


@pytest.mark.parametrize("tooth", [1, 2])
def test_comb_with_one_pixel_gaps(tooth):
    # A back bar and teeth `tooth` px wide separated by 1 px gaps; points on the bar and on
    # a few tooth tips: each tooth bends on its own.
    m = comb_mask(tooth)
    rng = np.random.default_rng(tooth)
    pts = [[5.0, 4.0], [30.0, 5.0], [58.0, 3.0]]
    tips = [x for x in range(2, 62, tooth + 1)][::4]
    pts += [[float(x), 36.0] for x in tips[:4]]
    problem = Problem(m.shape, np.array(pts), rng.normal(0, 4, (len(pts), 2)), mask=m)
    check_against_oracle(problem, f"comb {tooth}")


@pytest.mark.parametrize("family", ["comb 1", "comb 2", "character"])
def test_longer_strands_stay_in_few_cycles(family):
    # The combs at 4x and the character at 2x (the oracle's kernel step is slow beyond):
    # teeth and hair keep their width and grow longer. Their bending is slow for the cycle
    # (841 and over 2000 cycles for the combs, 27 for the character, before the thin parts
    # were solved whole); it must not be left to it.
    if family == "character":
        m, pts, disp = character_problem(0, 2)
    else:
        tooth = int(family[-1])
        m = comb_mask(tooth, 4)
        h, w = m.shape
        tips = list(range(2, w - 2, tooth + 1))[::16]
        pts = np.array([[5.0, 4.0], [w / 2, 5.0], [w - 6.0, 3.0]] + [[float(x), h - 4.0] for x in tips])
        disp = np.random.default_rng(tooth).normal(0, 4, (len(pts), 2))
    _, report = check_against_oracle(Problem(m.shape, pts, disp, mask=m), f"{family}, longer")
    assert report.cycles <= 40, report


def straight_comb(length, spacing=9, teeth=14, body=40, width=1):
    """A body `body` px tall with `teeth` straight strands `width` px wide and `length` px
    long hanging from it, `spacing` px apart; points on the body and on every third tip."""
    w = spacing * (teeth - 1) + 11
    m = np.zeros((body + length, w), np.uint8)
    m[:body] = 1
    xs = [5 + spacing * k for k in range(teeth)]
    for x in xs:
        m[body:, x:x + width] = 1
    pts = [[3.0, 3.0], [w - 4.0, 3.0], [w / 2, body - 4.0]] + [[float(x), body + length - 1.0] for x in xs[::3]]
    return m, np.array(pts)


def test_an_animation_of_long_free_strands_converges_at_the_default_cap():
    # Long straight strands that no point holds are slow for the cycle: 2 px wide and
    # 750 px long, the first frame needs over 100 cycles. At the old default cap of 100 it stopped there, so
    # every next frame started cold (an unconverged answer is no start) and stopped there
    # too. At the default cap the first converges, and the next ones start warm: the second
    # from the first (most of its cycles again), the third from the two before (fewer: its
    # slow modes are found again, not carried over from the earlier solves). (If
    # the solver gets faster than 100 cycles here, the case no longer tests the cap: take
    # another family; 1 px strands 750 px long served until straight 1 px strands were
    # factored exactly.)
    m, pts = straight_comb(750, width=2)
    disp = np.random.default_rng(0).normal(0, 4, pts.shape)
    warm, fields, reports = inkwarp.WarmStart(), [], []
    for k in range(3):
        field, report = inkwarp.thin_plate_report(pts, disp * (1 + 0.05 * k), m.shape, mask=m, warm=warm)
        fields.append(field)
        reports.append(report)
    assert all(r.converged for r in reports) and reports[0].cycles > 100, reports
    assert reports[2].cycles < reports[1].cycles < reports[0].cycles, reports
    for k in range(3):
        exact, skipped, _ = oracle(Problem(m.shape, pts, disp * (1 + 0.05 * k), mask=m))
        assert not skipped.any()
        assert float(np.abs(fields[k] - exact)[m > 0].max()) < TOLERANCE_PX, k


@pytest.mark.parametrize("length", [600, 1000, 1200])
def test_long_straight_free_strands_take_a_bounded_number_of_cycles(length):
    # A straight 1 px strand that no point holds extends its root's slope: its own system
    # is factored exactly (shifted, or with its smallest pivots dropped, its slowest bending
    # was left to the cycle: 67 / 960 cycles at 600 / 1000 px). Every strand length up to
    # about 1,400 px takes about as many cycles (1,200: 36). Judged by the direct solve (a
    # solve to a tighter tolerance is no reference here: on such strands it can claim
    # convergence it has not reached, see docs/dev/solver-correctness.md).
    m, pts = straight_comb(length)
    disp = np.random.default_rng(0).normal(0, 4, pts.shape)
    _, report = check_against_oracle(Problem(m.shape, pts, disp, mask=m), f"straight strands {length} px", _off="")
    assert report.cycles <= 40, report


def solve_near_tight(m, pts, disp, tolerance=1e-5, max_cycles=400, solver=None):
    """The default solve of a matte too large for the direct solve, checked against a far
    tighter one: both converge, and every active node is within the contract of the tight
    answer. Returns the default solve's report."""
    field, report = inkwarp.thin_plate_report(pts, disp, m.shape, mask=m, solver=solver)
    tight, tight_report = inkwarp.thin_plate_report(pts, disp, m.shape, mask=m, tolerance=tolerance, max_cycles=max_cycles)
    assert report.converged and tight_report.converged, (report, tight_report)
    assert float(np.abs(field - tight)[m > 0].max()) < TOLERANCE_PX
    return report


def drawn_matte(width, height, draw):
    """The matte (alpha > 0) of what `draw(ImageDraw.Draw, k)` draws at k = 4 times the size,
    box-filtered down: strokes antialiased as a painting's are."""
    from PIL import Image, ImageDraw

    k = 4
    big = Image.new("L", (width * k, height * k))
    draw(ImageDraw.Draw(big), k)
    return (np.array(big.resize((width, height), Image.BOX)) > 0).astype(np.uint8)


def test_a_hairy_matte_at_photograph_size_converges_to_the_tight_answer():
    # The character at 12x (864 x 768, 48+ hairs up to 170 px long on a 1 px root): beyond
    # the direct solve's reach, so the default solve is checked against a solve a thousand
    # times tighter. Solved exactly, a hair's response swamped the search direction and the
    # solve stalled at its cycle limit (see `solve/strands.rs`, SHIFT).
    m, pts, disp = character_problem(2, 12)
    report = solve_near_tight(m, pts, disp)
    assert report.cycles <= 60, report


def hair_tangle(width, height, strands, seed=1):
    """A head with `strands` curved hair strands 1 or 2 px wide, drawn at 4x and box-filtered
    (matte = alpha > 0), that cross one another into one thin set over the head's top; 4
    points on the head turn it 8 degrees, 2 pull strands near their tips. At 480 x 360 with
    200 strands that set's band was too wide to factor at 64 entries a row (242 cycles; 21
    factored at 128)."""
    rng = np.random.default_rng(seed)
    cx, cy, rx, ry = width / 2, height * 0.75, width * 0.19, height * 0.33

    def head(draw, k):
        draw.ellipse([(cx - rx) * k, (cy - ry) * k, (cx + rx) * k, (cy + ry) * k], fill=255)
        for _ in range(strands):
            a, length, bend = rng.uniform(np.pi * 1.1, np.pi * 1.9), rng.uniform(0.1, 0.28) * width * k, rng.uniform(-0.6, 0.6)
            x0, y0 = (cx + rx * 0.93 * np.cos(a)) * k, (cy + ry * 0.95 * np.sin(a)) * k
            line = [(x0 + length * t * np.cos(a + bend * t), y0 + length * t * np.sin(a + bend * t)) for t in np.linspace(0, 1, 30)]
            draw.line(line, fill=255, width=int(rng.choice([1, 2]) * k))

    m = drawn_matte(width, height, head)
    pts = np.array([[cx - rx / 2, cy - ry / 2], [cx + rx / 2, cy - ry / 2], [cx + rx / 2, cy + ry / 2], [cx - rx / 2, cy + ry / 2]])
    turn = np.radians(8)
    rotation = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
    disp = (pts - pts.mean(0)) @ rotation.T + pts.mean(0) - pts
    # Two strands pulled by a point near their tips (a flick of the hair).
    ys, xs = np.nonzero(m)
    tips = [min(zip(xs, ys), key=lambda q: np.hypot(q[0] - x, q[1] - y)) for x, y in ((cx, cy - 1.6 * ry), (cx - 1.6 * rx, cy - 0.9 * ry))]
    pull = np.array([[0.05, -0.02], [-0.04, -0.05]]) * width
    return m, np.vstack([pts, np.array(tips, float)]), np.vstack([disp, pull])


def test_a_tangle_of_crossing_strands_matches_the_direct_solve():
    m, pts, disp = hair_tangle(160, 120, 60)
    check_against_oracle(Problem(m.shape, pts, disp, mask=m), "hair tangle 160 x 120")


def test_a_tangle_of_crossing_strands_at_photograph_size_converges_in_few_cycles():
    # Its thin set was too wide a band to factor (more than 64 entries a row): left to the
    # cycles, it took over 2,000 of them at 800 x 600 (the default cap of 300 stopped 0.83 px off).
    m, pts, disp = hair_tangle(480, 360, 200)
    report = solve_near_tight(m, pts, disp)
    assert report.cycles <= 40, report


def strand_scribble(width, height, strands, seed=1):
    """`strands` long curved strands 1 or 2 px wide scribbled across the picture, drawn at 4x
    and box-filtered (matte = alpha > 0), crossing into one mesh of strands too wide a band to
    factor whole; 6 points on them with random displacements. At 400 x 300 with 120 strands
    the cycle alone stopped at 600 cycles unconverged; halved at cycle 40, converged at 52."""
    rng = np.random.default_rng(seed)

    def scribble(draw, k):
        for _ in range(strands):
            x0, y0 = rng.uniform(0, width), rng.uniform(0, height)
            a, length, bend = rng.uniform(0, 2 * np.pi), rng.uniform(0.3, 0.8) * width, rng.uniform(-1.5, 1.5)
            line = [((x0 + length * t * np.cos(a + bend * t)) * k, (y0 + length * t * np.sin(a + bend * t)) * k) for t in np.linspace(0, 1, 40)]
            draw.line(line, fill=255, width=int(rng.choice([1, 2]) * k))

    m = drawn_matte(width, height, scribble)
    ys, xs = np.nonzero(m)
    pick = rng.choice(len(xs), 6, replace=False)
    pts = np.column_stack([xs[pick], ys[pick]]).astype(float)
    return m, pts, rng.normal(0, 4, pts.shape)


def test_a_mesh_of_crossing_strands_too_wide_to_factor_converges():
    # The strands cross into one thin set whose band is too wide to factor whole. Left to the
    # cycle it did not settle (600 cycles, unconverged); a solve still running at cycle 40
    # solves it in overlapping parts from there (their sweeps are checked against the set's own
    # system in the crate's tests), and lands within the contract of a tight solve.
    m, pts, disp = strand_scribble(400, 300, 120)
    solver = inkwarp.Solver()
    report = solve_near_tight(m, pts, disp, tolerance=1e-4, max_cycles=600, solver=solver)
    assert 40 < report.cycles <= 80, report
    # The next frame with the kept solver starts from the parts.
    _, second = inkwarp.thin_plate_report(pts, disp * 1.02, m.shape, mask=m, solver=solver)
    assert second.converged and second.cycles < 40, second


# --- many cuts ----------------------------------------------------------------------------


def random_cuts(seed, integer, scale=1):
    """20-50 random straight and bent cuts on 64 x 64 (float end points, or integer ones
    through node centres and along links), 40 points and their displacements; at `scale`
    the same picture on a grid `scale` times larger (`benchmarks/ablation.py`)."""
    rng = np.random.default_rng(seed + 10 * integer)
    cuts = []
    for _ in range(int(rng.integers(20, 51))):
        k = int(rng.integers(2, 4))
        c = np.column_stack([rng.uniform(-4, 68, k), rng.uniform(-4, 68, k)])
        cuts.append((np.round(c) if integer else c) * scale)
    pts = np.column_stack([rng.uniform(0, 63, 40), rng.uniform(0, 63, 40)]) * scale
    return pts, rng.normal(0, 5, (40, 2)), cuts


@pytest.mark.parametrize("seed, integer", [(seed, integer) for integer in (False, True) for seed in range(4)])
def test_many_random_cuts(seed, integer):
    # 20-50 random straight and bent cuts on 64 x 64, float or integer end points (integer
    # ones run through node centres and along links).
    pts, disp, cuts = random_cuts(seed, integer)
    problem = Problem((64, 64), pts, disp, cuts=cuts)
    check_against_oracle(problem, f"{len(cuts)} cuts")


def test_a_slow_mode_under_the_oracles_kernel_bound_is_not_taken_for_a_free_function():
    # Float cuts of seed 390 at 4x, displacements scaled to a tenth: a piece of 5,764 nodes
    # has a plate eigenvalue of 4.3e-12, under the oracle's KERNEL_BELOW, yet proved
    # positive by its residual (7.5e-15). Taken for a free function, the oracle settled it
    # by the membrane and stood hundreds of px from the solver, whose answer had the lower
    # plate energy; told apart, the two agree.
    pts, disp, cuts = random_cuts(390, False, 4)
    problem = Problem((256, 256), pts, disp * 0.1, cuts=cuts)
    kernel_values = []
    real = test_solver_oracle.plate_kernel

    def watched(a):
        z = real(a)
        kernel_values.extend(np.einsum("ij,ij->j", z, a @ z))
        return z

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(test_solver_oracle, "plate_kernel", watched)
        check_against_oracle(problem, "a slow mode among float cuts", _off="")
    assert kernel_values and max(kernel_values) < 1e-13, max(kernel_values, default=None)


def test_three_close_points_on_a_piece_of_many_cuts_small_displacements():
    # Integer cuts of seed 61 at 4x, displacements scaled to a fiftieth: a piece holds
    # three points a few pixels apart whose affine map reaches 2.8 px far away. Iterated,
    # its slow mode hid from the stopping rule: converged=True at 2.2 px off. At tension 0
    # the map is the answer (DESIGN section 4: an affine map has no plate energy).
    pts, disp, cuts = random_cuts(61, True, 4)
    check_against_oracle(Problem((256, 256), pts, disp * 0.02, cuts=cuts), "three close points among integer cuts")


@pytest.mark.parametrize("off", ["", "whole"])
@pytest.mark.parametrize("scale, seed", [(4, 3), (2, 38), (2, 49)])
def test_a_slow_solve_looks_for_hidden_modes_before_it_stops(scale, seed, off):
    # Float cuts at a fiftieth of the displacements: a piece's slow mode (a part bounded by
    # cuts, nearly rigid) barely shows in the residual, and the changes fell below the
    # tolerance while its error stayed (converged=True 0.118, 0.061 and 0.092 px off). A
    # solve past the deflation's start now stops only after its second look at the slow
    # modes (seed 49's wedge is not in the first window's directions).
    pts, disp, cuts = random_cuts(seed, False, scale)
    problem = Problem((64 * scale, 64 * scale), pts, disp * 0.02, cuts=cuts)
    check_against_oracle(problem, f"float cuts of seed {seed} at {scale}x", _off=off)


def test_a_probes_cycles_are_reported_beside_the_cycles():
    # Seed 38 at 2x probes one piece (24 cycles on A x = 0); the report counts them in
    # `probe_cycles`, apart from `cycles` and from `max_cycles`, and none without the probe.
    pts, disp, cuts = random_cuts(38, False, 2)
    solve = functools.partial(inkwarp.thin_plate_report, pts, disp * 0.02, (128, 128), cuts=cuts)
    (_, probed), (_, plain) = solve(), solve(_off="probe")
    assert probed.converged and probed.probe_cycles == 24 and plain.probe_cycles == 0, (probed, plain)
    _, capped = solve(max_cycles=probed.cycles)
    assert capped.converged and (capped.cycles, capped.probe_cycles) == (probed.cycles, 24), capped


@pytest.mark.parametrize("seed, integer", [(14, True), (26, False)])
@pytest.mark.parametrize("off", ["", "whole"])
def test_a_weakly_held_piece_with_a_hidden_mode_is_not_claimed_early(seed, integer, off):
    # Cuts at 4x and a fiftieth of the displacements: seed 14's piece (1,241 nodes) held by
    # two points (its tilt about their line is a free function) holds a wedge between two
    # cuts that turns about its base. Iterated, the piece stopped at cycle 5, changes
    # 0.003 px, the wedge 0.222 px off (seed 26: 0.196 px), converged=True. Such a piece is
    # solved whole by its banded factor; iterated (`_off="whole"`, as a larger piece is) a
    # piece with free functions now probes its operator before its first claim.
    pts, disp, cuts = random_cuts(seed, integer, 4)
    check_against_oracle(Problem((256, 256), pts, disp * 0.02, cuts=cuts), f"cuts of seed {seed} at 4x", _off=off)


def torn_case(case):
    """`(points, displacements, cuts, off)` of a stored sweep case, or `weak-SEED`: the
    random float cuts of SEED at 4x with a fiftieth of the displacements, iterated."""
    if case.startswith("weak-"):
        pts, disp, cuts = random_cuts(int(case[5:]), False, 4)
        return pts, disp * 0.02, cuts, "whole"
    data = np.load(DATA / f"{case}.npz")
    return data["points"], data["displacements"], np.split(data["cut_points"], np.cumsum(data["cut_lengths"])[:-1]), ""


@functools.cache
def torn_exact(case):
    """The direct solve of a stored sweep case (see `torn_case`), once per run. Its plate
    blocks' slow modes (eigenvalues down to 2e-10) are told from free functions by their
    residuals; a tight iterative solve is no reference where parts are this weakly attached."""
    pts, disp, cuts, _ = torn_case(case)
    exact, skipped, _ = oracle(Problem((256, 256), pts, disp, cuts=cuts))
    assert not skipped.any()
    return exact


@pytest.mark.parametrize("case", ["flap_on_a_border_strip", "many_cuts_256_seed61", "many_cuts_256_seed62"])
def test_weakly_attached_parts_among_many_cuts_are_not_claimed_early(case):
    # Found by a user's sweep: 50 random cuts on 256², six points on the right and below;
    # the upper left is a flap joined to the rest through a strip along the left border,
    # nearly free to turn. With displacements of a few hundredths of a pixel (an answer of
    # 0.9 px at most; a warm start from the answer before a 2 % change is the same problem)
    # the default solve stopped at cycle 41, changes 0.001 px, the flap 0.64 px off,
    # converged=True (its scaled residual 7e-7: the mode's residual is too small to show).
    # The same cuts with 5 or 50 times the displacements run 73 to 81 cycles and hold.
    # The same sweep's seeds 61 and 62 (46 and 50 cuts, answers up to 273 and 84 px) stopped
    # at cycles 79 and 53, 0.16 and 0.074 px off. A solve still running at cycle 20 now
    # probes its operator from a random start, and what the cycles leave of it (the flap's
    # bending) is deflated from then on.
    # Judged by the direct solve (`torn_exact`).
    pts, disp, cuts, _ = torn_case(case)
    problem = Problem((256, 256), pts, disp, cuts=cuts)
    exact = torn_exact(case)
    field, report = solve(problem)
    assert report.converged and float(np.abs(field - exact).max()) < TOLERANCE_PX, report
    if case == "flap_on_a_border_strip":
        # Its warm twin (0.63 px off at cycle 32 before): the next frame through a kept
        # Solver, every displacement 2 % larger, started from this answer.
        kept = inkwarp.Solver()
        solve(problem, solver=kept)
        field, report = inkwarp.thin_plate_report(pts, disp * 1.02, (256, 256), cuts=cuts, solver=kept, initial=field)
        assert report.converged and float(np.abs(field - exact * 1.02).max()) < TOLERANCE_PX, report


def small_moves(case):
    """`(problem, warm)` of a torn problem whose answer is a pixel or less, found by a sweep of
    new seeds; `warm`: solve it, then the same with every displacement 2 % larger from that
    answer through a kept Solver (an animation's next frame)."""
    if case == "holes_and_cuts":  # a 256² grid with holes, 10 cuts, 17 points
        return stored_torn("holes_and_cuts_small_moves"), False
    if case.startswith("hinge"):  # two squares joined by one node, tension 1e-6
        m = np.zeros((128, 128), np.uint8)
        m[35:91, 1:57] = m[21:79, 58:116] = m[36, 57] = 1
        pts = np.array([[43.72, 88.21], [1.80, 50.21], [10.13, 89.75], [110.15, 31.77], [57.81, 27.16]])
        disp = np.array([[0.1446, -0.0608], [-0.1436, 0.0536], [0.0173, 0.0276], [-0.0876, 0.0451], [0.0246, -0.1001]])
        return Problem((128, 128), pts, disp, mask=m, tension=1e-6), case.endswith("warm")
    seed, integer, scale = {"cuts132": (132, True, 0.004), "cuts384 warm": (384, False, 0.01)}[case]
    pts, disp, cuts = random_cuts(seed, integer, 2)
    return Problem((128, 128), pts, disp * scale, cuts=cuts), case.endswith("warm")


@pytest.mark.parametrize("case", ["cuts132", "hinge", "hinge warm", "cuts384 warm", "holes_and_cuts"])
def test_small_displacements_on_torn_pieces_are_not_claimed_early(case):
    # Answers of 0.3-3 px: the first changes are small in pixels, and the rule met the
    # tolerance in 4-7 cycles (a warm start in 1-5), before a weakly held part's slow mode
    # showed, 0.062-0.19 px off, converged=True. The same problems with larger displacements
    # ran on and held; a torn piece's claim now also waits for changes under a thousandth of
    # its largest constrained displacement (at least a tenth of the tolerance).
    problem, warm = small_moves(case)
    frames = [dataclasses.replace(problem, displacements=problem.displacements * k) for k in (1.0, 1.02)[:1 + warm]]
    kept, field = inkwarp.Solver(), None
    for frame in frames:
        exact, skipped, _ = oracle(frame)
        assert not skipped.any()
        field, report = solve(frame, solver=kept, initial=field)
        assert report.converged and float(np.abs(field - exact).max()) < TOLERANCE_PX, report


@pytest.mark.parametrize("case", ["flap_on_a_border_strip", "many_cuts_256_seed62", "weak-26", "weak-14"])
@pytest.mark.parametrize("steps", [1, 7])
def test_a_capped_solve_goes_on_where_it_stopped(case, steps):
    # Solved a few cycles a call through a kept Solver, each call from the last one's answer
    # (a progress bar's loop, as the editor once solved its frames ahead): every call
    # restarted the directions and the search for slow modes, and the series ended on a
    # small change 0.5-0.7 px off, converged=True. Now a capped solve goes on where it
    # stopped: the series takes the one solve's cycles and ends on its answer. (The weak
    # pieces are held on one line: their answer is written tilted, from which they go on.)
    pts, disp, cuts, off = torn_case(case)
    shape = (256, 256)
    whole, whole_report = inkwarp.thin_plate_report(pts, disp, shape, cuts=cuts, solver=inkwarp.Solver(), _off=off)
    assert whole_report.converged, whole_report
    kept, field, cycles = inkwarp.Solver(), None, []
    for _ in range(whole_report.cycles):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", inkwarp.InkwarpWarning)
            field, report = inkwarp.thin_plate_report(pts, disp, shape, cuts=cuts, solver=kept, initial=field, max_cycles=steps, _off=off)
        cycles.append(report.cycles)
        if report.converged:
            break
        assert report.stop == "max_cycles" and report.cycles == steps, report
    assert report.converged and sum(cycles) == whole_report.cycles, (cycles, whole_report)
    # (Pieces that converged in an earlier call are solved again from their answer by each
    # later one, so the two answers agree to the tolerance, not to the bit.)
    assert float(np.abs(field - whole).max()) <= 0.01
    chunked = field
    # Stopped again, then asked for other displacements from there: a solve of its own,
    # whose claim holds (the exact answer is linear in the displacements). Capped at 4 at
    # most: this solve takes 7 to 45 cycles.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", inkwarp.InkwarpWarning)
        field, report = inkwarp.thin_plate_report(pts, disp, shape, cuts=cuts, solver=kept, max_cycles=min(steps, 4), _off=off)
    assert not report.converged
    exact = torn_exact(case)
    assert max(float(np.abs(whole - exact).max()), float(np.abs(chunked - exact).max())) < TOLERANCE_PX
    field, report = inkwarp.thin_plate_report(pts, disp * 1.02, shape, cuts=cuts, solver=kept, initial=field, _off=off)
    assert not report.converged or float(np.abs(field - 1.02 * exact).max()) < TOLERANCE_PX, report


def test_a_kept_solver_from_its_last_answer_keeps_to_growing_values():
    # Frames through a kept Solver, each from the last answer (`initial=`), every value 2 %
    # larger than the frame before: the later frames' claims were probed and corrected on the
    # probe's modes against a residual already small, and the border-strip flap's third frame
    # ended 0.067 px off, reported converged. A later claim is now checked on the first
    # frame's slow modes and goes on where they would move it.
    case, scale = "flap_on_a_border_strip", 2.5
    pts, disp, cuts, _ = torn_case(case)
    exact = torn_exact(case) * scale
    solver, field = inkwarp.Solver(), None
    for k in range(5):
        values = disp * scale * 1.02**k
        field, report = inkwarp.thin_plate_report(pts, values, (256, 256), cuts=cuts, solver=solver, initial=field)
        off = float(np.abs(field - exact * 1.02**k).max())
        assert report.converged and off < TOLERANCE_PX, (k, off, report)


def stored_torn(name):
    """A torn problem stored by a sweep (`tests/data/NAME.npz`): grid, matte, cuts, points."""
    d = np.load(DATA / f"{name}.npz")
    shape = tuple(int(v) for v in d["shape"])
    mask = np.unpackbits(d["mask"])[:shape[0] * shape[1]].reshape(shape).astype(np.uint8)
    cuts = np.split(d["cut_points"], np.cumsum(d["cut_lengths"])[:-1])
    return Problem(shape, d["points"], d["displacements"], mask=mask, cuts=cuts, tension=float(d["tension"]))


def lever():
    """Two squares joined by one node, the second held by two points on one row beside the
    joint: the answer turns it about the joint, about 170 times the constrained values."""
    m = np.zeros((160, 160), np.uint8)
    m[21:75, 1:55] = m[7:50, 56:99] = m[48, 55] = 1
    pts = np.array([[31.20231806, 47.96386312], [49.91686747, 54.85182224], [19.27183126, 38.84364572],
                    [87.15293479, 46.80485624], [57.14215763, 47.19829978]])
    disp = np.array([[-4.8296542, -4.85789141], [0.61718508, -0.0670845], [1.32533867, 2.43866889],
                     [-4.75177698, 0.8874714], [2.33468904, -6.17611938]])
    return Problem((160, 160), pts, disp * 0.004, mask=m, tension=0.0)


@pytest.mark.parametrize("case", ["lever", "holes_and_ten_cuts_warm", "cuts384 offset"])
def test_a_kept_solvers_next_frame_is_checked_on_the_slow_modes_it_found(case):
    # The next frame through a kept Solver from the last answer, every displacement 2 %
    # larger: its error is the start's, 2 % of an answer whose larger part is a slow mode,
    # which the first changes do not show. The lever (no free function, so no check)
    # claimed after 3 cycles, 0.070 px off; holes with 10 cuts (224², 26 points, answer
    # 60 px) after its own probe, at cycle 43 on a plateau of the changes, 0.143 px off;
    # small moves among float cuts carried 20 px from rest after 2 cycles, 0.061 px off
    # (its third frame 0.124). Every claim is now checked on the slow modes the first
    # frame found, and the solve goes on where they would move it.
    if case == "lever":
        problem, offset = lever(), 0.0
    elif case == "cuts384 offset":
        problem, offset = small_moves("cuts384 warm")[0], 20.0
    else:
        problem, offset = stored_torn(case), 0.0
    # The answer is linear in the values: the frames' exact answers from one direct solve of
    # the values and one of the offset (a piece no point holds stays still under both).
    exact, skipped, _ = oracle(problem)
    assert not skipped.any()
    moved = oracle(dataclasses.replace(problem, displacements=np.ones_like(problem.displacements)))[0] if offset else 0.0
    kept, field = inkwarp.Solver(), None
    for k in (1.0, 1.02, 1.04):
        frame = dataclasses.replace(problem, displacements=offset + problem.displacements * k)
        field, report = solve(frame, solver=kept, initial=field)
        off = float(np.abs(field - (k * exact + offset * moved)).max())
        assert report.converged and off < TOLERANCE_PX, (k, off, report)


def test_a_warm_start_on_a_new_hierarchy_is_judged_by_its_correction():
    # The same holes with 10 cuts, the next frame from the last answer with no kept Solver
    # (`inkwarp.thin_plate(..., initial=)`): no slow modes to check the claim on, and it
    # claimed at cycle 43, on a plateau of the changes, 0.143 px off (0.141 at 0.98).
    # Such a start solves its correction, whose constrained values are 2 % of the
    # problem's: its claim is now relative to them, as a cold solve of it would be.
    problem = stored_torn("holes_and_ten_cuts_warm")
    exact, skipped, _ = oracle(problem)
    assert not skipped.any()
    start, _ = solve(problem)
    for k in (1.02, 0.98):
        field, report = solve(dataclasses.replace(problem, displacements=problem.displacements * k), initial=start)
        assert report.converged and float(np.abs(field - exact * k).max()) < TOLERANCE_PX, (k, report)

def test_no_claim_builds_on_an_answer_that_did_not_converge():
    # The border-strip flap stopped by a cap of 30 cycles is 0.69 px off, honestly
    # unconverged. The next frame through a WarmStart (every displacement 2 % larger)
    # started from that answer and claimed convergence after one cycle, 0.70 px off; the
    # same call again through a kept Solver adopted the slow modes the first call had found
    # and claimed it at cycle 20, 0.64 px off. (At 512² a user's sweep found both at the
    # default cap of 100.) Now such a frame starts afresh, and no Solver carries slow modes
    # from one solve to the next.
    pts, disp, cuts, _ = torn_case("flap_on_a_border_strip")
    shape = (256, 256)
    exact = torn_exact("flap_on_a_border_strip")
    warm, kept = inkwarp.WarmStart(), inkwarp.Solver()
    for k, scale in enumerate([1.0, 1.02, 1.04]):
        field, report = inkwarp.thin_plate_report(pts, disp * scale, shape, cuts=cuts, warm=warm, max_cycles=30)
        assert not report.converged or np.abs(field - exact * scale).max() < TOLERANCE_PX, (k, report)
        if k == 0:
            assert not report.converged and report.cycles == 30, report
    for k in range(3):
        field, report = inkwarp.thin_plate_report(pts, disp, shape, cuts=cuts, solver=kept, max_cycles=30)
        assert not report.converged or np.abs(field - exact).max() < TOLERANCE_PX, (k, report)
    # Nor is a probe counted as done by a solve that stopped unconverged after it (cycle 20):
    # counted, it was never run again, and the next two frames at the default cap claimed
    # convergence at cycles 40 and 10, 0.66 and 0.65 px off.
    kept = inkwarp.Solver()
    inkwarp.thin_plate_report(pts, disp, shape, cuts=cuts, solver=kept, max_cycles=30)
    for k in range(2):
        field, report = inkwarp.thin_plate_report(pts, disp * 1.02, shape, cuts=cuts, solver=kept)
        assert report.converged and np.abs(field - exact * 1.02).max() < TOLERANCE_PX, (k, report)


def test_no_cycle_leaves_a_start_and_a_kept_solvers_slow_modes_alone():
    # max_cycles=0 returns the start: a kept solver's slow modes (found by an earlier slow
    # solve of the same operator, kept then) corrected it all the same. What the solver
    # keeps stays for the next solve as it was.
    pts, disp, cuts = random_cuts(0, False, 4)
    shape, a, b = (256, 256), inkwarp.Solver(), inkwarp.Solver()
    field, first = inkwarp.thin_plate_report(pts, disp, shape, cuts=cuts, solver=a)
    inkwarp.thin_plate(pts, disp, shape, cuts=cuts, solver=b)
    assert first.cycles > 10, first  # past the cycle where deflation starts keeping modes
    start = field * 1.1
    fresh, _ = inkwarp.thin_plate_report(pts, disp * 1.1, shape, cuts=cuts, initial=start, max_cycles=0)
    kept, report = inkwarp.thin_plate_report(pts, disp * 1.1, shape, cuts=cuts, initial=start, max_cycles=0, solver=a)
    assert report.cycles == 0 and np.array_equal(kept, fresh)
    after_a = inkwarp.thin_plate_report(pts, disp * 1.2, shape, cuts=cuts, initial=field, solver=a)
    after_b = inkwarp.thin_plate_report(pts, disp * 1.2, shape, cuts=cuts, initial=field, solver=b)
    assert after_a[1].cycles == after_b[1].cycles and np.array_equal(after_a[0], after_b[0])


def test_a_cold_torn_solve_does_not_stop_after_its_first_cycle():
    # Random cuts at a fiftieth of the displacements: one piece's first step moved it by
    # 0.0018 px, which with no ratio yet the rule took for converged, while a slow mode left
    # it 0.049 px off (the contract's edge; the later cycles move it by up to 0.018 px).
    pts, disp, cuts = random_cuts(46, False, 4)
    err, report = check_against_oracle(Problem((256, 256), pts, disp * 0.02, cuts=cuts), "seed 46 at 4x")
    assert err < 0.01, (err, report)


def test_a_slow_mode_does_not_fool_the_stopping_rule():
    # The float cuts of seed 1 leave a wedge bending against a distant arm (a near-null
    # mode); with the cycle cap far away the report must still be true: converged means
    # every node within the contract.
    pts, disp, cuts = random_cuts(1, False)
    problem = Problem((64, 64), pts, disp, cuts=cuts)
    check_against_oracle(problem, "seed 1 cuts, 2000 cycles allowed", max_cycles=2000)


HOOK = np.array([[16.97, 199.69], [21.31, 157.92], [24.40, 148.72], [-0.0433, 141.84]])


@pytest.mark.parametrize("points, tension", [(2, 0.0), (5, 1e-3)])
def test_a_flap_cut_from_the_border_turns_with_its_root(points, tension):
    # A hook-shaped cut from the left border walls off a flap 20 px wide, held along its
    # foot. At the hook's bend node (24, 149) keeps one link, left to a node of the coarse
    # cell before its own: no coarse function moved it, the flap turned by a few hundredths
    # of its motion a cycle (21 cycles at full size), and with displacements of a quarter
    # pixel the solve claimed convergence after 3-4 cycles 0.12-0.14 px off.
    pts = np.array([[112.7, 105.7], [36.8, 86.8], [80, 30], [100, 240], [60, 200]])[:points]
    disp = np.array([[-0.121, -0.247], [-0.126, 0.021], [0.1, -0.1], [0.05, 0.2], [-0.1, 0.0]])[:points]
    problem = Problem((255, 129), pts, disp, cuts=[HOOK], tension=tension)
    err, report = check_against_oracle(problem, f"hook, {points} points, tension {tension}")
    assert err < 0.01, (err, report)
    _, full = solve(dataclasses.replace(problem, displacements=disp * 100))
    assert full.converged and full.cycles <= 12, full


def test_a_v_cut_and_two_points_at_a_small_tension():
    # The V's tip cuts off a two-node island, so the piece's box has inactive nodes and the
    # second (plain) coarse space runs. At tension 1e-5 its correction came out about ten
    # times too large, the cycle stopped being positive, and with displacements of a
    # quarter pixel the solve claimed convergence after 3 cycles, 0.78 px off.
    cut = np.array([[33.01, 263.98], [41.78, 283.80], [125.40, 314.05], [58.43, 260.82]])
    problem = Problem((384, 256), np.array([[254.12, 345.78], [98.08, 293.40]]),
                      np.array([[0.244, 0.081], [-0.263, 0.082]]), cuts=[cut], tension=1e-5)
    err, report = check_against_oracle(problem, "V cut, two points, tension 1e-5")
    assert err < 0.01, (err, report)


LEAK_CUT = np.array([[-5.0, 40.7], [70.0, 33.2]])
LEAK_POINTS = np.array([[5.0, 5.0], [60.0, 5.0], [30.0, 20.0], [10.0, 25.0]])


def test_a_cut_through_node_centres_does_not_leak():
    # Its line passes through node centres up to float rounding. The lower piece has no
    # constraint: it must not move at all.
    rng = np.random.default_rng(7)
    problem = Problem((64, 64), LEAK_POINTS, rng.normal(0, 6, (4, 2)), cuts=[LEAK_CUT])
    field, _ = solve(problem)
    label = piece_labels(problem).reshape(64, 64)
    assert len(np.unique(label)) == 2, "the oracle's own links must split the grid in two"
    lower = label == label[63, 0]
    assert label[0, 0] != label[63, 0]
    assert np.all(field[lower] == 0), f"the free piece moved {np.abs(field[lower]).max():.3f} px"
    check_against_oracle(problem, "leak repro")


@pytest.mark.parametrize("seed", range(3))
def test_cuts_through_node_centres_and_along_links(seed):
    # Cuts between node centres: along rows and columns, diagonals, and general integer
    # lines (through many centres), some ending on nodes inside the grid.
    rng = np.random.default_rng(50 + seed)
    cuts = [np.array([[-2.0, 20.0], [40.0, 20.0]]),  # along row 20, ending on a node
            np.array([[44.0, 70.0], [44.0, 30.0]]),  # along column 44, ending on a node
            np.array([[0.0, 0.0], [25.0, 25.0], [25.0, 50.0]]),  # diagonal, then down
            np.array([[-5.0, 40.7], [70.0, 33.2]])]  # the leak line
    for _ in range(6):
        a, b = rng.integers(-3, 67, 2), rng.integers(-3, 67, 2)
        cuts.append(np.array([a, b], float))
    pts = np.column_stack([rng.uniform(0, 63, 30), rng.uniform(0, 63, 30)])
    problem = Problem((64, 64), pts, rng.normal(0, 5, (30, 2)), cuts=cuts)
    check_against_oracle(problem, "cuts through nodes")


@pytest.mark.parametrize("seed", range(40))
def test_border_to_border_cuts_at_a_tenth_of_a_pixel(seed):
    # Random straight cuts from border to border with end points at 0.1 px: about 7 % of
    # them leaked through rounding. Both sides must solve on their own: the field equals
    # the oracle's, whose links are decided exactly.
    rng = np.random.default_rng(1000 + seed)
    t = rng.uniform(0, 4, 2)

    def on_border(s):
        side, f = int(s), s % 1
        return [(f * 66 - 1, -1), (65, f * 66 - 1), (65 - f * 66, 65), (-1, 65 - f * 66)][side]

    cut = np.round(np.array([on_border(t[0]), on_border(t[1])], float), 1)
    pts = np.column_stack([rng.uniform(0, 63, 8), rng.uniform(0, 63, 8)])
    problem = Problem((64, 64), pts, rng.normal(0, 5, (8, 2)), cuts=[cut])
    check_against_oracle(problem, f"border cut {cut.tolist()}")


# --- warm starts from garbage -------------------------------------------------------------


@pytest.mark.parametrize("garbage", ["huge", "nan", "inf", "noise"])
def test_warm_start_from_garbage_is_recovered_or_refused(garbage):
    rng = np.random.default_rng(3)
    mask = np.ones((48, 48), np.uint8)
    mask[disc((48, 48), 30, 20, 6)] = 0
    problem = Problem((48, 48), np.column_stack([rng.uniform(0, 47, 10), rng.uniform(0, 47, 10)]),
                      rng.normal(0, 5, (10, 2)), mask=mask, cuts=[np.array([[-1.0, 30.3], [30.0, 28.1]])])
    initial = {
        "huge": np.full((48, 48, 2), 1e20, np.float32),
        "nan": np.full((48, 48, 2), np.nan, np.float32),
        "inf": np.full((48, 48, 2), np.inf, np.float32),
        "noise": rng.normal(0, 1e6, (48, 48, 2)).astype(np.float32),
    }[garbage]
    try:
        check_against_oracle(problem, f"warm start from {garbage}", initial=initial)
    except ValueError as e:  # refused: the message must say what is wrong with `initial`
        assert "initial" in str(e), e


# --- the report ---------------------------------------------------------------------------


def test_max_cycles_stopping_early_reports_not_converged():
    rng = np.random.default_rng(9)
    mask = np.ones((64, 64), np.uint8)
    mask[disc((64, 64), 40, 25, 5)] = 0
    problem = Problem((64, 64), np.column_stack([rng.uniform(0, 63, 10), rng.uniform(0, 63, 10)]),
                      rng.normal(0, 6, (10, 2)), mask=mask, cuts=[np.array([[6.0, 44.3], [28.0, 39.3], [50.0, 47.3]])])
    exact, _, _ = oracle(problem)
    field, report = solve(problem, max_cycles=1, tolerance=1e-6)
    err = float(np.abs(field - exact).max())
    assert not report.converged, f"one cycle at tolerance 1e-6 claims convergence ({err:.3g} px off): {report}"
    assert report.cycles <= 1


def test_converged_report_on_an_accurate_solve_with_a_cycle_budget():
    # The other half of honesty: with enough cycles allowed, the same solve converges and
    # is right.
    rng = np.random.default_rng(9)
    problem = Problem((40, 40), np.column_stack([rng.uniform(0, 39, 6), rng.uniform(0, 39, 6)]),
                      rng.normal(0, 6, (6, 2)))
    check_against_oracle(problem, "budgeted", max_cycles=200)


# --- grid independence --------------------------------------------------------------------


def grid_problem(n: int, hole: bool, cut: bool):
    """The issue's model problems at n x n: 10 seeded points, a disc hole of radius 150 s at
    (1300 s, 800 s), a two-segment cut through (200, 1400.3), (900, 1250.3), (1600, 1500.3)
    times s, s = n / 2049."""
    s = n / 2049
    rng = np.random.default_rng(2049)
    pts = rng.uniform(0.05, 0.95, (10, 2)) * (n - 1)
    disp = rng.normal(0, 0.01 * n, (10, 2))
    mask = None
    if hole:
        mask = np.ones((n, n), np.uint8)
        mask[disc((n, n), 1300 * s, 800 * s, 150 * s)] = 0
    cuts = [np.array([[200, 1400.3], [900, 1250.3], [1600, 1500.3]]) * s] if cut else None
    return pts, disp, mask, cuts


def test_cycles_do_not_grow_with_the_grid():
    table = {}
    for name, hole, cut in [("open", False, False), ("hole", True, False), ("cut", False, True), ("hole+cut", True, True)]:
        for n in (257, 513, 1025):
            pts, disp, mask, cuts = grid_problem(n, hole, cut)
            # Capped at twice the bound, which any passing solve stays under, so that a
            # failing solver does not make the suite slow (a capped solve reports the cap).
            _, report = inkwarp.thin_plate_report(pts, disp, (n, n), mask=mask, cuts=cuts, max_cycles=24)
            table[name, n] = (report.cycles, report.converged)
    text = "; ".join(f"{k[0]} {k[1]}: {v[0]}{'' if v[1] else ' (not converged)'}" for k, v in table.items())
    for name in ("open", "hole", "cut", "hole+cut"):
        cycles = [table[name, n][0] for n in (257, 513, 1025)]
        assert all(table[name, n][1] for n in (257, 513, 1025)), text
        assert max(cycles) <= 12, text
        assert max(cycles) - min(cycles) <= 2, text


@pytest.mark.parametrize("name, seed, n", [("hole", 2045, 513), ("cut", 2049, 513), ("hole+cut", 2050, 257), ("cut", 2045, 257)])
def test_a_model_solve_still_running_at_cycle_ten_stops_by_twelve(name, seed, n):
    # Rows of benchmarks/grid_independence.py that were within 0.0016 px at cycle 10 but
    # then waited for two looks at slow modes: 19 cycles. The wait is now for pieces whose
    # spectrum shows a slow mode (these show none), and a settled spectrum judges the rate
    # over two cycles, not one rising change. (Some now stop before cycle 10.)
    pts, disp, mask, cuts = model_problem(n, n, "hole" in name, "cut" in name, seed)
    _, report = check_against_oracle(Problem((n, n), pts, disp, mask=mask, cuts=cuts or []), name, _off="", max_cycles=24)
    assert report.cycles <= 12, report


@pytest.mark.parametrize("name", ["cut", "hole+cut"])
def test_where_the_changes_swing_the_energy_rate_judges(name):
    # benchmarks/grid_independence.py's rows of seed 2048, 8, 8, 11 and 8, 9, 11 cycles: at
    # 1025² the changes' ratios swung (0.19, 0.79, 0.56 at cycles 8-10: a two-cycle rate of
    # 0.67 at cycle 10) where the steps' energy decrements gave 0.35-0.43 a step; the answer
    # was 0.0005 px off when the rule went on to cycle 11. Where the spectrum has settled and
    # the last change fell, the rate counts no more than the energy norm's.
    cycles = []
    for n in (257, 513, 1025):
        pts, disp, mask, cuts = model_problem(n, n, "hole" in name, True, 2048)
        field, report = inkwarp.thin_plate_report(pts, disp, (n, n), mask=mask, cuts=cuts, max_cycles=24)
        assert report.converged, report
        cycles.append(report.cycles)
    assert max(cycles) <= 12 and max(cycles) - min(cycles) <= 2, cycles
    tight, _ = inkwarp.thin_plate_report(pts, disp, (n, n), mask=mask, cuts=cuts, tolerance=1e-5, max_cycles=300)
    assert float(np.abs(field - tight).max()) < TOLERANCE_PX


def test_cycles_stay_flat_at_2049():
    # The same problems at 2049 x 2049 (4.2 million nodes): within the bound of the smaller
    # grids. Here the coarse levels' products of smooth vectors as large as the answer (the
    # coarse-to-fine start's, the K-cycles') summed in f32 lost the residual they carried,
    # and the start came out hundreds of pixels off: 15, 19, 25 and 19 cycles.
    table = {}
    for name, hole, cut in [("open", False, False), ("hole", True, False), ("cut", False, True), ("hole+cut", True, True)]:
        pts, disp, mask, cuts = grid_problem(2049, hole, cut)
        _, report = inkwarp.thin_plate_report(pts, disp, (2049, 2049), mask=mask, cuts=cuts, max_cycles=24)
        table[name] = (report.cycles, report.converged)
    assert all(c <= 12 and ok for c, ok in table.values()), table


@pytest.mark.parametrize("n, vertex", [(257, (113.11, 155.88)), (513, (225.11, 313.88)), (1025, (451.11, 625.88))])
def test_a_cut_vertex_just_above_a_node_does_not_pin_it(n, vertex):
    # The vertex sits just above a node (odd column, even row) whose row neighbours the two
    # arms both cut off: hanging by its link down, it had an empty prolongation row, so
    # every coarse function held it at zero, and the part below the vertex converged
    # against that pin in 19, 21 and 22 cycles. With its neighbour's row: 9-10. (Flipped
    # upside down, the node's neighbour lies in the coarse cell before: still 19-22, see
    # docs/dev/solver-correctness.md.)
    s = n / 1537
    pts, disp, _, _ = grid_problem(n, False, True)
    cuts = [np.array([[150.02 * s, 1050.4 * s], vertex, [1200.2 * s, 1125.4 * s]])]
    if n == 257:
        _, report = check_against_oracle(Problem((n, n), pts, disp, cuts=cuts), "a cut vertex above a node", _off="", max_cycles=24)
    else:
        _, report = inkwarp.thin_plate_report(pts, disp, (n, n), cuts=cuts, max_cycles=24)
    assert report.converged and report.cycles <= 12, report


def test_a_tight_solve_is_judged_by_its_settled_answer():
    # Random cuts leave slivers with free functions (moves of zero plate energy), settled
    # after the cycles by the least-membrane rule. Where the coarse space holds one, the
    # iteration drifts along it: at 1e-8 px this solve's changes grew from 1e-5 to 2e-3 px
    # while its settled answer stood still, and it stopped unconverged after 2000 cycles.
    # The stopping rule judges the change of the settled answer. (1e-6 px here: finer than
    # about 1e-7 of the largest displacement is beyond the float32 field and never claimed.)
    pts, disp, cuts = random_cuts(38, False, 2)
    problem = Problem((128, 128), pts, disp * 0.02, cuts=cuts)
    exact, skipped, _ = oracle(problem)
    assert not skipped.any()
    field, report = solve(problem, tolerance=1e-6, max_cycles=300)
    assert report.converged, report
    assert float(np.abs(field - exact).max()) < 1e-5


def test_each_piece_of_a_cut_grid_matches_alone():
    # The leak line and two more through node centres cut 64 x 64 into pieces; each piece,
    # solved alone (the rest masked out), equals its part of the whole solve.
    rng = np.random.default_rng(11)
    cuts = [LEAK_CUT, np.array([[20.0, -1.0], [20.0, 70.0]]), np.array([[-1.0, -1.0], [64.0, 64.0]])]
    pts = np.column_stack([rng.uniform(0, 63, 24), rng.uniform(0, 63, 24)])
    problem = Problem((64, 64), pts, rng.normal(0, 5, (24, 2)), cuts=cuts)
    check_against_oracle(problem, "cut into pieces")
    field, _ = solve(problem)
    label = piece_labels(problem).reshape(64, 64)
    for lab in np.unique(label):
        piece = label == lab
        alone, rep = solve(dataclasses.replace(problem, mask=piece.astype(np.uint8)))
        assert np.abs(alone[piece] - field[piece]).max() < 2 * TOLERANCE_PX, f"piece {lab}: {rep}"


@pytest.mark.parametrize("torn", [False, True])
def test_southwell_default_budget_cuts_the_start_error_tenfold_and_claims_nothing(torn):
    # The paper's fixed budget on the bench's model problem at 257 x 257, judged by the
    # direct solve: at its default 10 rounds the error of the coarse-to-fine start (a
    # budget of 0) falls at least tenfold, and `converged` is claimed only where it holds.
    # (At 65 x 65 with the hole and the cut the default budget cuts it 6.8-fold:
    # docs/concepts/thin-plate.md.)
    pts, disp, mask, cuts = grid_problem(257, hole=torn, cut=torn)
    shape = (257, 257)
    exact, skipped, _ = oracle(Problem(shape, pts, disp, mask=mask, cuts=cuts or []))
    assert not skipped.any()

    def error(**kwargs):
        field, report = inkwarp.thin_plate_report(pts, disp, shape, mask=mask, cuts=cuts,
                                                  method="southwell", **kwargs)
        return float(np.abs(field - exact).max()), report

    start, report0 = error(southwell_sweeps=0)
    assert not report0.converged and start > 1.0
    spent, report = error()
    assert spent <= start / 10, f"default budget: {start:.3f} -> {spent:.3f} px"
    assert not report.converged or spent < TOLERANCE_PX
    short, report1 = error(southwell_sweeps=1)
    assert not report1.converged or short < TOLERANCE_PX


@pytest.mark.parametrize("seed, integer", [(2, True), (3, False), (3, True)])
def test_a_tight_tolerance_never_runs_away(seed, integer):
    # Dense cuts carve slivers whose free functions the thin-part solves must drop, not
    # amplify: asked for 1e-4 px, such a solve once took steps of 1e7 px along them and
    # ended 1e13-1e18 px off. Whether or not it can prove the tolerance, its field stays
    # finite and close to the direct solve, and a converged report is within 5x of it.
    pts, disp, cuts = random_cuts(seed, integer)
    problem = Problem((64, 64), pts, disp, cuts=cuts)
    exact, skipped, _ = oracle(problem)
    assert not skipped.any()
    for tolerance in (1e-4, 1e-7):
        field, report = solve(problem, tolerance=tolerance, max_cycles=300)
        err = float(np.abs(field - exact).max())
        assert np.isfinite(field).all() and err < 1e-3, f"tolerance {tolerance}: {err:.3g} px off ({report})"
        if report.converged:
            assert err <= 5 * max(tolerance, 1e-5), f"tolerance {tolerance}: converged {err:.3g} px off ({report})"


def kept_families():
    """Problems for a kept solver: (name, problem, whether its slowest piece can start from its
    earlier answers: not where a piece has free functions, as the character's hair and some of
    the many cuts' pieces do, or is held on one line)."""
    pts, disp, mask, cuts = model_problem(65, 65, True, True, 2049)
    yield "hole and cut", Problem((65, 65), pts, disp, mask=mask, cuts=cuts), True
    m = comb_mask(2)
    pts = np.array([[5.0, 4.0], [30.0, 5.0], [58.0, 3.0], [2.0, 36.0], [14.0, 36.0], [26.0, 36.0]])
    yield "comb 2", Problem(m.shape, pts, disp[:6], mask=m), True
    pts, disp, cuts = random_cuts(0, False)
    yield "many cuts", Problem((64, 64), pts, disp, cuts=cuts), False
    m, pts, disp = character_problem(0)
    yield "character", Problem(m.shape, pts, disp, mask=m), False


def test_a_kept_solvers_later_frame_among_many_cuts_is_checked_before_its_claim():
    # A kept solver's second frame on 20-50 random cuts (tension 0, small displacements)
    # claimed convergence after 10 cycles 2.8 px from the direct solve: the probe that a
    # weakly held piece's claim waits for ran in the hierarchy's first solve only. Now a later
    # claim is checked on the slow modes the first solve found: here they would move it by
    # pixels, so it goes on, and probes at cycle 20 (`probe_cycles`).
    pts, _, cuts = random_cuts(49, False, 2)
    rng = np.random.default_rng(0)
    a, b = rng.normal(0, 4, (40, 2)), rng.normal(0, 4, (40, 2))
    solver = inkwarp.Solver()
    for t in (0, 1 / 12):
        problem = Problem((128, 128), pts, 0.05 * (a * np.cos(2 * np.pi * t) + b * np.sin(2 * np.pi * t)), cuts=cuts, tension=0.0)
        _, report = check_against_oracle(problem, f"frame at {t:.3f} s", _off="", solver=solver)
        assert report.probe_cycles > 0, report


def test_a_warm_start_among_many_cuts_is_corrected_on_its_slow_modes_with_its_true_residual():
    # Frames of independent values on 20-50 random cuts at 256 x 256, each from the last
    # answer: the fourth claimed convergence 0.075 px off. The correction on the slow modes a
    # probe found updated the residual by their products kept in `f32`, whose rounding is far
    # above those modes' eigenvalues: the updated residual parted from the true one and the
    # iteration converged to a wrong answer. The residual is computed anew after a correction.
    pts, _, cuts = random_cuts(49, False, 4)
    rng = np.random.default_rng(0)
    rng.normal(0, 4, (80, 2))
    start = None
    for k in range(4):
        problem = Problem((256, 256), pts, 0.02 * rng.normal(0, 5, (40, 2)), cuts=cuts)
        given = {} if start is None else {"initial": start}
        check_against_oracle(problem, f"frame {k}", _off="", **given)
        start, _ = solve(problem, **given)


@pytest.mark.parametrize("family", ["hole and cut", "comb 2", "many cuts", "character"])
def test_a_kept_solver_starts_from_earlier_answers_within_the_contract(family):
    # One solver, new values at the same points every solve: once the earlier values span
    # the new ones (at most 10 points a piece: 5 solves), a piece starts from the combination
    # of their answers and takes a cycle or two; every claim is checked against the direct
    # solve (the iterated path: `_off="whole"`).
    name, problem, spans = next(f for f in kept_families() if f[0] == family)
    solver, rng = inkwarp.Solver(), np.random.default_rng(7)
    cycles = []
    for _ in range(9):
        problem = dataclasses.replace(problem, displacements=rng.normal(0, 5, problem.displacements.shape))
        _, report = check_against_oracle(problem, name, _off="whole", solver=solver)
        cycles.append(report.cycles)
    if spans:
        assert max(cycles[-3:]) <= 2 < min(cycles[:2]), cycles
