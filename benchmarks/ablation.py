"""What each of the solver's optional mechanisms buys (issue 42 item 6), in paired rounds.

For every switch (`inkwarp.thin_plate_report(..., _off="name")`, a private keyword for this
benchmark only) and every problem, the solve runs with the mechanism on and off in
alternating rounds of one process (the order reversed every other round, so that a
drifting machine treats both sides alike), each side's time in a round that of `--repeat`
calls in a row. The table gives the median over the rounds of the time ratio off / on, with
its middle half, and the cycles on / off. A ratio of 1.10
means the mechanism saves a tenth of the solve's time; a mechanism must earn that on at
least one problem to stay.

Problems: 513×513 with 10, 100, 1000 and 4000 random points, cold (no start) and warm
(the previous answer as the start, every displacement changed by 2 %, as in
`ratios.py`); the issue's 513×513 model problem with a disc hole and a two-segment cut
(`tests/test_solver_families.py::grid_problem`), cold and warm; a solid matte (an ellipse
filling most of the picture, 8 points in it), cold and warm; and two problems with thin
parts, whatever the size: `strands.py`'s comb with 2 px teeth at twice its size (80×128)
and `test_many_random_cuts`'s float cuts of seed 0 at four times theirs (256×256). The
free function builds its hierarchy every call; three kinds of problem keep a solver
between calls, the only ones where `cache` can buy anything:

- frames of an animation through a `WarmStart` (10 and 1000 points, hole+cut, matte,
  comb, cuts), every displacement scaled by 1 + 0.2 sin(0.3 k) in frame k;
- `kept warm` (hole+cut, comb, cuts): the warm solve through a `Solver` kept from the cold
  solve before it, the same values every call (from the second, earlier answers span them);
- `drag` (10 and 4000 points): a kept `Solver`, each call from the previous answer with
  every displacement changed by a factor of its own, drawn anew, as a drag in the editor
  (with 4000 points the cycles run every call; with 10, earlier answers span the values
  from about the seventh call: one cycle a call).

Each side of a pair keeps its own solver, and both start afresh for every switch.

Usage: python benchmarks/ablation.py [--rounds 6] [--repeat 3] [--quick] [--only second,kcycle]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

import inkwarp

SWITCHES = ["second", "kcycle", "cache", "fours", "strands", "coarse_strands", "outside", "whole", "exact_coarsest", "answers"]


def random_problem(n: int, size: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    pts = rng.uniform(0, size - 1, (n, 2))
    disp = rng.normal(0, 0.01 * size, (n, 2))
    return pts, disp


def hole_and_cut(n: int):
    """tests/test_solver_families.py `grid_problem(n, hole=True, cut=True)`."""
    s = n / 2049
    rng = np.random.default_rng(2049)
    pts = rng.uniform(0.05, 0.95, (10, 2)) * (n - 1)
    disp = rng.normal(0, 0.01 * n, (10, 2))
    ys, xs = np.mgrid[0:n, 0:n]
    mask = (((xs - 1300 * s) ** 2 + (ys - 800 * s) ** 2) > (150 * s) ** 2).astype(np.uint8)
    cuts = [np.array([[200, 1400.3], [900, 1250.3], [1600, 1500.3]]) * s]
    return pts, disp, mask, cuts


def matte_problem(n: int):
    """A solid matte: an ellipse (a character's body, the layer's alpha) filling most of
    the picture, 8 seeded points inside it."""
    ys, xs = np.mgrid[0:n, 0:n]
    mask = ((((xs - 0.5 * n) / (0.3 * n)) ** 2 + ((ys - 0.55 * n) / (0.4 * n)) ** 2) <= 1).astype(np.uint8)
    rng = np.random.default_rng(5)
    pts = np.column_stack([rng.uniform(0.35, 0.65, 8) * n, rng.uniform(0.35, 0.75, 8) * n])
    return pts, rng.normal(0, 0.01 * n, (8, 2)), mask, None


def comb_problem(tooth: int, scale: int):
    """`benchmarks/strands.py`'s comb: teeth `tooth` px wide, 1 px apart, at `scale`."""
    from strands import comb

    m, pts, disp = comb(tooth, scale)
    return pts, disp, m, None


