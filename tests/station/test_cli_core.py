from __future__ import annotations

from pathlib import Path

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


def test_sigterm_raises_keyboard_interrupt_in_a_command_and_is_restored(monkeypatch, capsys):
    # While a command runs, SIGTERM is turned into KeyboardInterrupt (so that `kill PID` runs every command's Ctrl-C
    # clean-up); main exits 130 and gives whoever called it their own handler back.
    import signal

    import station.commands.robust as robust

    during = []

    def interrupted(args):
        during.append(signal.getsignal(signal.SIGTERM))
        raise KeyboardInterrupt

    monkeypatch.setattr(robust, "run_optimize", interrupted)
    before = signal.getsignal(signal.SIGTERM)
    assert cli.main(["optimize", "simple", "--out", "x.json"]) == 130
    assert "interrupted" in capsys.readouterr().err
    assert during and during[0] is not before
    with pytest.raises(KeyboardInterrupt):
        during[0](signal.SIGTERM, None)
    assert signal.getsignal(signal.SIGTERM) == before


def wait_for(condition, limit: float, what: str, poll: float = 0.05):
    """Poll ``condition`` until it returns a true value (returned); fail naming ``what`` after ``limit`` seconds.

    The limit only bounds a hung test; nothing is asserted about how long the wait took.
    """
    import time

    deadline = time.monotonic() + limit
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            pytest.fail(f"gave up waiting for {what}")
        time.sleep(poll)


def test_sigterm_during_optimize_stops_the_workers_and_keeps_the_cache(tmp_path):
    # A real `station optimize` with two worker processes, killed with SIGTERM while its simulations run. The clean-up
    # it promises: the worker pool is stopped (no worker outlives the command: they are gone the moment the command
    # has exited, before the orphan watchdog of design/robust/executor.py could end them), the cache keeps every
    # finished simulation (as many rows as the message says, readable), no layout is written, exit 130, no traceback.
    import os
    import signal
    import sqlite3
    import subprocess
    import sys

    import psutil  # a dependency of dask's distributed, which the robust commands use

    home = tmp_path / "home"
    out = tmp_path / "layout.json"
    cache = home / "cache" / "robust-simulations.sqlite3"
    env = dict(os.environ, CHAOS_STATION_HOME=str(home))
    command = [sys.executable, "-m", "station", "optimize", "examples/scenarios/simple.toml", "--budget", "400",
               "--workers", "2", "--seed", "0", "--out", str(out)]
    root = Path(__file__).resolve().parents[2]
    station = subprocess.Popen(command, cwd=root, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    process = psutil.Process(station.pid)
    everyone: list[psutil.Process] = []
    try:
        def cached_rows() -> int:
            if not cache.exists():
                return 0
            try:
                with sqlite3.connect(cache, timeout=5) as db:
                    return db.execute("SELECT COUNT(*) FROM simulations").fetchone()[0]
            except sqlite3.OperationalError:  # created but its table not yet
                return 0

        # Simulations are running (some finished) when the signal comes; the limit is generous for a loaded machine.
        wait_for(lambda: cached_rows() > 0 or station.poll() is not None, 300, "the first cached simulation")
        assert station.poll() is None, "optimize ended before it could be interrupted: " + station.stderr.read()
        everyone = process.children(recursive=True)
        # Pool workers: with forkserver they are the forkserver's children, with spawn the command's own children
        # (the forkserver and multiprocessing's resource tracker are helpers, not workers).
        helper_marks = ("multiprocessing.forkserver import main", "multiprocessing.resource_tracker import main")
        helpers = [p for p in everyone
                   if p.ppid() == station.pid and any(mark in " ".join(p.cmdline()) for mark in helper_marks)]
        workers = [p for p in everyone if p not in helpers]
        assert len(workers) == 2, [p.cmdline() for p in everyone]
        station.send_signal(signal.SIGTERM)
        # The command has exited once it is a zombie; it stays one (its status unread) until communicate() below.
        wait_for(lambda: process.status() == psutil.STATUS_ZOMBIE, 120, "optimize to exit after SIGTERM")
        alive = [p.pid for p in workers if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
        assert not alive, f"worker processes {alive} outlived the interrupted command"
        stdout, stderr = station.communicate(timeout=60)
    finally:
        if station.poll() is None:
            station.kill()
            station.communicate()
    assert station.returncode == 130, stderr
    assert "Traceback" not in stderr and "Error" not in stderr, stderr
    assert stderr.rstrip().endswith("station: interrupted"), stderr
    kept = [line for line in stderr.splitlines() if "new simulations of this run are kept in the cache" in line]
    assert len(kept) == 1 and str(cache) in kept[0], stderr
    reported = int(kept[0].split("the ", 1)[1].split()[0])
    assert reported > 0
    with sqlite3.connect(cache) as db:
        assert db.execute("PRAGMA integrity_check").fetchone() == ("ok",)
        assert db.execute("SELECT COUNT(*) FROM simulations").fetchone()[0] == reported
    assert not out.exists()
    # The helpers end too, once the command has gone (they read its end of a pipe).
    wait_for(lambda: not [p for p in everyone if p.is_running() and p.status() != psutil.STATUS_ZOMBIE], 60,
             "the multiprocessing helpers to end")
