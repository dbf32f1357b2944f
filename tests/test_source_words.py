"""Code and help say what is and why, not the story of how it came to be: no tracker numbers in the source or in
the command line's help texts (a reader cannot follow them, and they outlive what they pointed at)."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from station.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
#: Where the station's code, benchmarks and tests live.
SOURCE_FOLDERS = ("common", "design", "drivers", "calibration", "projector", "vision", "cam", "station", "bench",
                  "tests")
#: A tracker's reference: "issue 18", "issues 19 and 20", "issue #7", "(issue" (written in pieces, so that this file
#: does not hold what it looks for).
TRACKER = re.compile(r"\bissues? ?#?[0-9]+|\(" + "issue\\b", re.IGNORECASE)


def tracker_references(text: str) -> list[str]:
    """The tracker references in ``text``, as found."""
    return [match.group(0) for match in TRACKER.finditer(text)]


def help_texts(parser: argparse.ArgumentParser, prog: str = "") -> list[tuple[str, str]]:
    """Every text ``--help`` shows, as ``(where, text)``: each parser's description and epilog, each option's help,
    each subcommand's summary and its own parser's texts, recursively."""
    where = prog or parser.prog
    texts = [(where, parser.description or ""), (where, parser.epilog or "")]
    for action in parser._actions:
        texts.append((f"{where} {'/'.join(action.option_strings) or action.dest}", action.help or ""))
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                texts.append((f"{where} {choice.dest}", choice.help or ""))
            for name, sub in action.choices.items():
                texts.extend(help_texts(sub, f"{where} {name}"))
    return texts


def test_no_tracker_numbers_in_the_source():
    offenders = []
    for folder in SOURCE_FOLDERS:
        for path in sorted((ROOT / folder).rglob("*.py")):
            if path == Path(__file__).resolve():
                continue  # its examples below
            for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
                if tracker_references(line):
                    offenders.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not offenders, "\n".join(offenders)


def test_no_tracker_numbers_in_the_help():
    texts = help_texts(build_parser())
    assert len(texts) > 100 and any(where.startswith("station tolerances") for where, _ in texts)
    offenders = [f"{where}: {text}" for where, text in texts if tracker_references(text)]
    assert not offenders, "\n".join(offenders)


def test_the_scans_see_a_tracker_number():
    # The tests above must be able to fail: the forms a reference takes are found, ordinary words are not.
    assert tracker_references("the map (issue 18) and Issues 19, 20; issue #7") == ["(issue", "Issues 19", "issue #7"]
    assert tracker_references("an issue of the magazine, 18 issues, tissue 3") == []
    parser = argparse.ArgumentParser(prog="station")
    commands = parser.add_subparsers()
    command = commands.add_parser("tolerances", help="the tolerance map", description="how far (issue 18)")
    command.add_argument("--verify", help="simulate N layouts, as issue 20 asked")
    found = [where for where, text in help_texts(parser) if tracker_references(text)]
    assert found == ["station tolerances", "station tolerances --verify"]
