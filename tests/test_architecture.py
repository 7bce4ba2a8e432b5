"""The engine crate stays pure: no Python or browser binding code in its dependency tree."""

import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_core_depends_on_no_binding_crate():
    tree = subprocess.run(
        ["cargo", "tree", "-p", "inkwarp-core", "-e", "normal", "--prefix", "none",
         "--target", "all"],
        cwd=ROOT, check=True, capture_output=True, text=True).stdout
    crates = {line.split()[0] for line in tree.splitlines() if line.strip()}
    assert "inkwarp-core" in crates
    for binding in ("pyo3", "numpy", "wasm-bindgen", "js-sys", "web-sys"):
        assert binding not in crates, f"inkwarp-core must not depend on {binding}"

