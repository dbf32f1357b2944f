"""Scenario files: the scene, the causal graph and the design space of a chain-reaction contraption (thesis 4.3).

A scenario is a data file (TOML or JSON, never executed). Its top-level tables:

``[scenario]``
    ``name``, ``description`` (optional).
``[settings]`` (optional)
    ``time_step`` (s, default 1/500), ``event_timeout`` (s, default 2), ``max_duration`` (s, default 4),
    ``gravity`` (m/s², default -9.81, along z), ``solver_iterations`` (default 50),
    ``overlap_tolerance`` (fraction of the smaller body's smallest dimension tolerated as interpenetration,
    default 0.05), ``ignore_overlap`` (list of ``[a, b]`` object pairs allowed to interpenetrate).
``[[objects]]``
    ``name``, ``type`` (a primitive, see :data:`PRIMITIVES`), ``parent`` (optional: the transform is then in the
    parent's frame), ``[objects.transform]`` (``x``, ``y``, ``z`` in m; ``heading``, ``pitch``, ``roll`` in degrees),
    ``[objects.ranges]`` (``component = [min, max]``: makes the component a design parameter),
    ``[objects.shape]`` (the primitive's shape parameters), ``[objects.physics]`` (``mass`` — 0 or absent is
    static —, ``friction``, ``rolling_friction``, ``spinning_friction``, ``restitution``, ``linear_damping``,
    ``angular_damping``), ``[objects.tag]`` (optional AprilTag: ``id``, ``x``, ``y``, ``z``, ``size`` on the part),
    ``sleeping`` (true: the bodies start asleep and are not simulated until something touches them — for parts
    resting stably, a large speed-up; default true for DominoRun, false otherwise).
``[[events]]``
    ``name``, ``type`` (see :data:`EVENTS`), the event's parameters (object names; a domino of a run is
    ``run[0]``, ``run[-1]``), ``after`` (parent events; none for the single root), ``join`` (``"all"``: every parent
    must succeed, the thesis's rule; ``"any"``: one parent is enough), ``timeout`` (s), ``duration`` (s: the
    condition must hold that long), ``label`` (words shown to people).
``[layouts.NAME]`` (optional)
    Named layouts: ``"object.component" = value`` in real units (m, degrees); absent parameters keep the transform's
    value. The examples carry a ``success`` and a ``failure`` layout.

Angles: ``heading`` turns about +z, ``pitch`` about +x, ``roll`` about +y (right-handed; the rotation is
``Rz(heading) Rx(pitch) Ry(roll)``, Panda3D's HPR order). With z up and the layout in the x-z plane, ``roll`` is the
rotation in that plane: a positive roll tilts the +x end down.

The design space lists the ranged components in file order of the objects, and for each object in the order
x, y, z, heading, pitch, roll; its names are ``"object.component"``.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from design.contraption.errors import LayoutError, ScenarioFormatError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

TRANSFORM_KEYS = ("x", "y", "z", "heading", "pitch", "roll")
ANGLE_KEYS = frozenset({"heading", "pitch", "roll"})
PHYSICS_KEYS = (
    "mass",
    "friction",
    "rolling_friction",
    "spinning_friction",
    "restitution",
    "linear_damping",
    "angular_damping",
)
PHYSICS_DEFAULTS = {
    "mass": 0.0,
    "friction": 0.5,
    "rolling_friction": 0.0,
    "spinning_friction": 0.0,
    "restitution": 0.0,
    "linear_damping": 0.0,
    "angular_damping": 0.0,
}
_BODY_REF = re.compile(r"^([A-Za-z_][A-Za-z0-9_\-]*)(?:\[(-?\d+)\])?$")
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_\-]*$")

# ---------------------------------------------------------------------------------------------------------------
# Schemas. A parameter spec is (kind, default); default ``...`` means required, ``None`` means optional.
# Kinds: pos (float > 0), nonneg (float >= 0), float, int (int >= 1), vec3 (3 floats), vec3pos (3 floats > 0),
# axis ("x"|"y"|"z" or 3 floats, not zero), body (a body reference), bodies (1-2 body references), names (object
# names), poses (list of [x, y, heading_deg]), points2 (list of [x, y]), points3 (list of [x, y, z]).
# ---------------------------------------------------------------------------------------------------------------

REQUIRED = ...
Y_AXIS = (0.0, 1.0, 0.0)

#: Shape parameters of each primitive (thesis App. C.1). ``body`` says whether the primitive makes rigid bodies.
PRIMITIVES: dict[str, dict[str, Any]] = {
    "Plane": {"body": True, "params": {}},
    "Empty": {"body": False, "params": {}},
    "Ball": {"body": True, "params": {"radius": ("pos", REQUIRED)}},
    "Box": {"body": True, "params": {"size": ("vec3pos", REQUIRED)}},
    "OpenBox": {"body": True, "params": {"size": ("vec3pos", REQUIRED), "thickness": ("pos", REQUIRED)}},
    "Cylinder": {"body": True, "params": {"radius": ("pos", REQUIRED), "height": ("pos", REQUIRED)}},
    "Capsule": {"body": True, "params": {"radius": ("pos", REQUIRED), "length": ("pos", REQUIRED)}},
    "Goblet": {
        "body": True,
        "params": {
            "height": ("pos", REQUIRED),
            "radius_top": ("pos", REQUIRED),
            "radius_bottom": ("pos", REQUIRED),
            "thickness": ("pos", 0.002),
            "sides": ("int", 12),
        },
    },
    "Track": {
        "body": True,
        "params": {
            "length": ("pos", REQUIRED),
            "width": ("pos", REQUIRED),
            "height": ("pos", REQUIRED),
            "wall_thickness": ("pos", REQUIRED),
        },
    },
    "Pivot": {"body": False, "params": {"body": ("body", REQUIRED), "other": ("body", None), "axis": ("axis", Y_AXIS)}},
    "Fastener": {"body": False, "params": {"bodies": ("bodies", REQUIRED)}},
    "Lever": {
        "body": True,
        "params": {"size": ("vec3pos", REQUIRED), "pivot": ("vec3", (0.0, 0.0, 0.0)), "axis": ("axis", Y_AXIS)},
    },
    "Pulley": {"body": True, "params": {"radius": ("pos", REQUIRED), "height": ("pos", REQUIRED)}},
    "DominoRun": {
        "body": True,
        "params": {
            "size": ("vec3pos", REQUIRED),
            "poses": ("poses", None),
            "path": ("points2", None),
            "spacing": ("pos", None),
            "count": ("int", None),
        },
    },
    "TensionRope": {
        "body": False,
        "params": {
            "ends": ("bodies2", REQUIRED),
            "anchors": ("anchors", ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))),
            "guides": ("points3", ()),
            "length": ("pos", None),
        },
    },
    "RopePulley": {
        "body": False,
        "params": {
            "ends": ("bodies2", REQUIRED),
            "pulleys": ("bodies1+", REQUIRED),
            "anchors": ("anchors", ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))),
            "length": ("pos", None),
        },
    },
}

#: Parameters of each event type (thesis App. C.2); every event also takes after, join, timeout, duration, label.
EVENTS: dict[str, dict[str, tuple[str, Any]]] = {
    "Contact": {"a": ("body", REQUIRED), "b": ("body", REQUIRED)},
    "NoContact": {"a": ("body", REQUIRED), "b": ("body", REQUIRED)},
    "RollingOn": {"body": ("body", REQUIRED), "on": ("body", REQUIRED), "min_angular_speed": ("pos", 1.0)},
    "Falling": {"body": ("body", REQUIRED), "min_speed": ("pos", 0.05)},
    "Rising": {"body": ("body", REQUIRED), "min_speed": ("pos", 0.05)},
    "Pivoting": {"body": ("body", REQUIRED), "min_angular_speed": ("pos", 0.5), "axis": ("axis", None)},
    "Stopping": {"body": ("body", REQUIRED), "max_speed": ("pos", 0.01), "max_angular_speed": ("pos", 0.2)},
    "NotMoving": {"body": ("body", REQUIRED), "tolerance": ("pos", 0.002)},
    "Toppling": {"body": ("body", REQUIRED), "angle": ("pos", 15.0)},
    "Inclusion": {"body": ("body", REQUIRED), "container": ("body", REQUIRED)},
}
EVENT_COMMON = ("name", "type", "after", "join", "timeout", "duration", "label")

#: Primitives whose objects cannot be placed (no ranges): they only tie other objects together.
UNPLACED = frozenset({"Fastener"})


# ---------------------------------------------------------------------------------------------------------------
# Data model
# ---------------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Transform:
    """A pose relative to the parent: position in m, angles in degrees (heading, pitch, roll)."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    heading: float = 0.0
    pitch: float = 0.0
    roll: float = 0.0

    def replace(self, **values: float) -> Transform:
        data = {k: getattr(self, k) for k in TRANSFORM_KEYS}
        data.update(values)
        return Transform(**data)


