"""The station database: a local SQLite file, or one PostgreSQL database that several stations share.

Schema migrations are a numbered list; opening a database applies the missing ones in one transaction, so a
database made by an older station is upgraded and never thrown away, and two processes opening a new database at
once (the TUI and a CLI command) do not both migrate it: the first takes the write lock, the second waits, finds the
schema current and applies nothing. The schema version is ``PRAGMA user_version`` in SQLite and the one row of
``station_schema`` in PostgreSQL; version N means the same tables and columns in both
(tests/station/test_trial_postgres.py compares them).

SQLite is opened in WAL mode (readers never wait for a writer), with foreign keys on, a busy timeout of
:data:`BUSY_SECONDS` (a writer waits for another instead of failing with "database is locked") and
``synchronous = FULL`` (a committed transaction survives a power cut, not only a killed process). Every write is
one short ``BEGIN IMMEDIATE`` transaction (:meth:`Database.transaction`): it takes the write lock first, so it never
has to upgrade a read snapshot that another writer made stale (which SQLite refuses at once, busy timeout or not).

A writer that must not give up (a logged trial) goes through :meth:`Database.write`: the whole transaction is run
again, after a growing pause, while the database stays busy (SQLite still locked after its busy timeout; PostgreSQL's
serialization failures and deadlocks, which abort one of two transactions for the other's sake), for up to
:data:`WRITE_PATIENCE_SECONDS`. Every failure of the database is a :class:`DatabaseError` (:class:`DatabaseBusy`
when waiting longer could help), one line naming the database.

Where
-----
:func:`database_url`: ``CHAOS_STATION_DATABASE``, else ``[database] url`` in ``station.toml``, else the SQLite file
``station.sqlite3`` in the data folder. A URL is ``postgresql://USER:PASSWORD@HOST:PORT/DB`` (libpq's form;
``postgres://`` and SQLAlchemy's ``postgresql+psycopg://`` are accepted), ``sqlite:///PATH`` or a plain file path.
The machine-job history (:mod:`station.joblog`) stays in the local file whatever the URL says: it is about this
computer's machines and processes.
"""

from __future__ import annotations

import os
import sqlite3
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

from station.config import load_config
from station.db_url import parse_url, redact
from station.errors import StationError
from station.paths import database_path

#: The environment variable that names the station database (a URL or a SQLite file path).
DATABASE_VARIABLE = "CHAOS_STATION_DATABASE"

#: How long one statement waits for another process's write lock (SQLite's busy timeout, seconds): longer than the
#: slowest writer holds it (an import of thousands of trials, a migration) on a loaded machine.
BUSY_SECONDS = 30.0

#: How long :meth:`Database.write` keeps trying one transaction while the database stays busy (seconds, in all).
WRITE_PATIENCE_SECONDS = 120.0

#: The pauses between :meth:`Database.write`'s attempts: the first, and the longest as it doubles (seconds).
RETRY_FIRST_PAUSE, RETRY_LONGEST_PAUSE = 0.2, 5.0

#: PostgreSQL's codes for a transaction aborted for another's sake (serialization_failure, deadlock_detected,
#: lock_not_available): the same transaction run again succeeds.
_PG_RETRY_CODES = frozenset({"40001", "40P01", "55P03"})

T = TypeVar("T")


class DatabaseError(StationError):
    """The station database failed (cannot be opened, a lost server, a full disk, still busy): one line naming it.

    Attributes
    ----------
    where : str
        The database as messages name it (a SQLite file, or a PostgreSQL URL without its password).
    """

    def __init__(self, message: str, where: str = "") -> None:
        super().__init__(message)
        self.where = where


class DatabaseBusy(DatabaseError):
    """Another writer kept the database (SQLite still locked after :data:`BUSY_SECONDS`), or PostgreSQL aborted the
    transaction for another one's sake: the same transaction may succeed when tried again."""


def _is_busy(error: BaseException) -> bool:
    """Whether a driver error says "another writer is in the way" rather than "this cannot work"."""
    if isinstance(error, sqlite3.OperationalError):
        return "locked" in str(error) or "busy" in str(error)
    return getattr(error, "sqlstate", None) in _PG_RETRY_CODES

#: SQLite's migrations. Each entry upgrades the schema by one version. Append; never edit a released migration.
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