def random_cuts(seed: int, scale: int):
    """`test_many_random_cuts`'s float cuts (20–50 on 64×64) and 40 points, at `scale`."""
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
    from test_solver_families import random_cuts as cuts_problem

    pts, disp, cuts = cuts_problem(seed, False, scale)
    return pts, disp, np.ones((64 * scale, 64 * scale), np.uint8), cuts


def problems(size: int) -> dict:
    """Name → a function of the switch list that solves once and returns its report."""
    out = {}
    cases = [(f"{n} pts", *random_problem(n, size, seed=n), None, None) for n in (10, 100, 1000, 4000)]
    cases.append(("hole+cut", *hole_and_cut(size)))
    cases.append(("matte", *matte_problem(size)))
    cases.append(("comb", *comb_problem(2, 2)))
    cases.append(("cuts", *random_cuts(0, 4)))
    for name, pts, disp, mask, cuts in cases:
        shape = mask.shape if mask is not None else (size, size)
        field = inkwarp.thin_plate(pts, disp, shape, mask=mask, cuts=cuts)
        changed = disp * 1.02

        def cold(off, pts=pts, disp=disp, mask=mask, cuts=cuts, shape=shape):
            return inkwarp.thin_plate_report(pts, disp, shape, mask=mask, cuts=cuts, _off=off)[1]

        def warm(off, pts=pts, changed=changed, mask=mask, cuts=cuts, field=field, shape=shape):
            return inkwarp.thin_plate_report(pts, changed, shape, mask=mask, cuts=cuts, initial=field, _off=off)[1]

        out[f"{name} cold"] = cold
        out[f"{name} warm"] = warm
        if name in ("hole+cut", "comb", "cuts"):
            out[f"{name} kept warm"] = kept_warm(pts, disp, changed, shape, mask, cuts)
        if name in ("10 pts", "4000 pts"):
            out[f"{name} drag"] = drag(pts, disp, shape)
        if name in ("10 pts", "1000 pts", "hole+cut", "matte", "comb", "cuts"):
            out[f"{name} frames"] = frames(pts, disp, shape, mask, cuts)
    return out


def per_side(start, step):
    """A problem that keeps state between calls, one state per side of a pair: `start(off)`
    makes a side's on its first call, `step(state, off)` solves once from it and returns
    the report. `reset` forgets both, so that every switch's pair starts afresh (else the
    side with everything on would run on from the switch before)."""
    sides: dict[str, list] = {}

    def solve(off):
        if off not in sides:
            sides[off] = start(off)
        return step(sides[off], off)

    solve.reset = sides.clear
    return solve


def kept_warm(pts, disp, changed, shape, mask, cuts):
    """The warm solve with a `Solver` kept from the cold solve before it (its hierarchy,
    and whether that solve probed it); each side of a pair has a solver of its own."""
    def start(off):
        solver = inkwarp.Solver()
        return [solver, inkwarp.thin_plate_report(pts, disp, shape, mask=mask, cuts=cuts, solver=solver, _off=off)[0]]

    def step(state, off):
        solver, field = state
        return inkwarp.thin_plate_report(pts, changed, shape, mask=mask, cuts=cuts, initial=field, solver=solver, _off=off)[1]

    return per_side(start, step)


