"""The station's local SQLite database.

Schema migrations are a numbered list; opening a database applies the missing ones in a transaction, so a database
made by an older station is upgraded and never thrown away.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path

from station.errors import StationError

#: Each entry upgrades the schema by one version. Append; never edit a released migration.
MIGRATIONS: list[str] = [
    """
    CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
    CREATE TABLE jobs (
        id INTEGER PRIMARY KEY,
        kind TEXT NOT NULL,
        device TEXT,
        created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ', 'now')),
        finished_at TEXT,
        status TEXT NOT NULL DEFAULT 'created',
        detail TEXT
    );
    """,
    # 2: the meta table held nothing and nothing read it (the schema version is PRAGMA user_version).
    """
    DROP TABLE IF EXISTS meta;
    """,
]


def schema_version(connection: sqlite3.Connection) -> int:
    return int(connection.execute("PRAGMA user_version").fetchone()[0])


def open_database(path: str | Path) -> sqlite3.Connection:
    """Open (creating and migrating as needed) the station database at ``path``.

    Raises
    ------
    StationError
        If the file is not a SQLite database or was written by a newer station.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        connection = sqlite3.connect(path)
        connection.execute("PRAGMA foreign_keys = ON")
        version = schema_version(connection)
    except sqlite3.DatabaseError as error:
        raise StationError(f"database {str(path)!r}: not a SQLite database ({error})") from None
    if version > len(MIGRATIONS):
        connection.close()
        raise StationError(
            f"database {str(path)!r}: schema version {version} is newer than this station "
            f"(knows up to {len(MIGRATIONS)}); upgrade the station"
        )
    for number in range(version, len(MIGRATIONS)):
        with connection:
            connection.executescript(MIGRATIONS[number])
            connection.execute(f"PRAGMA user_version = {number + 1}")
    return connection