#: The trial log (3): scenarios are stored once per file text (``text_hash``, the sha256 of the text; several
#: texts can share a ``content_hash``, which ignores comments and layouts); a trial's JSON fields (layout, as-built
#: layout, check report, photos) are JSON text, so the schema is the same in both databases; every event's outcome
#: is a row of ``trial_events``, written in the trial's transaction. ``{serial}`` is each dialect's identity key.
_TRIALS = """
    CREATE TABLE scenarios (
        id {serial},
        text_hash TEXT NOT NULL UNIQUE,
        content_hash TEXT NOT NULL,
        name TEXT NOT NULL,
        content TEXT NOT NULL
    );
    CREATE INDEX scenarios_content_hash ON scenarios (content_hash);
    CREATE TABLE trials (
        id {serial},
        uid TEXT NOT NULL UNIQUE,
        scenario_id BIGINT NOT NULL REFERENCES scenarios (id),
        layout TEXT NOT NULL,
        as_built TEXT,
        check_report TEXT,
        physics_name TEXT,
        physics_content TEXT,
        success INTEGER NOT NULL CHECK (success IN (0, 1)),
        who TEXT,
        created_at TEXT NOT NULL,
        notes TEXT,
        photos TEXT NOT NULL
    );
    CREATE INDEX trials_scenario ON trials (scenario_id);
    CREATE TABLE trial_events (
        trial_id BIGINT NOT NULL REFERENCES trials (id) ON DELETE CASCADE,
        ordinal INTEGER NOT NULL,
        event TEXT NOT NULL,
        outcome TEXT NOT NULL CHECK (outcome IN ('yes', 'no', 'not-reached')),
        seconds DOUBLE PRECISION,
        PRIMARY KEY (trial_id, event)
    );
"""
MIGRATIONS.append(_TRIALS.format(serial="INTEGER PRIMARY KEY AUTOINCREMENT"))

#: The station loop (migration 4; :mod:`station.loopstore`): a run of ``station loop`` is keyed by its arguments
#: (``run_key``: a second run with the same ones resumes it); each loop keeps the layout it placed (LAYOUT.json text)
#: and the physics profile it was optimized and predicted with; each attempt its logged trial, its predicted success
#: and the check rounds it took (loop 0: the baseline), written in the trial's own transaction. Optimized layouts
#: are cached by what they were optimized from (``cache_key``).
_LOOPS = """
    CREATE TABLE loop_runs (
        id {serial},
        run_key TEXT NOT NULL UNIQUE,
        scenario_name TEXT NOT NULL,
        content_hash TEXT NOT NULL,
        world TEXT NOT NULL,
        settings TEXT NOT NULL,
        created_at TEXT NOT NULL
    );
    CREATE TABLE loop_loops (
        run_id BIGINT NOT NULL REFERENCES loop_runs (id) ON DELETE CASCADE,
        loop_number INTEGER NOT NULL,
        layout TEXT NOT NULL,
        physics_name TEXT,
        physics_content TEXT,
        physics_values TEXT NOT NULL,
        PRIMARY KEY (run_id, loop_number)
    );
    CREATE TABLE loop_attempts (
        run_id BIGINT NOT NULL REFERENCES loop_runs (id) ON DELETE CASCADE,
        loop_number INTEGER NOT NULL,
        attempt INTEGER NOT NULL,
        trial_id BIGINT NOT NULL REFERENCES trials (id),
        success INTEGER NOT NULL CHECK (success IN (0, 1)),
        predicted DOUBLE PRECISION,
        check_rounds INTEGER NOT NULL,
        PRIMARY KEY (run_id, loop_number, attempt)
    );
    CREATE TABLE optimized_layouts (
        cache_key TEXT PRIMARY KEY,
        layout TEXT NOT NULL
    );
"""
MIGRATIONS.append(_LOOPS.format(serial="INTEGER PRIMARY KEY AUTOINCREMENT"))

_PG_SERIAL = "BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY"

