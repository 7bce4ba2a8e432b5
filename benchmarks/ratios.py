"""The solver's speed ratios (issue "How fast"), each measured in alternating rounds of one run.

This machine's speed drifts by up to 2× within minutes, so no absolute time here is
compared with another run's: every ratio pairs the two sides round by round (the order of
the sides reversed every other round) and reports the median of the rounds' ratios with
its middle half.

1. 513×513, 10 random points, against OpenCV's thin-plate warp
   (`cv2.createThinPlateSplineShapeTransformer`: `estimateTransformation` + `warpImage` of
   a 513×513 RGBA image): inkwarp cold (goal ≤ 1.0×), warm from the previous answer with
   the displacements changed by 2 % (goal ≤ 0.5×); inkwarp cold with 4000 points over
   cold with 10 (goal ≤ 1.3×). Also, not goals: an animation's next frame through a
   `WarmStart` (the earlier frames predict it) over OpenCV's warp; and two variants of the
   warm solve. A kept `Solver` starts from its earlier answers once their displacements
   span the new ones, which the warm solve's (the same 2 % every call: a multiple of the
   first call's) do from its second call: "answers off" is the same solve without them, as
   a drawing's first solves run; "own 2 %" changes every displacement by a factor of its
   own, drawn anew each call (as a drag does), which the answers span from the sixth call.
2. 2049×2049 open with 100 points over 513×513 with 100 points (16× the nodes; goal ≤ 20×).
3. 2049×2049 and 3840×2160 with a disc hole and a two-segment cut (the issue's model
   problem): converged or not, cycles, the cold solve's time and the peak memory of a
   fresh process (goal ≤ 2 GiB), one child process per grid.

Usage: python benchmarks/ratios.py [--quick] [--rounds 9] [--no-big]
(`--quick`: small grids and two rounds, a smoke run of every section.)
"""

from __future__ import annotations

import argparse
import itertools
import json
import statistics
import subprocess
import sys
import time

import numpy as np

import inkwarp


