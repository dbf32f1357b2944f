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

import math

import numpy as np
from scipy.spatial.transform import Rotation

from design.contraption.model import EventSpec
from design.contraption.world import World, world_label

#: Contact points farther apart than this (m) do not count as touching (Bullet keeps near-contacts in its cache).
CONTACT_DISTANCE = 2e-4


class Condition:
    """Base: resolves body references once; :meth:`__call__` evaluates the condition now."""

    def __init__(self, world: World, spec: EventSpec) -> None:
        self.world = world
        self.client = world.client
        self.spec = spec
        self.params = spec.params

    def uid(self, key: str) -> int:
        return self.world.uid(world_label(self.world, self.params[key]))

    def __call__(self) -> bool:  # pragma: no cover - abstract
        raise NotImplementedError


def touching(client, a: int, b: int) -> bool:
    return any(point[8] <= CONTACT_DISTANCE for point in client.getContactPoints(bodyA=a, bodyB=b))


class Contact(Condition):
    def __init__(self, world, spec):
        super().__init__(world, spec)
        self.a, self.b = self.uid("a"), self.uid("b")

    def __call__(self) -> bool:
        return touching(self.client, self.a, self.b)


class NoContact(Contact):
    def __call__(self) -> bool:
        return not touching(self.client, self.a, self.b)


class RollingOn(Condition):
    def __init__(self, world, spec):
        super().__init__(world, spec)
        self.body, self.on = self.uid("body"), self.uid("on")
        self.threshold = self.params["min_angular_speed"]

    def __call__(self) -> bool:
        _, angular = self.client.getBaseVelocity(self.body)
        return math.hypot(*angular) > self.threshold and touching(self.client, self.body, self.on)


class Falling(Condition):
    sign = -1.0

    def __init__(self, world, spec):
        super().__init__(world, spec)
        self.body = self.uid("body")
        self.threshold = self.params["min_speed"]

    def __call__(self) -> bool:
        linear, _ = self.client.getBaseVelocity(self.body)
        return self.sign * linear[2] > self.threshold


class Rising(Falling):
    sign = 1.0


class Pivoting(Condition):
    def __init__(self, world, spec):
        super().__init__(world, spec)
        self.body = self.uid("body")
        self.threshold = self.params["min_angular_speed"]
        axis = self.params.get("axis")
        self.axis = None if axis is None else np.asarray(axis, dtype=float) / np.linalg.norm(axis)

    def __call__(self) -> bool:
        _, angular = self.client.getBaseVelocity(self.body)
        if self.axis is None:
            return math.hypot(*angular) > self.threshold
        return abs(float(np.dot(angular, self.axis))) > self.threshold


class Stopping(Condition):
    def __init__(self, world, spec):
        super().__init__(world, spec)
        self.body = self.uid("body")
        self.max_speed = self.params["max_speed"]
        self.max_angular = self.params["max_angular_speed"]

    def __call__(self) -> bool:
        linear, angular = self.client.getBaseVelocity(self.body)
        return math.hypot(*linear) < self.max_speed and math.hypot(*angular) < self.max_angular


class NotMoving(Condition):
    def __init__(self, world, spec):
        super().__init__(world, spec)
        label = world_label(world, self.params["body"])
        self.body = world.uid(label)
        self.initial = world.bodies[label].initial.position
        self.tolerance = self.params["tolerance"]

    def __call__(self) -> bool:
        position, _ = self.client.getBasePositionAndOrientation(self.body)
        return float(np.linalg.norm(np.asarray(position) - self.initial)) <= self.tolerance


class Toppling(Condition):
    def __init__(self, world, spec):
        super().__init__(world, spec)
        label = world_label(world, self.params["body"])
        self.body = world.uid(label)
        self.initial_inverse = world.bodies[label].initial.rotation.inv()
        self.threshold = math.radians(self.params["angle"])

    def __call__(self) -> bool:
        _, quaternion = self.client.getBasePositionAndOrientation(self.body)
        return (self.initial_inverse * Rotation.from_quat(quaternion)).magnitude() > self.threshold


class Inclusion(Condition):
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
        position, _ = self.client.getBasePositionAndOrientation(self.body)
        c_position, c_quaternion = self.client.getBasePositionAndOrientation(self.container)
        local = Rotation.from_quat(c_quaternion).inv().apply(np.asarray(position) - np.asarray(c_position))
        return self.inside_local(local)


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
