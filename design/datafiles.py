"""Reading JSON data files so that a bad one is reported one way: a :class:`~design.errors.FileFormatError` whose
one line names the file, where in it (line and column) and what was expected.

``json.loads`` alone lets three kinds of bad file escape as something else: bytes that are not UTF-8
(``UnicodeDecodeError``), arrays nested deeper than the interpreter's recursion limit (``RecursionError``) and the
non-JSON constants ``NaN`` and ``Infinity`` (read as floats). Commands that read a user's JSON file call
:func:`load_json` instead.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from design.errors import FileFormatError


def load_json(path: str | Path, expected: str) -> Any:
    """The parsed content of a JSON file.

    Parameters
    ----------
    path : str or Path
        The file.
    expected : str
        What the file should be, in words (``"the JSON of `station pattern --json`"``): the end of every message.

    Raises
    ------
    FileFormatError
        The file is not UTF-8 text or not JSON: ``FILE: not valid JSON (Expecting ',' delimiter at line 3 column 7);
        expected ...``.
    OSError
        The file cannot be read (missing, a folder, no permission): the caller's "no such file" is clearer.
    """
    path = Path(path)
    return parse_json(path.read_bytes(), str(path), expected)


def parse_json(raw: bytes, file: str, expected: str) -> Any:
    """Parse the bytes of a JSON file; ``file`` and ``expected`` are for the message (see :func:`load_json`)."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as error:
        raise FileFormatError(f"{file}: not UTF-8 text ({error.reason} at byte {error.start}); "
                              f"expected {expected}") from None
    try:
        return json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as error:
        raise FileFormatError(f"{file}: not valid JSON ({error.msg} at line {error.lineno} column {error.colno}); "
                              f"expected {expected}") from None
    except RecursionError:
        raise FileFormatError(f"{file}: not valid JSON (nested too deeply to read); expected {expected}") from None
    except ValueError as error:  # NaN, Infinity (from _reject_constant)
        raise FileFormatError(f"{file}: not valid JSON ({error}); expected {expected}") from None


def _reject_constant(name: str) -> float:
    raise ValueError(f"{name} is not a JSON number")
