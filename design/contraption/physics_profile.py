"""Physics profiles: material values measured for real parts, in a versioned TOML file, applied over a scenario's.

A profile (``station calibrate sim`` writes one; ``--physics PROFILE.toml`` uses it)::

    [profile]
    format = "chaos-station physics"
    version = 1
    name = "makerspace wood"
    created = "2026-12-03T12:00:00Z"
    source = "calibrate sim: 34 trials of BALLRUN"     # where the values came from
    scenarios = ["BALLRUN"]                             # optional: the contraptions it was fitted on
    [values]
    "wood.friction" = 0.42
    [intervals]                                         # optional: an uncertainty interval per value
    "wood.friction" = [0.40, 0.44]
    [fit]                                               # optional: numbers about the fit (brier_before, trials...)
    trials = 34

Applying a profile to a scenario (:func:`apply_profile`) sets the values of the scenario's materials that the
profile names and leaves the others: a profile fitted on several scenarios may name materials one of them lacks.
A profile made for another contraption is refused: one whose ``scenarios`` do not name the scenario (two
contraptions may share a material's name, ``wood``, and not its wood), or one none of whose values is a material
of the scenario. A profile without ``scenarios`` (written by hand) applies wherever its values fit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from design.contraption.errors import ScenarioFormatError
from design.contraption.fields import Checker, describe
from design.contraption.materials import split_name
from design.contraption.model import Scenario
from design.contraption.schema import MATERIAL_KEYS
from design.contraption.validation import with_physics
from design.datafiles import parse_toml

FORMAT = "chaos-station physics"
VERSION = 1
#: What a profile file should be, the end of the message for one that is not TOML.
PROFILE_FILE = "a physics profile: [profile] with format = \"chaos-station physics\", and [values]"


class PhysicsProfileError(ScenarioFormatError):
    """A physics profile is malformed, or does not fit the scenario it is applied to (names file and field)."""


@dataclass(frozen=True)
class PhysicsProfile:
    """Material values with where they came from.

    Attributes
    ----------
    name, created, source : str
        A name for people, when it was made (ISO 8601), and where its values came from.
    values : mapping
        ``{"wood.friction": 0.42}``.
    intervals : mapping
        ``{"wood.friction": (0.40, 0.44)}``, for some or all of ``values``.
    fit : mapping
        Numbers (and words) about the fit that made it: ``brier_before``, ``brier_after``, ``trials``, ...
    scenarios : tuple of str
        The names of the scenarios it was fitted on (``("BALLRUN",)``); empty: not said, it applies to any.
    """

    name: str
    values: Mapping[str, float]
    intervals: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    created: str = ""
    source: str = ""
    fit: Mapping[str, Any] = field(default_factory=dict)
    scenarios: tuple[str, ...] = ()

    def to_toml(self) -> str:
        """The profile as TOML text (what :func:`save_profile` writes and :func:`profile_from_text` reads)."""
        lines = ["[profile]", f"format = {_toml(FORMAT)}", f"version = {VERSION}", f"name = {_toml(self.name)}",
                 f"created = {_toml(self.created)}", f"source = {_toml(self.source)}"]
        if self.scenarios:
            lines.append(f"scenarios = {_toml(list(self.scenarios))}")
        lines += ["", "[values]"]
        lines += [f"{_toml(k)} = {_toml(v)}" for k, v in self.values.items()]
        if self.intervals:
            lines += ["", "[intervals]"]
            lines += [f"{_toml(k)} = {_toml(list(v))}" for k, v in self.intervals.items()]
        if self.fit:
            lines += ["", "[fit]"]
            lines += [f"{_toml(k)} = {_toml(v)}" for k, v in self.fit.items() if v is not None]
        return "\n".join(lines) + "\n"


class _ProfileChecker(Checker):
    """The scenario reader's typed field access, raising :class:`PhysicsProfileError`."""

    def fail(self, path: str, message: str) -> PhysicsProfileError:
        return PhysicsProfileError(self.file, path, message)


