"""Where the station keeps its files.

``CHAOS_STATION_HOME`` overrides everything (tests and CI set it to a temporary folder); otherwise the user's
data directory from :mod:`platformdirs`.
"""

from __future__ import annotations

import os
from pathlib import Path

import platformdirs

APP_NAME = "chaos-station"


def data_dir() -> Path:
    """The station's data directory, created if missing."""
    override = os.environ.get("CHAOS_STATION_HOME")
    path = Path(override) if override else Path(platformdirs.user_data_dir(APP_NAME, appauthor=False))
    path.mkdir(parents=True, exist_ok=True)
    return path


def cache_dir() -> Path:
    """The station's cache directory (safe to delete), created if missing."""
    override = os.environ.get("CHAOS_STATION_HOME")
    path = Path(override) / "cache" if override else Path(platformdirs.user_cache_dir(APP_NAME, appauthor=False))
    path.mkdir(parents=True, exist_ok=True)
    return path


def database_path() -> Path:
    """The local SQLite trial database."""
    return data_dir() / "station.sqlite3"
