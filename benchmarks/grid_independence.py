"""Cycles of the issue's model problems by grid size, across seeds (issue 42, "Grid
independence": at 257², 513² and 1025² the cycles differ by at most 2 and none exceeds 12).

`tests/test_solver_families.py::test_cycles_do_not_grow_with_the_grid` checks one seed.
This runs the same problems (the disc hole, the two-segment cut, both, and the open grid),
as `ratios.py`'s `model_problem` builds them, with the points and displacements of several
seeds: one cold solve at default settings each, every row reported and the rows that break
either bound counted (`docs/dev/solver-correctness.md`, "Grid independence across seeds").

Usage: python benchmarks/grid_independence.py [--quick] [--seeds 2045-2052]
"""

from __future__ import annotations

import argparse
import sys

import inkwarp
from ratios import model_problem

PROBLEMS = [("open", False, False), ("hole", True, False), ("cut", False, True), ("hole+cut", True, True)]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="one seed at 65² and 129²: a smoke run")
    ap.add_argument("--seeds", default="2045-2052", help="a range a-b of seeds")
    args = ap.parse_args()
    first, last = (int(v) for v in args.seeds.split("-"))
    sizes = (65, 129) if args.quick else (257, 513, 1025)
    seeds = [first] if args.quick else list(range(first, last + 1))
    print("| problem | seed | " + " | ".join(f"{n}²" for n in sizes) + " | within the bounds |")
    print("|---|---|" + "---|" * len(sizes) + "---|")
    broken = 0
    for name, hole, cut in PROBLEMS:
        for seed in seeds:
            reports = []
            for n in sizes:
                pts, disp, mask, cuts = model_problem(n, n, hole, cut, seed)
                reports.append(inkwarp.thin_plate_report(pts, disp, (n, n), mask=mask, cuts=cuts)[1])
            counts = [r.cycles for r in reports]
            ok = max(counts) - min(counts) <= 2 and max(counts) <= 12 and all(r.converged for r in reports)
            broken += not ok
            cells = [f"{r.cycles}" + ("" if r.converged else " (not converged)") for r in reports]
            print(f"| {name} | {seed} | " + " | ".join(cells) + f" | {'yes' if ok else 'no'} |", flush=True)
    print(f"\nrows past a bound (spread over 2 or over 12 cycles): {broken} of {len(PROBLEMS) * len(seeds)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
