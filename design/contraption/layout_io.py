"""Layout files: the one reader of every command that takes a layout of a scenario's design space.

Accepted forms (JSON, or TOML for the hand-written ones; values in real units, m and degrees):

``LAYOUT.json``
    What ``station optimize --out`` writes: ``{"format": "chaos-station robust layout 1", "scenario": ...,
    "content_hash": ..., "parameters": [{"name": "track.x", "value": -0.06, ...}, ...], ...}``. Every parameter of
    the scenario must be listed (the optimizer lists them all; a missing one means another design space). The rest
    of the optimizer's record (predictions, settings) is not the layout and is not read here.
``{"parameters": {"track.x": -0.1, ...}}``
    Hand-written: missing parameters take the scenario's defaults, and the result names them.
``{"x": [v1, v2, ...]}``
    Every parameter in design-space order.
``{"track.x": -0.1, ...}``
    The flat form of the scenario files' ``[layouts.NAME]`` tables (missing parameters defaulted too); also inside
    ``{"layout": {...}}``.

A ``content_hash`` (and ``scenario`` name) different from the scenario's is a warning, not an error: the file was
written for another version of the scenario (an edited mass, say) and its values still name points of the design
space. Every error is a :class:`~design.contraption.errors.ScenarioFormatError` naming the file, the field and the
expected value.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from design.contraption.errors import LayoutError, ScenarioFormatError
from design.contraption.fields import describe as _kind
from design.contraption.fields import join_path as _join
from design.contraption.model import Scenario
from design.contraption.schema import ANGLE_KEYS
from design.datafiles import parse_data

#: What a layout file should be, the end of the message for one that is not JSON or TOML.
LAYOUT_FILE = ('a layout: the LAYOUT.json of `station optimize`, {"x": [...]} or {"parameters": {...}} '
               '(JSON or TOML)')

#: The ``format`` value of the optimizer's LAYOUT.json (design/robust/pipeline.py writes it).
OPTIMIZER_FORMAT = "chaos-station robust layout 1"

#: Every way a layout can be given, in words (the ``format`` of a :class:`LoadedLayout`).
FORMATS = {
    "LAYOUT.json": "the optimizer's LAYOUT.json",
    "parameters": '{"parameters": {name: value}}',
    "x": '{"x": [values in design-space order]}',
    "mapping": "{name: value}",
    "named": "a layout named in the scenario file",
    "values": "values given in order",
    "defaults": "the scenario's defaults",
}

#: Top-level fields a hand-written file may carry beside its values (the optimizer's file may carry anything).
_ANNOTATIONS = ("scenario", "content_hash", "format", "description")


@dataclass(frozen=True, eq=False)
class LoadedLayout:
    """A layout of a scenario's design space and where it came from.

    Attributes
    ----------
    x : ndarray
        The values in real units (m, degrees), in design-space order, within the design space's bounds.
    source : str
        The file it was read from (the scenario file for a named layout; what gave the values, e.g. ``"--x"``, for
        values given in order; "" for the scenario's defaults).
    format : str
        A key of :data:`FORMATS`.
    name : str
        The layout's name for a named layout, else "".
    defaulted : tuple of str
        Parameters the source did not give, which took the scenario's defaults.
    warnings : tuple of str
        Things to tell the user that do not stop the layout being used (a content hash of another scenario).
    """

    x: np.ndarray
    source: str
    format: str
    name: str = ""
    defaulted: tuple[str, ...] = ()
    warnings: tuple[str, ...] = field(default=())

    def describe(self) -> str:
        """Which layout this is, in words, e.g. ``"layout.json (the optimizer's LAYOUT.json)"``."""
        if self.format == "defaults":
            return "the scenario's defaults"
        if self.format == "named":
            return f"{self.name!r} (named in {self.source})"
        if self.format == "values":
            return f"the values of {self.source}" if self.source else "values given in order"
        return f"{self.source} ({FORMATS[self.format]})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly description (without the values): source, format, name, defaulted, warnings."""
        return {"source": self.source, "format": self.format, "name": self.name,
                "defaulted": list(self.defaulted), "warnings": list(self.warnings)}


def default_layout(scenario: Scenario) -> LoadedLayout:
    """The scenario file's own transforms as a layout."""
    return LoadedLayout(scenario.default_layout(), "", "defaults", defaulted=tuple(scenario.design_space.names))


def named_layout(scenario: Scenario, name: str) -> LoadedLayout:
    """A layout named in the scenario file (``[layouts.NAME]``); raises :class:`LayoutError` for another name."""
    return LoadedLayout(scenario.layout(name), scenario.source, "named", name=name)


def values_layout(scenario: Scenario, values, *, what: str = "values") -> LoadedLayout:
    """Every parameter's value in design-space order, checked against the bounds (raises :class:`LayoutError`)."""
    space = scenario.design_space
    x = np.asarray(values, dtype=float).reshape(-1)
    if x.shape != (space.dim,):
        raise LayoutError(f"{what}: expected {space.dim} values ({', '.join(space.names)}), got {x.size}")
    return LoadedLayout(space.check_bounds(x, what=what).copy(), what, "values")


def resolve_layout(text: str, scenario: Scenario) -> LoadedLayout:
    """A layout file (any form of this module), or else a layout named in the scenario file (``success``).

    Raises
    ------
    LayoutError
        When ``text`` is neither an existing file nor a layout name of the scenario.
    ScenarioFormatError
        For a malformed file.
    """
    path = Path(text)
    if text in scenario.layouts and not path.is_file():
        return named_layout(scenario, text)
    if not path.exists() and path.suffix.lower() not in (".json", ".toml"):
        names = ", ".join(sorted(scenario.layouts)) or "none"
        raise LayoutError(f"layout {text!r}: no such file and no layout of that name in {scenario.source} "
                          f"(its layouts: {names})")
    return read_layout(path, scenario)


def read_layout(path: str | Path, scenario: Scenario) -> LoadedLayout:
    """Read a layout file of any form of this module for ``scenario``.

    Raises
    ------
    ScenarioFormatError
        The file is not UTF-8, not JSON/TOML, or its content does not fit the scenario; the message names the file,
        the field and the expected value.
    OSError
        The file cannot be read (``FileNotFoundError``, ``IsADirectoryError``...).
    """
    path = Path(path)
    return layout_from_data(read_layout_data(path), scenario, file=str(path))


def load_layout(path: str | Path, scenario: Scenario) -> np.ndarray:
    """The values of :func:`read_layout` (real units, design-space order)."""
    return read_layout(path, scenario).x


def read_layout_data(path: str | Path) -> Any:
    """The parsed content of a layout file: TOML for ``.toml``, JSON otherwise (a LAYOUT.json of any name).

    Text that is not UTF-8 or not JSON/TOML raises :class:`ScenarioFormatError` with :mod:`design.datafiles`'s one
    message (``"FILE: not valid JSON (... at line L column C); expected a layout file..."``);
    ``OSError`` passes, so that callers can say "no such file" their own way.
    """
    path = Path(path)
    file = str(path)
    try:
        return parse_data(path.read_bytes(), file, LAYOUT_FILE, object_pairs_hook=_unique_keys,
                          error=lambda detail: ScenarioFormatError(file, "", detail))
    except _DuplicateKey as error:
        raise ScenarioFormatError(file, str(error), "given twice; expected each field once") from None


class _DuplicateKey(ValueError):
    pass


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    # json.loads keeps the last of two equal keys silently; a layout with "track.x" twice is a mistake to report.
    result: dict[str, Any] = {}
    for key, value in pairs:
        if key in result:
            raise _DuplicateKey(key)
        result[key] = value
    return result


def layout_from_data(data: Any, scenario: Scenario, *, file: str = "<data>") -> LoadedLayout:
    """Validate layout data (any form of this module) against the scenario's design space."""
    return _Reader(file, scenario).read(data)


class _Reader:
    """One file's reading: typed field access whose errors name the file, the field and the expected value."""

    def __init__(self, file: str, scenario: Scenario) -> None:
        self.file = file
        self.scenario = scenario
        self.space = scenario.design_space
        self.warnings: list[str] = []

    def fail(self, field_path: str, message: str) -> ScenarioFormatError:
        return ScenarioFormatError(self.file, field_path, message)

    def read(self, data: Any) -> LoadedLayout:
        table = self.table(data, "")
        prefix = ""
        if set(table) == {"layout"}:
            table, prefix = self.table(table["layout"], "layout"), "layout"
        if "parameters" in table:
            parameters = table["parameters"]
            if isinstance(parameters, list):
                return self.optimizer_form(table)
            if isinstance(parameters, dict):
                self.annotations(table, prefix, allowed=("parameters", *_ANNOTATIONS))
                values = self.mapping(self.table(parameters, _join(prefix, "parameters")),
                                      _join(prefix, "parameters"))
                return self.result(values, "parameters")
            raise self.fail(_join(prefix, "parameters"), "expected a list of {name, value} (a LAYOUT.json) or a "
                            f"table of name: value, got {_kind(parameters)}")
        if "x" in table:
            self.annotations(table, prefix, allowed=("x", *_ANNOTATIONS))
            return self.x_form(table["x"], _join(prefix, "x"))
        return self.result(self.mapping(table, prefix), "mapping")

    # -- the forms ------------------------------------------------------------------------------------------------
    def optimizer_form(self, table: dict) -> LoadedLayout:
        if "format" in table and table["format"] != OPTIMIZER_FORMAT:
            raise self.fail("format", f"expected {OPTIMIZER_FORMAT!r} (written by station optimize), "
                            f"got {_kind(table['format'])}")
        mismatch = self.check_origin(table)
        values: dict[str, float] = {}
        for i, entry in enumerate(table["parameters"]):
            where = f"parameters[{i}]"
            entry = self.table(entry, where)
            for key in ("name", "value"):
                if key not in entry:
                    raise self.fail(f"{where}.{key}", "missing; expected {name, value} as station optimize writes")
            name = entry["name"]
            if not isinstance(name, str) or name not in self.space.names:
                raise self.fail(f"{where}.name", f"expected one of {self.expected_names()}, got {_kind(name)}"
                                + mismatch)
            if name in values:
                raise self.fail(f"{where}.name", f"{name!r} is listed twice; expected each parameter once")
            values[name] = self.value(entry["value"], f"{where}.value", name)
        missing = [n for n in self.space.names if n not in values]
        if missing:
            raise self.fail("parameters", f"lacks {', '.join(missing)}; a LAYOUT.json lists every parameter "
                            f"(expected {self.expected_names()})" + mismatch)
        return self.result(values, "LAYOUT.json")

    def x_form(self, value: Any, where: str) -> LoadedLayout:
        if not isinstance(value, list):
            raise self.fail(where, f"expected an array of {self.space.dim} numbers ({self.expected_names()}), "
                            f"got {_kind(value)}")
        if len(value) != self.space.dim:
            raise self.fail(where, f"expected an array of {self.space.dim} items ({self.expected_names()}), "
                            f"got {len(value)}")
        values = {name: self.value(v, f"{where}[{i}]", name) for i, (name, v) in enumerate(zip(self.space.names,
                                                                                             value))}
        return self.result(values, "x")

    def mapping(self, table: dict, prefix: str) -> dict[str, float]:
        values = {}
        for key, value in table.items():
            if key not in self.space.names:
                also = " (or 'x': [...], or 'parameters': {...})" if not prefix else ""
                raise self.fail(_join(prefix, key), f"unknown design parameter; expected one of "
                                f"{self.expected_names()}{also}")
            values[key] = self.value(value, _join(prefix, key), key)
        return values

    # -- pieces ---------------------------------------------------------------------------------------------------
    def result(self, values: Mapping[str, float], form: str) -> LoadedLayout:
        x = self.space.default.copy()
        for name, value in values.items():
            x[self.space.names.index(name)] = value
        defaulted = tuple(n for n in self.space.names if n not in values)
        return LoadedLayout(np.clip(x, self.space.lower, self.space.upper), self.file, form,
                            defaulted=defaulted, warnings=tuple(self.warnings))

    def value(self, value: Any, where: str, name: str) -> float:
        """A parameter's value: a finite number within its range (a rounding hair outside is clipped)."""
        i = self.space.names.index(name)
        lo, hi = float(self.space.lower[i]), float(self.space.upper[i])
        unit = "deg" if name.rsplit(".", 1)[-1] in ANGLE_KEYS else "m"
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(where, f"expected a number in [{lo:g}, {hi:g}] {unit}, got {_kind(value)}")
        number = float(value)
        slack = 1e-9 * max(1.0, hi - lo)
        if not (math.isfinite(number) and lo - slack <= number <= hi + slack):
            raise self.fail(where, f"expected a value in [{lo:g}, {hi:g}] {unit}, got {number:g}")
        return number

    def check_origin(self, table: dict) -> str:
        """Warn when the file names another scenario or content; returns the words to add to an error."""
        written_for = table.get("scenario")
        digest = table.get("content_hash")
        if digest is not None and not isinstance(digest, str):
            raise self.fail("content_hash", f"expected the scenario's sha256 as text, got {_kind(digest)}")
        if written_for is not None and not isinstance(written_for, str):
            raise self.fail("scenario", f"expected the scenario's name as text, got {_kind(written_for)}")
        if digest is not None and digest != self.scenario.content_hash:
            named = f"{written_for!r}" if written_for else "a scenario"
            words = (f"content_hash: written for {named} of another content ({digest[:12]}...) than "
                     f"{self.scenario.name!r} ({self.scenario.content_hash[:12]}...)")
        elif digest is None and written_for is not None and written_for != self.scenario.name:
            words = f"scenario: written for {written_for!r}, not {self.scenario.name!r}"
        else:
            return ""
        self.warnings.append(f"{self.file}: {words}; its values are used as they are")
        return f"; the file's {words}"

    def annotations(self, table: dict, prefix: str, allowed: tuple[str, ...]) -> None:
        # The hand-written forms: a field beside the values that is no annotation is a typo or a mix of forms.
        for key in table:
            if key not in allowed:
                raise self.fail(_join(prefix, key), f"unknown field; expected {', '.join(allowed)}")
        if "format" in table and not isinstance(table["format"], str):
            raise self.fail(_join(prefix, "format"), f"expected text, got {_kind(table['format'])}")
        self.check_origin(table)

    def table(self, value: Any, where: str) -> dict:
        if not isinstance(value, dict):
            raise self.fail(where, f"expected a table (a JSON object), got {_kind(value)}")
        return value

    def expected_names(self) -> str:
        return ", ".join(self.space.names) or "none (the scenario has no design parameters)"