@dataclass(frozen=True)
class Physics:
    """Physical parameters of a body (SI units); ``mass == 0`` means static."""

    mass: float = 0.0
    friction: float = 0.5
    rolling_friction: float = 0.0
    spinning_friction: float = 0.0
    restitution: float = 0.0
    linear_damping: float = 0.0
    angular_damping: float = 0.0

    @property
    def static(self) -> bool:
        return self.mass <= 0.0


@dataclass(frozen=True)
class Tag:
    """An AprilTag printed on a part: its id and the centre of the tag in the part's frame (m), edge size (m)."""

    id: int
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    size: float = 0.02


@dataclass(frozen=True)
class ObjectSpec:
    """One object of the scene: a primitive with its shape, physics, parent and transform."""

    name: str
    type: str
    transform: Transform
    parent: str | None = None
    ranges: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    shape: Mapping[str, Any] = field(default_factory=dict)
    physics: Physics = field(default_factory=Physics)
    tag: Tag | None = None
    index: int = 0
    sleeping: bool | None = None

    @property
    def starts_asleep(self) -> bool:
        """Whether the bodies start asleep (not simulated until something touches them)."""
        return self.type == "DominoRun" if self.sleeping is None else self.sleeping

    @property
    def has_body(self) -> bool:
        return bool(PRIMITIVES[self.type]["body"])


@dataclass(frozen=True)
class EventSpec:
    """One event of the causal graph."""

    name: str
    type: str
    params: Mapping[str, Any]
    after: tuple[str, ...]
    join: str
    timeout: float
    duration: float
    label: str
    index: int = 0