def random_problem(n: int, height: int, width: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    pts = np.column_stack([rng.uniform(0, width - 1, n), rng.uniform(0, height - 1, n)])
    disp = rng.normal(0, 0.01 * min(height, width), (n, 2))
    return pts, disp


def model_problem(height: int, width: int, hole: bool = True, cut: bool = True, seed: int = 2049):
    """The issue's problem scaled to the grid: 10 points of `seed`, a disc hole of radius
    150 s at (1300 s, 800 s) and a cut through (200, 1400.3), (900, 1250.3),
    (1600, 1500.3) · s, with s = size / 2049 along each axis."""
    sx, sy = width / 2049, height / 2049
    pts, disp = random_problem(10, height, width, seed=seed)
    mask = None
    if hole:
        ys, xs = np.mgrid[0:height, 0:width]
        r = 150 * min(sx, sy)
        mask = (((xs - 1300 * sx) ** 2 + (ys - 800 * sy) ** 2) > r * r).astype(np.uint8)
    cuts = [np.array([[200, 1400.3], [900, 1250.3], [1600, 1500.3]]) * [sx, sy]] if cut else None
    return pts, disp, mask, cuts


def have_opencv() -> bool:
    try:
        import cv2

        return hasattr(cv2, "createThinPlateSplineShapeTransformer")
    except ImportError:
        return False


def opencv_warp(pts, disp, image):
    """OpenCV's thin-plate warp of `image` by the points' motion: estimate, then warpImage."""
    import cv2

    tps = cv2.createThinPlateSplineShapeTransformer()
    src = pts.astype(np.float32).reshape(1, -1, 2)
    dst = (pts + disp).astype(np.float32).reshape(1, -1, 2)
    matches = [cv2.DMatch(i, i, 0) for i in range(len(pts))]
    tps.estimateTransformation(dst, src, matches)  # warpImage maps the second shape onto the first
    return tps.warpImage(image)


def timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def summary(values: list[float]) -> str:
    if len(values) == 1:
        return f"{values[0]:.2f}×"
    q = statistics.quantiles(values, n=4, method="inclusive")
    return f"{statistics.median(values):.2f}× (middle half {q[0]:.2f}–{q[2]:.2f}×)"


def verdict(values: list[float], goal: float) -> str:
    return "met" if statistics.median(values) <= goal else "not met"


def rounds_of(sides: dict, rounds: int, reps: int) -> dict[str, list[float]]:
    """Each side's best of `reps` runs in every round, sides in turn, the order reversed
    every other round (so that a drifting machine treats them alike)."""
    names = list(sides)
    times: dict[str, list[float]] = {k: [] for k in names}
    for fn in sides.values():  # warm-up: first-call costs are not the steady state
        fn()
    for r in range(rounds):
        for name in names if r % 2 == 0 else names[::-1]:
            times[name].append(min(timed(sides[name]) for _ in range(reps)))
    return times


def against_opencv(size: int, rounds: int, reps: int) -> None:
    shape = (size, size)
    pts, disp = random_problem(10, *shape)
    many_pts, many_disp = random_problem(4000, *shape, seed=1)
    field = inkwarp.thin_plate(pts, disp, shape)
    changed = disp * 1.02
    image = np.random.default_rng(0).integers(0, 256, (size, size, 4), dtype=np.uint8)
    # Cold: a fresh solve, its coarse levels built in the call. Warm: an animation's next
    # frame, from the previous answer with a kept Solver (its levels reused), as the scene
    # renderer and the editor solve frames. "kept" is cold with a kept Solver.
    kept, kept_warm, kept_off, kept_own = inkwarp.Solver(), inkwarp.Solver(), inkwarp.Solver(), inkwarp.Solver()
    own = np.random.default_rng(4)
    # An animation's next frame through a WarmStart (the earlier frames predict it), each
    # call the next frame of the 10 points moving on sines of their own.
    warm, frame = inkwarp.WarmStart(), itertools.count()
    phase = np.random.default_rng(3).uniform(0, 2 * np.pi, disp.shape)
    sides = {
        "inkwarp cold, N=10": lambda: inkwarp.thin_plate(pts, disp, shape),
        "inkwarp cold, kept Solver, N=10": lambda: inkwarp.thin_plate(pts, disp, shape, solver=kept),
        "inkwarp warm, N=10": lambda: inkwarp.thin_plate(pts, changed, shape, initial=field, solver=kept_warm),
        "inkwarp warm, answers off, N=10": lambda: inkwarp.thin_plate_report(
            pts, changed, shape, initial=field, solver=kept_off, _off="answers"),
        "inkwarp warm, own 2 %, N=10": lambda: inkwarp.thin_plate(
            pts, disp * (1 + 0.02 * own.standard_normal(disp.shape)), shape, initial=field, solver=kept_own),
        "inkwarp cold, N=4000": lambda: inkwarp.thin_plate(many_pts, many_disp, shape),
        "inkwarp frame (WarmStart), N=10": lambda: inkwarp.thin_plate(
            pts, disp * np.sin(0.15 * next(frame) + phase), shape, warm=warm),
    }
    opencv = have_opencv()
    if opencv:
        sides["opencv TPS, N=10"] = lambda: opencv_warp(pts, disp, image)
    times = rounds_of(sides, rounds, reps)
    print(f"\n### {size}×{size}, 10 random points: {rounds} alternating rounds, best of {reps} per side\n")
    print("| side | median ms |")
    print("|---|---|")
    for name, t in times.items():
        print(f"| {name} | {statistics.median(t) * 1e3:.1f} |")
    goals = size == 513
    print("\n| ratio (median of the rounds' ratios) | value | goal |")
    print("|---|---|---|")
    rows = []
    if opencv:
        cv = times["opencv TPS, N=10"]
        rows.append(("cold / OpenCV", [a / b for a, b in zip(times["inkwarp cold, N=10"], cv)], 1.0))
        rows.append(("cold with a kept Solver / OpenCV",
                     [a / b for a, b in zip(times["inkwarp cold, kept Solver, N=10"], cv)], 1.0))
        rows.append(("warm / OpenCV", [a / b for a, b in zip(times["inkwarp warm, N=10"], cv)], 0.5))
        frames = [a / b for a, b in zip(times["inkwarp frame (WarmStart), N=10"], cv)]
        variants = [(name, [a / b for a, b in zip(times[side], cv)]) for name, side in (
            ("warm, answers off / OpenCV (not a goal: a drawing's first solves)", "inkwarp warm, answers off, N=10"),
            ("warm, each displacement changed by its own 2 % every call / OpenCV (not a goal)", "inkwarp warm, own 2 %, N=10"))]
    rows.append(("cold N=4000 / cold N=10",
                 [a / b for a, b in zip(times["inkwarp cold, N=4000"], times["inkwarp cold, N=10"])], 1.3))
    for name, values, goal in rows:
        judged = f"≤ {goal}×: {verdict(values, goal)}" if goals else f"≤ {goal}× (judged at 513×513)"
        print(f"| {name} | {summary(values)} | {judged} |")
    if opencv:
        print(f"| animation frame through a WarmStart / OpenCV (not a goal: what an animation's frames cost) | {summary(frames)} | – |")
        for name, values in variants:
            print(f"| {name} | {summary(values)} | – |")
    if not opencv:
        print("\nOpenCV's thin-plate transformer is not installed (requirements-bench.txt): "
              "its ratios are not measured.")


def grid_growth(small: int, big: int, rounds: int) -> None:
    ps, ds = random_problem(100, small, small)
    pb, db = random_problem(100, big, big)
    times = rounds_of({
        f"{small}²": lambda: inkwarp.thin_plate(ps, ds, (small, small)),
        f"{big}²": lambda: inkwarp.thin_plate(pb, db, (big, big)),
    }, rounds, 1)
    ratios = [b / s for s, b in zip(times[f"{small}²"], times[f"{big}²"])]
    nodes = (big / small) ** 2
    goal = 20.0 if (small, big) == (513, 2049) else 1.25 * nodes
    print(f"\n### Open grid, 100 points: {big}×{big} over {small}×{small} ({nodes:.1f}× the nodes), "
          f"{rounds} alternating rounds\n")
    print(f"median ms: {small}² {statistics.median(times[f'{small}²']) * 1e3:.1f}, "
          f"{big}² {statistics.median(times[f'{big}²']) * 1e3:.1f}; ratio {summary(ratios)}, "
          f"goal ≤ {goal:.0f}×: {verdict(ratios, goal)}")


def big_child(height: int, width: int) -> None:
    """In a fresh process: one cold solve of the model problem with a hole and a cut;
    prints converged, cycles, seconds and the process's peak resident memory as JSON."""
    import resource

    pts, disp, mask, cuts = model_problem(height, width)
    t0 = time.perf_counter()
    _, report = inkwarp.thin_plate_report(pts, disp, (height, width), mask=mask, cuts=cuts)
    seconds = time.perf_counter() - t0
    peak_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps({"converged": report.converged, "cycles": report.cycles,
                      "seconds": seconds, "peak_mib": peak_mib}))


