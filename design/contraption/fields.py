"""Typed access to the fields of parsed TOML/JSON data, raising one error that names file, field and expectation.

Used by the scenario validator (:mod:`design.contraption.validation`) and the layout-file reader
(:mod:`design.contraption.layout_io`), so that every bad value of either reads the same:
``t.toml: objects[3].transform.heading: expected a number, got text ('north')``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

from design.contraption.errors import ScenarioFormatError
from design.contraption.schema import BODY_REF, REQUIRED, Kind, Param

_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
_BODY_COUNTS = {Kind.BODIES: (1, 2), Kind.BODIES2: (2, 2), Kind.BODIES1_PLUS: (1, None)}


class Checker:
    """Typed field access that raises :class:`ScenarioFormatError` naming file, field path and expectation.

    Parameters
    ----------
    file : str
        The file the data came from, the first part of every message (``"<data>"`` for data built in memory).
    """

    def __init__(self, file: str) -> None:
        self.file = file

    def fail(self, path: str, message: str) -> ScenarioFormatError:
        return ScenarioFormatError(self.file, path, message)

    def table(self, value: Any, path: str) -> dict:
        if not isinstance(value, dict):
            raise self.fail(path, f"expected a table (mapping), got {describe(value)}")
        for key in value:
            if not isinstance(key, str):
                raise self.fail(path, f"expected text keys, got {key!r}")
        return value

    def only(self, table: dict, path: str, allowed) -> None:
        for key in table:
            if key not in allowed:
                expected = ", ".join(allowed) if allowed else "no fields"
                raise self.fail(join_path(path, key), f"unknown field; expected one of: {expected}")

    def string(self, value: Any, path: str, *, pattern: re.Pattern | None = None, what: str = "text") -> str:
        if not isinstance(value, str):
            raise self.fail(path, f"expected {what}, got {describe(value)}")
        if pattern is not None and not pattern.match(value):
            raise self.fail(path, f"expected {what}, got {value!r}")
        return value

    def number(self, value: Any, path: str, *, minimum: float | None = None, strict: bool = False) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(path, f"expected a number, got {describe(value)}")
        number = float(value)
        if not math.isfinite(number):
            raise self.fail(path, f"expected a finite number, got {value!r}")
        if minimum is not None:
            if strict and not number > minimum:
                raise self.fail(path, f"expected a number > {minimum:g}, got {value!r}")
            if not strict and not number >= minimum:
                raise self.fail(path, f"expected a number >= {minimum:g}, got {value!r}")
        return number

    def integer(self, value: Any, path: str, *, minimum: int = 1) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(path, f"expected an integer >= {minimum}, got {describe(value)}")
        if value < minimum:
            raise self.fail(path, f"expected an integer >= {minimum}, got {value!r}")
        return int(value)

    def boolean(self, value: Any, path: str) -> bool:
        if not isinstance(value, bool):
            raise self.fail(path, f"expected true or false, got {describe(value)}")
        return value

    def array(self, value: Any, path: str, *, min_len: int = 0, max_len: int | None = None) -> list:
        if not isinstance(value, list):
            raise self.fail(path, f"expected an array, got {describe(value)}")
        if len(value) < min_len or (max_len is not None and len(value) > max_len):
            size = f"{min_len}" if max_len == min_len else f"{min_len} to {max_len if max_len is not None else 'any'}"
            raise self.fail(path, f"expected an array of {size} items, got {len(value)}")
        return value

    def vector(self, value: Any, path: str, n: int, *, positive: bool = False) -> tuple[float, ...]:
        items = self.array(value, path, min_len=n, max_len=n)
        return tuple(
            self.number(v, f"{path}[{i}]", minimum=0.0 if positive else None, strict=positive)
            for i, v in enumerate(items)
        )

    def points(self, value: Any, path: str, n: int, *, min_len: int = 0, max_len: int | None = None) -> tuple:
        """An array of points of ``n`` numbers each."""
        items = self.array(value, path, min_len=min_len, max_len=max_len)
        return tuple(self.vector(v, f"{path}[{i}]", n) for i, v in enumerate(items))

    def param(self, kind: Kind, value: Any, path: str) -> Any:
        """The value of a schema field of this kind (see :class:`~design.contraption.schema.Kind`)."""
        if kind is Kind.POS:
            return self.number(value, path, minimum=0.0, strict=True)
        if kind is Kind.NONNEG:
            return self.number(value, path, minimum=0.0)
        if kind is Kind.FLOAT:
            return self.number(value, path)
        if kind is Kind.INT:
            return self.integer(value, path)
        if kind is Kind.VEC3:
            return self.vector(value, path, 3)
        if kind is Kind.VEC3POS:
            return self.vector(value, path, 3, positive=True)
        if kind is Kind.AXIS:
            if isinstance(value, str):
                if value not in _AXES:
                    raise self.fail(path, f'expected "x", "y", "z" or 3 numbers, got {value!r}')
                return _AXES[value]
            axis = self.vector(value, path, 3)
            if math.hypot(*axis) < 1e-12:
                raise self.fail(path, "expected a non-zero axis")
            return axis
        if kind is Kind.BODY:
            return self.body_ref(value, path)
        if kind in _BODY_COUNTS:
            lo, hi = _BODY_COUNTS[kind]
            items = self.array(value, path, min_len=lo, max_len=hi)
            return tuple(self.body_ref(v, f"{path}[{i}]") for i, v in enumerate(items))
        if kind is Kind.ANCHORS:
            return self.points(value, path, 3, min_len=2, max_len=2)
        if kind is Kind.POSES:
            return self.points(value, path, 3, min_len=1)
        if kind is Kind.POINTS2:
            return self.points(value, path, 2, min_len=2)
        if kind is Kind.POINTS3:
            return self.points(value, path, 3)
        raise AssertionError(kind)  # pragma: no cover

    def body_ref(self, value: Any, path: str) -> str:
        return self.string(value, path, pattern=BODY_REF, what='an object name (or "run[i]" for a domino)')

    def params(self, schema: Mapping[str, Param], table: dict, path: str) -> dict[str, Any]:
        """The fields of ``schema`` read from ``table``: given, defaulted, or absent when optional."""
        result = {}
        for key, (kind, default) in schema.items():
            if key in table:
                result[key] = self.param(kind, table[key], join_path(path, key))
            elif default is REQUIRED:
                raise self.fail(join_path(path, key), f"missing; expected {kind.expected}")
            elif default is not None:
                result[key] = default
        return result


def describe(value: Any) -> str:
    """What a parsed value is, in words, for the "got ..." of a message (``text ('north')``, ``an array``)."""
    if isinstance(value, bool):
        return f"a boolean ({str(value).lower()})"
    if isinstance(value, (int, float)):
        return f"a number ({value!r})"
    if isinstance(value, str):
        return f"text ({value!r})"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, dict):
        return "a table"
    if value is None:
        return "null"
    return type(value).__name__


def join_path(path: str, key: str) -> str:
    """The path of ``key`` inside the table at ``path`` ("" is the top level)."""
    return f"{path}.{key}" if path else key