@dataclass(frozen=True)
class Settings:
    """Simulation settings of a scenario."""

    time_step: float = 1.0 / 500.0
    event_timeout: float = 2.0
    max_duration: float = 4.0
    gravity: float = -9.81
    solver_iterations: int = 50
    overlap_tolerance: float = 0.05
    ignore_overlap: tuple[tuple[str, str], ...] = ()


class DesignSpace:
    """The ranged transform components of a scenario, in a stable order, and their normalization to [0, 1]^d.

    Parameters
    ----------
    names : sequence of str
        ``"object.component"`` names.
    lower, upper : array_like
        Bounds in real units (m, degrees).
    default : array_like
        The values of the scenario file's transforms.
    """

    def __init__(self, names, lower, upper, default) -> None:
        self.names: tuple[str, ...] = tuple(names)
        self.lower = np.asarray(lower, dtype=float).reshape(-1)
        self.upper = np.asarray(upper, dtype=float).reshape(-1)
        self.default = np.asarray(default, dtype=float).reshape(-1)
        for array in (self.lower, self.upper, self.default):
            array.setflags(write=False)

    @property
    def dim(self) -> int:
        return len(self.names)

    def __len__(self) -> int:
        return self.dim

    def __repr__(self) -> str:
        return f"DesignSpace({list(self.names)!r})"

    def _check(self, x, what: str) -> np.ndarray:
        array = np.asarray(x, dtype=float)
        if array.shape[-1:] != (self.dim,) and not (self.dim == 0 and array.size == 0):
            raise LayoutError(f"{what}: expected {self.dim} values ({', '.join(self.names)}), got shape {array.shape}")
        if not np.all(np.isfinite(array)):
            raise LayoutError(f"{what}: every value must be finite, got {array.tolist()}")
        return array

    def to_normalized(self, x) -> np.ndarray:
        """Real units → [0, 1]^d (works on one vector or on rows of a matrix)."""
        x = self._check(x, "layout")
        span = np.where(self.upper > self.lower, self.upper - self.lower, 1.0)
        return (x - self.lower) / span

    def from_normalized(self, u) -> np.ndarray:
        """[0, 1]^d → real units (works on one vector or on rows of a matrix)."""
        u = self._check(u, "normalized layout")
        return self.lower + u * (self.upper - self.lower)

    def contains(self, x, tol: float = 1e-9) -> bool:
        x = self._check(x, "layout")
        span = self.upper - self.lower
        return bool(np.all(x >= self.lower - tol * span) and np.all(x <= self.upper + tol * span))

    def vector(self, values: Mapping[str, float] | None = None, *, what: str = "layout") -> np.ndarray:
        """A layout vector from ``{"object.component": value}`` (missing names keep their default)."""
        x = self.default.copy()
        for name, value in (values or {}).items():
            if name not in self.names:
                raise LayoutError(f"{what}: unknown design parameter {name!r}; expected one of {list(self.names)}")
            x[self.names.index(name)] = float(value)
        self.check_bounds(x, what=what)
        return x

    def as_dict(self, x) -> dict[str, float]:
        x = self._check(x, "layout")
        return {name: float(v) for name, v in zip(self.names, x)}

    def check_bounds(self, x, *, what: str = "layout") -> np.ndarray:
        """Raise :class:`LayoutError` naming the first component outside its range."""
        x = self._check(x, what)
        for name, value, lo, hi in zip(self.names, x, self.lower, self.upper):
            slack = 1e-9 * max(1.0, abs(hi - lo))
            if not lo - slack <= value <= hi + slack:
                raise LayoutError(f"{what}: {name} = {value:g} is outside its range [{lo:g}, {hi:g}]")
        return x


@dataclass(frozen=True, eq=False)
class Scenario:
    """A loaded, validated scenario: scene (objects), causal graph (events) and design space."""

    name: str
    description: str
    settings: Settings
    objects: tuple[ObjectSpec, ...]
    event_specs: tuple[EventSpec, ...]
    design_space: DesignSpace
    layouts: Mapping[str, np.ndarray]
    content_hash: str
    source: str = "<data>"

    @property
    def events(self) -> tuple[str, ...]:
        """Event names in file order."""
        return tuple(e.name for e in self.event_specs)

    @property
    def root(self) -> str:
        return next(e.name for e in self.event_specs if not e.after)

    @property
    def edges(self) -> list[tuple[str, str]]:
        return [(parent, e.name) for e in self.event_specs for parent in e.after]

    def children(self, event: str) -> list[str]:
        return [e.name for e in self.event_specs if event in e.after]

    def leaves(self) -> list[str]:
        parents = {p for e in self.event_specs for p in e.after}
        return [e.name for e in self.event_specs if e.name not in parents]

    def object(self, name: str) -> ObjectSpec:
        for obj in self.objects:
            if obj.name == name:
                return obj
        raise KeyError(name)

    def event(self, name: str) -> EventSpec:
        for event in self.event_specs:
            if event.name == name:
                return event
        raise KeyError(name)

    def default_layout(self) -> np.ndarray:
        return self.design_space.default.copy()

    def layout(self, name: str) -> np.ndarray:
        """A named layout of the file (e.g. ``"success"``), as a vector in real units."""
        if name not in self.layouts:
            raise LayoutError(f"{self.source}: no layout named {name!r}; the file has {sorted(self.layouts)}")
        return np.array(self.layouts[name], dtype=float)

    def transforms(self, x=None) -> dict[str, Transform]:
        """The transform of every object (relative to its parent) for the layout ``x`` (default layout if None)."""
        x = self.default_layout() if x is None else self.design_space.check_bounds(x)
        values = dict(zip(self.design_space.names, np.asarray(x, dtype=float).tolist()))
        result = {}
        for obj in self.objects:
            changes = {key: values[f"{obj.name}.{key}"] for key in TRANSFORM_KEYS if f"{obj.name}.{key}" in values}
            result[obj.name] = obj.transform.replace(**changes) if changes else obj.transform
        return result


