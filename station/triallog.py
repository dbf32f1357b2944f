"""The trial log: physical runs of contraptions in the station database (SQLite or PostgreSQL, see :mod:`station.db`).

Python API (also what simulator calibration reads)::

    from station.triallog import TrialStore
    with TrialStore() as store:                       # the station's database (database_url()); or TrialStore(url)
        trial_id = store.add(record)                  # a checked trial (station.services.trials builds one)
        trials = store.trials(scenario_hash=None)     # list of dicts in the JSON export's form, oldest first
        store.get(trial_id)                           # one, or ServiceError(field="id")
        added, duplicates = store.import_trials(records)

A trial is written in one short transaction (its scenario text once per distinct text, its row, one row per event),
so a process killed at any moment leaves either the whole trial or none of it; while another process keeps the
database busy the transaction is tried again (:meth:`station.db.Database.write`).
"""

from __future__ import annotations

import json
import uuid
from collections.abc import Callable, Mapping, Sequence
from datetime import datetime, timezone
from typing import Any

from station.db import Database, Transaction, database_url
from station.errors import ServiceError
from station.trialformat import text_hash

#: Trial ids are 64-bit integers in both databases (SQLite's INTEGER, PostgreSQL's BIGINT).
MAX_ID = 2**63 - 1


def now_utc() -> str:
    """Now, as the log writes it: ISO 8601 UTC with milliseconds and ``Z``."""
    return datetime.now(timezone.utc).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def new_uid() -> str:
    return uuid.uuid4().hex


def _json(value: Any) -> str | None:
    return None if value is None else json.dumps(value, separators=(",", ":"))


def _unjson(text: str | None) -> Any:
    return None if text is None else json.loads(text)


# A scenario's text is read once per query, not once per trial (a log of thousands of runs of one scenario would
# otherwise carry thousands of copies of it): the trials' rows name it, :meth:`TrialStore._scenarios` reads it.
_SELECT = """
    SELECT t.id, t.uid, t.scenario_id, t.layout, t.as_built, t.check_report, t.physics_name,
           t.physics_content, t.success, t.who, t.created_at, t.notes, t.photos
    FROM trials t JOIN scenarios s ON s.id = t.scenario_id
"""


