"""Schema migrations of the station database: an older database is upgraded in place, its rows kept; writes that
find it busy are tried again, a mistake is not."""

from __future__ import annotations

import sqlite3

import pytest

import station.db as db
from station.db import MIGRATIONS, Database, DatabaseBusy, DatabaseError, open_database, schema_version

#: The trial log's tables (migration 3; sqlite_sequence is SQLite's own, for AUTOINCREMENT ids).
TRIAL_TABLES = {"scenarios", "trials", "trial_events", "sqlite_sequence"}
#: The station loop's tables (migration 4).
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


def test_a_write_is_tried_again_only_while_the_database_is_busy(tmp_path, monkeypatch):
    monkeypatch.setattr(db, "BUSY_SECONDS", 0.05)
    monkeypatch.setattr(db, "WRITE_PATIENCE_SECONDS", 0.3)
    monkeypatch.setattr(db, "RETRY_FIRST_PAUSE", 0.05)
    path = tmp_path / "t.sqlite3"
    with Database(str(path)) as database:
        holder = sqlite3.connect(path, isolation_level=None)
        holder.execute("BEGIN IMMEDIATE")
        calls = []

        def work(tx):
            calls.append(1)
            tx.execute("INSERT INTO jobs (kind) VALUES ('x')")

        # another writer keeps it past the patience: one line naming the database, the time and the attempts
        with pytest.raises(DatabaseBusy, match=rf"^database '{path}': still busy after \d+ s and [2-9]\d* attempts "
                           r"\(another station process is writing to it\)$"):
            database.write(work)
        assert calls == []  # no attempt got the write lock: the work never ran
        holder.execute("ROLLBACK")
        # a mistake is not busy: raised at once, the transaction rolled back, not tried again
        with pytest.raises(DatabaseError, match=r"no such table: nowhere") as caught:
            database.write(lambda tx: (calls.append(1), tx.execute("INSERT INTO nowhere VALUES (1)")))
        assert not isinstance(caught.value, DatabaseBusy) and calls == [1]
        database.write(work)
        with database.transaction(write=False) as tx:
            assert tx.one("SELECT count(*) FROM jobs") == (1,)  # the failed ones left nothing
        holder.close()


def test_a_commit_refused_by_a_busy_database_is_rolled_back(tmp_path, monkeypatch):
    # a COMMIT SQLite finds busy leaves the transaction open: the next one must not start inside it
    path = tmp_path / "t.sqlite3"
    with Database(str(path)) as database:
        real = database._run

        def busy_commit(sql, params=()):
            if sql == "COMMIT":
                raise DatabaseBusy(f"database {str(path)!r}: still busy", str(path))
            return real(sql, params)

        monkeypatch.setattr(database, "_run", busy_commit)
        with pytest.raises(DatabaseBusy):
            with database.transaction() as tx:
                tx.execute("INSERT INTO jobs (kind) VALUES ('x')")
        monkeypatch.setattr(database, "_run", real)
        assert not database._connection.in_transaction
        with database.transaction() as tx:
            tx.execute("INSERT INTO jobs (kind) VALUES ('y')")
        with database.transaction(write=False) as tx:
            assert tx.all("SELECT kind FROM jobs") == [("y",)]
