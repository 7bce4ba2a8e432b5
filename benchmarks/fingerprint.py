"""Fingerprints of the solver's answers: one line per solve, its field's hash and its report.

A refactor of the solver that claims "the same answers" is checked with this: run it on the
build before and on the build after and compare the two outputs (`diff`). The problems cover
every path of the solver (open grids cold and warm, holes and cuts, many cuts, thin parts,
tensions, a kept `Solver`, a `WarmStart` animation, capped solves in series, `grid_step`,
Southwell), at sizes that keep the whole run to a minute or two.

Usage: python benchmarks/fingerprint.py [> fingerprints.txt]
"""

from __future__ import annotations

import hashlib
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import inkwarp  # noqa: E402
from ratios import random_problem  # noqa: E402
from test_solver_families import character_problem, comb_mask, grid_problem, random_cuts, torn_case  # noqa: E402


def line(name: str, field, report=None) -> str:
    digest = hashlib.sha256(np.ascontiguousarray(field, dtype=np.float32).tobytes()).hexdigest()[:16]
    said = "" if report is None else f" cycles={report.cycles} converged={report.converged} stop={report.stop} change={report.final_change!r}"
    return f"{name}: {digest}{said}"


def solves():
    for count in (10, 1000):
        pts, disp = random_problem(count, 257, 257, seed=1)
        field, report = inkwarp.thin_plate_report(pts, disp, (257, 257))
        yield line(f"open {count} cold", field, report)
        yield line(f"open {count} warm", *inkwarp.thin_plate_report(pts, disp * 1.02 + 0.05, (257, 257), initial=field))
    for hole, cut in ((True, False), (False, True), (True, True)):
        pts, disp, mask, cuts = grid_problem(257, hole, cut)
        yield line(f"model hole={hole} cut={cut}", *inkwarp.thin_plate_report(pts, disp, (257, 257), mask=mask, cuts=cuts))
    pts, disp, mask, cuts = grid_problem(257, True, True)
    for tension in (1e-6, 1.0):
        yield line(f"model tension {tension:g}", *inkwarp.thin_plate_report(pts, disp, (257, 257), mask=mask, cuts=cuts, tension=tension))
    yield line("model grid_step 2", *inkwarp.thin_plate_report(pts, disp, (257, 257), mask=mask, cuts=cuts, grid_step=2))
    yield line("model southwell", *inkwarp.thin_plate_report(pts, disp, (257, 257), mask=mask, cuts=cuts, method="southwell"))
    for seed in range(3):
        for integer in (False, True):
            p, d, c = random_cuts(seed, integer, 2)
            yield line(f"cuts 2x seed {seed} integer={integer}", *inkwarp.thin_plate_report(p, d, (128, 128), cuts=c))
    p, d, c = random_cuts(0, False, 4)
    kept = inkwarp.Solver()
    start = inkwarp.thin_plate(p, d * 0.02, (256, 256), cuts=c, solver=kept)
    yield line("cuts 4x seed 0 small", start)
    yield line("cuts 4x seed 0 kept x1.1", *inkwarp.thin_plate_report(p, d * 0.022, (256, 256), cuts=c, solver=kept))
    yield line("cuts 4x seed 0 warm", *inkwarp.thin_plate_report(p, d * 0.0204, (256, 256), cuts=c, initial=start))
    for seed in (1, 2):
        for integer in (False, True):
            p, d, c = random_cuts(seed, integer, 4)
            yield line(f"cuts 4x seed {seed} integer={integer}", *inkwarp.thin_plate_report(p, d, (256, 256), cuts=c))
    for case in ("weak-14", "many_cuts_256_seed61"):
        p, d, c, off = torn_case(case)
        yield line(f"{case} off={off}", *inkwarp.thin_plate_report(p, d, (256, 256), cuts=c, _off=off))
    for seed in (0, 1):
        for scale in (1, 2, 4):
            m, p, d = character_problem(seed, scale)
            for tension in (0.0, 1e-6):
                yield line(f"character {seed} {scale}x tension {tension:g}", *inkwarp.thin_plate_report(p, d, m.shape, mask=m, tension=tension))
    for tooth in (1, 2):
        m = comb_mask(tooth, 2)
        h, w = m.shape
        p = np.array([[5.0, 4.0], [w / 2, 5.0], [w - 6.0, 3.0], [w / 3, h - 4.0], [2 * w / 3, h - 4.0]])
        d = np.random.default_rng(tooth).normal(0, 4, (len(p), 2))
        yield line(f"comb {tooth} 2x", *inkwarp.thin_plate_report(p, d, m.shape, mask=m))
    # A capped solve in series, through one Solver.
    p, d, c, off = torn_case("flap_on_a_border_strip")
    kept, field = inkwarp.Solver(), None
    shape = (256, 256)
    for step in range(60):
        field, report = inkwarp.thin_plate_report(p, d, shape, cuts=c, solver=kept, initial=field, max_cycles=7, _off=off)
        if report.converged:
            break
    yield line(f"flap in steps of 7 ({step + 1} steps)", field, report)
    # An animation through a WarmStart.
    pts, disp, mask, cuts = grid_problem(257, True, True)
    warm = inkwarp.WarmStart()
    for frame in range(4):
        yield line(f"frames {frame}", *inkwarp.thin_plate_report(pts, disp * (1 + 0.1 * frame), (257, 257), mask=mask, cuts=cuts, warm=warm))


def main() -> int:
    warnings.simplefilter("ignore", inkwarp.InkwarpWarning)
    for text in solves():
        print(text, flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
