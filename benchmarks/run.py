"""`make bench`: every benchmark in this directory, one after another.

Each script prints its own Markdown table; they are separate so that one can be run alone
(`python benchmarks/solve.py --help`).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
SUITES = ["solve.py", "ratios.py", "ablation.py", "strands.py", "grid_independence.py", "honesty.py", "scene.py", "methods.py", "pipeline.py", "track.py"]


def main() -> int:
    failed = []
    for name in SUITES:
        script = HERE / name
        if not script.exists():
            continue
        print(f"\n# benchmarks/{name}\n", flush=True)
        if subprocess.run([sys.executable, str(script), *sys.argv[1:]]).returncode != 0:
            failed.append(name)
    if failed:
        print(f"failed: {', '.join(failed)}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
