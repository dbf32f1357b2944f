"""Numbers with units in machine profiles: lengths in millimetres, feeds in mm/min, durations in seconds.

A bare number is millimetres, mm/min or seconds; a string carries its unit (``"297mm"``, ``"11in"``, ``"50mm/s"``,
``"150ms"``). A value that is neither, or a unit not listed, is a :class:`ProfileError` naming the field.
"""

from __future__ import annotations

import re
from typing import Any

from drivers.profiles.model import ProfileError

__all__ = ["parse_duration", "parse_feed", "parse_length"]

_LENGTH_UNITS = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4, "inch": 25.4, "pt": 25.4 / 72.0}
_TIME_UNITS = {"ms": 1e-3, "s": 1.0, "min": 60.0}
_NUMBER_UNIT = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-z/]*)\s*$")


def _split(value: Any, where: str, expected: str) -> tuple[float, str]:
    if isinstance(value, bool):
        raise ProfileError(f"{where}: expected {expected}, got {value!r}")
    if isinstance(value, (int, float)):
        return float(value), ""
    if isinstance(value, str):
        match = _NUMBER_UNIT.match(value)
        if match:
            return float(match.group(1)), match.group(2).lower()
    raise ProfileError(f"{where}: expected {expected}, got {value!r}")


def _scaled(value: Any, where: str, expected: str, kind: str, units: dict[str, float]) -> float:
    """``value`` (a number, or a string with one of ``units``) times its unit's factor; a bare number is unit 1."""
    number, unit = _split(value, where, expected)
    if unit == "":
        return number
    if unit not in units:
        raise ProfileError(f"{where}: unknown {kind} unit {unit!r} in {value!r}; use one of {sorted(units)}")
    return number * units[unit]


def parse_length(value: Any, where: str = "length") -> float:
    """A length in millimetres from a number (mm) or a string with a unit (mm, cm, m, in, pt)."""
    return _scaled(value, where, "a length such as 300 or '300mm' or '11in'", "length", _LENGTH_UNITS)


def parse_feed(value: Any, where: str = "feed") -> float:
    """A feed rate in mm/min from a number (mm/min) or a string such as '3000mm/min' or '50mm/s'."""
    number, unit = _split(value, where, "a feed such as 3000 or '3000mm/min' or '50mm/s'")
    if unit == "":
        return number
    length_unit, sep, time_unit = unit.partition("/")
    if not sep or length_unit not in _LENGTH_UNITS or time_unit not in _TIME_UNITS:
        raise ProfileError(f"{where}: unknown feed unit {unit!r} in {value!r}; use e.g. 'mm/min', 'mm/s', 'in/min'")
    return number * _LENGTH_UNITS[length_unit] * 60.0 / _TIME_UNITS[time_unit]


def parse_duration(value: Any, where: str = "duration") -> float:
    """A duration in seconds from a number (s) or a string such as '150ms' or '0.2s'."""
    return _scaled(value, where, "a duration such as 0.2 or '200ms'", "time", _TIME_UNITS)