#: PostgreSQL's migrations: the same versions as :data:`MIGRATIONS`, in PostgreSQL's words.
POSTGRES_MIGRATIONS: list[str] = [
    f"""
    CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
    CREATE TABLE jobs (
        id {_PG_SERIAL},
        kind TEXT NOT NULL,
        device TEXT,
        created_at TEXT NOT NULL DEFAULT (to_char(now() AT TIME ZONE 'UTC', 'YYYY-MM-DD"T"HH24:MI:SS.MS"Z"')),
        finished_at TEXT,
        status TEXT NOT NULL DEFAULT 'created',
        detail TEXT
    );
    """,
    "DROP TABLE IF EXISTS meta;",
    _TRIALS.format(serial=_PG_SERIAL),
    _LOOPS.format(serial=_PG_SERIAL),
]
assert len(POSTGRES_MIGRATIONS) == len(MIGRATIONS)

#: Any constant: the advisory lock that serializes migrations of one PostgreSQL database across stations.
_PG_MIGRATION_LOCK = 0x5747A710


def schema_version(connection: sqlite3.Connection) -> int:
    return int(connection.execute("PRAGMA user_version").fetchone()[0])


def statements(script: str) -> list[str]:
    """The SQL statements of a migration script, in order (``;`` inside a statement, as in a trigger, is kept)."""
    result, pending = [], ""
    for piece in script.split(";"):
        pending += piece + ";"
        if sqlite3.complete_statement(pending):
            if pending.strip(" \n\t;"):
                result.append(pending.strip())
            pending = ""
    if pending.strip(" \n\t;"):
        result.append(pending.strip())
    return result


