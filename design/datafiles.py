"""Reading a user's data files in ``design``: :mod:`common.datafiles` with :class:`~design.errors.FileFormatError`.

Every reader of a design, pattern, sketch, scenario or layout file calls these, so that a bad file is one line naming
the file, where in it and what was expected (see :mod:`common.datafiles`). An area with its own subclass of
:class:`FileFormatError` (a scenario's, which also carries the field) passes ``error`` to get its own type.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from common import datafiles as _common
from common.datafiles import ErrorFactory
from design.errors import FileFormatError

__all__ = ["ErrorFactory", "load_json", "parse_data", "parse_json", "parse_toml"]


def _file_error(file: str) -> ErrorFactory:
    return lambda detail: FileFormatError(f"{file}: {detail}")


def _in_design(reader):
    """``reader`` from :mod:`common.datafiles`, raising :class:`FileFormatError` unless told otherwise."""

    def read(raw, file, expected, *, error: ErrorFactory | None = None, **options) -> Any:
        return reader(raw, file, expected, error=error or _file_error(file), **options)

    read.__doc__ = reader.__doc__
    read.__name__ = reader.__name__
    return read


parse_json = _in_design(_common.parse_json)
parse_toml = _in_design(_common.parse_toml)
parse_data = _in_design(_common.parse_data)


def load_json(path: str | Path, expected: str) -> Any:
    """The parsed content of a JSON file; a bad one is a :class:`FileFormatError` (see :mod:`common.datafiles`)."""
    return _common.load_json(path, expected, error=_file_error(str(path)))


