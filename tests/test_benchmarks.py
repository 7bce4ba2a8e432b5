"""The benchmarks' smoke runs: `benchmarks/solve.py --quick` prints its tables, the
goals section included, with a row for every N. Structure only: no time is asserted
(benchmarks are never timed tests)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_quick_field_benchmark_prints_every_table():
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "solve.py"), "--quick"],
        check=True, capture_output=True, text=True, timeout=300).stdout
    assert "| grid | N | cold ms | warm ms | animated ms | cycles |" in out
    for size in (65, 129):
        for n in (10, 100):
            assert f"| {size}×{size} | {n} |" in out
    # The interleaved section (at 513×513 in a full run, where it also judges the goals).
    section = out.split("### 129×129: 2 rounds")[1]
    assert "| N | cold ms | warm ms |" in section
    rows = [line for line in section.splitlines() if line.startswith(("| 10 |", "| 100 |"))]
    assert len(rows) == 2
    for row in rows:
        cells = [c.strip() for c in row.strip("|").split("|")]
        # "median (25th–75th percentile)" for the cold and the warm solves.
        for cell in cells[1:]:
            median, rest = cell.split(" (")
            low, high = rest.rstrip(")").split("–")
            assert float(low) <= float(median) <= float(high)
    assert "N=100 cold / N=10 cold:" in section
    assert "goal" not in section  # the goals are judged at 513×513 only


def test_quick_track_benchmark_prints_its_table():
    """`benchmarks/track.py --quick`: a row per tracker and kind of feature, every accuracy
    column a number (no time or accuracy asserted: benchmarks are not tests)."""
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "track.py"), "--quick", "--rounds", "1"],
        check=True, capture_output=True, text=True, timeout=300).stdout
    assert "| video | motion | features | tracker | median | p90 |" in out
    rows = [line for line in out.splitlines() if line.startswith("| 256×192×16 |")]
    assert len(rows) == 6
    for tracker in ("inkwarp", "LK", "DIS"):
        for kind in ("textured", "low-texture"):
            row = next(r for r in rows if f"| {kind} | {tracker} |" in r)
            cells = [c.strip() for c in row.strip("|").split("|")]
            assert float(cells[4]) <= float(cells[5])  # median <= 90th percentile
    assert "low-texture: LK median" in out and "low-texture: DIS median" in out


def test_quick_ratio_benchmark_prints_every_section():
    # `benchmarks/ratios.py --quick`: the OpenCV comparison (without OpenCV installed it
    # says so), the grid-growth ratio and the big-grid table, on small grids.
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "ratios.py"), "--quick"],
        check=True, capture_output=True, text=True, timeout=300).stdout
    assert "### 129×129, 10 random points: 2 alternating rounds" in out
    assert "| cold N=4000 / cold N=10 |" in out
    assert ("| cold / OpenCV |" in out and "| warm / OpenCV |" in out) or "OpenCV's thin-plate transformer is not installed" in out
    assert "### Open grid, 100 points: 129×129 over 65×65" in out
    rows = [line for line in out.splitlines() if line.startswith(("| 129×129 |", "| 160×90 |"))]
    assert len(rows) == 2
    for row in rows:
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert cells[1] in ("True", "False") and int(cells[2]) >= 0 and float(cells[4]) > 0


def test_quick_pipeline_benchmark_prints_its_table():
    """`benchmarks/pipeline.py --quick --no-ray`: a row per size with a number in every column
    and the per-pixel ratios below (no time asserted: benchmarks are not tests)."""
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "pipeline.py"), "--quick", "--rounds", "1",
         "--no-ray"],
        check=True, capture_output=True, text=True, timeout=300).stdout
    assert "## Big frames: per-frame ms (median of 1 rounds)" in out
    header = "| size | frames | cold | frame | solve | render | png | mp4 | peak MiB |"
    assert header in out
    rows = [line for line in out.splitlines()
            if line.startswith(("| 128×128 |", "| 480×270 |", "| 960×540 |"))]
    assert len(rows) == 3
    for row in rows:
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert len(cells) == len(header.strip("|").split("|"))
        assert int(cells[1]) >= 1  # frames
        for cell in cells[2:]:
            float(cell)  # every column measured, none left as "–"
        assert float(cells[-1]) > 0  # peak memory
    for key in ("cold", "frame", "solve", "render", "png"):
        assert f"- {key}: 480×270 / 128×128 = " in out
    assert "pixels 7.9×" in out
    assert "Ray speed-up" not in out  # --no-ray


def test_quick_ablation_benchmark_prints_a_row_per_switch():
    # `benchmarks/ablation.py --quick`: every switch's row, a ratio and the cycles on/off
    # for each of the 27 problems; and the line-count script's totals.
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "ablation.py"), "--quick", "--only", "kcycle,cache"],
        check=True, capture_output=True, text=True, timeout=300).stdout
    rows = {line.split("|")[1].strip(): line for line in out.splitlines() if line.startswith("| ") and "mechanism" not in line}
    assert set(rows) == {"kcycle", "cache"}
    for row in rows.values():
        cells = [c.strip() for c in row.strip().strip("|").split("|")]
        assert len(cells) == 29 and all("/" in c for c in cells[1:28]) and float(cells[28]) > 0
    counts = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "line_counts.py")],
        check=True, capture_output=True, text=True, timeout=60).stdout
    assert "| solve/ |" in counts and "| core crate |" in counts


def test_ablation_pairs_walk_the_same_frames_for_every_switch():
    # Both sides of a pair walk an animation from its first frame for every switch, the
    # same number of frames: the side with everything on once ran on from the switch
    # before, many frames and a long history ahead of the other.
    import re

    import numpy as np

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import ablation

    pts, disp = np.array([[3.0, 3.0], [12.0, 10.0], [7.0, 13.0]]), np.array([[1.0, 0.0], [0.0, 1.0], [0.5, 0.5]])
    solve = ablation.frames(pts, disp, (16, 16), None, None)
    sides = solve.reset.__self__  # the sides' [WarmStart, frames walked]
    for switch in ("kcycle", "cache"):
        ratios, on, off = ablation.paired(solve, switch, 2, 2)
        assert len(ratios) == 2 and sides[""][1] == sides[switch][1] == 1 + 2 * 2
        assert all(re.fullmatch(r"\d+(–\d+)?", c) for c in (on, off)), (on, off)  # the timed calls' cycles: "1", "1–4"
    # The kept solvers too: a drag's sides draw the same displacements, both from the
    # first call, and a kept warm solve's sides are built again for every switch.
    drag = ablation.drag(pts, disp, (16, 16))
    kept = ablation.kept_warm(pts, disp, disp * 1.02, (16, 16), None, None)
    for switch in ("kcycle", "cache"):
        ablation.paired(drag, switch, 2, 2)
        drawn = {side: state[2].bit_generator.state["state"] for side, state in drag.reset.__self__.items()}
        assert set(drawn) == {"", switch} and drawn[""] == drawn[switch]
        ablation.paired(kept, switch, 2, 1)
        assert set(kept.reset.__self__) == {"", switch}


def test_quick_strands_benchmark_prints_a_row_per_family_and_size():
    # `benchmarks/strands.py --quick`: the comb, character and many-cuts families scaled; cycles and
    # convergence are numbers the table reports, not asserted.
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "strands.py"), "--quick"],
        check=True, capture_output=True, text=True, timeout=300).stdout
    assert "| family | grid | cycles | converged | seconds |" in out
    for row in ("| comb, 1 px teeth | 40×64 |", "| comb, 2 px teeth | 40×64 |",
                "| character with hair | 72×64 |", "| character with hair | 144×128 |",
                "| many cuts, seed 0 | 64×64 |", "| many cuts, seed 3 | 128×128 |"):
        line = next(r for r in out.splitlines() if r.startswith(row))
        cells = [c.strip() for c in line.strip("|").split("|")]
        assert int(cells[2]) >= 1 and cells[3] in ("True", "False")


def test_quick_memory_benchmark_prints_a_row_per_problem():
    # `benchmarks/memory.py --quick`: the estimate against a child's peak memory over one solve;
    # how close it comes is what the table reports, not asserted.
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "memory.py"), "--quick"],
        check=True, capture_output=True, text=True, timeout=300).stdout
    assert "| problem | grid | thin nodes | grew (MiB) | estimate ÷ grew | first term ÷ grew | cycles |" in out
    for row in ("| open:10:200 | 200×150 | 0 |", "| comb:1:2 |", "| character:0:2 |"):
        line = next(r for r in out.splitlines() if r.startswith(row))
        cells = [c.strip() for c in line.strip("|").split("|")]
        assert float(cells[4]) > 0 and int(cells[6]) >= 1


def test_pair_packages_compares_a_build_with_itself():
    # `benchmarks/pair_packages.py`: this checkout's package against itself, one round on
    # two small problems; the same build solves each problem in the same cycles.
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "pair_packages.py"), str(ROOT / "python"),
         "--rounds", "1", "--problems", "cuts:0:1,comb:1:1"],
        check=True, capture_output=True, text=True, timeout=300).stdout
    for name in ("cuts:0:1", "comb:1:1"):
        cells = [c.strip() for c in next(r for r in out.splitlines() if r.startswith(f"| {name} |")).strip("|").split("|")]
        old, new = cells[2].split(" → ")
        assert int(old) == int(new) >= 1 and float(cells[1].split()[0]) > 0


def test_quick_grid_independence_prints_a_row_per_problem_and_the_count():
    # `benchmarks/grid_independence.py --quick`: the four model problems, one seed, two
    # small sizes; the cycles are what the table reports, not asserted.
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "grid_independence.py"), "--quick"],
        check=True, capture_output=True, text=True, timeout=300).stdout
    rows = [r for r in out.splitlines() if r.startswith("| ") and r[2:3].isalpha() and "problem" not in r]
    assert [r.split("|")[1].strip() for r in rows] == ["open", "hole", "cut", "hole+cut"]
    for row in rows:
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert all(int(c.split()[0]) >= 1 for c in cells[2:4]) and cells[4] in ("yes", "no")
    assert "rows past a bound" in out and "of 4" in out


def test_quick_honesty_sweep_counts_every_claim():
    # `benchmarks/honesty.py --quick`: one seed's cuts, cold at two scales, warm and through a
    # kept Solver; the counts are what the sweep reports, not asserted (the contract is the
    # oracle tests').
    # With `--families`: the character and the two combs at 1x, three tensions, three
    # displacement scales. With `--oracle`: one speckle and one collinear problem against
    # the direct solve (4 and 6 cold solves, 6 warm). With `--open`: four point counts on 65²,
    # two displacement scales, cold and warm. With `--kept`: one seed's three problems, a
    # Solver kept through 8, 12 and 12 calls, two displacement scales. With `--direct`: the
    # cuts judged by the direct solve instead of tight solves.
    for extra, expected in (([], 12), (["--direct"], 12), (["--families"], 27), (["--oracle"], 16), (["--open"], 16),
                            (["--kept"], 64)):
        out = subprocess.run(
            [sys.executable, str(ROOT / "benchmarks" / "honesty.py"), "--quick", *extra],
            check=True, capture_output=True, text=True, timeout=300).stdout
        line = next(r for r in out.splitlines() if r.startswith("| ") and r[2].isdigit())
        cells = [int(c) for c in line.strip("|").split("|")]
        solves, not_converged, claimed = cells[:3]
        assert solves == expected and not_converged + claimed == solves and cells[5] > 0
        assert ("against the direct solve" in out) == bool({"--direct", "--oracle"} & set(extra)), out


def _study_rows(*args):
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "prolongation_study.py"), *args],
        check=True, capture_output=True, text=True, timeout=300).stdout
    return {r.split("|")[3].strip(): [c.strip() for c in r.strip("|").split("|")]
            for r in out.splitlines() if r.startswith("| 129 ")}


def test_prolongation_study_counts_cycles_for_each_space():
    # `benchmarks/prolongation_study.py` at 129² (four levels, so the K-cycles' steps run),
    # open and around the disc hole: a row per prolongation, every count within the study's
    # cap; the smoother spaces take fewer cycles than the bilinear one, which is what the
    # study measures at larger sizes.
    for args, kinds in ((["--sizes", "129"], {"lin", "bspl0", "bspl"}), (["--hole", "--sizes", "129"], {"lin", "bspl0"})):
        rows = _study_rows(*args)
        assert set(rows) == kinds
        for cells in rows.values():
            assert all(c.isdigit() for c in cells[3:7]) and float(cells[7]) > 1.0
        # V-cycles (column 3) and K-cycles (column 5).
        assert int(rows["bspl0"][3]) < int(rows["lin"][3]) and int(rows["bspl0"][5]) < int(rows["lin"][5])


def test_the_studys_smoothed_prolongation_is_the_b_spline_subdivision_on_an_open_grid():
    # `S Q` (S smoothing across straight linked triples) equals the tensor product of the 1-D
    # subdivision (1/8, 3/4, 1/8 on even nodes, 1/2, 1/2 on odd ones, ends kept) exactly.
    import importlib.util

    import numpy as np
    import scipy.sparse as sp

    sys.path.insert(0, str(ROOT / "benchmarks"))
    spec = importlib.util.spec_from_file_location("prolongation_study", ROOT / "benchmarks" / "prolongation_study.py")
    study = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(study)
    n, nc = 9, 5
    right = np.zeros((n, n), bool)
    right[:, :-1] = True
    s = study.smoothing(right, right.T.copy())
    lin, bspl = study.prolongation_1d(nc, "lin"), study.prolongation_1d(nc, "bspl")
    assert abs(s @ sp.kron(lin, lin) - sp.kron(bspl, bspl)).max() == 0.0
    assert np.allclose(bspl.toarray()[4], [0, 0.125, 0.75, 0.125, 0]) and np.allclose(bspl.toarray()[3], [0, 0.5, 0.5, 0, 0])
