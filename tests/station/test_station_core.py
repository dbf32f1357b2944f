from __future__ import annotations

import sqlite3

import pytest

from station.db import MIGRATIONS, open_database, schema_version
from station.errors import StationError
from station.paths import database_path


def test_database_lives_in_station_home(station_home):
    assert database_path().parent == station_home


def test_open_database_migrates_and_reopens(tmp_path):
    path = tmp_path / "db.sqlite3"
    connection = open_database(path)
    assert schema_version(connection) == len(MIGRATIONS)
    connection.execute("INSERT INTO jobs (kind) VALUES ('plot')")
    connection.commit()
    connection.close()
    again = open_database(path)
    assert again.execute("SELECT kind FROM jobs").fetchall() == [("plot",)]


def test_open_database_refuses_garbage_and_newer(tmp_path):
    garbage = tmp_path / "garbage.sqlite3"
    garbage.write_bytes(b"not a database at all" * 100)
    with pytest.raises(StationError, match="not a SQLite database"):
        open_database(garbage)
    newer = tmp_path / "newer.sqlite3"
    sqlite3.connect(newer).execute(f"PRAGMA user_version = {len(MIGRATIONS) + 5}")
    with pytest.raises(StationError, match="newer than this station"):
        open_database(newer)
