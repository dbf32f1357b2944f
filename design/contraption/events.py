"""Event conditions (thesis App. C.2): Boolean functions of the bodies' transforms, velocities and contacts.

- ``Contact`` / ``NoContact``: Bullet's contact points between two bodies (a point counts when its distance is
  at most :data:`CONTACT_DISTANCE`).
- ``RollingOn``: contact with the support and an angular speed above a threshold (Pivoting + Contact).
- ``Falling`` / ``Rising``: vertical velocity below ``-min_speed`` / above ``min_speed``.
- ``Pivoting``: angular speed (or its component along a world ``axis``) above ``min_angular_speed``.
- ``Stopping``: linear and angular speeds below thresholds.
- ``NotMoving``: the position is within ``tolerance`` of the initial one (give it a ``duration`` to mean "stays").
- ``Toppling``: the rotation from the initial orientation exceeds ``angle`` degrees, whatever its axis.
- ``Inclusion``: the body's centre is inside the container's inner volume, in the container's frame (a Goblet's
  frustum, an OpenBox's or Track's inside, other shapes' bounding box). The thesis cast rays; a containment test in
  the container's frame gives the same answer for cups and is not fooled by other bodies in the way.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from design.contraption.bullet import pybullet
from design.contraption.model import EventSpec
from design.contraption.world import World, world_label

#: Contact points farther apart than this (m) do not count as touching (Bullet keeps near-contacts in its cache).
CONTACT_DISTANCE = 2e-4
#: A body at rest counts as possibly toppling when its angle is within this of the threshold (radians).
TOPPLE_MARGIN = math.radians(1.0)


def bound(client, name: str):
    """pybullet's function ``name`` bound to ``client``'s connection, made once (a BulletClient makes a new partial
    at every attribute access, a cost paid at every step by every awake event)."""
    number = getattr(client, "_client", None)
    if isinstance(number, int):
        return functools.partial(getattr(pybullet, name), physicsClientId=number)
    return getattr(client, name)


def _unit(q) -> tuple[float, float, float, float]:
    x, y, z, w = (float(v) for v in q)
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    return x / norm, y / norm, z / norm, w / norm


def _compose(p, q) -> tuple[float, float, float, float]:
    """The quaternion ``p * q`` (x, y, z, w), as scipy's Rotation composes them."""
    cross = (p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0])
    return (p[3] * q[0] + q[3] * p[0] + cross[0],
            p[3] * q[1] + q[3] * p[1] + cross[1],
            p[3] * q[2] + q[3] * p[2] + cross[2],
            p[3] * q[3] - p[0] * q[0] - p[1] * q[1] - p[2] * q[2])


def _rotate_inverse(q, v) -> tuple[float, float, float]:
    """``v`` rotated by the inverse of the unit quaternion ``q`` (the transpose of its matrix)."""
    x, y, z, w = q
    m00, m01, m02 = 1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)
    m10, m11, m12 = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
    m20, m21, m22 = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)
    return (m00 * v[0] + m10 * v[1] + m20 * v[2],
            m01 * v[0] + m11 * v[1] + m21 * v[2],
            m02 * v[0] + m12 * v[1] + m22 * v[2])


class Condition:
    """Base: resolves body references and binds the pybullet queries once; :meth:`__call__` evaluates the condition
    now. Conditions only read the simulation, so they cannot change a run's course, only when it is noticed."""

    def __init__(self, world: World, spec: EventSpec) -> None:
        self.world = world
        self.client = world.client
        self.spec = spec
        self.params = spec.params
        self._velocity = bound(self.client, "getBaseVelocity")
        self._pose = bound(self.client, "getBasePositionAndOrientation")
        self._contacts = bound(self.client, "getContactPoints")

    def uid(self, key: str) -> int:
        return self.world.uid(world_label(self.world, self.params[key]))

    def __call__(self) -> bool:  # pragma: no cover - abstract
        raise NotImplementedError

    #: Whether :meth:`may_hold` can ever answer False (the early stop reads the world only when every awake
    #: event's can).
    bounded = False

    def may_hold(self, bounds) -> bool:
        """Whether the condition can still hold over ``bounds.horizon`` (a
        :class:`~design.contraption.reach.Bounds`); False only when it certainly cannot. By default it can."""
        return True

    def surely_may_hold(self, reach, horizon: float) -> bool:
        """A cheap look before the bounds (:meth:`~design.contraption.reach.Reach.alone`): True when a moving body
        can make the condition hold with its own energy, so :meth:`may_hold` would say so too. False: look closer."""
        return False


