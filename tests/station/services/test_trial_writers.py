"""Several writers at once: `station trial log` processes logging and predicting while a slow writer holds the trial
log and the simulation cache; a database that stays busy longer than a writer waits; Ctrl-C while waiting. Nothing
the maker typed is ever lost, and no traceback is printed."""

from __future__ import annotations

import json
import os
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

import design.robust.executor as executor
import station.db as db
from station.paths import database_path
from station.services.robust import simulation_cache_path
from station.services.trials import (
    TrialKept,
    build_trial,
    import_trials,
    layout_values,
    load_trial_scenario,
    log_trial,
    pending_files,
)
from station.triallog import TrialStore

from ..conftest import log_json, run_cli

ROOT = Path(__file__).resolve().parents[3]

#: The slow writer: holds a write transaction on the trial log for a seeded while, and the simulation cache until
#: every other writer (their process ids come on stdin) has opened it to predict, and a while more: longer than a
#: cache write waited (5 s) before failing with "database is locked".
SLOW_WRITER = """
import random, sqlite3, sys, time
import psutil
trials_path, cache_path, seed = sys.argv[1], sys.argv[2], int(sys.argv[3])
rng = random.Random(seed)
trials = sqlite3.connect(trials_path, isolation_level=None, timeout=60)
cache = sqlite3.connect(cache_path, isolation_level=None, timeout=60)
trials.execute("BEGIN IMMEDIATE")
trials.execute("INSERT INTO jobs (kind, status) VALUES ('slow writer', 'running')")
cache.execute("BEGIN EXCLUSIVE")
print("held", flush=True)
writers = [psutil.Process(int(pid)) for pid in sys.stdin.readline().split()]
time.sleep(rng.uniform(0.5, 1.5))
trials.execute("COMMIT")


def waiting(process):
    try:
        return any(f.path == cache_path for f in process.open_files())
    except psutil.Error:  # ended
        return True


while not all(waiting(p) for p in writers):
    time.sleep(0.05)
time.sleep(rng.uniform(5.5, 6.0))
cache.execute("COMMIT")
print("released", flush=True)
"""


def _record(**changes):
    scenario = load_trial_scenario("simple")
    record = build_trial(scenario, layout_values(scenario, scenario.layout("success")), {"last_stops": "yes"},
                         who="ann", notes="the run that must not be lost", times={"last_stops": 2.5})
    return {**record, **changes}


def _hold(path) -> sqlite3.Connection:
    """Another process's write transaction, as far as SQLite's locks go (a connection of its own)."""
    holder = sqlite3.connect(path, isolation_level=None)
    holder.execute("BEGIN IMMEDIATE")
    return holder


@pytest.fixture
def impatient(monkeypatch):
    """A database that gives up quickly: what a slow writer's minutes look like, in a fraction of a second."""
    monkeypatch.setattr(db, "BUSY_SECONDS", 0.05)
    monkeypatch.setattr(db, "WRITE_PATIENCE_SECONDS", 0.4)
    monkeypatch.setattr(db, "RETRY_FIRST_PAUSE", 0.05)


