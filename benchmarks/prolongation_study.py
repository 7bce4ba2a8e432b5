"""Bilinear against cubic B-spline prolongation for the plate, on open grids (issue 42 item 1).

A development study, not part of `make bench`: it rebuilds the engine's kind of hierarchy in
scipy to ask what a smoother coarse space would buy before building it
(docs/dev/coarse-space.md, "A smoother prolongation, measured in a model"). The matrix is
the DESIGN §4 energy of the test oracle (tests/test_solver_oracle.py) on an open N × N grid
with `ratios.py`'s random points fixed; the unknowns are the other nodes, and each
component is solved alone (the x component here).

The hierarchy is the engine's: `P = M Q`, `Q` a tensor-product prolongation from every other
node, `M` zeroing the rows of nodes that are not unknowns (a coarse node left without
unknowns is dropped), Galerkin products `Pᵀ A P`, Chebyshev smoothing on `[λ/16, λ]` of
`D⁻¹A` before and after (two steps on the finest level, one on the coarse levels of an open
grid and two on a torn one's), a direct solve below 300 unknowns, a flexible conjugate
gradient outside. Not modelled: the engine's coarse-to-fine start (here every solve starts
from zero), its deflation and strands, and its bounds of `λ` (here ARPACK's estimate, 2 %
up). `Q` is

- `lin`: bilinear, the engine's (which is link-aware on torn grids; here plain, and masked);
- `bspl`: the cubic B-spline subdivision (`1/8, 3/4, 1/8` on even nodes, `1/2, 1/2` on odd
  ones, bilinear at the ends: the bilinear one followed by a `1/4, 1/2, 1/4` smoothing on the
  finer grid), whose coarse functions, composed level by level, are smooth where bilinear
  ones kink;
- `bspl0`: the B-spline one from the first coarse level to the finest only, bilinear below.

Into the finest level the B-spline prolongation is built as `S Q` (`smoothing`: `S`
smooths only across straight linked triples), so that `--hole` (the model problem's disc
hole and its 10 points; the nodes inside are not unknowns) keeps affine functions in the
space; cuts would need the engine's link-aware prolongation and are not modelled.

Each is run as V-cycles and as K-cycles (two flexible steps on every level between the
finest and the one above the coarsest, the second where the first left more than 0.3 of
the residual), with the finest correction unscaled or line-searched (`+LS`). A cell counts
the outer iterations until every unknown is within 0.01 px of the direct solve (the true
error: no stopping rule). `OC` is the operator complexity (the levels' nonzeros over the
finest's), `taps` the widest row on each level.

    python benchmarks/prolongation_study.py                       # 129², 257², 513², 10 points
    python benchmarks/prolongation_study.py --sizes 257 --points 1000
    python benchmarks/prolongation_study.py --hole --sizes 129 257 513
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import test_solver_oracle as orc  # noqa: E402
from ratios import model_problem, random_problem  # noqa: E402

TOLERANCE_PX = 0.01
COARSEST = 300
CHEB_RATIO = 16.0
K_SECOND_STEP = 0.3
MAX_ITS = 80


def prolongation_1d(nc: int, kind: str) -> sp.csr_matrix:
    """From `nc` nodes to the `2 nc − 1` of the finer line."""
    rows, cols, vals = [], [], []
    for i in range(2 * nc - 1):
        c = i // 2
        if i % 2:
            taps = [(c, 0.5), (c + 1, 0.5)]
        elif kind == "bspl" and 0 < c < nc - 1:
            taps = [(c - 1, 0.125), (c, 0.75), (c + 1, 0.125)]
        else:
            taps = [(c, 1.0)]
        for j, v in taps:
            rows.append(i)
            cols.append(j)
            vals.append(v)
    return sp.csr_matrix((vals, (rows, cols)), shape=(2 * nc - 1, nc))


class Level:
    def __init__(self, a: sp.csr_matrix):
        self.a = a
        self.inv_diag = 1.0 / a.diagonal()
        scaled = sp.diags(self.inv_diag) @ a
        top = spla.eigs(scaled, k=1, which="LM", return_eigenvectors=False, maxiter=3000, tol=1e-3)[0].real
        self.lam = 1.02 * top  # the engine takes an upper bound
        self.p: sp.csr_matrix | None = None
        self.solve = None
        self.steps = 2


def smoothing(right: np.ndarray, down: np.ndarray) -> sp.csr_matrix:
    """`S = S_y S_x`: `1/4, 1/2, 1/4` along a row (a column) at each node centred on two links
    of it, the identity elsewhere (so affine functions stay affine). On an open grid `S Q` is
    the B-spline subdivision."""
    h, w = right.shape
    n = h * w
    p = np.arange(n)

    def along(link: np.ndarray, step: int) -> sp.csr_matrix:
        before = np.zeros_like(link)
        if step == 1:
            before[:, 1:] = link[:, :-1]
        else:
            before[1:, :] = link[:-1, :]
        tri = (before & link).ravel()
        rows = np.concatenate([p[~tri], p[tri], p[tri], p[tri]])
        cols = np.concatenate([p[~tri], p[tri], p[tri] - step, p[tri] + step])
        vals = np.concatenate([np.ones((~tri).sum()), np.full(tri.sum(), 0.5), np.full(2 * tri.sum(), 0.25)])
        return sp.csr_matrix((vals, (rows, cols)), shape=(n, n))

    return (along(down, w) @ along(right, 1)).tocsr()


def hierarchy(a: sp.csr_matrix, unknowns: np.ndarray, n: int, kind: str, smooth: sp.csr_matrix, coarse_steps: int) -> list[Level]:
    idx = np.flatnonzero(unknowns)
    levels = [Level(a[idx][:, idx].tocsr())]
    while levels[-1].a.shape[0] > COARSEST and n > 5:
        nc = (n + 1) // 2
        q1 = prolongation_1d(nc, "bspl" if kind == "bspl" and len(levels) > 1 else "lin")
        q = sp.kron(q1, q1).tocsr()
        if kind != "lin" and len(levels) == 1:
            q = smooth @ q
        q = q.tocsr()[idx]
        coarse = (q.T @ levels[-1].a @ q).tocsr()
        d = coarse.diagonal()
        idx = np.flatnonzero(d > 1e-9 * d.max())
        levels[-1].p = q[:, idx].tocsr()
        levels.append(Level(coarse[idx][:, idx].tocsr()))
        n = nc
    levels[-1].solve = spla.factorized(levels[-1].a.tocsc())
    for level in levels[1:]:
        level.steps = coarse_steps
    return levels


def chebyshev(level: Level, x: np.ndarray, f: np.ndarray) -> np.ndarray:
    steps, b = level.steps, level.lam
    a = b / CHEB_RATIO
    theta, delta = (b + a) / 2, (b - a) / 2
    sigma = theta / delta
    rho = 1 / sigma
    d = level.inv_diag * (f - level.a @ x) / theta
    for k in range(steps):
        x = x + d
        if k + 1 == steps:
            break
        rho_new = 1 / (2 * sigma - rho)
        d = rho_new * rho * d + 2 * rho_new / delta * level.inv_diag * (f - level.a @ x)
        rho = rho_new
    return x


def cycle(levels: list[Level], k: int, f: np.ndarray, kcycle: bool, line_search: bool) -> np.ndarray:
    level = levels[k]
    if k + 1 == len(levels):
        return level.solve(f)
    x = chebyshev(level, np.zeros_like(f), f)
    fc = level.p.T @ (f - level.a @ x)
    coarse = levels[k + 1].a
    if kcycle and 0 < k and k + 2 < len(levels):
        z1 = cycle(levels, k + 1, fc, kcycle, line_search)
        az1 = coarse @ z1
        a1 = (z1 @ fc) / (z1 @ az1)
        f2 = fc - a1 * az1
        e = a1 * z1
        if np.linalg.norm(f2) > K_SECOND_STEP * np.linalg.norm(fc):
            z2 = cycle(levels, k + 1, f2, kcycle, line_search)
            beta = (z2 @ az1) / (z1 @ az1)
            d, ad = z2 - beta * z1, coarse @ z2 - beta * az1
            e = e + (d @ f2) / (d @ ad) * d
    else:
        e = cycle(levels, k + 1, fc, kcycle, line_search)
        if k > 0 or line_search:
            e = e * (e @ fc) / (e @ (coarse @ e))
    return chebyshev(level, x + level.p @ e, f)


def iterations(levels: list[Level], b: np.ndarray, exact: np.ndarray, kcycle: bool, line_search: bool) -> str:
    a = levels[0].a
    x, r = np.zeros_like(b), b.copy()
    z = cycle(levels, 0, r, kcycle, line_search)
    p, rz = z.copy(), r @ z
    for it in range(1, MAX_ITS + 1):
        q = a @ p
        alpha = rz / (p @ q)
        x += alpha * p
        r -= alpha * q
        if np.abs(x - exact).max() < TOLERANCE_PX:
            return str(it)
        z = cycle(levels, 0, r, kcycle, line_search)
        beta = max((z @ (-alpha * q)) / rz, 0.0)  # flexible (Polak–Ribière)
        p, rz = z + beta * p, r @ z
    return f">{MAX_ITS}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="*", default=[129, 257, 513])
    ap.add_argument("--points", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--hole", action="store_true", help="the model problem's disc hole (ratios.py), its 10 points")
    args = ap.parse_args()
    print("| N | points | prolongation | V | V+LS | K | K+LS | OC | taps by level |")
    print("|---|---|---|---|---|---|---|---|---|")
    for n in args.sizes:
        if args.hole:
            pts, disp, mask, _ = model_problem(n, n, hole=True, cut=False, seed=2049)
        else:
            (pts, disp), mask = random_problem(args.points, n, n, args.seed), None
        problem = orc.Problem(shape=(n, n), points=pts, displacements=disp, mask=mask)
        a = orc.energy_matrix(problem).tocsr()
        values, _ = orc.constraints(problem)
        active, right, down = orc.links(problem)
        unknowns = active.ravel().copy()
        unknowns[list(values)] = False
        held = np.zeros(n * n)
        for i, v in values.items():
            held[i] = v[0]
        idx = np.flatnonzero(unknowns)
        b = -(a[idx] @ held)
        exact = spla.spsolve(a[idx][:, idx].tocsc(), b)
        smooth = smoothing(right, down)
        for kind in ("lin", "bspl0") if args.hole else ("lin", "bspl0", "bspl"):
            # The engine's smoothing: two steps on the finest level, one on the coarse levels of an
            # open grid and two on a torn one's.
            levels = hierarchy(a, unknowns, n, kind, smooth, 2 if args.hole else 1)
            cells = [iterations(levels, b, exact, kc, ls) for kc in (False, True) for ls in (False, True)]
            oc = sum(lv.a.nnz for lv in levels) / levels[0].a.nnz
            taps = ", ".join(str(int(np.diff(lv.a.indptr).max())) for lv in levels)
            print(f"| {n} | {'10, hole' if args.hole else args.points} | {kind} | " + " | ".join(cells) + f" | {oc:.2f} | {taps} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
