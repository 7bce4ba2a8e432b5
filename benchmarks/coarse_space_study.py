"""Coarse spaces for the thin plate, compared with pyamg (issue 42 item 1).

A development study, not part of `make bench` or `make test`: it needs `pyamg`
(requirements-bench.txt) and minutes of CPU. It measures which multigrid coarse space makes
the iteration count independent of the grid, its holes and its cuts, so that the engine's
own smoothed aggregation is built on a measured choice (docs/dev/coarse-space.md).

The matrix is the DESIGN §4 energy assembled by the test oracle (tests/test_solver_oracle.py)
restricted to the free nodes: active nodes of pieces with a constraint, the constrained
nodes eliminated. For each variant (aggregation, near-null space B, smoother, prolongation
smoothing) it reports, with conjugate gradients preconditioned by one V-cycle from a zero
start, both components x and y:

- `its`: iterations until every node is within 0.05 px of the exact answer (DESIGN §4's
  contract), the larger of the two components;
- `rho`: the mean residual reduction per iteration over those iterations;
- `OC`: operator complexity (sum of the levels' nonzeros over the finest's), and `its·OC`,
  a proxy for the work (fine-grid matrix applications);
- `levels`.

Where a piece's plate matrix has an exact kernel beyond what the constraints pin (hinges,
strands, lines of constraints) the iterate is compared after the same least-membrane step
the oracle and the engine take (the oracle's `least_membrane_step`), so only the part the
multigrid must find is measured.

    python benchmarks/coarse_space_study.py                       # model problem 257², 513²
    python benchmarks/coarse_space_study.py --sizes 257 513 1025
    python benchmarks/coarse_space_study.py --families            # the hard families
    python benchmarks/coarse_space_study.py --variants geo-1xy std-1 --sizes 257
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.csgraph as csgraph
import scipy.sparse.linalg as spla

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

try:
    import pyamg
except ImportError:  # pragma: no cover - a study, not a test
    sys.exit("coarse_space_study needs pyamg: pip install -r requirements-bench.txt")

import test_solver_families as fam  # noqa: E402
import test_solver_oracle as orc  # noqa: E402

CONTRACT_PX = orc.TOLERANCE_PX
MAX_ITS = 150


# --- the free-node system ------------------------------------------------------------------


class System:
    """The free-node block of the plate energy, its right-hand sides and exact answer."""

    def __init__(self, problem: orc.Problem, exact: str = "direct"):
        h, w = problem.shape
        self.problem = problem
        active, right, down = orc.links(problem)
        label = orc.piece_labels(problem)
        fixed, _ = orc.constraints(problem)
        pinned_pieces = {label[i] for i in fixed}
        in_pinned = active.ravel() & np.isin(label, list(pinned_pieces))
        is_fixed = np.zeros(h * w, bool)
        is_fixed[list(fixed)] = True
        self.free = np.flatnonzero(in_pinned & ~is_fixed)
        fixed_idx = np.array(sorted(fixed), int)
        uc = np.array([fixed[i] for i in fixed_idx])
        a = orc.energy_matrix(problem)
        self.A = a[self.free][:, self.free].tocsr()
        self.A.sum_duplicates()
        self.b = -(a[self.free][:, fixed_idx] @ uc)
        self.xy = np.stack([self.free % w, self.free // w], 1).astype(float)
        # The link graph among the free nodes (for geometric aggregates).
        n = h * w
        idx = np.arange(n).reshape(h, w)
        g = sp.coo_matrix((np.ones(right.sum() + down.sum()),
                           (np.concatenate([idx[right], idx[down]]),
                            np.concatenate([idx[right] + 1, idx[down] + w]))), shape=(n, n)).tocsr()
        g = g + g.T
        self.graph = g[self.free][:, self.free].tocsr()
        # Exact kernel handling: the least-membrane step of the oracle, if the block is
        # singular (piece by piece).
        self.step = None
        if exact == "oracle":
            ref, step = orc.free_block_solution(problem, self.free)
            self.exact, self.step = ref, step
        elif exact == "direct":
            self.exact = np.column_stack([spla.spsolve(self.A.tocsc(), self.b[:, k]) for k in range(2)])
        else:  # "iterative": a tight CG solve, checked by a second preconditioner
            self.exact = None

    def error(self, x, k):
        if self.step is not None:
            x = self.step(x, k)
        return float(np.abs(x - self.exact[:, k]).max())

    def near_null(self, kind: str):
        ones = np.ones((len(self.free), 1))
        if kind == "1":
            return ones
        h, w = self.problem.shape
        x = (self.xy[:, 0] - (w - 1) / 2) / ((w - 1) / 2)
        y = (self.xy[:, 1] - (h - 1) / 2) / ((h - 1) / 2)
        return np.column_stack([ones[:, 0], x, y])


def geometric_aggregates(system: System, block: int = 3, max_coarse: int = 64):
    """Per level, the AggOp of link-connected components of block x block node squares
    (the next level: components of block x block squares of aggregates, joined where a
    fine link joins them)."""
    xy = system.xy.astype(int)
    graph = system.graph
    cell = xy // block  # block coordinates of each node
    aggops = []
    while True:
        n = graph.shape[0]
        key = cell[:, 1] * (1 << 20) + cell[:, 0]
        g = graph.tocoo()
        same = key[g.row] == key[g.col]
        inner = sp.coo_matrix((np.ones(same.sum()), (g.row[same], g.col[same])), shape=(n, n))
        m, lab = csgraph.connected_components(inner, directed=False)
        agg = sp.csr_matrix((np.ones(n), (np.arange(n), lab)), shape=(n, m))
        aggops.append(agg)
        if m <= max_coarse or m == n:
            break
        coarse = (agg.T @ graph @ agg).tocsr()
        coarse.setdiag(0)
        coarse.eliminate_zeros()
        graph = coarse
        # An aggregate's square: the square of its first node, one level up.
        first = np.zeros(m, int)
        first[lab[::-1]] = np.arange(n)[::-1]
        cell = cell[first] // block
    return aggops


JACOBI_P = ("jacobi", {"omega": 4.0 / 3.0, "degree": 1})
JACOBI_P2 = ("jacobi", {"omega": 4.0 / 3.0, "degree": 2})
VARIANTS = {
    # name: (aggregation, B, smoother, prolongation smoothing)
    "std-1": ("standard", "1", "gs", JACOBI_P),
    "std-1xy": ("standard", "1xy", "gs", JACOBI_P),
    "geo-1": ("geometric", "1", "gs", JACOBI_P),
    "geo-1xy": ("geometric", "1xy", "gs", JACOBI_P),
    "geo-1xy-unsmoothed": ("geometric", "1xy", "gs", None),
    "geo-1xy-jacobi": ("geometric", "1xy", "jacobi", JACOBI_P),
    "geo-1xy-cheb": ("geometric", "1xy", "chebyshev", JACOBI_P),
    "geo-1xy-gs2": ("geometric", "1xy", "gs2", JACOBI_P),
    "geo-1xy-P2": ("geometric", "1xy", "gs", JACOBI_P2),
    "geo-1xy-P3": ("geometric", "1xy", "gs", ("jacobi", {"omega": 4.0 / 3.0, "degree": 3})),
    "geo-1xy-energy": ("geometric", "1xy", "gs", ("energy", {"krylov": "cg", "maxiter": 4, "degree": 1})),
    "geo-1xy-energy8": ("geometric", "1xy", "gs", ("energy", {"krylov": "cg", "maxiter": 8, "degree": 2})),
    "geo-1-P2": ("geometric", "1", "gs", JACOBI_P2),
    "geo-1xy-P2-jacobi": ("geometric", "1xy", "jacobi", JACOBI_P2),
    "geo-1xy-P2-cheb": ("geometric", "1xy", "chebyshev", JACOBI_P2),
    "geo-1xy-P2-gs2": ("geometric", "1xy", "gs2", JACOBI_P2),
    "std-1xy-P2": ("standard", "1xy", "gs", JACOBI_P2),
    "geo4-1xy-P2": ("geometric4", "1xy", "gs", JACOBI_P2),
    # geometric aggregates, candidates an aggregate cannot carry dropped, scalar CSR levels
    "geoC-1xy": ("compressed", "1xy", "gs", JACOBI_P),
    "geoC-1xy-P2": ("compressed", "1xy", "gs", JACOBI_P2),
    "geoC-1xy-P3": ("compressed", "1xy", "gs", ("jacobi", {"omega": 4.0 / 3.0, "degree": 3})),
    "geoC4-1xy-P2": ("compressed4", "1xy", "gs", JACOBI_P2),
    "geoC-1xy-P2-gs2": ("compressed", "1xy", "gs2", JACOBI_P2),
    # ... with each row's Jacobi weight from its Gershgorin bound (sum of |a_ij|) instead of a
    # randomly started estimate of rho(D^-1 A)
    "geoC-1xy-P2L": ("compressed", "1xy", "gs", ("jacobi", {"omega": 4.0 / 3.0, "degree": 2,
                                                           "weighting": "local"})),
    "geo4-1xy-P3": ("geometric4", "1xy", "gs", ("jacobi", {"omega": 4.0 / 3.0, "degree": 3})),
    "std-1xy-energy": ("standard", "1xy", "gs", ("energy", {"krylov": "cg", "maxiter": 4, "degree": 1})),
}
MAIN = ["std-1xy", "geo-1xy", "geo-1xy-unsmoothed", "geo-1xy-P2", "geo-1xy-P3", "geo-1-P2", "geo-1xy-P2-jacobi", "geo-1xy-P2-cheb", "std-1xy-P2"]

SMOOTHERS = {
    "gs": ("gauss_seidel", {"sweep": "symmetric"}),
    "gs2": ("gauss_seidel", {"sweep": "symmetric", "iterations": 2}),
    "jacobi": ("jacobi", {"omega": 4.0 / 3.0, "iterations": 2}),
    "chebyshev": ("chebyshev", {"degree": 3}),
}


def hierarchy(system: System, variant: str):
    aggregation, b_kind, smoother, smooth = VARIANTS[variant]
    if aggregation.startswith("compressed"):
        return compressed_hierarchy(system, smooth[1]["degree"] if smooth else 0, smoother,
                                    block=int(aggregation[10:] or 3),
                                    weighting=smooth[1].get("weighting", "diagonal") if smooth else "diagonal")
    kwargs = dict(B=system.near_null(b_kind), presmoother=SMOOTHERS[smoother],
                  postsmoother=SMOOTHERS[smoother], smooth=smooth, keep=False)
    if aggregation.startswith("geometric"):
        aggops = geometric_aggregates(system, block=int(aggregation[9:] or 3))
        kwargs.update(aggregate=[("predefined", {"AggOp": a}) for a in aggops],
                      max_levels=len(aggops) + 1, max_coarse=1)
    else:
        kwargs.update(max_coarse=64 if b_kind == "1xy" else 200)
    return pyamg.smoothed_aggregation_solver(system.A, **kwargs)


def compressed_hierarchy(system: System, smooth_degree: int, smoother: str, block: int = 3,
                         weighting: str = "diagonal"):
    """Smoothed aggregation built level by level (pyamg's pieces, not its driver): the same
    geometric aggregates and B = {1, x, y}, but the candidates an aggregate cannot carry
    (fewer than three nodes, or nodes on one line: zero columns of the tentative P) are
    dropped, so no coarse level has empty rows, and every level is scalar CSR, smoothed
    point by point. This is the form an implementation on the engine's grids would take."""
    from pyamg.aggregation import fit_candidates, jacobi_prolongation_smoother
    from pyamg.multilevel import MultilevelSolver
    from pyamg.relaxation.smoothing import change_smoothers

    aggops = geometric_aggregates(system, block=block)
    a = system.A.tocsr()
    b = system.near_null("1xy")
    owner = np.arange(a.shape[0])  # the level-l aggregate each dof belongs to (its "node")
    levels = []
    for agg in aggops:
        lab = agg.tocsr().indices  # one entry per row
        dof_agg = lab[owner]
        dof_op = sp.csr_matrix((np.ones(len(dof_agg)), (np.arange(len(dof_agg)), dof_agg)),
                               shape=(len(dof_agg), agg.shape[1]))
        t, bc = fit_candidates(dof_op, b)
        t = t.tocsc()
        keep = np.flatnonzero(np.abs(t).max(axis=0).toarray().ravel() > 0)
        t = t[:, keep].tocsr()
        bc = bc[keep]
        p = t
        if smooth_degree:
            p = jacobi_prolongation_smoother(a, t, a, b, omega=4.0 / 3.0, degree=smooth_degree,
                                             weighting=weighting).tocsr()
        coarse = (p.T @ a @ p).tocsr()
        # Coarse functions in the plate's kernel (aggregates of loose nodes, strands) have a
        # diagonal at rounding level: dividing by it blows the cycle up (a V-cycle with
        # eigenvalues of 1e31 on torn grids). Drop them: the kernel is settled exactly
        # outside the cycles.
        d = coarse.diagonal()
        live = np.flatnonzero(d > 1e-10 * d.max())
        if len(live) < len(d):
            p = p[:, live].tocsr()
            coarse = (p.T @ a @ p).tocsr()
            keep, bc = keep[live], bc[live]
        level = MultilevelSolver.Level()
        level.A, level.P, level.R, level.B = a, p, p.T.tocsr(), b
        levels.append(level)
        a = coarse
        b = bc
        owner = keep // 3  # coarse dof -> the aggregate it came from
    level = MultilevelSolver.Level()
    level.A, level.B = a, b
    levels.append(level)
    # The coarsest matrix keeps combinations of coarse functions in the plate's kernel, with
    # eigenvalues at rounding level; scipy's default pinv cut-off (n eps) inverts some of
    # them (a V-cycle with eigenvalues of 1e15). Cut at 1e-10 of the largest instead.
    ml = MultilevelSolver(levels, coarse_solver=("pinv", {"rtol": 1e-10}))
    change_smoothers(ml, SMOOTHERS[smoother], SMOOTHERS[smoother])
    return ml


def measure(system: System, variant: str):
    """(iterations to the contract, residual factor per iteration, OC, levels) for x and y."""
    ml = hierarchy(system, variant)
    m = ml.aspreconditioner(cycle="V")
    its, factors = [], []
    for k in range(2):
        b = system.b[:, k]
        state = {"it": 0, "done": None, "res": []}

        def callback(xk):
            state["it"] += 1
            state["res"].append(float(np.linalg.norm(b - system.A @ xk)))
            if state["done"] is None and system.error(xk, k) < CONTRACT_PX:
                state["done"] = state["it"]
                raise StopIteration

        try:
            spla.cg(system.A, b, M=m, rtol=1e-14, atol=0.0, maxiter=MAX_ITS, callback=callback)
        except StopIteration:
            pass
        done = state["done"]
        its.append(done if done is not None else MAX_ITS + 1)
        r0 = float(np.linalg.norm(b))
        last = state["res"][-1] if state["res"] else r0
        factors.append((last / r0) ** (1 / max(1, state["it"])) if r0 else 0.0)
    return max(its), max(factors), ml.operator_complexity(), len(ml.levels)


def reference_by_cg(system: System):
    """The exact answer of a large system: CG to a tiny residual with two preconditioners;
    their difference bounds its error."""
    sols = []
    for variant in ("geo-1xy-P2", "geo-1xy-P3"):
        m = hierarchy(system, variant).aspreconditioner(cycle="V")
        sols.append(np.column_stack([
            spla.cg(system.A, system.b[:, k], M=m, rtol=1e-13, atol=0.0, maxiter=2000)[0]
            for k in range(2)]))
    gap = float(np.abs(sols[0] - sols[1]).max())
    system.exact = sols[0]
    return gap


# --- problems ------------------------------------------------------------------------------


def model_problem(n: int, hole: bool, cut: bool) -> orc.Problem:
    pts, disp, mask, cuts = fam.grid_problem(n, hole, cut)
    return orc.Problem((n, n), pts, disp, mask, cuts or [])


def families():
    """The hard families of tests/test_solver_families.py, as (name, Problem)."""
    out = []
    # comb, 1 px gaps, teeth 1 and 2 px
    for tooth in (1, 2):
        m = np.zeros((40, 64), np.uint8)
        m[2:8, 2:62] = 1
        for x in range(2, 62, tooth + 1):
            m[8:38, x: x + tooth] = 1
        rng = np.random.default_rng(tooth)
        pts = [[5.0, 4.0], [30.0, 5.0], [58.0, 3.0]]
        tips = list(range(2, 62, tooth + 1))[::4]
        pts += [[float(x), 36.0] for x in tips[:4]]
        out.append((f"comb, {tooth} px teeth", orc.Problem(m.shape, np.array(pts), rng.normal(0, 4, (len(pts), 2)), mask=m)))
    # 20-50 random cuts
    for seed, integer in [(1, False), (0, False), (2, False), (0, True), (1, True)]:
        rng = np.random.default_rng(seed + 10 * integer)
        cuts = []
        for _ in range(int(rng.integers(20, 51))):
            k = int(rng.integers(2, 4))
            c = np.column_stack([rng.uniform(-4, 68, k), rng.uniform(-4, 68, k)])
            cuts.append(np.round(c) if integer else c)
        pts = np.column_stack([rng.uniform(0, 63, 40), rng.uniform(0, 63, 40)])
        out.append((f"{len(cuts)} random cuts, seed {seed}{', integer' if integer else ''}",
                    orc.Problem((64, 64), pts, rng.normal(0, 5, (40, 2)), cuts=cuts)))
    # thin ring
    ys, xs = np.mgrid[0:64, 0:64]
    r = np.hypot(xs - 32, ys - 32)
    m = ((r >= 20) & (r <= 21.5)).astype(np.uint8)
    angles = np.arange(6) * np.pi / 3 + 0.2
    pts = np.column_stack([32 + 20.7 * np.cos(angles), 32 + 20.7 * np.sin(angles)])
    pts = np.array([p for p in pts if m[int(round(p[1])), int(round(p[0]))]])
    rng = np.random.default_rng(6)
    out.append(("ring 1.5 px wide", orc.Problem((64, 64), pts, rng.normal(0, 4, (len(pts), 2)), mask=m)))
    # hinged squares and a chain of hinged blocks
    out.append(("two squares joined at one node", orc.Problem(
        (14, 30), np.array([[2.0, 2.0], [10.0, 3.0], [5.0, 11.0]]),
        np.array([[1.0, 2.0], [-2.0, 0.5], [3.0, -1.5]]), mask=fam.hinge_mask())))
    # antialiased character mattes
    for seed in range(2):
        alpha = fam.character_alpha(seed)
        m = (alpha > 0).astype(np.uint8)
        rng = np.random.default_rng(seed)
        body = np.zeros_like(m)
        body[36:64, 22:42] = 1
        head = np.zeros_like(m)
        head[10:22, 27:37] = 1
        pts = np.vstack([fam.random_points(rng, m & body, 4), fam.random_points(rng, m & head, 2)])
        out.append((f"character matte {seed}", orc.Problem(m.shape, pts, rng.normal(0, 5, (6, 2)), mask=m)))
    return out


# --- tables --------------------------------------------------------------------------------


def run_model(sizes, variants, print_fn=print, problems=("open", "hole", "cut", "hole+cut")):
    print_fn("## Model problem: CG + one V-cycle, iterations to 0.05 px (residual factor per iteration)\n")
    print_fn("| problem | n | " + " | ".join(variants) + " |")
    print_fn("|---|---|" + "---|" * len(variants))
    oc = {}
    for hole, cut, name in [(False, False, "open"), (True, False, "hole"), (False, True, "cut"), (True, True, "hole+cut")]:
        if name not in problems:
            continue
        for n in sizes:
            t0 = time.time()
            exact = "direct" if n <= 513 else "iterative"
            system = System(model_problem(n, hole, cut), exact=exact)
            note = ""
            if exact == "iterative":
                note = f" (ref. gap {reference_by_cg(system):.1e})"
            cells = []
            for v in variants:
                its, rho, c, lv = measure(system, v)
                oc.setdefault(v, {})[name, n] = (c, lv)
                cells.append(f"{its if its <= MAX_ITS else f'>{MAX_ITS}'} ({rho:.2f})")
            print_fn(f"| {name} | {n}{note} | " + " | ".join(cells) + f" |  <!-- {time.time() - t0:.0f} s -->")
    print_fn(f"\nOperator complexity (levels), {problems[-1]}:\n")
    print_fn("| n | " + " | ".join(variants) + " |")
    print_fn("|---|" + "---|" * len(variants))
    last = [name for name in ("open", "hole", "cut", "hole+cut") if name in problems][-1]
    for n in sizes:
        print_fn(f"| {n} | " + " | ".join(f"{oc[v][last, n][0]:.2f} ({oc[v][last, n][1]})" for v in variants) + " |")


def run_families(variants, print_fn=print):
    print_fn("\n## Hard families: CG + one V-cycle, iterations to 0.05 px (residual factor per iteration)\n")
    print_fn("| family | free nodes | kernel | " + " | ".join(variants) + " |")
    print_fn("|---|---|---|" + "---|" * len(variants))
    for name, problem in families():
        system = System(problem, exact="oracle")
        cells = []
        for v in variants:
            its, rho, c, lv = measure(system, v)
            cells.append(f"{its if its <= MAX_ITS else f'>{MAX_ITS}'} ({rho:.2f}, OC {c:.2f})")
        k = 0 if system.step is None else system.step.kernel
        print_fn(f"| {name} | {len(system.free)} | {k} | " + " | ".join(cells) + " |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="*", default=[257, 513])
    ap.add_argument("--variants", nargs="*", default=MAIN, choices=list(VARIANTS))
    ap.add_argument("--problems", nargs="*", default=["open", "hole", "cut", "hole+cut"],
                    choices=["open", "hole", "cut", "hole+cut"])
    ap.add_argument("--families", action="store_true", help="the hard families instead of the model problem")
    args = ap.parse_args(argv)

    def out(line):
        print(line, flush=True)

    if args.families:
        run_families(args.variants, out)
    else:
        run_model(args.sizes, args.variants, out, tuple(args.problems))


if __name__ == "__main__":
    main()
