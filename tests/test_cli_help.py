"""`--help` works for every command, shows an example, and every example parses."""

from __future__ import annotations

import re
import shlex

import pytest

from inkwarp.cli import COMMANDS, build_parser, main


def help_text(capsys, *command):
    with pytest.raises(SystemExit) as stop:
        main([*command, "--help"])
    assert stop.value.code == 0
    return capsys.readouterr().out


def example_commands(text):
    """The `inkwarp ...` lines under "examples:", without their trailing notes."""
    block = text.split("examples:\n", 1)[1]
    lines = []
    for line in block.splitlines():
        if not line.startswith("  inkwarp"):
            continue
        lines.append(re.split(r"\s{2,}", line.strip())[0])  # notes follow two spaces
    return lines


@pytest.mark.parametrize("command", [[], *[[name] for name in COMMANDS]],
                         ids=["inkwarp", *COMMANDS])
def test_help_shows_usage_and_examples_that_parse(capsys, command):
    text = help_text(capsys, *command)
    assert text.startswith(f"usage: {' '.join(['inkwarp', *command])}")
    examples = example_commands(text)
    assert examples, "every --help shows at least one example"
    for example in examples:
        argv = shlex.split(example)[1:]
        if command:
            assert argv[0] == command[0], example
        args = build_parser().parse_args(argv)
        assert callable(args.func), example


def test_every_command_is_listed_in_the_top_level_help(capsys):
    text = help_text(capsys)
    for name in COMMANDS:
        assert re.search(rf"^\s+{name}\s+\S", text, re.M), name
