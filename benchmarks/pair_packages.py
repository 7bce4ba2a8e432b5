"""Two builds of the Python package compared on the slow families, in alternating rounds.

For a change to the solver that is not a runtime switch: keep a copy of the package built
before it (the `python/inkwarp` folder with its compiled module), then

    python benchmarks/pair_packages.py OLD_DIR [NEW_DIR] [--rounds 5] [--problems cuts:0:8,comb:1:8]

where `OLD_DIR` holds the old `inkwarp` folder (the child's `PYTHONPATH` is that folder) and
`NEW_DIR` the new one (default: this checkout's `python/`). Each round runs one child
process per build (the order reversed every other round); a child solves every problem
once, cold, at default settings but `max_cycles=2000`, and prints its time and cycles. A
row is the median over the rounds of the time ratio new / old (below 1: the new build is
faster), its middle half in brackets, then the cycles old → new.

Problems: `benchmarks/strands.py`'s `problem` specs, `cuts:SEED:SCALE` (many random float
cuts), `comb:TOOTH:SCALE` (1 or 2 px teeth), `character:SEED:SCALE` (a matte with hair);
and, made by `benchmarks/ratios.py`'s functions, `open:POINTS:SIZE` (random points of seed 0
on an open SIZE × SIZE grid) and `model:SEED:SIZE` (the disc hole and two-segment cut);
`tangle:STRANDS:WIDTH` (`tests/test_solver_families.py::hair_tangle`: a head with STRANDS
crossing hair strands, WIDTH × 3/4 WIDTH); `scribble:STRANDS:WIDTH` (`strand_scribble`: STRANDS
long strands crossing into a mesh, WIDTH × 3/4 WIDTH).

`--repeat K`: with K > 1 each child times K cold solves of a problem after one untimed,
and reports their median (for solves of tens of milliseconds, where one says little).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DEFAULT = "cuts:0:8,cuts:3:8,comb:1:8,comb:2:8,character:0:8,cuts:0:16,cuts:3:16"

CHILD = """
import json, sys, time
sys.path[:0] = [{bench!r}, {tests!r}]
import inkwarp
import statistics
from strands import problem
from ratios import model_problem, random_problem

def make(name):
    kind, a, size = name.split(":")
    if kind == "open":
        return None, (int(size), int(size)), *random_problem(int(a), int(size), int(size)), None
    if kind == "model":
        pts, disp, m, cuts = model_problem(int(size), int(size), seed=int(a))
        return m, m.shape, pts, disp, cuts
    if kind == "tangle":
        from test_solver_families import hair_tangle
        m, pts, disp = hair_tangle(int(size), int(size) * 3 // 4, int(a))
        return m, m.shape, pts, disp, None
    if kind == "scribble":
        from test_solver_families import strand_scribble
        m, pts, disp = strand_scribble(int(size), int(size) * 3 // 4, int(a))
        return m, m.shape, pts, disp, None
    m, pts, disp, cuts = problem(name)
    return m, m.shape, pts, disp, cuts

out = {{}}
for name in {problems!r}:
    m, shape, pts, disp, cuts = make(name)
    solve = lambda: inkwarp.thin_plate_report(pts, disp, shape, mask=m, cuts=cuts, max_cycles=2000)[1]
    if {repeat} > 1:
        solve()
    times = []
    for _ in range({repeat}):
        t = time.perf_counter()
        rep = solve()
        times.append(time.perf_counter() - t)
    out[name] = (statistics.median(times), rep.cycles, rep.converged)
print(json.dumps(out))
"""


def run(package_dir: str, problems: list[str], repeat: int) -> dict:
    code = CHILD.format(bench=str(ROOT / "benchmarks"), tests=str(ROOT / "tests"), problems=problems, repeat=repeat)
    env = dict(os.environ, PYTHONPATH=package_dir)
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True, env=env,
                         cwd=ROOT).stdout
    return json.loads(out.splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("old")
    ap.add_argument("new", nargs="?", default=str(ROOT / "python"))
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--problems", default=DEFAULT)
    ap.add_argument("--repeat", type=int, default=1, help="cold solves per problem in each child (their median)")
    args = ap.parse_args()
    if args.repeat < 1 or args.rounds < 1:
        ap.error("--rounds and --repeat must be at least 1")
    problems = args.problems.split(",")
    builds = {"old": args.old, "new": args.new}
    results: dict[str, list[dict]] = {k: [] for k in builds}
    for r in range(args.rounds):
        for name in (list(builds) if r % 2 == 0 else list(builds)[::-1]):
            results[name].append(run(builds[name], problems, args.repeat))
    each = "one cold solve" if args.repeat == 1 else f"the median of {args.repeat} cold solves"
    print(f"{args.rounds} alternating rounds, {each} per problem and build per round\n")
    print("| problem | new / old | cycles old → new | converged old, new |")
    print("|---|---|---|---|")
    for p in problems:
        ratios = [n[p][0] / o[p][0] for o, n in zip(results["old"], results["new"])]
        q = statistics.quantiles(ratios, n=4, method="inclusive") if len(ratios) > 1 else [ratios[0]] * 3
        o, n = results["old"][0][p], results["new"][0][p]
        print(f"| {p} | {statistics.median(ratios):.2f} ({q[0]:.2f}–{q[2]:.2f}) | {o[1]} → {n[1]} | {o[2]}, {n[2]} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
