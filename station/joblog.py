"""The machine-job history in the station database: what ran on which machine, how it ended, where to resume.

Every job the station streams (from the Machines screen or ``station send``) gets a row in the ``jobs`` table when it
starts and its outcome when it ends. A job whose process died before it ended (the station was killed, the computer
slept) is shown as ``interrupted``: its row still says ``running`` but the process that ran it is gone.
"""

from __future__ import annotations

import json
import os
import sqlite3
import threading
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from station.db import BUSY_SECONDS, open_database

#: The ``kind`` column by job mode: the job itself, its frame (bounding box traced), a dry run in check mode.
JOB_KINDS = {"run": "run", "frame": "frame", "dry": "dry run"}

#: Row states besides the job runner's own (done, stopped, aborted, error, refused, position_lost, ...).
RUNNING, INTERRUPTED = "running", "interrupted"

#: States of a job that started and did not finish: there is a line to resume from.
UNFINISHED = ("stopped", "aborted", "error", "position_lost", INTERRUPTED)


@dataclass(frozen=True)
class JobRecord:
    """One row of the job history."""

    id: int
    kind: str  # "run", "frame" or "dry run"
    device: str
    title: str
    status: str
    created_at: str
    finished_at: str | None
    lines_total: int
    lines_acked: int
    message: str
    resume_line: int | None
    layer: dict | None = None  # a multi-pen plot's layer the machine stood on: number, count, name, pen, line

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)

    @property
    def unfinished(self) -> bool:
        """The job started and did not run to its end (stopped, aborted, error, position lost, interrupted)."""
        return self.status in UNFINISHED

    def resume_hint(self) -> str:
        """Where to resume an unfinished job, e.g. ``resume from line 121``; ``""`` for other jobs.

        Without a recorded line (a station that died before recording one, an older record), the line after the
        last one confirmed: GRBL confirms a line when it is planned, so the machine stopped at or before it.
        """
        if not self.unfinished:
            return ""
        after = " after homing ($H)" if self.status == "position_lost" else ""
        layer = self.layer_hint()
        if self.resume_line:
            return f"resume from line {self.resume_line}{after}{layer}"
        return f"resume at or before line {min(self.lines_acked + 1, max(self.lines_total, 1))}{after}{layer}"

    def layer_hint(self) -> str:
        """``; in layer 2/3 "star" (pen "red"): --from-layer 2 starts it again`` for a multi-pen plot, else ``""``."""
        layer = self.layer if isinstance(self.layer, dict) else None
        if not layer or "number" not in layer:
            return ""
        return (f'; in layer {layer["number"]}/{layer.get("count", "?")} "{layer.get("name", "")}" '
                f'(pen "{layer.get("pen", "")}"): --from-layer {layer["number"]} starts it again')


def _alive(pid: int | None) -> bool:
    if not pid:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's live process
        return True
    return True


def local_time(stamp: str) -> str:
    """``2026-12-01T16:12:59.323Z`` (UTC, as SQLite writes it) as local ``2026-12-01 17:12``."""
    try:
        moment = datetime.fromisoformat(stamp.replace("Z", "+00:00"))
    except ValueError:
        return stamp[:16]
    if moment.tzinfo is None:
        moment = moment.replace(tzinfo=timezone.utc)
    return moment.astimezone().strftime("%Y-%m-%d %H:%M")