class TrialStore:
    """The trial log of one database.

    Parameters
    ----------
    url : str, optional
        The database (see :func:`station.db_url.parse_url`); default :func:`station.db.database_url`.
    database : Database, optional
        An open database to use instead (not closed by :meth:`close`).
    """

    def __init__(self, url: str | None = None, *, database: Database | None = None) -> None:
        self._owned = database is None
        self.database = database if database is not None else Database(url or database_url())

    def __enter__(self) -> TrialStore:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        if self._owned:
            self.database.close()

    @property
    def where(self) -> str:
        """The database, for messages (a PostgreSQL URL without its password)."""
        return self.database.where

    # -- writing ---------------------------------------------------------------------------------------------------
    def add(self, record: Mapping[str, Any], *, on_wait: Callable[[str], None] | None = None) -> int:
        """Store one checked trial (the export's form; ``uid`` and ``created_at`` are made when missing) in one
        transaction and return its id. While another process keeps the database busy the transaction is tried
        again (``on_wait``: see :meth:`station.db.Database.write`).

        Raises
        ------
        ServiceError
            ``field="uid"``: a trial with that uid is already in the log.
        station.db.DatabaseError
            The database failed, or stayed busy (:class:`station.db.DatabaseBusy`).
        """
        record = {**record, "uid": record.get("uid") or new_uid()}
        trial_id = self.database.write(lambda tx: self._insert(tx, record), on_wait=on_wait)
        if trial_id is None:
            raise ServiceError(f"uid: the trial {record['uid']} is already in the log", field="uid")
        return trial_id

    def import_trials(self, records: Sequence[Mapping[str, Any]], *,
                      on_wait: Callable[[str], None] | None = None) -> tuple[list[int], list[str]]:
        """Store checked trials from an export in one transaction: ``(new ids, uids already in the log)``; a trial
        already there is refused (not added twice), the others are added."""

        def insert(tx: Transaction) -> tuple[list[int], list[str]]:
            added, duplicates = [], []  # made again by each attempt: only the committed one counts
            for record in records:
                trial_id = self._insert(tx, record)
                if trial_id is None:
                    duplicates.append(record["uid"])
                else:
                    added.append(trial_id)
            return added, duplicates

        return self.database.write(insert, on_wait=on_wait)

    def _insert(self, tx: Transaction, record: Mapping[str, Any]) -> int | None:
        """Insert within ``tx``; None when the uid is already there (nothing written)."""
        uid = record.get("uid") or new_uid()
        if tx.one("SELECT 1 FROM trials WHERE uid = ?", (uid,)) is not None:
            return None  # already there: asked first, as an insert refused by its uid still uses up an id in SQLite
        scenario = record["scenario"]
        digest = text_hash(scenario["content"])
        tx.execute("INSERT INTO scenarios (text_hash, content_hash, name, content) VALUES (?, ?, ?, ?) "
                   "ON CONFLICT (text_hash) DO NOTHING",
                   (digest, scenario["content_hash"], scenario["name"], scenario["content"]))
        scenario_id = tx.one("SELECT id FROM scenarios WHERE text_hash = ?", (digest,))[0]
        physics = record.get("physics")
        # ON CONFLICT: a uid already there (another station imported the same file at the same moment) adds nothing
        inserted = tx.one(
            "INSERT INTO trials (uid, scenario_id, layout, as_built, check_report, physics_name, physics_content, "
            "success, who, created_at, notes, photos) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?) "
            "ON CONFLICT (uid) DO NOTHING RETURNING id",
            (uid, scenario_id, _json(dict(record["layout"])), _json(record.get("as_built")),
             _json(record.get("check")), physics["name"] if physics else None,
             physics["content"] if physics else None, int(bool(record["success"])), record.get("who"),
             record.get("created_at") or now_utc(), record.get("notes"), _json(list(record.get("photos") or []))),
        )
        if inserted is None:
            return None
        trial_id = inserted[0]
        times = record.get("times") or {}
        for ordinal, (event, outcome) in enumerate(record["outcomes"].items()):
            tx.execute("INSERT INTO trial_events (trial_id, ordinal, event, outcome, seconds) VALUES (?, ?, ?, ?, ?)",
                       (trial_id, ordinal, event, outcome, times.get(event)))
        return int(trial_id)

    # -- reading ---------------------------------------------------------------------------------------------------
    def trials(self, scenario_hash: str | None = None, *, scenario: str | None = None,
               success: bool | None = None, limit: int | None = None) -> list[dict[str, Any]]:
        """Trials in the export's form, oldest first.

        Parameters
        ----------
        scenario_hash : str, optional
            Only trials of scenarios with this content hash.
        scenario : str, optional
            Only trials of scenarios with this name (case-insensitive).
        success : bool, optional
            Only successes (True) or failures (False).
        limit : int, optional
            Only the latest ``limit`` (still oldest first).
        """
        where, params = [], []
        if scenario_hash is not None:
            where.append("s.content_hash = ?")
            params.append(scenario_hash)
        if scenario is not None:
            where.append("lower(s.name) = lower(?)")
            params.append(scenario)
        if success is not None:
            where.append("t.success = ?")
            params.append(int(success))
        sql = _SELECT + (" WHERE " + " AND ".join(where) if where else "") + " ORDER BY t.id DESC"
        if limit is not None:
            sql += f" LIMIT {int(limit)}"
        with self.database.transaction(write=False) as tx:
            rows = tx.all(sql, params)[::-1]
            events = self._events(tx, [row[0] for row in rows])
            scenarios = self._scenarios(tx, {row[2] for row in rows})
        return [self._record(row, events.get(row[0], []), scenarios) for row in rows]

    def get(self, trial_id: int) -> dict[str, Any]:
        """One trial (raises :class:`ServiceError` with ``field="id"`` when there is none with that id)."""
        if isinstance(trial_id, bool) or not isinstance(trial_id, int) or not 1 <= trial_id <= MAX_ID:
            raise ServiceError(f"id: expected a trial id, a whole number from 1 to {MAX_ID}, got {trial_id!r}",
                               field="id", value=trial_id)
        with self.database.transaction(write=False) as tx:
            row = tx.one(_SELECT + " WHERE t.id = ?", (int(trial_id),))
            if row is None:
                raise ServiceError(f"id: no trial {trial_id} in the log ({self.where})", field="id", value=trial_id)
            events = self._events(tx, [int(trial_id)])
            scenarios = self._scenarios(tx, {row[2]})
        return self._record(row, events.get(row[0], []), scenarios)

    def count(self) -> int:
        with self.database.transaction(write=False) as tx:
            return int(tx.one("SELECT count(*) FROM trials")[0])

    @staticmethod
    def _events(tx: Transaction, ids: list[int]) -> dict[int, list[tuple]]:
        if not ids:
            return {}
        result: dict[int, list[tuple]] = {}
        # one query for a range of ids (a list of thousands of placeholders would hit SQLite's limit)
        for trial_id, event, outcome, seconds in tx.all(
                "SELECT trial_id, event, outcome, seconds FROM trial_events WHERE trial_id BETWEEN ? AND ? "
                "ORDER BY trial_id, ordinal", (min(ids), max(ids))):
            result.setdefault(trial_id, []).append((event, outcome, seconds))
        return result

    @staticmethod
    def _scenarios(tx: Transaction, ids: set[int]) -> dict[int, tuple[str, str, str]]:
        """Scenario id -> (name, content hash, text), for the ``ids`` given."""
        if not ids:
            return {}
        rows = tx.all("SELECT id, name, content_hash, content FROM scenarios WHERE id BETWEEN ? AND ?",
                      (min(ids), max(ids)))
        return {row[0]: tuple(row[1:]) for row in rows if row[0] in ids}

    @staticmethod
    def _record(row: tuple, events: list[tuple], scenarios: Mapping[int, tuple[str, str, str]]) -> dict[str, Any]:
        (trial_id, uid, scenario_id, layout, as_built, check, physics_name, physics_content, success, who,
         created_at, notes, photos) = row
        name, content_hash, content = scenarios[scenario_id]
        return {
            "id": int(trial_id), "uid": uid,
            "scenario": {"name": name, "content_hash": content_hash, "content": content},
            "layout": _unjson(layout), "as_built": _unjson(as_built), "check": _unjson(check),
            "physics": None if physics_name is None else {"name": physics_name, "content": physics_content},
            "outcomes": {event: outcome for event, outcome, _ in events},
            "times": {event: float(seconds) for event, _, seconds in events if seconds is not None},
            "success": bool(success), "who": who, "created_at": created_at, "notes": notes,
            "photos": _unjson(photos),
        }
