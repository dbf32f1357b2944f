"""What ``station loop`` keeps in the station database: its runs, loops and attempts, and a cache of
optimized layouts.

A run is keyed by its arguments (:func:`run_key`): a second ``station loop`` with the same ones finds the run (the
same id: one per run, not per invocation) and carries on from the last attempt stored. An attempt and its trial are
written in one transaction (:meth:`LoopStore.add_attempt`): a loop killed at any moment has either logged the
attempt whole or not at all, so the resumed run replays exactly the attempts that were lost (their seeds depend on
the run, the loop and the attempt only). The tables are migration 4 of :mod:`station.db` (SQLite and PostgreSQL).

A run's stored settings are the ones its key is made of plus ``station_commits``: the commit of every station
code that made or carried on the run (:func:`station_commit`, in order; "+changes" when that code differed from its
commit), so that a table of results can say which code each figure came from. They are not part of the key: a run
carried on by newer code is still the same run, and says so there.
"""

from __future__ import annotations

import functools
import hashlib
import json
import subprocess
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from station.db import Database, database_url
from station.triallog import TrialStore, now_utc

__all__ = ["AttemptRow", "LoopRow", "LoopStore", "run_key", "station_commit"]


#: The folders of the station's code whose changes make a run's figures differ from its commit's.
CODE_FOLDERS = ("station", "design", "calibration", "drivers", "common", "vision", "projector", "cam")


@functools.cache
def station_commit() -> str | None:
    """The short commit of the station code running (``"a12fa16"``), with ``"+changes"`` when its code differs
    from that commit; None when the code is not a git checkout of its own (an installed copy)."""
    root = Path(__file__).resolve().parent.parent
    try:
        # an installed copy inside some other repository (a venv in a checkout) must not take that one's commit
        if Path(_git(root, "rev-parse", "--show-toplevel")).resolve() != root:
            return None
        commit = _git(root, "rev-parse", "--short", "HEAD")
        changed = _git(root, "status", "--porcelain", "--", *CODE_FOLDERS)
    except (OSError, subprocess.SubprocessError):
        return None
    return f"{commit}{'+changes' if changed else ''}" if commit else None


def _git(root: Path, *words: str) -> str:
    return subprocess.run(["git", "-C", str(root), *words], capture_output=True, text=True, timeout=10,
                          check=True).stdout.strip()


