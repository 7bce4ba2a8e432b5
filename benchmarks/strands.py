"""Cycles of the thin-plate solve on thin strands and many cuts as the picture grows (issue 42 item 1).

The oracle families (`tests/test_solver_families.py`) check combs and antialiased
character mattes at 40×64 and 72×64. Real mattes have the same shapes at photograph size:
strands stay 1–2 px wide while they grow longer. This benchmark scales both families and
reports the cycles, convergence and time of a cold solve at default settings (but
`max_cycles`, raised so the count is seen), one row per size:

- a comb: the mask of `test_comb_with_one_pixel_gaps` (a back bar and teeth 1 or 2 px
  wide with 1 px gaps), points on the bar and on every 4·scale-th tip;
- a character: `test_antialiased_character_mattes`'s problem (seed 0): body, head on a thin
  neck, an arm, and hair strands 0.3–1.6 px wide whose length and number grow with the
  scale;
- many cuts: `test_many_random_cuts`' float cuts (seeds 0 and 3: 20–50 straight and bent
  cuts, 40 points) with the picture and the displacements scaled together, so that every
  part keeps its shape and its share of the motion.

The thin parts solved whole (`solve/strands.rs`) keep these counts nearly flat; before
them the combs took 62/502/841 and 96/403/2000+ cycles (see docs/dev/ablation.md,
"Strands as the picture grows" and "Ninth change").

The many cuts' counts grow with the picture: parts joined to the rest through necks that
scale with it (`docs/dev/solver-correctness.md`, "Many cuts as the picture grows").

`--straight`: straight strands 1 px wide and 150–1,400 px long (and 2 px, 750 px) that no point holds
(`tests/test_solver_families.py::straight_comb`, a point on every third tip), each
default solve judged against the direct solve (the oracle of the tests): a straight
1 px strand's block is factored exactly, so the count stays flat where the shifted factor
left the strands' slowest bending to the cycle (`docs/dev/solver-correctness.md`,
"Straight strands factored exactly").

Usage: python benchmarks/strands.py [--quick | --photo | --straight] [--max-cycles 2000]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import inkwarp

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from test_solver_families import character_problem, comb_mask, random_cuts, straight_comb  # noqa: E402
from test_solver_oracle import Problem, oracle  # noqa: E402


def comb(tooth: int, scale: int):
    """The comb family's mask at `scale`, points on the bar and on every 4·scale-th tip (the
    test takes the first four tips of every fourth)."""
    m = comb_mask(tooth, scale)
    h, w = m.shape
    tips = list(range(2, w - 2, tooth + 1))[:: 4 * scale]
    pts = np.array([[5.0, 4.0], [w / 2, 5.0], [w - 6.0, 3.0]] + [[float(x), h - 4.0] for x in tips])
    disp = np.random.default_rng(tooth).normal(0, 4, (len(pts), 2))
    return m, pts, disp


def many_cuts(seed: int, scale: int):
    """The random float cuts of `seed` on 64·scale square, displacements scaled too; no mask."""
    pts, disp, cuts = random_cuts(seed, False, scale)
    return np.ones((64 * scale, 64 * scale), np.uint8), pts, disp * scale, cuts


def straight(width: int, length: int):
    """Straight strands `width` px wide and `length` px long that no point holds
    (`straight_comb`), displacements of seed 0."""
    m, pts = straight_comb(length, width=width)
    return m, pts, np.random.default_rng(0).normal(0, 4, pts.shape)


def problem(spec: str):
    """`(mask, points, displacements, cuts or None)` of a spec `KIND:A:SCALE`: `cuts:SEED`
    (many cuts), `comb:TOOTH`, `character:SEED`, or `straight:WIDTH:LENGTH`."""
    kind, a, scale = spec.split(":")
    make = {"cuts": many_cuts, "comb": comb, "character": character_problem, "straight": straight}[kind]
    m, pts, disp, *cuts = make(int(a), int(scale))
    return m, pts, disp, cuts[0] if cuts else None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="scale 1 (and 2 for the character): a smoke run")
    ap.add_argument("--max-cycles", type=int, default=2000)
    ap.add_argument("--photo", action="store_true",
                    help="only the character at photograph sizes (16x and 32x: 1152 x 1024 and 2304 x 2048, its "
                         "displacements scaled with it; making the 32x matte takes about a minute)")
    ap.add_argument("--straight", action="store_true", help="only the straight strands no point holds, by width and length")
    args = ap.parse_args()
    if args.photo:
        return photo(args.max_cycles)
    if args.straight:
        return straight_table()
    scales = (1, 2) if args.quick else (1, 2, 4, 8, 16)
    print("| family | grid | cycles | converged | seconds |")
    print("|---|---|---|---|---|")
    cases = [(f"comb, {t} px teeth", lambda s, t=t: comb(t, s)) for t in (1, 2)]
    cases.append(("character with hair", lambda s: character_problem(0, s)))
    cases += [(f"many cuts, seed {k}", lambda s, k=k: many_cuts(k, s)) for k in (0, 3)]
    for name, make in cases:
        for s in scales:
            # The combs and the character stop at 8x (a 320 × 512 comb, a 576 × 512
            # character), as before; the cuts run to 1,024 px.
            if (name.startswith("comb") and args.quick and s > 1) or (s > 8 and not name.startswith("many")):
                continue
            m, pts, disp, *cuts = make(s)
            t = time.perf_counter()
            _, rep = inkwarp.thin_plate_report(pts, disp, m.shape, mask=m, cuts=cuts[0] if cuts else None, max_cycles=args.max_cycles)
            print(f"| {name} | {m.shape[0]}×{m.shape[1]} | {rep.cycles} | {rep.converged} | "
                  f"{time.perf_counter() - t:.2f} |", flush=True)
    return 0


def photo(max_cycles: int) -> int:
    """The character with hair as a photograph's matte: hundreds of strands hundreds of
    pixels long, their free bends settled in blocks of thousands (`solve/nullspace.rs`)."""
    print("| character with hair | grid | cycles | converged | stop | seconds |")
    print("|---|---|---|---|---|---|")
    for s in (16, 32):
        m, pts, disp = character_problem(0, s)
        t = time.perf_counter()
        _, rep = inkwarp.thin_plate_report(pts, disp * s / 4, m.shape, mask=m, max_cycles=max_cycles)
        print(f"| {s}x | {m.shape[0]}×{m.shape[1]} | {rep.cycles} | {rep.converged} | {rep.stop} | "
              f"{time.perf_counter() - t:.1f} |", flush=True)
    return 0


def straight_table() -> int:
    """Straight free strands by width and length: cycles at the default cap, and the answer's
    largest distance from the direct solve (`test_solver_oracle.oracle`: a solve to a tighter
    tolerance is no reference on these strands, it can claim what it has not reached)."""
    print("| width | length | cycles | converged | off the direct solve (px) | seconds |")
    print("|---|---|---|---|---|---|")
    for width, lengths in ((1, (150, 300, 600, 1000, 1400)), (2, (750,))):
        for length in lengths:
            m, pts, disp = straight(width, length)
            t = time.perf_counter()
            field, rep = inkwarp.thin_plate_report(pts, disp, m.shape, mask=m)
            seconds = time.perf_counter() - t
            exact, skipped, _ = oracle(Problem(m.shape, pts, disp, mask=m))
            off = "(the direct solve left nodes out)" if skipped.any() else f"{np.abs(field - exact)[m > 0].max():.4f}"
            print(f"| {width} | {length} | {rep.cycles} | {rep.converged} | {off} | {seconds:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
