"""The documented examples of the methods, compare and transfer modules and the
comparison page run, and the page's plates exist."""

import doctest
import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("module", ["inkwarp.methods", "inkwarp.compare", "inkwarp.transfer", "inkwarp.outputs"])
def test_docstring_examples_run(module):
    result = doctest.testmod(importlib.import_module(module))
    assert result.attempted > 0 and result.failed == 0


def test_the_comparison_page_runs():
    page = ROOT / "docs" / "concepts" / "comparison.md"
    result = doctest.testfile(str(page), module_relative=False)
    assert result.attempted > 0 and result.failed == 0