def touching(client, a: int, b: int) -> bool:
    return any(point[8] <= CONTACT_DISTANCE for point in client.getContactPoints(bodyA=a, bodyB=b))


def _touching(contacts, a: int, b: int) -> bool:
    return any(point[8] <= CONTACT_DISTANCE for point in contacts(bodyA=a, bodyB=b))


class Contact(Condition):
    bounded = True

    def __init__(self, world, spec):
        super().__init__(world, spec)
        self.a, self.b = self.uid("a"), self.uid("b")

    def __call__(self) -> bool:
        return _touching(self._contacts, self.a, self.b)

    def may_hold(self, bounds) -> bool:
        return not bounds.apart(self.a, self.b)

    def surely_may_hold(self, reach, horizon: float) -> bool:
        for mover, other in ((self.a, self.b), (self.b, self.a)):
            alone = reach.alone(mover, horizon)
            if alone is not None and alone.meets(reach.core(other)):
                return True
        return False


class NoContact(Contact):
    bounded = False

    def __call__(self) -> bool:
        return not _touching(self._contacts, self.a, self.b)

    def may_hold(self, bounds) -> bool:
        return True

    def surely_may_hold(self, reach, horizon: float) -> bool:
        return False


class RollingOn(Condition):
    bounded = True

    def __init__(self, world, spec):
        super().__init__(world, spec)
        self.body, self.on = self.uid("body"), self.uid("on")
        self.threshold = self.params["min_angular_speed"]

    def __call__(self) -> bool:
        _, angular = self._velocity(self.body)
        return math.hypot(*angular) > self.threshold and _touching(self._contacts, self.body, self.on)

    def may_hold(self, bounds) -> bool:
        return bounds.angular(self.body) > self.threshold and not bounds.apart(self.body, self.on)

    def surely_may_hold(self, reach, horizon: float) -> bool:
        alone = reach.alone(self.body, horizon)
        return alone is not None and alone.angular > self.threshold and alone.meets(reach.core(self.on))


class Falling(Condition):
    bounded = True

    sign = -1.0

    def __init__(self, world, spec):
        super().__init__(world, spec)
        self.body = self.uid("body")
        self.threshold = self.params["min_speed"]

    def __call__(self) -> bool:
        linear, _ = self._velocity(self.body)
        return self.sign * linear[2] > self.threshold

    def may_hold(self, bounds) -> bool:
        return bounds.speed(self.body) > self.threshold

    def surely_may_hold(self, reach, horizon: float) -> bool:
        alone = reach.alone(self.body, horizon)
        return alone is not None and alone.speed > self.threshold


class Rising(Falling):
    sign = 1.0


class Pivoting(Condition):
    bounded = True

    def __init__(self, world, spec):
        super().__init__(world, spec)
        self.body = self.uid("body")
        self.threshold = self.params["min_angular_speed"]
        axis = self.params.get("axis")
        self.axis = None if axis is None else tuple(np.asarray(axis, dtype=float) / np.linalg.norm(axis))

    def __call__(self) -> bool:
        _, angular = self._velocity(self.body)
        if self.axis is None:
            return math.hypot(*angular) > self.threshold
        a = self.axis
        return abs(angular[0] * a[0] + angular[1] * a[1] + angular[2] * a[2]) > self.threshold

    def may_hold(self, bounds) -> bool:
        return bounds.angular(self.body) > self.threshold

    def surely_may_hold(self, reach, horizon: float) -> bool:
        alone = reach.alone(self.body, horizon)
        return alone is not None and alone.angular > self.threshold


class Stopping(Condition):
    def __init__(self, world, spec):
        super().__init__(world, spec)
        self.body = self.uid("body")
        self.max_speed = self.params["max_speed"]
        self.max_angular = self.params["max_angular_speed"]

    def __call__(self) -> bool:
        linear, angular = self._velocity(self.body)
        return math.hypot(*linear) < self.max_speed and math.hypot(*angular) < self.max_angular


