"""Acceptance: a writer killed (SIGKILL) at random moments loses no trial whose command returned and never corrupts
the file; two writers at once (a CLI-like and a TUI-like process) lose nothing and never see "database is locked".
The full versions (100 kills, 60 s) are bench/bench_trials.py."""

from __future__ import annotations

from bench.trial_crash import crash_test, two_writers


def test_killed_writers_lose_no_committed_trial(tmp_path):
    path = tmp_path / "crash.sqlite3"
    figures = crash_test(path, kills=8, seed=20)
    assert figures["returned"] >= 8  # every run logged at least one trial before its kill
    assert figures["missing"] == []
    assert figures["integrity"] == "ok"
    assert figures["foreign_key_problems"] == 0
    assert figures["incomplete"] == 0  # a trial is never stored without all its events
    assert figures["trials"] >= figures["returned"]  # (a trial committed just before the kill may be unprinted)


def test_a_cli_and_a_tui_writer_at_once_lose_nothing(tmp_path):
    path = tmp_path / "two.sqlite3"
    figures = two_writers(str(path), seconds=3.0, sqlite_path=path)
    assert figures["errors"] == [] and figures["exit_codes"] == [0, 0]
    assert figures["cli_trials"] > 5 and figures["tui_trials"] > 5
    assert figures["overlap"] == 0 and figures["missing"] == []
    assert figures["trials"] == figures["cli_trials"] + figures["tui_trials"]
    assert figures["integrity"] == "ok" and figures["incomplete"] == 0
