"""What the faces show of the station itself: the devices and what a probe finds, the station database, the latest
machine jobs, the data folder where results are written.

The devices come from ``station.toml`` (:mod:`station.devices`), the database and the job history from
:mod:`station.db` and :mod:`station.joblog`, the folders from :mod:`station.paths`; a face reaches them here.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path

from station.db import open_database
from station.devices import DeviceEntry, default_devices, probe_device
from station.errors import station_errors
from station.joblog import JobLog, JobRecord, local_time
from station.paths import data_dir, database_path

__all__ = ["DeviceEntry", "JobLog", "JobRecord", "data_dir", "default_devices", "local_time", "open_station_database",
           "probe", "recent_jobs", "shared_job_log"]


@station_errors
def open_station_database(path: str | Path | None = None) -> tuple[Path, sqlite3.Connection]:
    """The station database at ``path`` (default the data folder's), opened (created and migrated as needed)."""
    path = Path(path) if path is not None else database_path()
    return path, open_database(path)


@station_errors
def shared_job_log(path: str | Path) -> JobLog:
    """The job history of the database at ``path`` on a connection every thread may use (the machine sessions')."""
    return JobLog.open_shared(path)


@station_errors
def recent_jobs(connection: sqlite3.Connection | None, limit: int) -> list[JobRecord]:
    """The latest ``limit`` machine jobs of an open station database, newest first (none without one)."""
    return JobLog(connection).recent(limit)


@station_errors
def probe(device: DeviceEntry) -> str:
    """The state a short probe finds (``station devices``): ``"connected: Grbl 1.1h, Idle"``, ``"not connected:
    no such port"``... Whatever goes wrong in a driver is said the same way, so that one device's bug never stops
    the station: ``"probe failed: ..."``."""
    try:
        return probe_device(device)
    except Exception as error:  # noqa: BLE001 - any driver's failure is a state line, not a crash of the screen
        return f"probe failed: {error}"
