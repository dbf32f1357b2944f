"""Reading JSON and TOML data files so that a bad one is reported one way, in every package: one line naming the
file, where in it (line and column) and what was expected::

    sketch.json: not valid JSON (Expecting ',' delimiter at line 2 column 6); expected a list of strokes ...
    ballrun.toml: not valid TOML (Invalid value at line 1 column 5); expected a scenario file

``json.loads`` alone lets three kinds of bad file escape as something else: bytes that are not UTF-8
(``UnicodeDecodeError``), arrays nested deeper than the interpreter's recursion limit (``RecursionError``) and the
non-JSON constants ``NaN`` and ``Infinity`` (read as floats); ``tomllib`` recurses the same way on nested arrays and
inline tables. A file nested deeper than :data:`MAX_DEPTH` is refused whatever reads it: no data file of the station
nests beyond a few levels, and the code that walks what was read (validation, hashing, JSON output) recurses too.

Every reader of a user's data file (designs, patterns, sketches, scenarios, layouts, machine profiles, the station's
config) calls :func:`load_json`, :func:`parse_json`, :func:`parse_toml` or :func:`parse_data` instead. The error is
the caller's: each package passes ``error``, a factory that makes its own type (``design``'s
:class:`~design.errors.FileFormatError`, ``drivers``' ``ProfileError``, ``station``'s ``ConfigError``) from the same
message; without one it is a :class:`DataFileError` (a ``ValueError``). It lives in ``common`` because ``design``
and ``drivers`` may not import each other.
"""

from __future__ import annotations

import json
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


class DataFileError(ValueError):
    """A data file that cannot be read as its format (the default error when the caller gives no factory)."""


#: The deepest nesting of arrays and tables (objects) a data file may have. The station's own files nest a few
#: levels; tomllib reaches Python's recursion limit at 400 levels of inline tables (500 of arrays), and the code
#: that walks what was read recurses as well, so the limit sits well under that.
MAX_DEPTH = 100


#: Makes the error from the part of the message after ``FILE: `` (default: a :class:`DataFileError` naming the file).
ErrorFactory = Callable[[str], Exception]


def load_json(path: str | Path, expected: str, *, error: ErrorFactory | None = None) -> Any:
    """The parsed content of a JSON file.

    Parameters
    ----------
    path : str or Path
        The file.
    expected : str
        What the file should be, in words (``"the JSON of `station pattern --json`"``): the end of every message.

    Raises
    ------
    DataFileError
        Or ``error``'s type: the file is not UTF-8 text or not JSON: ``FILE: not valid JSON (Expecting ','
        delimiter at line 3 column 7); expected ...``.
    OSError
        The file cannot be read (missing, a folder, no permission): the caller's "no such file" is clearer.
    """
    path = Path(path)
    return parse_json(path.read_bytes(), str(path), expected, error=error)


def parse_json(raw: bytes, file: str, expected: str, *, error: ErrorFactory | None = None,
               object_pairs_hook: Callable[[list[tuple[str, Any]]], Any] | None = None) -> Any:
    """Parse the bytes of a JSON file; ``file`` and ``expected`` are for the message (see :func:`load_json`).

    ``error(detail)`` makes the exception from the message after ``FILE: `` (default: a :class:`DataFileError`
    with the file in front). ``object_pairs_hook`` goes to :func:`json.loads`; what it raises passes through.
    """
    fail = error or _file_error(file)
    text = _decode(raw, expected, fail)
    try:
        data = json.loads(text, parse_constant=_reject_constant, object_pairs_hook=object_pairs_hook)
    except json.JSONDecodeError as decode:
        raise fail(f"not valid JSON ({decode.msg} at line {decode.lineno} column {decode.colno}); "
                   f"expected {expected}") from None
    except RecursionError:
        raise fail(_too_deep(expected)) from None
    except _NotJSON as constant:  # NaN, Infinity
        raise fail(f"not valid JSON ({constant}); expected {expected}") from None
    return _shallow(data, expected, fail)


def parse_toml(raw: bytes, file: str, expected: str, *, error: ErrorFactory | None = None) -> Any:
    """Parse the bytes of a TOML file, reporting a bad one as :func:`parse_json` does."""
    fail = error or _file_error(file)
    text = _decode(raw, expected, fail)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as decode:
        # "Invalid value (at line 1, column 5)" -> "Invalid value at line 1 column 5", as JSON's messages read
        where = re.fullmatch(r"(.*) \(at line (\d+), column (\d+)\)", str(decode))
        detail = f"{where[1]} at line {where[2]} column {where[3]}" if where else str(decode)
        raise fail(f"not valid TOML ({detail}); expected {expected}") from None
    except RecursionError:  # arrays or inline tables within each other, hundreds deep
        raise fail(_too_deep(expected)) from None
    return _shallow(data, expected, fail)


def parse_data(raw: bytes, file: str, expected: str, *, error: ErrorFactory | None = None,
               object_pairs_hook: Callable[[list[tuple[str, Any]]], Any] | None = None) -> Any:
    """TOML for a file ending in ``.toml``, JSON otherwise (see :func:`parse_json`, :func:`parse_toml`)."""
    if file.lower().endswith(".toml"):
        return parse_toml(raw, file, expected, error=error)
    return parse_json(raw, file, expected, error=error, object_pairs_hook=object_pairs_hook)


def _too_deep(expected: str) -> str:
    return f"nested deeper than {MAX_DEPTH} levels of arrays and tables; expected {expected}"


def _shallow(data: Any, expected: str, fail: ErrorFactory) -> Any:
    """``data``, refused if its arrays and tables nest deeper than :data:`MAX_DEPTH` (walked without recursion)."""
    stack = [(data, 1)]
    while stack:
        value, depth = stack.pop()
        children = value.values() if isinstance(value, dict) else value if isinstance(value, list) else None
        if children is None:
            continue
        if depth > MAX_DEPTH:
            raise fail(_too_deep(expected))
        stack.extend((child, depth + 1) for child in children if isinstance(child, (dict, list)))
    return data


def _file_error(file: str) -> ErrorFactory:
    return lambda detail: DataFileError(f"{file}: {detail}")


def _decode(raw: bytes, expected: str, fail: ErrorFactory) -> str:
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as decode:
        raise fail(f"not UTF-8 text ({decode.reason} at byte {decode.start}); expected {expected}") from None


class _NotJSON(ValueError):
    """``NaN`` or ``Infinity``: Python's json reads them, JSON has no such number."""


def _reject_constant(name: str) -> float:
    raise _NotJSON(f"{name} is not a JSON number")