# ---------------------------------------------------------------------------------------------------------------
# Loading and validation
# ---------------------------------------------------------------------------------------------------------------


class _Checker:
    """Typed field access that raises :class:`ScenarioFormatError` naming file, field path and expectation."""

    def __init__(self, file: str) -> None:
        self.file = file

    def fail(self, path: str, message: str) -> ScenarioFormatError:
        return ScenarioFormatError(self.file, path, message)

    def table(self, value: Any, path: str) -> dict:
        if not isinstance(value, dict):
            raise self.fail(path, f"expected a table (mapping), got {_kind(value)}")
        for key in value:
            if not isinstance(key, str):
                raise self.fail(path, f"expected text keys, got {key!r}")
        return value

    def only(self, table: dict, path: str, allowed) -> None:
        for key in table:
            if key not in allowed:
                expected = ", ".join(allowed) if allowed else "no fields"
                raise self.fail(_join(path, key), f"unknown field; expected one of: {expected}")

    def string(self, value: Any, path: str, *, pattern: re.Pattern | None = None, what: str = "text") -> str:
        if not isinstance(value, str):
            raise self.fail(path, f"expected {what}, got {_kind(value)}")
        if pattern is not None and not pattern.match(value):
            raise self.fail(path, f"expected {what}, got {value!r}")
        return value

    def number(self, value: Any, path: str, *, minimum: float | None = None, strict: bool = False) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(path, f"expected a number, got {_kind(value)}")
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
            raise self.fail(path, f"expected an integer >= {minimum}, got {_kind(value)}")
        if value < minimum:
            raise self.fail(path, f"expected an integer >= {minimum}, got {value!r}")
        return int(value)

    def array(self, value: Any, path: str, *, min_len: int = 0, max_len: int | None = None) -> list:
        if not isinstance(value, list):
            raise self.fail(path, f"expected an array, got {_kind(value)}")
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

    def param(self, kind: str, value: Any, path: str) -> Any:
        if kind == "pos":
            return self.number(value, path, minimum=0.0, strict=True)
        if kind == "nonneg":
            return self.number(value, path, minimum=0.0)
        if kind == "float":
            return self.number(value, path)
        if kind == "int":
            return self.integer(value, path)
        if kind == "vec3":
            return self.vector(value, path, 3)
        if kind == "vec3pos":
            return self.vector(value, path, 3, positive=True)
        if kind == "axis":
            if isinstance(value, str):
                if value not in ("x", "y", "z"):
                    raise self.fail(path, f'expected "x", "y", "z" or 3 numbers, got {value!r}')
                return {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}[value]
            axis = self.vector(value, path, 3)
            if math.hypot(*axis) < 1e-12:
                raise self.fail(path, "expected a non-zero axis")
            return axis
        if kind == "body":
            return self.body_ref(value, path)
        if kind in ("bodies", "bodies2", "bodies1+"):
            lo, hi = {"bodies": (1, 2), "bodies2": (2, 2), "bodies1+": (1, None)}[kind]
            items = self.array(value, path, min_len=lo, max_len=hi)
            return tuple(self.body_ref(v, f"{path}[{i}]") for i, v in enumerate(items))
        if kind == "anchors":
            items = self.array(value, path, min_len=2, max_len=2)
            return tuple(self.vector(v, f"{path}[{i}]", 3) for i, v in enumerate(items))
        if kind == "poses":
            items = self.array(value, path, min_len=1)
            return tuple(self.vector(v, f"{path}[{i}]", 3) for i, v in enumerate(items))
        if kind == "points2":
            items = self.array(value, path, min_len=2)
            return tuple(self.vector(v, f"{path}[{i}]", 2) for i, v in enumerate(items))
        if kind == "points3":
            items = self.array(value, path)
            return tuple(self.vector(v, f"{path}[{i}]", 3) for i, v in enumerate(items))
        raise AssertionError(kind)  # pragma: no cover

    def body_ref(self, value: Any, path: str) -> str:
        return self.string(value, path, pattern=_BODY_REF, what='an object name (or "run[i]" for a domino)')

    def params(self, schema: dict, table: dict, path: str) -> dict[str, Any]:
        result = {}
        for key, (kind, default) in schema.items():
            if key in table:
                result[key] = self.param(kind, table[key], _join(path, key))
            elif default is REQUIRED:
                raise self.fail(_join(path, key), f"missing; expected {_KIND_WORDS[kind]}")
            elif default is not None:
                result[key] = default
        return result