class JobLog:
    """Start and finish job rows in an open station database (see :func:`station.db.open_database`).

    The history never stops a job: with ``connection=None`` every call does nothing, and a database error (locked,
    read-only, disk full) is passed to ``on_error`` once and the record is skipped. The calls are serialized, so a
    log opened with :meth:`open_shared` may be written from any thread (a job is sent from a worker thread).
    """

    def __init__(self, connection: sqlite3.Connection | None,
                 on_error: Callable[[Exception], None] | None = None) -> None:
        self.connection = connection
        self.on_error = on_error
        self._warned = False
        self._lock = threading.RLock()

    @classmethod
    def open_shared(cls, path: str | Path, on_error: Callable[[Exception], None] | None = None) -> JobLog:
        """The job history of the station database at ``path`` on a connection of its own that every thread may use
        (the database made or migrated first, as :func:`station.db.open_database` does); :meth:`close` it."""
        open_database(path).close()
        connection = sqlite3.connect(path, timeout=BUSY_SECONDS, check_same_thread=False)
        connection.execute("PRAGMA foreign_keys = ON")
        return cls(connection, on_error)

    def close(self) -> None:
        """Close the connection (a log from :meth:`open_shared`)."""
        with self._lock:
            if self.connection is not None:
                self.connection.close()
                self.connection = None

    def _write(self, statement: str, values: tuple) -> int:
        if self.connection is None:
            return 0
        try:
            with self._lock, self.connection:
                return int(self.connection.execute(statement, values).lastrowid or 0)
        except sqlite3.Error as error:
            if self.on_error is not None and not self._warned:
                self._warned = True
                self.on_error(error)
            return 0

    def _detail(self, job_id: int) -> dict[str, Any]:
        if self.connection is None or not job_id:
            return {}
        try:
            with self._lock:
                row = self.connection.execute("SELECT detail FROM jobs WHERE id = ?", (job_id,)).fetchone()
            return json.loads(row[0]) if row and row[0] else {}
        except (sqlite3.Error, json.JSONDecodeError):
            return {}

    def start(self, kind: str, device: str, title: str, lines_total: int, source: str = "") -> int:
        """Record a job that starts now; returns its id for :meth:`progress` and :meth:`finish` (0: not recorded)."""
        detail = {"title": title, "lines_total": int(lines_total), "lines_acked": 0, "message": "",
                  "resume_line": None, "source": source, "pid": os.getpid()}
        return self._write("INSERT INTO jobs (kind, device, status, detail) VALUES (?, ?, ?, ?)",
                           (kind, device, RUNNING, json.dumps(detail)))

    def progress(self, job_id: int, lines_acked: int, resume_line: int | None = None,
                 layer: dict | None = None) -> None:
        """Record how far a running job has got (so an interrupted one still tells): the lines confirmed and,
        when known, the line the machine is executing (where to resume if the station dies now) and the layer of
        a multi-pen plot it stands on (:meth:`drivers.gcode_layers.LayerMark.to_dict`)."""
        if not job_id:
            return
        with self._lock:  # read and written back whole
            self._record_progress(job_id, lines_acked, resume_line, layer)

    def _record_progress(self, job_id: int, lines_acked: int, resume_line: int | None, layer: dict | None) -> None:
        detail = self._detail(job_id)
        detail["lines_acked"] = int(lines_acked)
        if resume_line is not None:
            detail["resume_line"] = int(resume_line)
        if layer is not None:
            detail["layer"] = dict(layer)
        self._write("UPDATE jobs SET detail = ? WHERE id = ?", (json.dumps(detail), job_id))

    def finish(self, job_id: int, status: str, lines_acked: int, message: str,
               resume_line: int | None = None, layer: dict | None = None) -> None:
        """Record how job ``job_id`` ended.

        An unfinished job (:data:`UNFINISHED`) finished without a ``resume_line`` keeps the line :meth:`progress`
        recorded last: an ending that could not tell (the runner did not answer in time after an interrupt) never
        erases where the machine was. A job that finished has none.
        """
        if not job_id:
            return
        detail = self._detail(job_id)
        if resume_line is None and status in UNFINISHED:
            resume_line = detail.get("resume_line")
        elif status not in UNFINISHED:
            resume_line = None
        detail.update(lines_acked=int(lines_acked), message=message,
                      resume_line=None if resume_line is None else int(resume_line))
        if layer is not None:
            detail["layer"] = dict(layer)
        self._write("UPDATE jobs SET status = ?, detail = ?, finished_at = strftime('%Y-%m-%dT%H:%M:%fZ', 'now') "
                    "WHERE id = ?", (status, json.dumps(detail), job_id))

    def recent(self, limit: int = 20) -> list[JobRecord]:
        """The latest ``limit`` jobs, newest first."""
        if self.connection is None:
            return []
        with self._lock:
            rows = self._rows(limit)
        records = []
        for job_id, kind, device, status, created, finished, text in rows:
            try:
                detail = json.loads(text) if text else {}
            except json.JSONDecodeError:
                detail = {"message": text}
            if status == RUNNING and not _alive(detail.get("pid")):
                status = INTERRUPTED
            records.append(JobRecord(
                id=job_id, kind=kind, device=device or "", title=str(detail.get("title", "")), status=status,
                created_at=created, finished_at=finished, lines_total=int(detail.get("lines_total", 0)),
                lines_acked=int(detail.get("lines_acked", 0)), message=str(detail.get("message", "")),
                resume_line=detail.get("resume_line"),
                layer=detail.get("layer") if isinstance(detail.get("layer"), dict) else None,
            ))
        return records

    def _rows(self, limit: int) -> list[tuple]:
        return self.connection.execute(
            "SELECT id, kind, device, status, created_at, finished_at, detail FROM jobs ORDER BY id DESC LIMIT ?",
            (int(limit),),
        ).fetchall()