def run_key(settings: Mapping[str, Any]) -> str:
    """The sha256 of a run's settings as canonical JSON: what makes two runs the same run."""
    text = json.dumps(dict(settings), sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


@dataclass(frozen=True)
class LoopRow:
    """One loop of a run: the layout it placed and the physics it was optimized and predicted with."""

    loop: int
    layout: dict
    physics_name: str | None
    physics_content: str | None
    physics_values: dict[str, float]


@dataclass(frozen=True)
class AttemptRow:
    """One stored attempt (loop 0: the baseline)."""

    loop: int
    attempt: int
    trial_id: int
    success: bool
    predicted: float | None
    check_rounds: int


class LoopStore:
    """The loop tables of one database (and its trial log, for the trials the attempts log).

    Parameters
    ----------
    url : str, optional
        The database (:func:`station.db_url.parse_url`); default :func:`station.db.database_url`.
    """

    def __init__(self, url: str | None = None) -> None:
        self.database = Database(url or database_url())
        self.trials = TrialStore(database=self.database)

    def __enter__(self) -> LoopStore:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self.database.close()

    # -- runs ---------------------------------------------------------------------------------------------------
    def run(self, key: str, *, scenario: str, content_hash: str, world: str,
            settings: Mapping[str, Any], commit: str | None = None) -> tuple[int, bool]:
        """The id of the run with ``key``, made if new, and whether it was made now (False: an earlier ``station
        loop`` began it). ``commit`` (default: :func:`station_commit`) joins the run's ``station_commits`` when it
        is not there yet.

        Looked up before any insert: an insert that finds the run there uses up an id all the same (SQLite's
        AUTOINCREMENT and PostgreSQL's identity both count it), so the next run's id would skip one per resume.
        """
        commit = commit or station_commit()
        with self.database.transaction() as tx:
            row = tx.one("SELECT id, settings FROM loop_runs WHERE run_key = ?", (key,))
            if row is not None:
                stored = json.loads(row[1])
                commits = list(stored.get("station_commits", []))
                if commit and commit not in commits:
                    stored["station_commits"] = [*commits, commit]
                    tx.execute("UPDATE loop_runs SET settings = ? WHERE id = ?",
                               (json.dumps(stored, sort_keys=True, default=str), row[0]))
                return int(row[0]), False
            kept = {**dict(settings), "station_commits": [commit] if commit else []}
            tx.execute("INSERT INTO loop_runs (run_key, scenario_name, content_hash, world, settings, created_at) "
                       "VALUES (?, ?, ?, ?, ?, ?) ON CONFLICT (run_key) DO NOTHING",
                       (key, scenario, content_hash, world, json.dumps(kept, sort_keys=True, default=str),
                        now_utc()))
            return int(tx.one("SELECT id FROM loop_runs WHERE run_key = ?", (key,))[0]), True

    def commits(self, run_id: int) -> list[str]:
        """The station commits that made and carried on run ``run_id`` (empty: none was stored)."""
        with self.database.transaction(write=False) as tx:
            row = tx.one("SELECT settings FROM loop_runs WHERE id = ?", (run_id,))
        return [] if row is None else list(json.loads(row[0]).get("station_commits", []))

    # -- loops --------------------------------------------------------------------------------------------------
    def loop(self, run_id: int, loop: int) -> LoopRow | None:
        with self.database.transaction(write=False) as tx:
            row = tx.one("SELECT loop_number, layout, physics_name, physics_content, physics_values FROM loop_loops "
                         "WHERE run_id = ? AND loop_number = ?", (run_id, loop))
        if row is None:
            return None
        return LoopRow(int(row[0]), json.loads(row[1]), row[2], row[3], json.loads(row[4]))

    def add_loop(self, run_id: int, row: LoopRow) -> None:
        """Store a loop's layout and physics (a loop already stored is kept as it is)."""
        with self.database.transaction() as tx:
            tx.execute("INSERT INTO loop_loops (run_id, loop_number, layout, physics_name, physics_content, "
                       "physics_values) VALUES (?, ?, ?, ?, ?, ?) ON CONFLICT (run_id, loop_number) DO NOTHING",
                       (run_id, row.loop, json.dumps(row.layout), row.physics_name, row.physics_content,
                        json.dumps(row.physics_values)))

    # -- attempts -----------------------------------------------------------------------------------------------
    def attempts(self, run_id: int, loop: int | None = None) -> list[AttemptRow]:
        """The run's attempts (of one loop), in order."""
        sql = ("SELECT loop_number, attempt, trial_id, success, predicted, check_rounds FROM loop_attempts "
               "WHERE run_id = ?")
        params: tuple = (run_id,)
        if loop is not None:
            sql += " AND loop_number = ?"
            params += (loop,)
        with self.database.transaction(write=False) as tx:
            rows = tx.all(sql + " ORDER BY loop_number, attempt", params)
        return [AttemptRow(int(r[0]), int(r[1]), int(r[2]), bool(r[3]), None if r[4] is None else float(r[4]),
                           int(r[5])) for r in rows]

    def add_attempt(self, run_id: int, loop: int, attempt: int, trial: Mapping[str, Any], *,
                    predicted: float | None, check_rounds: int) -> AttemptRow:
        """Log ``trial`` (the export's form) and the attempt in one transaction. An attempt already stored (another
        process resumed the same run meanwhile) keeps the stored one and logs nothing."""
        with self.database.transaction() as tx:
            row = tx.one("SELECT trial_id FROM loop_attempts WHERE run_id = ? AND loop_number = ? AND attempt = ?",
                         (run_id, loop, attempt))
            if row is None:
                trial_id = self.trials._insert(tx, trial)
                tx.execute("INSERT INTO loop_attempts (run_id, loop_number, attempt, trial_id, success, predicted, "
                           "check_rounds) VALUES (?, ?, ?, ?, ?, ?, ?)",
                           (run_id, loop, attempt, trial_id, int(bool(trial["success"])), predicted, check_rounds))
        return next(a for a in self.attempts(run_id, loop) if a.attempt == attempt)

    def trial(self, trial_id: int) -> dict[str, Any]:
        """A logged trial in the export's form."""
        return self.trials.get(trial_id)

    # -- the optimized-layout cache -----------------------------------------------------------------------------
    def cached_layout(self, key: str) -> dict | None:
        with self.database.transaction(write=False) as tx:
            row = tx.one("SELECT layout FROM optimized_layouts WHERE cache_key = ?", (key,))
        return None if row is None else json.loads(row[0])

    def cache_layout(self, key: str, layout: Mapping[str, Any]) -> None:
        with self.database.transaction() as tx:
            tx.execute("INSERT INTO optimized_layouts (cache_key, layout) VALUES (?, ?) "
                       "ON CONFLICT (cache_key) DO NOTHING", (key, json.dumps(dict(layout))))