@pytest.mark.slow  # ~18 s on 2 cores: three writers and their predictions wait out a slow one
def test_writers_at_once_with_a_slow_one_all_log_and_predict(capsys):
    # the trial log and the simulation cache exist (a first logged and predicted trial)
    code, _, err = run_cli(capsys, "trial", "log", "simple", "success", "--outcome", "last_stops=yes",
                           "--predict", "2")
    assert code == 0, err
    writers = 3
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    slow = subprocess.Popen([sys.executable, "-c", SLOW_WRITER, str(database_path()),
                             str(simulation_cache_path().resolve()), "37"],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert slow.stdout.readline() == "held\n"
        started = [subprocess.Popen(
            [sys.executable, "-m", "station", "trial", "log", "simple", "success", "--outcome", "last_stops=yes",
             "--who", f"writer-{i}", "--predict", "2"],
            env=env, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for i in range(writers)]
        slow.stdin.write(" ".join(str(p.pid) for p in started) + "\n")
        slow.stdin.flush()
        results = [process.communicate(timeout=300) for process in started]
        assert slow.communicate(timeout=60)[0] == "released\n" and slow.returncode == 0
    finally:
        slow.kill()
    for process, (out, err) in zip(started, results):
        assert process.returncode == 0 and "Traceback" not in err and "locked" not in err, err
        trial_id = int(out.splitlines()[0])
        assert f"trial {trial_id}: physical success on the table" in err  # predicted, after waiting for the cache
    ids = sorted(int(out.splitlines()[0]) for out, _ in results)
    assert len(set(ids)) == writers
    with TrialStore() as store:
        logged = {t["id"]: t["who"] for t in store.trials()}
    assert sorted(logged.values(), key=str) == [None, *sorted(f"writer-{i}" for i in range(writers))]
    assert set(ids) < set(logged)
    assert pending_files() == []


def test_a_prediction_the_busy_simulation_cache_stops_says_so_and_the_trial_stays_logged(capsys, monkeypatch):
    code, _, err = run_cli(capsys, "trial", "log", "simple", "success", "--outcome", "last_stops=yes",
                           "--predict", "2")
    assert code == 0, err
    monkeypatch.setattr(executor, "CACHE_BUSY_SECONDS", 0.1)  # past the other writer's patience, at once
    holder = sqlite3.connect(simulation_cache_path(), isolation_level=None)
    holder.execute("BEGIN EXCLUSIVE")
    try:
        code, out, err = run_cli(capsys, "trial", "log", "simple", "success", "--outcome", "last_stops=yes",
                                 "--predict", "2")
    finally:
        holder.execute("ROLLBACK")
        holder.close()
    assert code == 0 and out == "2\n" and "Traceback" not in err
    assert err.strip().splitlines()[-1] == "no prediction: the simulation cache: database is locked"
    with TrialStore() as store:
        assert store.count() == 2


def test_a_write_finding_the_database_busy_is_tried_again(impatient, station_home):
    with TrialStore() as store:  # made and migrated
        pass
    holder = _hold(database_path())
    waits = []

    def release(message):  # the other writer commits while this one pauses before its next attempt
        waits.append(message)
        holder.execute("COMMIT")

    with TrialStore() as store:
        trial_id = store.add(_record(), on_wait=release)
        assert store.get(trial_id)["notes"] == "the run that must not be lost"
    assert len(waits) == 1 and "is busy (another station process is writing to it); trying again" in waits[0]
    holder.close()


def test_a_database_busy_for_longer_than_a_writer_waits_keeps_the_trial_for_the_next_run(impatient, tmp_path,
                                                                                         capsys):
    log_json(capsys, "simple", "success", "--outcome", "last_stops=yes")
    photo = tmp_path / "run.jpg"
    photo.write_bytes(b"\xff\xd8")
    holder = _hold(database_path())
    code, out, err = run_cli(capsys, "trial", "log", "simple", "success", "--outcome", "ball_hits_domino=no",
                             "--who", "ann", "--notes", "wobbly start", "--photo", str(photo), "--predict", "0")
    assert code == 2 and out == "" and "Traceback" not in err
    lines = err.strip().splitlines()
    (kept,) = pending_files()
    assert lines[-1] == (f"station: error: database '{database_path()}': still busy after 0 s and "
                         f"{lines[-1].split(' and ')[1].split()[0]} attempts (another station process is writing to "
                         f"it); the trial is kept in {kept}: the next `station trial log` logs it first (or "
                         f"`station trial import {kept}`)")
    assert sum("error:" in line for line in lines) == 1
    # what the maker typed is in the file, as a trial export
    document = json.loads(kept.read_text())
    assert document["format"] == "chaos-station trials" and document["database"] == str(database_path())
    (trial,) = document["trials"]
    assert (trial["who"], trial["notes"], trial["photos"]) == ("ann", "wobbly start", [str(photo.resolve())])
    assert trial["outcomes"]["ball_hits_domino"] == "no" and trial["success"] is False
    code, _, err = run_cli(capsys, "trial", "list")
    assert code == 0 and f"1 trial(s) kept in {kept.parent} wait to be logged" in err

    holder.execute("ROLLBACK")  # the other writer is done
    code, out, err = run_cli(capsys, "trial", "log", "simple", "success", "--outcome", "last_stops=yes",
                             "--predict", "0")
    assert code == 0 and out == "3\n"
    assert "also logged 1 trial(s) kept by an earlier run (ids 2)" in err
    assert pending_files() == []
    code, out, _ = run_cli(capsys, "trial", "list", "--json")
    listed = json.loads(out)
    assert [t["uid"] for t in listed][1] == trial["uid"]
    assert [(t["who"], t["notes"]) for t in listed] == [(None, None), ("ann", "wobbly start"), (None, None)]

    # kept again, then imported by hand: the next run does not add it twice
    holder.execute("BEGIN IMMEDIATE")
    code, _, err = run_cli(capsys, "trial", "log", "simple", "success", "--outcome", "last_stops=yes",
                           "--predict", "0", "--notes", "by hand")
    assert code == 2
    holder.execute("ROLLBACK")
    (kept,) = pending_files()
    code, out, _ = run_cli(capsys, "trial", "import", str(kept), "--json")
    assert code == 0 and json.loads(out)["added"] == [4]
    code, out, err = run_cli(capsys, "trial", "log", "simple", "success", "--outcome", "last_stops=yes",
                             "--predict", "0")
    assert code == 0 and out == "5\n" and "also logged" not in err and pending_files() == []
    holder.close()


def test_ctrl_c_while_waiting_keeps_the_trial(impatient, capsys, monkeypatch):
    log_json(capsys, "simple", "success", "--outcome", "last_stops=yes")
    holder = _hold(database_path())

    class Interrupted:
        """The database module's clock, whose pause is a Ctrl-C (only there: other threads keep time.sleep)."""

        def __getattr__(self, name):
            return getattr(time, name)

        @staticmethod
        def sleep(seconds):
            raise KeyboardInterrupt

    with monkeypatch.context() as patched:
        patched.setattr(db, "time", Interrupted())  # Ctrl-C during the pause between two attempts
        code, out, err = run_cli(capsys, "trial", "log", "simple", "success", "--outcome", "last_stops=yes",
                                 "--notes", "stopped", "--predict", "0")
    assert code == 130 and out == ""
    (kept,) = pending_files()
    assert err.strip().splitlines()[-1] == (
        f"station: error: interrupted before the trial was logged; the trial is kept in {kept}: the next `station "
        f"trial log` logs it first (or `station trial import {kept}`)")
    assert json.loads(kept.read_text())["trials"][0]["notes"] == "stopped"
    holder.close()


def test_a_trial_that_cannot_even_be_kept_is_printed_for_import(impatient, station_home, tmp_path, monkeypatch):
    with TrialStore():
        pass
    holder = _hold(database_path())
    (station_home / "pending-trials").write_text("a file where the folder would be")
    with pytest.raises(TrialKept) as caught:
        log_trial(_record())
    assert caught.value.path is None
    assert "the trial could not be kept in a file either" in str(caught.value)
    assert "it is printed as JSON on stdout, save it and log it with `station trial import FILE`" in str(caught.value)
    holder.execute("ROLLBACK")
    saved = tmp_path / "saved.json"
    saved.write_text(json.dumps(caught.value.document))
    (station_home / "pending-trials").unlink()
    with TrialStore() as store:
        added, _ = import_trials(store, saved)
        assert store.get(added[0])["notes"] == "the run that must not be lost"
    holder.close()
