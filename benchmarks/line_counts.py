"""Line counts of the core crate against issue 42's budget: `solve/` at most 3,000 lines
outside its tests, the whole `inkwarp-core/src` at most 13,000.

A line counts unless it belongs to a test: files named `tests.rs` and every
`#[cfg(test)]` item (a `mod tests { ... }` block or a single function) are left out.
Blank lines and comments count, as they do for a reader.

Usage: python benchmarks/line_counts.py
"""

from __future__ import annotations

import sys
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "crates" / "inkwarp-core" / "src"
BUDGET = {"solve/": 3000, "core crate": 13000}


def non_test_lines(path: Path) -> int:
    if path.name == "tests.rs":
        return 0
    lines = path.read_text(encoding="utf-8").splitlines()
    count, i = 0, 0
    while i < len(lines):
        if lines[i].strip().startswith("#[cfg(test)]"):
            i = skip_item(lines, i + 1)
            continue
        count += 1
        i += 1
    return count


def skip_item(lines: list[str], i: int) -> int:
    """The index past the item starting at line `i` (after its `#[cfg(test)]`): up to the
    end of its braces, or its `;` for an item without a body (`mod tests;`)."""
    depth, opened = 0, False
    while i < len(lines):
        code = lines[i].split("//")[0]
        depth += code.count("{") - code.count("}")
        opened = opened or "{" in code
        i += 1
        if (opened and depth <= 0) or (not opened and code.rstrip().endswith(";")):
            return i
    return i


def main() -> int:
    solve = {p.relative_to(SRC).as_posix(): non_test_lines(p) for p in sorted((SRC / "solve").rglob("*.rs"))}
    crate = sum(non_test_lines(p) for p in SRC.rglob("*.rs"))
    print("| file | lines outside tests |\n|---|---|")
    for name, n in solve.items():
        print(f"| {name} | {n} |")
    totals = {"solve/": sum(solve.values()), "core crate": crate}
    print()
    print("| part | lines outside tests | budget |\n|---|---|---|")
    for part, n in totals.items():
        print(f"| {part} | {n:,} | {BUDGET[part]:,} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
