"""Schema migrations of the station database: an older database is upgraded in place, its rows kept."""

from __future__ import annotations

import sqlite3

from station.db import MIGRATIONS, open_database, schema_version

#: The trial log's tables (migration 3; sqlite_sequence is SQLite's own, for AUTOINCREMENT ids).
TRIAL_TABLES = {"scenarios", "trials", "trial_events", "sqlite_sequence"}
#: The station loop's tables (migration 4, issue 21).
LOOP_TABLES = {"loop_runs", "loop_loops", "loop_attempts", "optimized_layouts"}


def _tables(connection: sqlite3.Connection) -> set[str]:
    return {row[0] for row in connection.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}


def test_a_version_1_database_loses_the_unused_meta_table_and_keeps_its_jobs(tmp_path):
    path = tmp_path / "old.sqlite3"
    old = sqlite3.connect(path)
    with old:
        old.executescript(MIGRATIONS[0])
        old.execute("PRAGMA user_version = 1")
        old.execute("INSERT INTO jobs (kind, device, status) VALUES ('run', 'plotter', 'done')")
    old.close()
    upgraded = open_database(path)
    try:
        assert schema_version(upgraded) == len(MIGRATIONS) == 4
        assert _tables(upgraded) == {"jobs", *TRIAL_TABLES, *LOOP_TABLES}
        assert upgraded.execute("SELECT kind, device, status FROM jobs").fetchall() == [("run", "plotter", "done")]
    finally:
        upgraded.close()


def test_a_new_database_has_no_meta_table(tmp_path):
    connection = open_database(tmp_path / "new.sqlite3")
    try:
        assert _tables(connection) == {"jobs", *TRIAL_TABLES, *LOOP_TABLES}
    finally:
        connection.close()
