"""The schema of scenario files: which fields each primitive and event takes, of which kind, with which default.

The tables are data read by the validator (:mod:`design.contraption.validation`); the format itself is described in
:mod:`design.contraption.scenario`. A field is a :class:`Param`, a ``(kind, default)`` pair: ``kind`` is a
:class:`Kind` (what the value must be: the validator parses it and the kind's :attr:`Kind.expected` words are the
"expected ..." of the error message), ``default`` is :data:`REQUIRED` (the field must be given), ``None`` (optional,
absent when not given) or the value used when the field is not given.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from enum import Enum
from types import MappingProxyType
from typing import Any, NamedTuple

#: The default of a field that must be given.
REQUIRED = ...

TRANSFORM_KEYS = ("x", "y", "z", "heading", "pitch", "roll")
ANGLE_KEYS = frozenset({"heading", "pitch", "roll"})
#: The physics fields of an object and their defaults (SI units; ``mass == 0`` means static).
PHYSICS_DEFAULTS = {
    "mass": 0.0,
    "friction": 0.5,
    "rolling_friction": 0.0,
    "spinning_friction": 0.0,
    "restitution": 0.0,
    "linear_damping": 0.0,
    "angular_damping": 0.0,
}
PHYSICS_KEYS = tuple(PHYSICS_DEFAULTS)
#: The physics fields a Plane takes: it is static, so it has no mass and no damping.
PLANE_PHYSICS_KEYS = ("friction", "rolling_friction", "spinning_friction", "restitution")
#: The fields of a ``[materials.NAME]`` table: what a material says about its surfaces and motion (not its mass).
MATERIAL_KEYS = tuple(k for k in PHYSICS_KEYS if k != "mass")
TAG_KEYS = ("id", "x", "y", "z", "size", "angle", "body")
#: The fields of the top-level table, of ``[scenario]``, ``[settings]`` and of each ``[[objects]]`` table.
TOP_KEYS = ("scenario", "settings", "materials", "objects", "events", "layouts")
HEADER_KEYS = ("name", "description")
SETTINGS_KEYS = (
    "time_step",
    "event_timeout",
    "max_duration",
    "gravity",
    "solver_iterations",
    "overlap_tolerance",
    "ignore_overlap",
)
OBJECT_KEYS = ("name", "type", "parent", "transform", "ranges", "shape", "material", "physics", "tag", "sleeping")
#: Fields every event takes besides those of its type.
EVENT_COMMON = ("name", "type", "after", "join", "timeout", "duration", "label")

#: A name of an object or an event; a body reference is an object's name, with ``[i]`` for one domino of a run.
NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_\-]*$")
BODY_REF = re.compile(r"^([A-Za-z_][A-Za-z0-9_\-]*)(?:\[(-?\d+)\])?$")

Y_AXIS = (0.0, 1.0, 0.0)


class Kind(str, Enum):
    """What the value of a field must be.

    A ``str`` enum, so a kind still equals the word that named it before the kinds were typed (``Kind.POS ==
    "pos"``).
    """

    POS = "pos"  #: a number > 0
    NONNEG = "nonneg"  #: a number >= 0
    FLOAT = "float"  #: any finite number
    INT = "int"  #: an integer >= 1
    VEC3 = "vec3"  #: 3 numbers
    VEC3POS = "vec3pos"  #: 3 numbers > 0
    AXIS = "axis"  #: "x", "y", "z" or 3 numbers, not all zero
    BODY = "body"  #: a body reference
    BODIES = "bodies"  #: 1 or 2 body references
    BODIES2 = "bodies2"  #: exactly 2 body references
    BODIES1_PLUS = "bodies1+"  #: at least 1 body reference
    ANCHORS = "anchors"  #: 2 points [x, y, z]
    POSES = "poses"  #: at least 1 pose [x, y, heading_deg]
    POINTS2 = "points2"  #: at least 2 points [x, y]
    POINTS3 = "points3"  #: points [x, y, z]

    @property
    def expected(self) -> str:
        """The kind in words, as error messages say what was expected."""
        return _EXPECTED[self]

    @property
    def refers_to_bodies(self) -> bool:
        """Whether values of this kind name bodies of other objects (checked once every object is known)."""
        return self in (Kind.BODY, Kind.BODIES, Kind.BODIES2, Kind.BODIES1_PLUS)


_EXPECTED = {
    Kind.POS: "a number > 0",
    Kind.NONNEG: "a number >= 0",
    Kind.FLOAT: "a number",
    Kind.INT: "an integer >= 1",
    Kind.VEC3: "an array of 3 numbers",
    Kind.VEC3POS: "an array of 3 numbers > 0",
    Kind.AXIS: '"x", "y", "z" or 3 numbers',
    Kind.BODY: "an object name",
    Kind.BODIES: "an array of 1 or 2 object names",
    Kind.BODIES2: "an array of 2 object names",
    Kind.BODIES1_PLUS: "an array of object names",
    Kind.ANCHORS: "an array of 2 points [x, y, z]",
    Kind.POSES: "an array of [x, y, heading] poses",
    Kind.POINTS2: "an array of [x, y] points",
    Kind.POINTS3: "an array of [x, y, z] points",
}


class Param(NamedTuple):
    """One field of a primitive's shape or of an event: its kind and its default (see the module's docstring)."""

    kind: Kind
    default: Any


@dataclass(frozen=True)
class Primitive:
    """The schema of one primitive: whether it makes rigid bodies, and its shape parameters in file order."""

    body: bool
    params: MappingProxyType[str, Param]


def _primitive(body: bool, /, **params: tuple[Kind, Any]) -> Primitive:
    return Primitive(body, MappingProxyType({key: Param(*spec) for key, spec in params.items()}))


def _required(kind: Kind, *names: str) -> dict[str, tuple[Kind, Any]]:
    """Fields ``names`` of one kind that must all be given, in that order."""
    return {name: (kind, REQUIRED) for name in names}


def _event(**params: tuple[Kind, Any]) -> MappingProxyType[str, Param]:
    return MappingProxyType({key: Param(*spec) for key, spec in params.items()})


K = Kind
_ZERO3 = (0.0, 0.0, 0.0)

#: Shape parameters of each primitive (thesis App. C.1), in the order the error messages list them.
PRIMITIVES: MappingProxyType[str, Primitive] = MappingProxyType({
    "Plane": _primitive(True),
    "Empty": _primitive(False),
    "Ball": _primitive(True, radius=(K.POS, REQUIRED)),
    "Box": _primitive(True, size=(K.VEC3POS, REQUIRED)),
    "OpenBox": _primitive(True, size=(K.VEC3POS, REQUIRED), thickness=(K.POS, REQUIRED)),
    "Cylinder": _primitive(True, radius=(K.POS, REQUIRED), height=(K.POS, REQUIRED)),
    "Capsule": _primitive(True, radius=(K.POS, REQUIRED), length=(K.POS, REQUIRED)),
    "Goblet": _primitive(
        True, **_required(K.POS, "height", "radius_top", "radius_bottom"), thickness=(K.POS, 0.002), sides=(K.INT, 12)
    ),
    "Track": _primitive(True, **_required(K.POS, "length", "width", "height", "wall_thickness")),
    "Pivot": _primitive(False, body=(K.BODY, REQUIRED), other=(K.BODY, None), axis=(K.AXIS, Y_AXIS)),
    "Fastener": _primitive(False, bodies=(K.BODIES, REQUIRED)),
    "Lever": _primitive(True, size=(K.VEC3POS, REQUIRED), pivot=(K.VEC3, _ZERO3), axis=(K.AXIS, Y_AXIS)),
    "Pulley": _primitive(True, radius=(K.POS, REQUIRED), height=(K.POS, REQUIRED)),
    "DominoRun": _primitive(
        True,
        size=(K.VEC3POS, REQUIRED),
        poses=(K.POSES, None),
        path=(K.POINTS2, None),
        spacing=(K.POS, None),
        count=(K.INT, None),
    ),
    "TensionRope": _primitive(
        False,
        ends=(K.BODIES2, REQUIRED),
        anchors=(K.ANCHORS, (_ZERO3, _ZERO3)),
        guides=(K.POINTS3, ()),
        length=(K.POS, None),
    ),
    "RopePulley": _primitive(
        False,
        ends=(K.BODIES2, REQUIRED),
        pulleys=(K.BODIES1_PLUS, REQUIRED),
        anchors=(K.ANCHORS, (_ZERO3, _ZERO3)),
        length=(K.POS, None),
    ),
})

#: Parameters of each event type (thesis App. C.2); every event also takes the fields of :data:`EVENT_COMMON`.
EVENTS: MappingProxyType[str, MappingProxyType[str, Param]] = MappingProxyType({
    "Contact": _event(a=(K.BODY, REQUIRED), b=(K.BODY, REQUIRED)),
    "NoContact": _event(a=(K.BODY, REQUIRED), b=(K.BODY, REQUIRED)),
    "RollingOn": _event(body=(K.BODY, REQUIRED), on=(K.BODY, REQUIRED), min_angular_speed=(K.POS, 1.0)),
    "Falling": _event(body=(K.BODY, REQUIRED), min_speed=(K.POS, 0.05)),
    "Rising": _event(body=(K.BODY, REQUIRED), min_speed=(K.POS, 0.05)),
    "Pivoting": _event(body=(K.BODY, REQUIRED), min_angular_speed=(K.POS, 0.5), axis=(K.AXIS, None)),
    "Stopping": _event(body=(K.BODY, REQUIRED), max_speed=(K.POS, 0.01), max_angular_speed=(K.POS, 0.2)),
    "NotMoving": _event(body=(K.BODY, REQUIRED), tolerance=(K.POS, 0.002)),
    "Toppling": _event(body=(K.BODY, REQUIRED), angle=(K.POS, 15.0)),
    "Inclusion": _event(body=(K.BODY, REQUIRED), container=(K.BODY, REQUIRED)),
})
del K

#: Primitives whose objects cannot be placed (no ranges): they only tie other objects together.
UNPLACED = frozenset({"Fastener"})