_KIND_WORDS = {
    "pos": "a number > 0",
    "nonneg": "a number >= 0",
    "float": "a number",
    "int": "an integer >= 1",
    "vec3": "an array of 3 numbers",
    "vec3pos": "an array of 3 numbers > 0",
    "axis": '"x", "y", "z" or 3 numbers',
    "body": "an object name",
    "bodies": "an array of 1 or 2 object names",
    "bodies2": "an array of 2 object names",
    "bodies1+": "an array of object names",
    "anchors": "an array of 2 points [x, y, z]",
    "poses": "an array of [x, y, heading] poses",
    "points2": "an array of [x, y] points",
    "points3": "an array of [x, y, z] points",
}


def _kind(value: Any) -> str:
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


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def load_scenario(path: str | Path) -> Scenario:
    """Load and validate a scenario file (``.toml`` or ``.json``).

    Raises
    ------
    ScenarioFormatError
        For any problem with the file's syntax or content; the message names the file, field and expectation.
    FileNotFoundError
        When the file does not exist.
    """
    path = Path(path)
    file = str(path)
    suffix = path.suffix.lower()
    if suffix not in (".toml", ".json"):
        raise ScenarioFormatError(file, "", f"expected a .toml or .json scenario file, got {suffix or 'no suffix'!r}")
    raw = path.read_bytes()
    data = parse_text(raw, file, suffix)
    return scenario_from_data(data, file=file)


