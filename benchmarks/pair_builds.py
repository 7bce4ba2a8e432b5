"""Two builds of the solver compared in alternating rounds, for mechanisms that cannot be a
runtime switch (docs/dev/ablation.md, "Two-build rows").

Build `crates/inkwarp-core/examples/pair_timing.rs` once with the mechanism and once
without (e.g. on main and on a branch that removes it), keep both binaries, then:

    python benchmarks/pair_builds.py WITH WITHOUT [WITHOUT ...] [--rounds 7]

Several builds without (one mechanism each) share the rounds of one build with. Each round
runs every binary once (the order reversed every other round); each prints the
fastest of a few solves per problem. A cell is the median over the rounds of the time ratio
without / with, its middle half in brackets, then the cycles with / without: above 1 the
mechanism saves time.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys


def run(binary: str) -> dict[str, tuple[float, int]]:
    out = subprocess.run([binary], check=True, capture_output=True, text=True).stdout
    rows = {}
    for line in out.splitlines():
        name, seconds, cycles = line.split()
        rows[name] = (float(seconds), int(cycles))
    return rows


def quartiles(values: list[float]) -> tuple[float, float, float]:
    v = sorted(values)
    q = statistics.quantiles(v, n=4, method="inclusive") if len(v) > 1 else [v[0]] * 3
    return q[0], statistics.median(v), q[2]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("with_", metavar="WITH", help="the build with the mechanism")
    ap.add_argument("without", metavar="WITHOUT", nargs="+", help="the builds without one mechanism each")
    ap.add_argument("--rounds", type=int, default=7)
    args = ap.parse_args()
    ratios: dict[tuple[str, str], list[float]] = {}
    cycles: dict[tuple[str, str], tuple[int, int]] = {}
    binaries = [args.with_, *args.without]
    for k in range(args.rounds):
        got = {b: run(b) for b in (binaries if k % 2 == 0 else binaries[::-1])}
        for b in args.without:
            for name, (t_with, c_with) in got[args.with_].items():
                t_without, c_without = got[b][name]
                ratios.setdefault((b, name), []).append(t_without / t_with)
                cycles[b, name] = (c_with, c_without)
    names = list(got[args.with_])
    print("| build | " + " | ".join(names) + " | best |")
    print("|" + "---|" * (len(names) + 2))
    for b in args.without:
        cells, best = [], 0.0
        for name in names:
            lo, med, hi = quartiles(ratios[b, name])
            best = max(best, med)
            cells.append(f"{med:.2f} ({lo:.2f}–{hi:.2f}) {cycles[b, name][0]}/{cycles[b, name][1]}")
        print(f"| {b} | " + " | ".join(cells) + f" | {best:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
