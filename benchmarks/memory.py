"""The thin-plate solve's memory estimate against what a solve takes (`docs/reference/limits.md`).

`inkwarp.thin_plate` refuses a grid whose estimate does not fit in free memory, and a render
runs as many frames at once as free memory holds its estimate. The estimate is
`inkwarp_core::limits` (read from the engine here): 220 bytes per pixel, plus 1,300 per thin
node (a node whose run of linked nodes along its row or its column is at most 16: strands,
teeth, outlines; the solver factors them exactly) and, on a torn grid (a matte, a hole or a
cut), 160 per node for the slow modes a long solve deflates (at most 256 MiB). The thin nodes
column is counted here on the matte, as the engine counts them.

Each problem is solved once in a child process, after a small solve that starts the thread
pool; the figure is the growth of the child's peak resident memory over the solve. Columns:
the estimate over that growth, now and with the first term alone.

Usage: python benchmarks/memory.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent

FULL = ["open:10:2400", "character:0:16", "character:1:16", "comb:1:16", "comb:2:16", "tangle:700:1200", "scribble:120:800"]
QUICK = ["open:10:200", "comb:1:2", "character:0:2"]

CHILD = r"""
import json, resource, sys
sys.path[:0] = [{bench!r}, {tests!r}]
import numpy as np
import inkwarp
from ratios import random_problem
from strands import problem

kind, a, size = sys.argv[1].split(":")
if kind == "open":
    side = int(size)
    m, shape = None, (side * 3 // 4, side)
    pts, disp = random_problem(int(a), side, side * 3 // 4)
elif kind in ("tangle", "scribble"):
    from test_solver_families import hair_tangle, strand_scribble
    make = hair_tangle if kind == "tangle" else strand_scribble
    m, pts, disp = make(int(size), int(size) * 3 // 4, int(a))
    shape = m.shape
else:
    m, pts, disp, cuts = problem(sys.argv[1])
    assert cuts is None
    shape = m.shape


def runs(alpha):
    # Each node's run of active nodes along its row.
    out = np.zeros(alpha.shape, int)
    for row, o in zip(alpha, out):
        edges = np.flatnonzero(np.diff(np.concatenate([[0], row, [0]])))
        for start, stop in zip(edges[::2], edges[1::2]):
            o[start:stop] = stop - start
    return out


active = np.ones(shape, bool) if m is None else m > 0
thin = int((active & (np.minimum(runs(active), runs(active.T).T) <= 16)).sum())
pixels = shape[0] * shape[1]
warm = np.zeros((64, 64), np.uint8)
warm[10:50, 10:30] = warm[20, 30:60] = 1
inkwarp.thin_plate_report(np.array([[12.0, 12.0], [28.0, 40.0], [58.0, 20.0]]), np.ones((3, 2)), (64, 64), mask=warm)
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
_, report = inkwarp.thin_plate_report(pts, disp, shape, mask=m, max_cycles=2000)
grew = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) * 1024
from inkwarp import _inkwarp

estimate = _inkwarp._solve_bytes(shape[1], shape[0], None if m is None else active.astype(np.uint8))
print(json.dumps(dict(shape=shape, thin=thin, grew=grew, estimate=estimate, plain=_inkwarp._solve_bytes(shape[1], shape[0]),
                      cycles=report.cycles, converged=report.converged)))
"""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="small problems: a smoke run")
    args = ap.parse_args()
    child = CHILD.format(bench=str(HERE), tests=str(HERE.parent / "tests"))
    print("| problem | grid | thin nodes | grew (MiB) | estimate ÷ grew | first term ÷ grew | cycles |")
    print("|---|---|---|---|---|---|---|")
    for name in QUICK if args.quick else FULL:
        out = subprocess.run([sys.executable, "-c", child, name], check=True, capture_output=True, text=True)
        d = json.loads(out.stdout.strip().splitlines()[-1])
        grew = max(d["grew"], 1)
        print(f"| {name} | {d['shape'][1]}×{d['shape'][0]} | {d['thin']:,} | {d['grew'] / 2**20:.0f} | "
              f"{d['estimate'] / grew:.2f} | {d['plain'] / grew:.2f} | {d['cycles']} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