def parse_text(raw: bytes, file: str, suffix: str) -> Any:
    """Parse the bytes of a TOML or JSON file into plain data, raising :class:`ScenarioFormatError`."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as error:
        raise ScenarioFormatError(file, "", f"expected UTF-8 text ({error.reason} at byte {error.start})") from None
    try:
        if suffix == ".json":
            return json.loads(text, parse_constant=_reject_constant)
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise ScenarioFormatError(file, "", f"expected valid TOML: {error}") from None
    except json.JSONDecodeError as error:
        raise ScenarioFormatError(file, "", f"expected valid JSON: {error}") from None
    except (ValueError, RecursionError) as error:
        raise ScenarioFormatError(file, "", f"expected valid {suffix[1:].upper()}: {error}") from None


def _reject_constant(name: str) -> float:
    raise ValueError(f"{name} is not a number")


def scenario_from_data(data: Any, *, file: str = "<data>") -> Scenario:
    """Validate parsed scenario data (the content of a TOML/JSON file) and build the :class:`Scenario`."""
    check = _Checker(file)
    top = check.table(data, "")
    check.only(top, "", ("scenario", "settings", "objects", "events", "layouts"))

    header = check.table(top.get("scenario", {}), "scenario")
    check.only(header, "scenario", ("name", "description"))
    name = check.string(header["name"], "scenario.name") if "name" in header else Path(file).stem
    description = check.string(header.get("description", ""), "scenario.description")

    settings = _settings(check, top.get("settings", {}))
    objects = _objects(check, top)
    by_name = {o.name: o for o in objects}
    for i, (a, b) in enumerate(settings.ignore_overlap):
        for j, ref in enumerate((a, b)):
            if ref not in by_name:
                raise check.fail(f"settings.ignore_overlap[{i}][{j}]", f"unknown object {ref!r}")
    _check_references(check, objects, by_name)
    events = _events(check, top, settings, by_name)
    space = _design_space(objects)
    layouts = _layouts(check, top.get("layouts", {}), space)

    hashed = {k: v for k, v in top.items() if k != "layouts"}
    canonical = json.dumps(hashed, sort_keys=True, separators=(",", ":"), ensure_ascii=True, default=str)
    content_hash = hashlib.sha256(canonical.encode("ascii")).hexdigest()
    return Scenario(
        name=name,
        description=description,
        settings=settings,
        objects=tuple(objects),
        event_specs=tuple(events),
        design_space=space,
        layouts=layouts,
        content_hash=content_hash,
        source=file,
    )


def _settings(check: _Checker, value: Any) -> Settings:
    table = check.table(value, "settings")
    allowed = (
        "time_step",
        "event_timeout",
        "max_duration",
        "gravity",
        "solver_iterations",
        "overlap_tolerance",
        "ignore_overlap",
    )
    check.only(table, "settings", allowed)
    kwargs: dict[str, Any] = {}
    for key in ("time_step", "event_timeout", "max_duration"):
        if key in table:
            kwargs[key] = check.number(table[key], f"settings.{key}", minimum=0.0, strict=True)
    if "gravity" in table:
        kwargs["gravity"] = check.number(table["gravity"], "settings.gravity")
    if "solver_iterations" in table:
        kwargs["solver_iterations"] = check.integer(table["solver_iterations"], "settings.solver_iterations")
    if "overlap_tolerance" in table:
        kwargs["overlap_tolerance"] = check.number(table["overlap_tolerance"], "settings.overlap_tolerance", minimum=0)
    if "ignore_overlap" in table:
        pairs = check.array(table["ignore_overlap"], "settings.ignore_overlap")
        kwargs["ignore_overlap"] = tuple(
            tuple(
                check.string(v, f"settings.ignore_overlap[{i}][{j}]", pattern=_NAME, what="an object name")
                for j, v in enumerate(check.array(pair, f"settings.ignore_overlap[{i}]", min_len=2, max_len=2))
            )
            for i, pair in enumerate(pairs)
        )
    settings = Settings(**kwargs)
    if settings.time_step > 0.05:
        raise check.fail("settings.time_step", f"expected at most 0.05 s, got {settings.time_step:g}")
    if settings.max_duration / settings.time_step > 1e6:
        raise check.fail("settings.max_duration", "expected at most a million time steps (max_duration / time_step)")
    return settings


def _objects(check: _Checker, top: dict) -> list[ObjectSpec]:
    if "objects" not in top:
        raise check.fail("objects", "missing; expected an array of object tables ([[objects]])")
    items = check.array(top["objects"], "objects", min_len=1)
    objects: list[ObjectSpec] = []
    seen: set[str] = set()
    for i, item in enumerate(items):
        path = f"objects[{i}]"
        table = check.table(item, path)
        check.only(
            table, path, ("name", "type", "parent", "transform", "ranges", "shape", "physics", "tag", "sleeping")
        )
        sleeping = None
        if "sleeping" in table:
            if not isinstance(table["sleeping"], bool):
                raise check.fail(f"{path}.sleeping", f"expected true or false, got {_kind(table['sleeping'])}")
            sleeping = table["sleeping"]
        if "name" not in table:
            raise check.fail(f"{path}.name", "missing; expected an object name")
        name = check.string(table["name"], f"{path}.name", pattern=_NAME, what="a name of letters, digits, _ or -")
        if name in seen:
            raise check.fail(f"{path}.name", f"expected a unique name, {name!r} is used twice")
        seen.add(name)
        if "type" not in table:
            raise check.fail(f"{path}.type", f"missing; expected one of {', '.join(PRIMITIVES)}")
        kind = check.string(table["type"], f"{path}.type")
        if kind not in PRIMITIVES:
            raise check.fail(f"{path}.type", f"expected one of {', '.join(PRIMITIVES)}, got {kind!r}")
        parent = None
        if "parent" in table:
            parent = check.string(table["parent"], f"{path}.parent", pattern=_NAME, what="an object name")
        transform_table = check.table(table.get("transform", {}), f"{path}.transform")
        check.only(transform_table, f"{path}.transform", TRANSFORM_KEYS)
        transform = Transform(
            **{k: check.number(v, f"{path}.transform.{k}") for k, v in transform_table.items()}
        )
        ranges_table = check.table(table.get("ranges", {}), f"{path}.ranges")
        check.only(ranges_table, f"{path}.ranges", TRANSFORM_KEYS)
        if ranges_table and kind in UNPLACED:
            raise check.fail(f"{path}.ranges", f"a {kind} has no placement of its own; expected no ranges")
        ranges: dict[str, tuple[float, float]] = {}
        for key in TRANSFORM_KEYS:  # stable order, whatever the file's order
            if key not in ranges_table:
                continue
            rpath = f"{path}.ranges.{key}"
            lo, hi = check.vector(ranges_table[key], rpath, 2)
            if not lo < hi:
                raise check.fail(rpath, f"expected [min, max] with min < max, got [{lo:g}, {hi:g}]")
            value = getattr(transform, key)
            if not lo <= value <= hi:
                raise check.fail(
                    f"{path}.transform.{key}",
                    f"expected a value inside its range [{lo:g}, {hi:g}] (the default layout), got {value:g}",
                )
            ranges[key] = (lo, hi)
        schema = PRIMITIVES[kind]["params"]
        shape_table = check.table(table.get("shape", {}), f"{path}.shape")
        check.only(shape_table, f"{path}.shape", tuple(schema))
        shape = check.params(schema, shape_table, f"{path}.shape")
        _check_shape(check, kind, shape, f"{path}.shape")
        physics_table = check.table(table.get("physics", {}), f"{path}.physics")
        if not PRIMITIVES[kind]["body"] or kind == "Plane":
            allowed = ("friction", "rolling_friction", "spinning_friction", "restitution") if kind == "Plane" else ()
            check.only(physics_table, f"{path}.physics", allowed)
        else:
            check.only(physics_table, f"{path}.physics", PHYSICS_KEYS)
        physics = Physics(
            **{k: check.number(v, f"{path}.physics.{k}", minimum=0.0) for k, v in physics_table.items()}
        )
        tag = None
        if "tag" in table:
            tag_table = check.table(table["tag"], f"{path}.tag")
            check.only(tag_table, f"{path}.tag", ("id", "x", "y", "z", "size"))
            if "id" not in tag_table:
                raise check.fail(f"{path}.tag.id", "missing; expected an AprilTag id (integer >= 0)")
            tag = Tag(
                id=check.integer(tag_table["id"], f"{path}.tag.id", minimum=0),
                **{
                    k: check.number(tag_table[k], f"{path}.tag.{k}", minimum=0.0 if k == "size" else None,
                                    strict=k == "size")
                    for k in ("x", "y", "z", "size")
                    if k in tag_table
                },
            )
        objects.append(
            ObjectSpec(
                name=name,
                type=kind,
                transform=transform,
                parent=parent,
                ranges=ranges,
                shape=shape,
                physics=physics,
                tag=tag,
                index=i,
                sleeping=sleeping,
            )
        )
    return objects


def _check_shape(check: _Checker, kind: str, shape: dict, path: str) -> None:
    if kind == "Goblet":
        if shape["thickness"] >= min(shape["radius_top"], shape["radius_bottom"]):
            raise check.fail(f"{path}.thickness", "expected a wall thinner than the smaller radius")
        if shape["sides"] < 3:
            raise check.fail(f"{path}.sides", f"expected an integer >= 3, got {shape['sides']}")
    elif kind == "Track":
        if 2 * shape["wall_thickness"] >= shape["width"] or shape["wall_thickness"] >= shape["height"] + 1e-12:
            raise check.fail(f"{path}.wall_thickness", "expected walls thinner than half the width and the height")
    elif kind == "OpenBox":
        size = shape["size"]
        if 2 * shape["thickness"] >= min(size[0], size[1]) or shape["thickness"] >= size[2]:
            raise check.fail(f"{path}.thickness", "expected walls thinner than half the size")
    elif kind == "DominoRun":
        has_poses = "poses" in shape
        has_path = "path" in shape
        if has_poses == has_path:
            raise check.fail(path, "expected exactly one of 'poses' or 'path' (with 'spacing' or 'count')")
        if has_path and ("spacing" in shape) == ("count" in shape):
            raise check.fail(f"{path}.spacing", "expected exactly one of 'spacing' or 'count' with a 'path'")
        if has_poses and ("spacing" in shape or "count" in shape):
            raise check.fail(path, "'spacing' and 'count' only go with a 'path'")
        if has_path and shape.get("count", 2) < 2:
            raise check.fail(f"{path}.count", "expected at least 2 dominoes along a path")
        if has_path:
            points = np.asarray(shape["path"], dtype=float)
            lengths = np.linalg.norm(np.diff(points, axis=0), axis=1)
            if np.any(lengths <= 1e-9):
                i = int(np.argmax(lengths <= 1e-9))
                raise check.fail(f"{path}.path[{i + 1}]", "expected a point distinct from the previous one")
    elif kind == "Pivot":
        if "other" in shape and shape["other"] == shape["body"]:
            raise check.fail(f"{path}.other", "expected a body other than 'body' (or none: the world)")
    elif kind == "Fastener":
        if len(shape["bodies"]) == 2 and shape["bodies"][0] == shape["bodies"][1]:
            raise check.fail(f"{path}.bodies", "expected two different bodies (or one: fastened to the world)")
    elif kind in ("TensionRope", "RopePulley"):
        if shape["ends"][0] == shape["ends"][1]:
            raise check.fail(f"{path}.ends", "expected two different bodies")


def _check_references(check: _Checker, objects: list[ObjectSpec], by_name: dict[str, ObjectSpec]) -> None:
    for obj in objects:
        path = f"objects[{obj.index}]"
        if obj.parent is not None:
            if obj.parent not in by_name:
                raise check.fail(f"{path}.parent", f"unknown object {obj.parent!r}")
            if obj.parent == obj.name:
                raise check.fail(f"{path}.parent", "an object cannot be its own parent")
        schema = PRIMITIVES[obj.type]["params"]
        for key, (kind, _default) in schema.items():
            if key not in obj.shape:
                continue
            if kind == "body":
                refs = [(f"{path}.shape.{key}", obj.shape[key])]
            elif kind in ("bodies", "bodies2", "bodies1+"):
                refs = [(f"{path}.shape.{key}[{i}]", r) for i, r in enumerate(obj.shape[key])]
            else:
                continue
            for rpath, ref in refs:
                target = resolve_body_ref(check, rpath, ref, by_name)
                if key == "pulleys" and by_name[target[0]].type != "Pulley":
                    raise check.fail(rpath, f"expected a Pulley object, {ref!r} is a {by_name[target[0]].type}")
    # Parent chains must end (no cycles).
    for obj in objects:
        seen = [obj.name]
        current = obj
        while current.parent is not None:
            if current.parent in seen:
                raise check.fail(
                    f"objects[{obj.index}].parent", f"expected a tree of parents, found a cycle {' -> '.join(seen)}"
                )
            seen.append(current.parent)
            current = by_name[current.parent]


def resolve_body_ref(check: _Checker, path: str, ref: str, by_name: Mapping[str, ObjectSpec]) -> tuple[str, int | None]:
    """Split ``"run[3]"`` into ``("run", 3)`` and check the object exists and has bodies."""
    match = _BODY_REF.match(ref)
    if match is None:  # pragma: no cover - checked by body_ref already
        raise check.fail(path, f"expected an object name, got {ref!r}")
    name, index = match.group(1), match.group(2)
    if name not in by_name:
        raise check.fail(path, f"unknown object {name!r}; expected one of {', '.join(sorted(by_name))}")
    obj = by_name[name]
    if not obj.has_body:
        raise check.fail(path, f"expected an object with a body, {name!r} is a {obj.type}")
    if obj.type == "DominoRun":
        if index is None:
            raise check.fail(path, f"expected one domino of the run, e.g. '{name}[0]' or '{name}[-1]'")
        count = domino_count(obj.shape)
        if not -count <= int(index) < count:
            raise check.fail(path, f"expected a domino index in [{-count}, {count - 1}], got {index}")
        return name, int(index) % count
    if index is not None:
        raise check.fail(path, f"{name!r} is a single body ({obj.type}); expected no index")
    return name, None


def domino_count(shape: Mapping[str, Any]) -> int:
    """Number of dominoes of a DominoRun's shape parameters."""
    if "poses" in shape:
        return len(shape["poses"])
    if "count" in shape:
        return int(shape["count"])
    points = np.asarray(shape["path"], dtype=float)
    length = float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1)))
    return int(math.floor(length / shape["spacing"] + 1e-9)) + 1