def _toml(value: Any) -> str:
    """A TOML literal of a string, number, boolean or array of them (all a profile holds)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"a profile holds finite numbers, got {value!r}")
        return repr(value)
    if isinstance(value, str):
        escaped = value.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")
        return f'"{escaped}"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    raise ValueError(f"a profile holds text, numbers and arrays, got {type(value).__name__}")


def load_profile(path: str | Path) -> PhysicsProfile:
    """Read and check a physics profile file.

    Raises
    ------
    PhysicsProfileError
        One line naming the file, the field and what was expected.
    FileNotFoundError
        When the file does not exist.
    """
    path = Path(path)
    return profile_from_text(path.read_bytes(), str(path))


def profile_from_text(raw: bytes | str, file: str = "<profile>") -> PhysicsProfile:
    """A physics profile from its TOML text (e.g. the ``physics.content`` of a logged trial)."""
    if isinstance(raw, str):
        raw = raw.encode("utf-8")
    data = parse_toml(raw, file, PROFILE_FILE, error=lambda detail: PhysicsProfileError(file, "", detail))
    check = _ProfileChecker(file)
    top = check.table(data, "")
    check.only(top, "", ("profile", "values", "intervals", "fit"))
    if "profile" not in top:
        raise check.fail("profile", f'missing; expected a [profile] table with format = "{FORMAT}"')
    header = check.table(top["profile"], "profile")
    check.only(header, "profile", ("format", "version", "name", "created", "source", "scenarios"))
    if header.get("format") != FORMAT:
        raise check.fail("profile.format", f'expected "{FORMAT}", got {describe(header.get("format"))}')
    version = header.get("version")
    if version != VERSION:
        raise check.fail("profile.version", f"expected {VERSION} (this station reads version {VERSION}), got "
                         f"{describe(version)}")
    text = {k: check.string(header.get(k, ""), f"profile.{k}") for k in ("name", "created", "source")}
    scenarios = header.get("scenarios", [])
    if not isinstance(scenarios, list) or not all(isinstance(s, str) and s.strip() for s in scenarios):
        raise check.fail("profile.scenarios", f"expected a list of scenario names (\"BALLRUN\"), got "
                         f"{describe(scenarios)}")
    if "values" not in top:
        raise check.fail("values", 'missing; expected a [values] table of "MATERIAL.PARAM" = number')
    values = {}
    for name, value in check.table(top["values"], "values").items():
        _check_name(check, f'values."{name}"', name)
        values[name] = check.number(value, f'values."{name}"', minimum=0.0)
    if not values:
        raise check.fail("values", 'expected at least one "MATERIAL.PARAM" = number')
    intervals = {}
    for name, value in check.table(top.get("intervals", {}), "intervals").items():
        path = f'intervals."{name}"'
        if name not in values:
            raise check.fail(path, f"expected an interval of a value in [values]; {name!r} has none")
        lo, hi = check.vector(value, path, 2)
        if not lo <= values[name] <= hi:
            raise check.fail(path, f"expected [low, high] around the value {values[name]:g}, got [{lo:g}, {hi:g}]")
        intervals[name] = (lo, hi)
    fit = dict(check.table(top.get("fit", {}), "fit"))
    return PhysicsProfile(name=text["name"] or Path(file).stem, values=values, intervals=intervals,
                          created=text["created"], source=text["source"], fit=fit, scenarios=tuple(scenarios))


def _check_name(check: Checker, path: str, name: str) -> None:
    try:
        split_name(name)
    except ValueError:
        raise check.fail(path, f"expected a name MATERIAL.PARAM with PARAM one of {', '.join(MATERIAL_KEYS)}, "
                         f"got {name!r}") from None


def save_profile(profile: PhysicsProfile, path: str | Path) -> Path:
    """Write ``profile`` as TOML (through a temporary file, so a failed write leaves no half profile)."""
    path = Path(path)
    text = profile.to_toml()
    profile_from_text(text, str(path))  # what we write must read back
    temporary = path.with_name(path.name + ".tmp")
    temporary.write_text(text, encoding="utf-8")
    temporary.replace(path)
    return path


def apply_profile(scenario: Scenario, profile: PhysicsProfile, file: str = "") -> Scenario:
    """``scenario`` with the profile's values for the materials it has (the others are left to other scenarios).

    Raises
    ------
    PhysicsProfileError
        When the profile was fitted on other scenarios, names none of the scenario's material values, or a value
        lies outside the scenario's range for it (one line naming the profile file and the field).
    """
    file = file or profile.name
    if profile.scenarios and scenario.name.casefold() not in {s.casefold() for s in profile.scenarios}:
        raise PhysicsProfileError(file, "profile.scenarios", f"a profile for another contraption "
                                  f"({', '.join(profile.scenarios)}); expected one fitted on {scenario.name}'s trials "
                                  "(`station calibrate sim --out`)")
    known = scenario.physics_parameters()
    values = {k: v for k, v in profile.values.items() if k in known}
    if not values:
        have = ", ".join(known) or "no materials"
        raise PhysicsProfileError(file, "values", f"none of its values ({', '.join(profile.values)}) is a material "
                                  f"value of {scenario.name!r}, which has: {have}")
    try:
        return with_physics(scenario, values)
    except ScenarioFormatError as error:
        raise PhysicsProfileError(file, error.field, str(error).split(": ", 2)[-1]) from None
