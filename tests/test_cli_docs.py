"""The docs that show the command line are true: docs/reference/cli.md matches `--help`, and
the commands and code in README.md and the first-animation guide run.

`INKWARP_UPDATE_DOCS=1 pytest tests/test_cli_docs.py` rewrites the generated part of
docs/reference/cli.md from the parser.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
from pathlib import Path

import numpy as np
import pytest

from inkwarp.cli import COMMANDS, build_parser, main

ROOT = Path(__file__).resolve().parents[1]
CLI_MD = ROOT / "docs" / "reference" / "cli.md"
BEGIN = "<!-- generated from --help by tests/test_cli_docs.py: begin -->"
END = "<!-- generated: end -->"
HELP_COLUMNS = "88"


def help_of(command: str | None) -> str:
    parser = build_parser()
    if command is None:
        return parser.format_help()
    sub = next(a for a in parser._actions if a.dest == "command")  # the subparsers action
    return sub.choices[command].format_help()


def generated_reference() -> str:
    parts = [BEGIN, ""]
    for command in [None, *COMMANDS]:
        title = "inkwarp" if command is None else f"inkwarp {command}"
        parts += [f"## `{title}`", "", "```text", help_of(command).rstrip(), "```", ""]
    parts.append(END)
    return "\n".join(parts)


def _normal(text: str) -> str:
    """Help text with what differs between Python versions made the same: "options" vs
    "optional arguments", and "-o OUT, --output OUT" vs "-o, --output OUT"."""
    text = text.replace("optional arguments:", "options:")
    text = re.sub(r"(-\w) ([A-Z:]+), (--[\w-]+) \2", r"\1, \3 \2", text)
    return " ".join(text.split())


def test_cli_reference_matches_the_help(monkeypatch):
    monkeypatch.setenv("COLUMNS", HELP_COLUMNS)
    expected = generated_reference()
    text = CLI_MD.read_text()
    assert BEGIN in text and END in text
    start, end = text.index(BEGIN), text.index(END) + len(END)
    if os.environ.get("INKWARP_UPDATE_DOCS"):
        text = text[:start] + expected + text[end:]
        CLI_MD.write_text(text)
        start, end = text.index(BEGIN), text.index(END) + len(END)
    assert _normal(text[start:end]) == _normal(expected), (
        "docs/reference/cli.md is stale: run INKWARP_UPDATE_DOCS=1 pytest "
        "tests/test_cli_docs.py")


# --- the docs' commands and code run ---------------------------------------------------------

#: Animations rendered by the docs' commands and code are cut to this many frames here, to
#: keep the suite fast; `make demo` renders the examples in full.
SHORT = 3

RUNNABLE_DOCS = [ROOT / "README.md", ROOT / "docs" / "guides" / "first-animation.md",
                 ROOT / "docs" / "guides" / "psd-and-svg.md"]
FENCE = re.compile(r"(?:<!-- file: (?P<file>\S+) -->\n)?```(?P<lang>\w*)\n(?P<body>.*?)```",
                   re.S)


def doc_blocks(path: Path):
    """(language, body, file) of every fenced block; ``file`` is set when the block is
    preceded by ``<!-- file: NAME -->`` (its text is that file's content)."""
    return [(m["lang"], m["body"], m["file"]) for m in FENCE.finditer(path.read_text())]


def run_shell_line(line: str, cwd: Path) -> None:
    words = shlex.split(line, comments=True)
    if not words:
        return
    if words[0] == "make":  # `make demo` and `make test` are what CI runs itself
        return
    if words[0] == "inkwarp":
        if words[1] == "render" and "--frames" not in words and (
                "--sprite-sheet" in words or not any(w.endswith(".png") for w in words)):
            words += ["--frames", f":{SHORT}"]  # the first frames show the command works
        code = main(words[1:])
        assert code == 0, line
    elif words[:2] == ["mkdir", "-p"]:
        for name in words[2:]:
            (cwd / name).mkdir(parents=True, exist_ok=True)
    elif words[0] == "cp":
        shutil.copy(cwd / words[1], cwd / words[2])
    elif words[0] == "python":
        import runpy
        import sys

        saved = sys.argv
        sys.argv = words[1:]
        try:
            runpy.run_path(str(cwd / words[1]), run_name="__main__")
        finally:
            sys.argv = saved
    else:
        pytest.fail(f"the docs use a command the test cannot run: {line}")


@pytest.mark.parametrize("doc", RUNNABLE_DOCS, ids=[p.name for p in RUNNABLE_DOCS])
def test_the_docs_commands_and_code_run(doc, tmp_path, monkeypatch, capsys):
    """Every sh block line and python block, in order, in a copy of the examples."""
    import inkwarp

    shutil.copytree(ROOT / "examples", tmp_path / "examples")
    monkeypatch.chdir(tmp_path)
    full = inkwarp.Scene.frames

    def first_frames(self, start=0, stop=None, **kw):
        stop = min(self.frame_count if stop is None else stop, start + SHORT)
        return full(self, start, stop, **kw)

    monkeypatch.setattr(inkwarp.Scene, "frames", first_frames)
    namespace: dict = {}
    ran = 0
    for lang, body, file in doc_blocks(doc):
        if file:
            (tmp_path / file).parent.mkdir(parents=True, exist_ok=True)
            (tmp_path / file).write_text(body)
        elif lang in ("sh", "shell", "console"):
            for line in body.splitlines():
                run_shell_line(line.removeprefix("$ "), tmp_path)
                ran += 1
        elif lang == "python":
            exec(compile(body, f"{doc.name} block", "exec"), namespace)  # noqa: S102
            ran += 1
    capsys.readouterr()
    assert ran, f"{doc.name} has nothing to run"
    if doc.name == "psd-and-svg.md":
        # What the guide says its tracing does: the chin drops, the shoulders stay.
        scene = inkwarp.Scene.load(tmp_path / "character.json")
        body = scene.field(0.75, layer="body")
        head = scene.field(0.75, layer="head")
        assert np.abs(body[80:151, 60:141]).max() < 0.05, np.abs(body[80:151, 60:141]).max()
        assert abs(head[76, 100, 1] - 3.0) < 0.05 and abs(head[23, 100, 1]) < 1.0