def _events(check: _Checker, top: dict, settings: Settings, by_name: dict[str, ObjectSpec]) -> list[EventSpec]:
    if "events" not in top:
        raise check.fail("events", "missing; expected an array of event tables ([[events]])")
    items = check.array(top["events"], "events", min_len=1)
    events: list[EventSpec] = []
    names: dict[str, int] = {}
    for i, item in enumerate(items):
        path = f"events[{i}]"
        table = check.table(item, path)
        if "name" not in table:
            raise check.fail(f"{path}.name", "missing; expected an event name")
        name = check.string(table["name"], f"{path}.name", pattern=_NAME, what="a name of letters, digits, _ or -")
        if name in names:
            raise check.fail(f"{path}.name", f"expected a unique name, {name!r} is used twice")
        names[name] = i
        if "type" not in table:
            raise check.fail(f"{path}.type", f"missing; expected one of {', '.join(EVENTS)}")
        kind = check.string(table["type"], f"{path}.type")
        if kind not in EVENTS:
            raise check.fail(f"{path}.type", f"expected one of {', '.join(EVENTS)}, got {kind!r}")
        schema = EVENTS[kind]
        check.only(table, path, EVENT_COMMON + tuple(schema))
        params = check.params(schema, {k: v for k, v in table.items() if k in schema}, path)
        for key, (kind_, _d) in schema.items():
            if kind_ == "body" and key in params:
                resolve_body_ref(check, f"{path}.{key}", params[key], by_name)
        after = tuple(
            check.string(v, f"{path}.after[{j}]", pattern=_NAME, what="an event name")
            for j, v in enumerate(check.array(table.get("after", []), f"{path}.after"))
        )
        if len(set(after)) != len(after):
            raise check.fail(f"{path}.after", "expected each parent event once")
        join = check.string(table.get("join", "all"), f"{path}.join")
        if join not in ("all", "any"):
            raise check.fail(f"{path}.join", f'expected "all" or "any", got {join!r}')
        timeout = check.number(table.get("timeout", settings.event_timeout), f"{path}.timeout", minimum=0, strict=True)
        duration = check.number(table.get("duration", 0.0), f"{path}.duration", minimum=0.0)
        label = check.string(table.get("label", name.replace("_", " ")), f"{path}.label")
        events.append(EventSpec(name, kind, params, after, join, timeout, duration, label, index=i))
    for event in events:
        for j, parent in enumerate(event.after):
            if parent not in names:
                raise check.fail(f"events[{event.index}].after[{j}]", f"unknown event {parent!r}")
            if parent == event.name:
                raise check.fail(f"events[{event.index}].after[{j}]", "an event cannot follow itself")
    roots = [e for e in events if not e.after]
    if len(roots) != 1:
        found = ", ".join(e.name for e in roots) or "none"
        raise check.fail("events", f"expected exactly one root event (an event without 'after'), found {found}")
    _check_acyclic(check, events)
    return events


