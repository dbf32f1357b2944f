"""Helpers shared by CLI commands: ``--set NAME=VALUE`` parsing, JSON output, output files."""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any, TextIO

from station.errors import UsageError


def parse_assignments(items: Iterable[str] | None, option: str = "--set") -> dict[str, float]:
    """Parse ``NAME=VALUE`` strings into a dict of floats.

    Raises
    ------
    UsageError
        On a missing ``=``, an empty name, a value that is not a finite number, or a name given twice.
    """
    values: dict[str, float] = {}
    for item in items or ():
        name, sep, text = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise UsageError(f"{option} {item!r}: expected NAME=VALUE, e.g. {option} d=2.5")
        try:
            value = float(text)
        except ValueError:
            raise UsageError(f"{option} {item!r}: value of {name!r} must be a number, got {text!r}") from None
        if not math.isfinite(value):
            raise UsageError(f"{option} {item!r}: value of {name!r} must be finite, got {text!r}")
        if name in values:
            raise UsageError(f"{option}: {name!r} is given twice")
        values[name] = value
    return values


def to_jsonable(value: Any) -> Any:
    """Convert numpy scalars and arrays, tuples, paths and dataclass-like objects to plain JSON values."""
    try:
        import numpy as np
    except ImportError:  # pragma: no cover
        np = None
    if np is not None:
        if isinstance(value, np.ndarray):
            return value.tolist()
        if isinstance(value, np.generic):
            return value.item()
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    return value


def emit_json(obj: Any, stream: TextIO | None = None) -> None:
    """Print ``obj`` as JSON on one line (stdout by default)."""
    stream = stream or sys.stdout
    json.dump(to_jsonable(obj), stream, allow_nan=False)
    stream.write("\n")


def output_suffix(path: str | Path, allowed: Iterable[str]) -> str:
    """The lower-case suffix of ``path``, checked against ``allowed`` (e.g. ``{".svg", ".png"}``)."""
    suffix = Path(path).suffix.lower()
    allowed = sorted(allowed)
    if suffix not in allowed:
        raise UsageError(f"output file {str(path)!r}: expected one of {', '.join(allowed)}, got {suffix or 'none'!r}")
    return suffix
