"""Where the station keeps its files.

``CHAOS_STATION_HOME`` overrides everything (tests and CI set it to a temporary folder); otherwise the user's
data directory from :mod:`platformdirs`. The data folder holds the database (``station.sqlite3``) and the config
file (``station.toml``, see :mod:`station.config`; ``CHAOS_STATION_CONFIG`` may name another).
"""

from __future__ import annotations

import os
from pathlib import Path

import platformdirs

from station.errors import ConfigError

APP_NAME = "chaos-station"
HOME_VARIABLE = "CHAOS_STATION_HOME"


def data_dir() -> Path:
    """The station's data directory, created if missing.

    Raises
    ------
    ConfigError
        When the folder cannot be made (the path or one of its parents is a file, or no permission); the message
        names ``CHAOS_STATION_HOME`` when it chose the path.
    """
    override = os.environ.get(HOME_VARIABLE)
    path = Path(override) if override else Path(platformdirs.user_data_dir(APP_NAME, appauthor=False))
    return _make_folder(path, "data folder", override)


def cache_dir() -> Path:
    """The station's cache directory (safe to delete), created if missing (raises :class:`ConfigError` as
    :func:`data_dir`)."""
    override = os.environ.get(HOME_VARIABLE)
    path = Path(override) / "cache" if override else Path(platformdirs.user_cache_dir(APP_NAME, appauthor=False))
    return _make_folder(path, "cache folder", override)


def database_path() -> Path:
    """The local SQLite trial database."""
    return data_dir() / "station.sqlite3"


def _make_folder(path: Path, what: str, override: str | None) -> Path:
    """``path`` created with its parents; a file in the way is a configuration error, not a traceback."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        problem = "is a file" if path.is_file() else "has a file among its parents"
        raise ConfigError(_where(path, what, override) + f" {problem}; it must be a folder or a path where one "
                          "can be created" + _fix(override)) from None
    except PermissionError:
        raise ConfigError(_where(path, what, override) + " cannot be created (permission denied); it must be a "
                          "writable folder" + _fix(override)) from None
    return path


def _where(path: Path, what: str, override: str | None) -> str:
    if override is None:
        return f"the station's {what} {str(path)!r}"
    if Path(override) == path:
        return f"{HOME_VARIABLE}={override!r}"
    return f"the {what} {str(path)!r} under {HOME_VARIABLE}={override!r}"


def _fix(override: str | None) -> str:
    return f" (set {HOME_VARIABLE} to another folder)" if override is None else ""