def big_grids(shapes: list[tuple[int, int]]) -> None:
    print("\n### Hole and cut on big grids (one fresh process each)\n")
    print("| grid | converged | cycles | cold solve s | peak memory MiB (whole process) | ≤ 2 GiB |")
    print("|---|---|---|---|---|---|")
    for h, w in shapes:
        out = subprocess.run([sys.executable, __file__, "--child", f"{h},{w}"],
                             check=True, capture_output=True, text=True)
        res = json.loads(out.stdout.strip().splitlines()[-1])
        print(f"| {w}×{h} | {res['converged']} | {res['cycles']} | {res['seconds']:.2f} | "
              f"{res['peak_mib']:.0f} | {'yes' if res['peak_mib'] <= 2048 else 'no'} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="small grids, two rounds: a smoke run")
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--no-big", action="store_true", help="skip the 2049² and 3840×2160 hole-and-cut runs")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        big_child(*map(int, args.child.split(",")))
        return
    print(f"## Solver ratios, inkwarp {inkwarp.__version__}")
    if args.quick:
        against_opencv(129, 2, 1)
        grid_growth(65, 129, 2)
        big_grids([(129, 129), (90, 160)])
    else:
        against_opencv(513, args.rounds, 3)
        grid_growth(513, 2049, max(3, args.rounds // 3))
        if not args.no_big:
            big_grids([(2049, 2049), (2160, 3840)])


if __name__ == "__main__":
    main()