def _check_acyclic(check: _Checker, events: list[EventSpec]) -> None:
    parents = {e.name: e.after for e in events}
    state: dict[str, int] = {}

    def visit(name: str, trail: list[str]) -> None:
        # Iterative depth would be nicer, but graphs are small; recursion depth is bounded by the event count.
        if state.get(name) == 2:
            return
        if state.get(name) == 1:
            cycle = trail[trail.index(name):] + [name]
            index = next(e.index for e in events if e.name == name)
            raise check.fail(f"events[{index}].after", f"expected a DAG, found a cycle {' <- '.join(cycle)}")
        state[name] = 1
        for parent in parents[name]:
            visit(parent, trail + [name])
        state[name] = 2

    for event in events:
        visit(event.name, [])


def _design_space(objects: list[ObjectSpec]) -> DesignSpace:
    names, lower, upper, default = [], [], [], []
    for obj in objects:
        for key in TRANSFORM_KEYS:
            if key in obj.ranges:
                lo, hi = obj.ranges[key]
                names.append(f"{obj.name}.{key}")
                lower.append(lo)
                upper.append(hi)
                default.append(getattr(obj.transform, key))
    return DesignSpace(names, lower, upper, default)


def _layouts(check: _Checker, value: Any, space: DesignSpace) -> dict[str, np.ndarray]:
    table = check.table(value, "layouts")
    layouts = {}
    for name, entry in table.items():
        path = f"layouts.{name}"
        values = check.table(entry, path)
        numbers = {}
        for key, v in values.items():
            if key not in space.names:
                raise check.fail(
                    f"{path}.{key}", f"unknown design parameter; expected one of {', '.join(space.names) or 'none'}"
                )
            numbers[key] = check.number(v, f'{path}."{key}"')
            i = space.names.index(key)
            if not space.lower[i] <= numbers[key] <= space.upper[i]:
                raise check.fail(
                    f'{path}."{key}"',
                    f"expected a value in [{space.lower[i]:g}, {space.upper[i]:g}], got {numbers[key]:g}",
                )
        layouts[name] = space.vector(numbers)
    return layouts

