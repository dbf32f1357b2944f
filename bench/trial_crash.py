"""Crash and concurrency tests of the trial log, shared by tests/station/test_trial_crash.py (fast) and
bench/bench_trials.py (full): writer processes log trials through the service in a loop and print each trial's id
once :meth:`TrialStore.add` has returned (committed); the tests kill them with SIGKILL at random moments, or run two
at once, and then look in the database.

Run a writer by hand: ``python -m bench.trial_crash URL cli|tui SECONDS SEED``.
"""

from __future__ import annotations

import os
import random
import select
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

from common.progress import Reporter

ROOT = Path(__file__).resolve().parents[1]


def writer(url: str, style: str, seconds: float, seed: int) -> None:
    """Log trials of SIMPLE with random outcomes for ``seconds``, printing each id after its commit.

    ``style="cli"`` opens the database for every trial (as one ``station trial log`` per run); ``"tui"`` keeps one
    connection and lists the log between writes (as the Trials screen does).
    """
    from station.services.trials import build_trial, layout_values, load_trial_scenario
    from station.triallog import TrialStore

    rng = random.Random(seed)
    scenario = load_trial_scenario("simple")
    layout = layout_values(scenario, scenario.layout("success"))
    events = scenario.graph_order
    store = TrialStore(url) if style == "tui" else None
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        stop = rng.randrange(len(events) + 1)  # the first event that did not happen (len: all happened)
        outcomes = {events[stop]: "no"} if stop < len(events) else {events[-1]: "yes"}
        record = build_trial(scenario, layout, outcomes, who=f"{style}-{seed}",
                             times={e: 0.3 * i for i, e in enumerate(events[:stop])})
        if store is None:
            with TrialStore(url) as once:
                trial_id = once.add(record)
        else:
            trial_id = store.add(record)
        os.write(1, f"{trial_id}\n".encode())  # one write: a line reaches the pipe whole or not at all
        if store is not None:
            store.trials(limit=20)  # the screen lists the log after logging
    if store is not None:
        store.close()


def _start(url: str, style: str, seconds: float, seed: int) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.Popen([sys.executable, "-m", "bench.trial_crash", url, style, str(seconds), str(seed)],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)


def _ids(raw: bytes) -> list[int]:
    """The ids of the complete lines a writer printed."""
    return [int(line) for line in raw.decode().split("\n")[:-1] if line.strip()]


def check_database(path: str | Path, returned: set[int]) -> dict:
    """What the file holds: integrity, trials, trials missing among ``returned``, trials without every event."""
    connection = sqlite3.connect(path)
    try:
        integrity = connection.execute("PRAGMA integrity_check").fetchone()[0]
        foreign = connection.execute("PRAGMA foreign_key_check").fetchall()
        stored = {row[0] for row in connection.execute("SELECT id FROM trials")}
        incomplete = connection.execute(
            "SELECT count(*) FROM trials t WHERE (SELECT count(*) FROM trial_events e WHERE e.trial_id = t.id) "
            "<> 5").fetchone()[0]
    finally:
        connection.close()
    return {"integrity": integrity, "foreign_key_problems": len(foreign), "trials": len(stored),
            "missing": sorted(returned - stored), "incomplete": incomplete}


def crash_test(path: str | Path, kills: int, seed: int = 0, report: Reporter | None = None) -> dict:
    """Kill a writer with SIGKILL ``kills`` times, each at a random moment (0-300 ms) after it logged its first
    trial of that run (the first runs also create and migrate the file); every id it printed must be stored.
    ``report`` hears of each kill (stage ``"kills"``) and may stop between two."""
    report = Reporter.of(report)
    rng = random.Random(seed)
    returned: set[int] = set()
    for number in range(kills):
        process = _start(str(path), "cli" if number % 2 else "tui", 60.0, seed * 1000 + number)
        raw = b""
        deadline = time.monotonic() + 60
        while b"\n" not in raw and time.monotonic() < deadline:  # until its first trial is committed
            ready, _, _ = select.select([process.stdout], [], [], 1.0)
            if ready:
                chunk = os.read(process.stdout.fileno(), 4096)
                if not chunk:
                    break
                raw += chunk
        time.sleep(rng.uniform(0.0, 0.3))
        process.send_signal(signal.SIGKILL)
        out, err = process.communicate()
        raw += out
        if b"\n" not in raw:
            raise RuntimeError(f"writer {number} logged nothing: {err.decode()[-500:]}")
        returned.update(_ids(raw))
        report("kills", number + 1, kills, f"writer {number + 1} of {kills} killed")
    return {"kills": kills, "returned": len(returned), **check_database(path, returned)}


def two_writers(url: str, seconds: float, sqlite_path: str | Path | None = None) -> dict:
    """A CLI-like and a TUI-like writer at once for ``seconds``: both must end normally, every printed id stored,
    no error (no "database is locked")."""
    processes = [_start(url, "cli", seconds, 1), _start(url, "tui", seconds, 2)]
    results = [p.communicate(timeout=seconds + 120) for p in processes]
    errors = [err.decode().strip() for _, err in results if err.strip()]
    ids = [set(_ids(out)) for out, _ in results]
    figures = {"cli_trials": len(ids[0]), "tui_trials": len(ids[1]), "exit_codes": [p.returncode for p in processes],
               "errors": errors, "overlap": len(ids[0] & ids[1])}
    if sqlite_path is not None:
        figures.update(check_database(sqlite_path, ids[0] | ids[1]))
    return figures


if __name__ == "__main__":
    writer(sys.argv[1], sys.argv[2], float(sys.argv[3]), int(sys.argv[4]))