class NotMoving(Condition):
    bounded = True

    def __init__(self, world, spec):
        super().__init__(world, spec)
        label = world_label(world, self.params["body"])
        self.body = world.uid(label)
        self.initial = tuple(float(v) for v in world.bodies[label].initial.position)
        self.tolerance = self.params["tolerance"]

    def __call__(self) -> bool:
        position, _ = self._pose(self.body)
        x, y, z = (p - i for p, i in zip(position, self.initial))
        return math.sqrt(x * x + y * y + z * z) <= self.tolerance

    def may_hold(self, bounds) -> bool:
        if bounds.fixed(self.body):
            # At rest out of reach: it stays where it is, give or take its creep.
            position, _ = self._pose(self.body)
            away = math.dist(position, self.initial)
            return away - bounds.creep() <= self.tolerance
        # A moving body's box is a sphere about its centre: the initial position must be within reach.
        box = bounds.box(self.body)
        if box is None:
            return True
        nearest = np.clip(self.initial, box[0], box[1])
        return float(np.linalg.norm(nearest - self.initial)) <= self.tolerance

    def surely_may_hold(self, reach, horizon: float) -> bool:
        alone = reach.alone(self.body, horizon)
        return alone is not None and alone.reaches(self.initial)


class Toppling(Condition):
    bounded = True

    def __init__(self, world, spec):
        super().__init__(world, spec)
        label = world_label(world, self.params["body"])
        self.body = world.uid(label)
        x, y, z, w = _unit(world.bodies[label].initial.rotation.as_quat())
        self.initial_inverse = (-x, -y, -z, w)
        self.threshold = math.radians(self.params["angle"])

    def angle(self) -> float:
        """The rotation from the initial orientation now (radians)."""
        _, quaternion = self._pose(self.body)
        x, y, z, w = _unit(_compose(self.initial_inverse, _unit(quaternion)))
        return 2.0 * math.atan2(math.sqrt(x * x + y * y + z * z), abs(w))

    def __call__(self) -> bool:
        return self.angle() > self.threshold

    def may_hold(self, bounds) -> bool:
        # A body that turns no faster than its bound cannot add more than that times the horizon to its angle; one
        # at rest out of reach keeps its angle (with a margin for its creep).
        return self.angle() + bounds.turn(self.body) + TOPPLE_MARGIN > self.threshold

    def surely_may_hold(self, reach, horizon: float) -> bool:
        alone = reach.alone(self.body, horizon)
        return alone is not None and self.angle() + alone.angular * horizon + TOPPLE_MARGIN > self.threshold


class Inclusion(Condition):
    bounded = True

    def __init__(self, world, spec):
        super().__init__(world, spec)
        self.body = self.uid("body")
        container_label = world_label(world, self.params["container"])
        self.container = world.uid(container_label)
        container = world.bodies[container_label]
        obj = world.scenario.object(container.object_name)
        self.kind = obj.type
        self.shape = obj.shape
        points = np.concatenate([p.surface_points(12) for p in container.spec.parts if p.kind != "plane"])
        self.lower = points.min(axis=0)
        self.upper = points.max(axis=0)

    def inside_local(self, p: np.ndarray) -> bool:
        if self.kind == "Goblet":
            height = self.shape["height"]
            z = p[2]
            if not -height / 2 + self.shape["thickness"] <= z <= height / 2:
                return False
            fraction = (z + height / 2) / height
            radius = self.shape["radius_bottom"] + fraction * (self.shape["radius_top"] - self.shape["radius_bottom"])
            return math.hypot(p[0], p[1]) <= radius
        return bool(np.all(p >= self.lower) and np.all(p <= self.upper))

    def __call__(self) -> bool:
        position, _ = self._pose(self.body)
        c_position, c_quaternion = self._pose(self.container)
        offset = tuple(p - c for p, c in zip(position, c_position))
        return self.inside_local(np.array(_rotate_inverse(_unit(c_quaternion), offset)))

    def may_hold(self, bounds) -> bool:
        # The inner volume lies inside the container's hull and the body's centre inside its own.
        return not bounds.apart(self.body, self.container)

    def surely_may_hold(self, reach, horizon: float) -> bool:
        alone = reach.alone(self.body, horizon)
        return alone is not None and alone.meets(reach.core(self.container))


CONDITIONS: dict[str, type[Condition]] = {
    "Contact": Contact,
    "NoContact": NoContact,
    "RollingOn": RollingOn,
    "Falling": Falling,
    "Rising": Rising,
    "Pivoting": Pivoting,
    "Stopping": Stopping,
    "NotMoving": NotMoving,
    "Toppling": Toppling,
    "Inclusion": Inclusion,
}


def make_condition(world: World, spec: EventSpec) -> Condition:
    return CONDITIONS[spec.type](world, spec)