def open_database(path: str | Path) -> sqlite3.Connection:
    """Open (creating and migrating as needed) the station's SQLite database at ``path``.

    The connection is in WAL mode with foreign keys on and a busy timeout (see the module notes).

    Raises
    ------
    DatabaseError
        If the file cannot be opened, is not a SQLite database or was written by a newer station
        (:class:`DatabaseBusy`: another process kept it locked while it had to be migrated).
    """
    path = Path(path)
    where = str(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        connection = sqlite3.connect(path, timeout=BUSY_SECONDS)
    except (sqlite3.Error, OSError) as error:
        raise DatabaseError(f"database {where!r}: cannot open ({error})", where) from None
    try:
        _prepare_sqlite(connection)
        _migrate_sqlite(connection, where)
    except sqlite3.DatabaseError as error:
        connection.close()
        if "not a database" in str(error) or "malformed" in str(error):
            raise DatabaseError(f"database {where!r}: not a SQLite database ({error})", where) from None
        if _is_busy(error):
            raise DatabaseBusy(f"database {where!r}: still busy after {BUSY_SECONDS:g} s (another station "
                               "process is writing to it)", where) from None
        raise DatabaseError(f"database {where!r}: {error}", where) from None
    except StationError:
        connection.close()
        raise
    return connection


def _prepare_sqlite(connection: sqlite3.Connection) -> None:
    connection.execute("PRAGMA foreign_keys = ON")
    connection.execute("PRAGMA synchronous = FULL")
    if connection.execute("PRAGMA journal_mode").fetchone()[0].lower() != "wal":
        # Switching to WAL needs the file to itself for a moment; another process opening it at the same moment is
        # waited for (the busy handler does not cover this pragma in every SQLite version).
        deadline = time.monotonic() + BUSY_SECONDS
        while True:
            try:
                connection.execute("PRAGMA journal_mode = WAL")
                break
            except sqlite3.OperationalError as error:
                if "locked" not in str(error) or time.monotonic() > deadline:
                    raise
                time.sleep(0.05)


def _migrate_sqlite(connection: sqlite3.Connection, where: str) -> None:
    """Apply the missing migrations in one ``BEGIN IMMEDIATE`` transaction (the version is read again under the
    lock: another process may have migrated meanwhile). A process killed half way leaves the old version whole."""
    if schema_version(connection) == len(MIGRATIONS):
        return  # the usual case: no write lock taken at all
    connection.execute("BEGIN IMMEDIATE")
    try:
        version = schema_version(connection)
        if version > len(MIGRATIONS):
            raise DatabaseError(
                f"database {where!r}: schema version {version} is newer than this station "
                f"(knows up to {len(MIGRATIONS)}); upgrade the station", where
            )
        for number in range(version, len(MIGRATIONS)):
            for statement in statements(MIGRATIONS[number]):
                connection.execute(statement)
        connection.execute(f"PRAGMA user_version = {len(MIGRATIONS)}")
        connection.execute("COMMIT")
    except BaseException:
        if connection.in_transaction:
            connection.execute("ROLLBACK")
        raise


# -- URLs ----------------------------------------------------------------------------------------------------------
def default_database_path() -> Path:
    return database_path()


def database_url() -> str:
    """The station database's URL: ``CHAOS_STATION_DATABASE``, else ``[database] url`` in the station config,
    else the SQLite file in the data folder (see the module notes)."""
    chosen = os.environ.get(DATABASE_VARIABLE, "").strip()
    if chosen:
        return chosen
    configured = load_config().database
    return configured or f"sqlite:///{default_database_path()}"


# -- connections ---------------------------------------------------------------------------------------------------
class Database:
    """An open, migrated station database: the SQLite file or a PostgreSQL database, one SQL dialect for both.

    Statements use ``?`` placeholders (translated for PostgreSQL) and portable SQL (``RETURNING``, ``ON CONFLICT
    DO NOTHING``). Use :meth:`transaction` for every statement: one short transaction, committed on leaving the
    block, rolled back on an error.

    Parameters
    ----------
    url : str
        See :func:`parse_url`.

    Raises
    ------
    StationError
        A URL of another database (:func:`parse_url`).
    DatabaseError
        The database cannot be opened (no server, wrong password, not a SQLite file, newer schema): one line.
    """

    def __init__(self, url: str) -> None:
        self.url = url
        self.dialect, target = parse_url(url)
        self.where = target if self.dialect == "sqlite" else redact(target)
        if self.dialect == "sqlite":
            self._connection: Any = open_database(target)
            self._connection.isolation_level = None  # transactions are explicit: BEGIN IMMEDIATE for writes
        else:
            self._connection = _connect_postgres(target, self.where)

    def __enter__(self) -> Database:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        if self._connection is not None:
            self._connection.close()
            self._connection = None

    @contextmanager
    def transaction(self, *, write: bool = True) -> Iterator[Transaction]:
        """One transaction: ``write`` takes the write lock at once (SQLite ``BEGIN IMMEDIATE``); a read-only one
        sees one snapshot (PostgreSQL ``REPEATABLE READ``)."""
        if self._connection is None:
            raise DatabaseError(f"database {self.where!r} is closed", self.where)
        if self.dialect == "sqlite":
            begin = "BEGIN IMMEDIATE" if write else "BEGIN"
        else:
            begin = "BEGIN" if write else "BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY"
        self._run(begin)
        try:
            yield Transaction(self)
            self._run("COMMIT")  # a COMMIT SQLite finds busy leaves the transaction open: rolled back below
        except BaseException:
            self._rollback()
            raise

    def write(self, work: Callable[[Transaction], T], *, on_wait: Callable[[str], None] | None = None) -> T:
        """``work(tx)`` in one write transaction, run again from the start while the database is busy
        (:class:`DatabaseBusy`), after a pause that doubles from :data:`RETRY_FIRST_PAUSE` to
        :data:`RETRY_LONGEST_PAUSE`, for up to :data:`WRITE_PATIENCE_SECONDS` in all. ``work`` must do nothing but
        statements in ``tx`` (it may run several times; only the last run is committed).

        ``on_wait(message)`` is called once, when the first attempt found the database busy (a command says that
        it waits).

        Raises
        ------
        DatabaseBusy
            Still busy after :data:`WRITE_PATIENCE_SECONDS`: one line naming the database and the time waited.
        DatabaseError
            Any other failure of the database (not retried).
        """
        start = time.monotonic()
        pause, attempts = RETRY_FIRST_PAUSE, 0
        while True:
            attempts += 1
            try:
                with self.transaction() as tx:
                    return work(tx)
            except DatabaseBusy as error:
                waited = time.monotonic() - start
                if waited + pause > WRITE_PATIENCE_SECONDS:
                    why = ("another station process is writing to it" if self.dialect == "sqlite"
                           else f"the last: {_reason(error, self.where)}")
                    raise DatabaseBusy(f"database {self.where!r}: still busy after {waited:.0f} s and {attempts} "
                                       f"attempts ({why})", self.where) from None
                if attempts == 1 and on_wait is not None:
                    on_wait(f"database {self.where!r} is busy (another station process is writing to it); "
                            f"trying again for up to {WRITE_PATIENCE_SECONDS - waited:.0f} s more")
            time.sleep(pause)
            pause = min(2.0 * pause, RETRY_LONGEST_PAUSE)

    def _rollback(self) -> None:
        try:
            self._connection.execute("ROLLBACK")
        except Exception:  # noqa: BLE001 - the connection may be gone; the original error matters
            pass

    def _run(self, sql: str, params: Sequence[Any] = ()) -> Any:
        if self.dialect == "postgresql":
            sql = sql.replace("?", "%s")
        try:
            return self._connection.execute(sql, tuple(params))
        except Exception as error:  # the driver's own errors (disk full, read-only file, a lost server): one line
            if not isinstance(error, sqlite3.Error) and not type(error).__module__.startswith("psycopg"):
                raise
            if _is_busy(error):
                what = (f"still busy after {BUSY_SECONDS:g} s (another station process is writing to it)"
                        if self.dialect == "sqlite" else _reason(error, self.where))
                raise DatabaseBusy(f"database {self.where!r}: {what}", self.where) from None
            raise DatabaseError(f"database {self.where!r}: {_reason(error, self.where)}", self.where) from None


def _reason(error: BaseException, where: str) -> str:
    """A driver error's words on one line, without the database's name (a message names it once)."""
    if isinstance(error, DatabaseError):
        text = str(error)
        prefix = f"database {where!r}: "
        return text[len(prefix):] if text.startswith(prefix) else text
    return " ".join(str(error).split()) or type(error).__name__


class Transaction:
    """The statements of one :meth:`Database.transaction`."""

    def __init__(self, database: Database) -> None:
        self._database = database

    def execute(self, sql: str, params: Sequence[Any] = ()) -> Any:
        return self._database._run(sql, params)

    def all(self, sql: str, params: Sequence[Any] = ()) -> list[tuple]:
        return [tuple(row) for row in self.execute(sql, params).fetchall()]

    def one(self, sql: str, params: Sequence[Any] = ()) -> tuple | None:
        row = self.execute(sql, params).fetchone()
        return tuple(row) if row is not None else None


def _connect_postgres(uri: str, where: str) -> Any:
    try:
        import psycopg
    except ImportError:
        raise DatabaseError(f"database {where!r}: PostgreSQL needs the psycopg package "
                            "(pip install 'chaos-station[postgres]')", where) from None
    try:
        connection = psycopg.connect(uri, autocommit=True, connect_timeout=10)
    except psycopg.Error as error:
        detail = " ".join(str(error).split())
        raise DatabaseError(f"database {where!r}: cannot connect ({detail})", where) from None
    try:
        _migrate_postgres(connection, where)
    except BaseException:
        connection.close()
        raise
    return connection


def _migrate_postgres(connection: Any, where: str) -> None:
    """As :func:`_migrate_sqlite`: one transaction, serialized across stations by an advisory lock (PostgreSQL's
    DDL is transactional, so a station killed half way leaves the old version whole)."""
    connection.execute("BEGIN")
    try:
        connection.execute("SELECT pg_advisory_xact_lock(%s)", (_PG_MIGRATION_LOCK,))
        connection.execute("CREATE TABLE IF NOT EXISTS station_schema (version INTEGER NOT NULL)")
        row = connection.execute("SELECT version FROM station_schema").fetchone()
        version = int(row[0]) if row else 0
        if version > len(POSTGRES_MIGRATIONS):
            raise DatabaseError(f"database {where!r}: schema version {version} is newer than this station "
                                f"(knows up to {len(POSTGRES_MIGRATIONS)}); upgrade the station", where)
        for number in range(version, len(POSTGRES_MIGRATIONS)):
            for statement in statements(POSTGRES_MIGRATIONS[number]):
                connection.execute(statement)
        if row is None:
            connection.execute("INSERT INTO station_schema (version) VALUES (%s)", (len(POSTGRES_MIGRATIONS),))
        elif version != len(POSTGRES_MIGRATIONS):
            connection.execute("UPDATE station_schema SET version = %s", (len(POSTGRES_MIGRATIONS),))
        connection.execute("COMMIT")
    except BaseException:
        connection.execute("ROLLBACK")
        raise