def drag(pts, disp, shape):
    """A drag in the editor: a kept `Solver`, each call from the previous answer with every
    displacement changed by a factor of its own (1 + 2 % noise, drawn anew each call). With
    4000 points earlier answers never span the values, so the cycles run; with 10 they do
    from about the seventh call on (one cycle a call: `answers`). Each side of a pair has a
    solver and a random sequence of its own, the same sequence."""
    def step(state, off):
        solver, field, rng = state
        d = disp * (1 + 0.02 * rng.standard_normal(disp.shape))
        state[1], report = inkwarp.thin_plate_report(pts, d, shape, initial=field, solver=solver, _off=off)
        return report

    return per_side(lambda off: [inkwarp.Solver(), None, np.random.default_rng(7)], step)


def frames(pts, disp, shape, mask, cuts):
    """An animation's frames through a `WarmStart` (which keeps the solver: its hierarchy
    and history), every displacement scaled by 1 + 0.2 sin(0.3 k) in frame k; each side of a
    pair has a WarmStart of its own and walks the same frames, from the first for every switch."""
    def step(state, off):
        ws, k = state
        state[1] = k + 1
        d = disp * (1 + 0.2 * np.sin(0.3 * k))
        return inkwarp.thin_plate_report(pts, d, shape, mask=mask, cuts=cuts, warm=ws, _off=off)[1]

    return per_side(lambda off: [inkwarp.WarmStart(), 0], step)


def paired(solve, switch: str, rounds: int, repeat: int = 1):
    """Ratios off / on of alternating rounds, each side's time in a round that of `repeat`
    calls in a row (a drag's or an animation's next ones), and the cycles on and off over
    the timed calls ("1–4" where they varied)."""
    getattr(solve, "reset", lambda: None)()  # both sides from the same first frame or call
    solve(""), solve(switch)  # warm-up: first-call costs are not the steady state
    ratios, cycles = [], {"": [], switch: []}
    for r in range(rounds):
        t = {}
        for side in ("", switch) if r % 2 == 0 else (switch, ""):
            t0 = time.perf_counter()
            reports = [solve(side) for _ in range(repeat)]
            t[side] = time.perf_counter() - t0
            cycles[side] += [rep.cycles for rep in reports]
        ratios.append(t[switch] / t[""])
    span = lambda c: f"{min(c)}" if min(c) == max(c) else f"{min(c)}–{max(c)}"  # noqa: E731
    return ratios, span(cycles[""]), span(cycles[switch])


def cell(ratios: list[float]) -> str:
    q = statistics.quantiles(ratios, n=4, method="inclusive") if len(ratios) > 1 else [ratios[0]] * 3
    return f"{statistics.median(ratios):.2f} ({q[0]:.2f}–{q[2]:.2f})"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=6,
                    help="alternating rounds per switch and problem (even: each side first as often)")
    ap.add_argument("--repeat", type=int, default=3,
                    help="calls per side in a round, timed together (a solve of a few milliseconds alone "
                         "is within the machine's noise; 1 with --quick)")
    ap.add_argument("--size", type=int, default=513)
    ap.add_argument("--quick", action="store_true", help="129×129 and three rounds: a smoke run")
    ap.add_argument("--only", default="", help="comma-separated switches (default: all)")
    args, _ = ap.parse_known_args()  # `make bench` passes every suite the same arguments
    size, rounds, repeat = (129, 3, 1) if args.quick else (args.size, args.rounds, args.repeat)
    if rounds < 1 or repeat < 1:
        ap.error("--rounds and --repeat take a whole number of at least 1")
    switches = [s for s in args.only.split(",") if s] or SWITCHES
    probs = problems(size)
    print(f"### Time off / on, median of {rounds} alternating rounds of {repeat} calls a side (middle half); "
          f"cycles on/off — {size}×{size}\n")
    print("| mechanism | " + " | ".join(probs) + " | best |")
    print("|---" * (len(probs) + 2) + "|")
    for switch in switches:
        cells, best = [], 0.0
        for solve in probs.values():
            ratios, on, off = paired(solve, switch, rounds, repeat)
            best = max(best, statistics.median(ratios))
            cells.append(f"{cell(ratios)} {on}/{off}")
        print(f"| {switch} | " + " | ".join(cells) + f" | {best:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
