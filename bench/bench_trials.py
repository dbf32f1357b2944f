"""The trial log under crashes and concurrency, and how fast it writes and reads.

Prints
- crash test: a writer process logging trials through the service (the first runs also create and migrate the
  file) killed with SIGKILL 100 times, each at a random moment (0-300 ms, seeded) after a commit of that run: the
  trials whose id it had printed (printed after the commit), how many of them are missing (goal 0), the
  integrity check (goal ok), foreign-key problems and trials without all their events (goal 0);
- two writers at once for 60 s on the SQLite file, a CLI-like process (opens the database for every trial) and a
  TUI-like one (one connection, lists the log after every write): trials each, errors (goal none: no "database is
  locked"), missing (goal 0);
- the same two writers for 20 s on a PostgreSQL server started here (pgserver), when it is installed;
- single-process figures: trials logged per second and the time to read 1000 trials back, SQLite and PostgreSQL.
"""

from __future__ import annotations

import shutil
import tempfile
import time
from pathlib import Path

from bench.trial_crash import crash_test, two_writers

KILLS = 100
SECONDS = 60.0
POSTGRES_SECONDS = 20.0


def _throughput(url: str, n: int = 300) -> tuple[float, float]:
    """(trials logged per second, seconds to read them all back), in one process."""
    from station.services.trials import build_trial, layout_values, load_trial_scenario
    from station.triallog import TrialStore

    scenario = load_trial_scenario("simple")
    layout = layout_values(scenario, scenario.layout("success"))
    records = [build_trial(scenario, layout, {"last_stops": "yes"}) for _ in range(n)]
    with TrialStore(url) as store:
        start = time.perf_counter()
        for record in records:
            store.add(record)
        rate = n / (time.perf_counter() - start)
        start = time.perf_counter()
        count = len(store.trials())
        read = time.perf_counter() - start
    return rate, read * 1000 / count


def _writers_line(where: str, seconds: float, figures: dict) -> str:
    return (f"two writers, {where}, {seconds:.0f} s: CLI-like {figures['cli_trials']} trials, TUI-like "
            f"{figures['tui_trials']} trials; exit codes {figures['exit_codes']}; errors {figures['errors'] or 'none'}")


def _postgres():
    try:
        import pgserver
        import psycopg
    except ImportError:
        return None, None, None
    folder = Path(tempfile.mkdtemp(prefix="bench-pg-"))
    start = time.perf_counter()
    server = pgserver.get_server(folder / "data", cleanup_mode="delete")
    started = time.perf_counter() - start
    with psycopg.connect(server.get_uri(), autocommit=True) as admin:
        for name in ("twowriters", "throughput"):
            admin.execute(f"CREATE DATABASE {name}")
    return server, started, folder


def main() -> None:
    with tempfile.TemporaryDirectory(prefix="bench-trials-") as folder:
        path = Path(folder) / "crash.sqlite3"
        start = time.perf_counter()
        figures = crash_test(path, KILLS, seed=20)
        print(f"crash test, SQLite: {figures['kills']} kills in {time.perf_counter() - start:.0f} s; "
              f"{figures['returned']} trials returned, {len(figures['missing'])} missing (goal 0), "
              f"{figures['trials']} stored; integrity_check {figures['integrity']!r}; foreign-key problems "
              f"{figures['foreign_key_problems']}; trials without all their events {figures['incomplete']}")

        path = Path(folder) / "two.sqlite3"
        figures = two_writers(str(path), SECONDS, sqlite_path=path)
        print(_writers_line("SQLite", SECONDS, figures) + f"; {len(figures['missing'])} missing (goal 0), "
              f"{figures['trials']} stored, integrity {figures['integrity']!r}")
        rate, read_ms = _throughput(str(Path(folder) / "throughput.sqlite3"))
        print(f"SQLite, one process: {rate:.0f} trials logged/s (each its own synchronous transaction), "
              f"{read_ms:.2f} ms per trial read back")

    server, started, pg_folder = _postgres()
    if server is None:
        print("PostgreSQL: pgserver or psycopg not installed; skipped")
        return
    try:
        print(f"PostgreSQL (pgserver) initialized and started in {started:.1f} s")
        figures = two_writers(server.get_uri(database="twowriters"), POSTGRES_SECONDS)
        print(_writers_line("PostgreSQL", POSTGRES_SECONDS, figures))
        rate, read_ms = _throughput(server.get_uri(database="throughput"))
        print(f"PostgreSQL, one process: {rate:.0f} trials logged/s, {read_ms:.2f} ms per trial read back")
    finally:
        server.cleanup()
        shutil.rmtree(pg_folder, ignore_errors=True)


if __name__ == "__main__":
    main()
