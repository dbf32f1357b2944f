from __future__ import annotations

import pytest

from station import cli
from station.cli_util import output_suffix, parse_assignments
from station.errors import UsageError


def test_help_lists_commands(capsys):
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["--help"])
    assert exit_info.value.code == 0
    assert "COMMAND" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("items", "expected"),
    [
        ([], {}),
        (["d=2.5"], {"d": 2.5}),
        (["r_f = 5", "e=0"], {"r_f": 5.0, "e": 0.0}),
    ],
)
def test_parse_assignments(items, expected):
    assert parse_assignments(items) == expected


@pytest.mark.parametrize(
    ("items", "message"),
    [
        (["d"], "expected NAME=VALUE"),
        (["=3"], "expected NAME=VALUE"),
        (["d=abc"], "must be a number"),
        (["d=nan"], "must be finite"),
        (["d=1", "d=2"], "given twice"),
    ],
)
def test_parse_assignments_errors(items, message):
    with pytest.raises(UsageError, match=message):
        parse_assignments(items)


def test_output_suffix():
    assert output_suffix("a/b.SVG", {".svg", ".png"}) == ".svg"
    with pytest.raises(UsageError, match="expected one of .png, .svg"):
        output_suffix("b.txt", {".svg", ".png"})


def test_user_errors_are_one_line_exit_2(monkeypatch, capsys):
    import argparse

    def boom(args):
        raise UsageError("thing: field 'x' must be 1, got 2")

    def fake_parser():
        parser = argparse.ArgumentParser(prog="station")
        sub = parser.add_subparsers(dest="command")
        sub.add_parser("boom").set_defaults(func=boom)
        return parser

    monkeypatch.setattr(cli, "build_parser", fake_parser)
    assert cli.main(["boom"]) == 2
    err = capsys.readouterr().err
    assert err == "station: error: thing: field 'x' must be 1, got 2\n"


def test_sigterm_stops_a_command_like_ctrl_c(monkeypatch, capsys):
    # `kill PID` must run the same clean-up as Ctrl-C (laser off, worker pool shut down), then exit 130.
    import os
    import signal
    import time

    import station.commands.robust as robust

    cleaned = []

    def killed_midway(args):
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)  # the handler interrupts this
        except KeyboardInterrupt:
            cleaned.append(True)
            raise
        return 0

    monkeypatch.setattr(robust, "run_optimize", killed_midway)
    before = signal.getsignal(signal.SIGTERM)
    started = time.monotonic()
    assert cli.main(["optimize", "simple", "--out", "x.json"]) == 130
    assert time.monotonic() - started < 4 and cleaned == [True]
    assert "interrupted" in capsys.readouterr().err
    assert signal.getsignal(signal.SIGTERM) == before  # restored for whoever called main
