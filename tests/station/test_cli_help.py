"""Every command's ``--help`` explains itself and shows a working example, and answering it loads no heavy library."""

from __future__ import annotations

import argparse
import shlex
import subprocess
import sys

import pytest

from station.cli import build_parser


def leaf_commands(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()):
    """(command words, parser) for every command that runs something (``scenario check``, not ``scenario``)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from leaf_commands(sub, (*path, name))
            return
    yield path, parser


COMMANDS = list(leaf_commands(build_parser()))
IDS = [" ".join(path) for path, _ in COMMANDS]


def examples_of(parser: argparse.ArgumentParser) -> list[str]:
    """The command lines of the epilog's ``example:`` / ``examples:`` part: those that start with ``station``, and
    shell lines that pipe into it (``printf 'y\\n' | station assemble ...``)."""
    epilog = parser.epilog or ""
    _, found, rest = epilog.partition("example")
    if not found:
        return []
    lines = []
    for line in rest.split("\n"):
        line = line.strip().removeprefix("s:").removeprefix(":").strip()
        if line.startswith("station ") or any(part.strip().startswith("station ") for part in line.split("|")[1:]):
            lines.append(line)
    return lines


def test_every_command_is_found():
    assert {"simulate", "scenario check", "optimize", "robustness", "compare", "send", "ports", "fabricate"} <= set(IDS)


@pytest.mark.parametrize(("path", "parser"), COMMANDS, ids=IDS)
def test_help_has_a_description_an_example_and_help_on_every_argument(path, parser):
    assert parser.description and len(parser.description) > 40, f"{' '.join(path)}: no description"
    assert examples_of(parser), f"{' '.join(path)}: no 'example: station ...' line in the epilog"
    undocumented = [
        "/".join(action.option_strings) or action.dest
        for action in parser._actions
        if not isinstance(action, argparse._HelpAction) and not action.help
    ]
    assert not undocumented, f"{' '.join(path)}: no help text for {undocumented}"


@pytest.mark.parametrize(("path", "parser"), COMMANDS, ids=IDS)
def test_examples_are_valid_command_lines(path, parser):
    # Each example parses as written (the shell's part after a pipe or && is another command).
    full = build_parser()
    for example in examples_of(parser):
        for part in example.replace("&&", "|").split("|"):
            words = shlex.split(part.split(">")[0])
            if not words or words[0] != "station":
                continue
            args = full.parse_args(words[1:])
            assert getattr(args, "func", None) is not None, example


def test_examples_keep_their_lines_in_the_help_text():
    # Several examples are several lines; argparse's default formatter would run them into one paragraph.
    text = build_parser()._subparsers._group_actions[0].choices["plot"].format_help()
    lines = [line.strip() for line in text.splitlines()]
    assert sum(line.startswith("station plot") or "station plot" in line[:30] for line in lines) >= 2


HEAVY = (
    "scipy", "pybullet", "sklearn", "shapely", "cv2", "PIL", "dask", "distributed", "textual", "reportlab",
    "pupil_apriltags", "design.contraption.simulation", "design.robust.pipeline", "design.robust.executor",
    "design.explore", "design.sketch.retrieval", "design.fabrication.gears", "design.fabrication.nesting",
)


def test_help_loads_no_heavy_library():
    # --help must answer at once: the parser is built from light modules; the work imports its libraries when run.
    code = (
        "import sys\nfrom station.cli import build_parser\nbuild_parser().format_help()\n"
        f"print(','.join(m for m in {HEAVY!r} if m in sys.modules))"
    )
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert loaded == "", f"building the parser imported {loaded}"


def command_groups(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()):
    """(command words, the group's line in its parent's command list, parser, its commands) for every command that
    has commands of its own (``calibrate``: board, camera, ...)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            lines = {choice.dest: choice.help or "" for choice in action._choices_actions}
            for name, sub in action.choices.items():
                inner = [a for a in sub._actions if isinstance(a, argparse._SubParsersAction)]
                if inner:
                    yield (*path, name), lines.get(name, ""), sub, list(inner[0].choices)
                yield from command_groups(sub, (*path, name))


GROUPS = list(command_groups(build_parser()))


@pytest.mark.parametrize(("path", "line", "parser", "commands"), GROUPS, ids=[" ".join(g[0]) for g in GROUPS])
def test_a_group_names_each_of_its_commands(path, line, parser, commands):
    # `station --help` lists the group in one line and `station GROUP --help` describes it: both name every command
    # (a command added to a group is not hidden behind an older summary).
    import re

    for where, text in (("station --help line", line), ("description", parser.description or "")):
        missing = [c for c in commands if not re.search(rf"\b{re.escape(c)}\b", text)]
        assert not missing, f"{' '.join(path)}: its {where} does not name {missing}: {text!r}"
