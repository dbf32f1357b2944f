"""The loaded scenario as frozen data: objects, events, settings, and the :class:`Scenario` that holds them.

Values here are already validated (:mod:`design.contraption.validation` builds them); the classes only answer
questions about them. The content hash is computed here too, from the parsed file content the scenario is made of.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from design.contraption.design_space import DesignSpace
from design.contraption.errors import LayoutError
from design.contraption.materials import MaterialValue, effective_content
from design.contraption.schema import PHYSICS_DEFAULTS, PRIMITIVES, TRANSFORM_KEYS


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

    # The defaults are the scenario format's (one table, in the schema).
    mass: float = PHYSICS_DEFAULTS["mass"]
    friction: float = PHYSICS_DEFAULTS["friction"]
    rolling_friction: float = PHYSICS_DEFAULTS["rolling_friction"]
    spinning_friction: float = PHYSICS_DEFAULTS["spinning_friction"]
    restitution: float = PHYSICS_DEFAULTS["restitution"]
    linear_damping: float = PHYSICS_DEFAULTS["linear_damping"]
    angular_damping: float = PHYSICS_DEFAULTS["angular_damping"]

    @property
    def static(self) -> bool:
        return self.mass <= 0.0


@dataclass(frozen=True)
class Tag:
    """An AprilTag printed on a part: its id, the centre of the tag in the part's frame (m), its black square's edge
    (m), and ``angle`` (degrees): the tag's printed "up" runs along the part's local +y (top view) or +z (side view),
    turned by ``angle`` counter-clockwise as the camera (the maker) sees the face."""

    id: int
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    size: float = 0.02
    angle: float = 0.0
    #: For a DominoRun: the domino the tag is on (0 the first, -1 the last); its place is in that domino's frame.
    body: int | None = None


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
    #: A DominoRun's tags on single dominoes (``tag = [{body = 0, ...}, {body = -1, ...}]``): its first and last.
    body_tags: tuple[Tag, ...] = ()
    sleeping: bool | None = None
    material: str | None = None

    @property
    def starts_asleep(self) -> bool:
        """Whether the bodies start asleep (not simulated until something touches them)."""
        return self.type == "DominoRun" if self.sleeping is None else self.sleeping

    @property
    def has_body(self) -> bool:
        return PRIMITIVES[self.type].body


def domino_count(shape: Mapping[str, Any]) -> int:
    """Number of dominoes of a DominoRun's shape parameters."""
    if "poses" in shape:
        return len(shape["poses"])
    if "count" in shape:
        return int(shape["count"])
    points = np.asarray(shape["path"], dtype=float)
    length = float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1)))
    return int(math.floor(length / shape["spacing"] + 1e-9)) + 1


@dataclass(frozen=True)
class EventSpec:
    """One event of the causal graph.

    Attributes
    ----------
    name, type : str
        The event's name and its type (a key of :data:`~design.contraption.schema.EVENTS`).
    params : mapping
        The parameters of its type, defaults filled in.
    after : tuple of str
        The events it waits for; ``join`` says whether all of them must succeed (``"all"``) or one is enough.
    timeout, duration : float
        Seconds it has to succeed once awake, and seconds its condition must hold (a duration event).
    label : str
        Words for people.
    index : int
        Its position in the scenario file (for messages).
    """

    name: str
    type: str
    params: Mapping[str, Any]
    after: tuple[str, ...]
    join: Literal["all", "any"]
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


def content_hash(top: Mapping[str, Any]) -> str:
    """The sha256 of a scenario file's parsed content as simulated, without its ``layouts`` and tags (a cache key).

    Layouts are points of the design space, not part of the contraption: adding one must not invalidate what was
    computed for the scenario. Materials are resolved into each object's physics and their ranges left out
    (:func:`~design.contraption.materials.effective_content`): a range says what calibration may fit, not what is
    simulated. The JSON is canonical (sorted keys, no spaces), so TOML and JSON files with the same content hash
    the same.
    """
    hashed = {k: v for k, v in effective_content(top).items() if k != "layouts"}
    # A part's AprilTag is how the camera finds it, not part of the contraption: tagging a part must not invalidate
    # its cached simulations nor the layouts optimized for it (a LAYOUT.json carries the hash).
    if isinstance(hashed.get("objects"), list):
        hashed["objects"] = [{k: v for k, v in o.items() if k != "tag"} if isinstance(o, dict) else o
                             for o in hashed["objects"]]
    canonical = json.dumps(hashed, sort_keys=True, separators=(",", ":"), ensure_ascii=True, default=str)
    return hashlib.sha256(canonical.encode("ascii")).hexdigest()


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
    #: Material name -> {parameter -> MaterialValue}, file order (see :mod:`design.contraption.materials`).
    materials: Mapping[str, Mapping[str, MaterialValue]] = field(default_factory=dict)
    #: The parsed file content it was built from (what :func:`~design.contraption.validation.with_physics`
    #: rewrites); None if not kept.
    data: Mapping[str, Any] | None = field(default=None, repr=False)
    #: The material values :func:`~design.contraption.validation.with_physics` set, ``{"wood.friction": 0.42}``
    #: (empty: the file's own).
    physics_overrides: Mapping[str, float] = field(default_factory=dict)

    def physics_parameters(self) -> dict[str, float]:
        """Every material value as simulated, ``{"wood.friction": 0.6, ...}`` in file order."""
        return {f"{m}.{k}": v.value for m, values in self.materials.items() for k, v in values.items()}

    def uncertain_parameters(self) -> dict[str, tuple[float, tuple[float, float]]]:
        """The uncertain material values, ``{"wood.friction": (value, (min, max))}`` in file order: what
        simulator calibration fits."""
        return {f"{m}.{k}": (v.value, v.range) for m, values in self.materials.items()
                for k, v in values.items() if v.range is not None}

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

    @property
    def graph_order(self) -> tuple[str, ...]:
        """Event names in the causal graph's order: every event after all its parents, otherwise in file order
        (the file's own order when it already is one; a file may list a child before its parent)."""
        order: list[str] = []
        remaining = list(self.event_specs)
        while remaining:
            ready = next((e for e in remaining if all(p in order for p in e.after)), None)
            if ready is None:  # pragma: no cover - a loaded scenario's graph is checked acyclic
                raise ValueError(f"{self.source}: the causal graph has a cycle among {[e.name for e in remaining]}")
            order.append(ready.name)
            remaining.remove(ready)
        return tuple(order)

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

    def transforms(self, x=None, *, checked: bool = True) -> dict[str, Transform]:
        """The transform of every object (relative to its parent) for the layout ``x`` (default layout if None);
        ``checked=False`` skips the range check (a fit that steps a hair outside while it works)."""
        if x is None:
            x = self.default_layout()
        elif checked:
            x = self.design_space.check_bounds(x)
        values = dict(zip(self.design_space.names, np.asarray(x, dtype=float).tolist()))
        result = {}
        for obj in self.objects:
            changes = {key: values[f"{obj.name}.{key}"] for key in TRANSFORM_KEYS if f"{obj.name}.{key}" in values}
            result[obj.name] = obj.transform.replace(**changes) if changes else obj.transform
        return result
