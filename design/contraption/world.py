"""Building a scenario's scene in a pybullet client: bodies, joints (Pivot, Fastener, Lever, Pulley) and ropes.

Simplifications, said plainly:

- A Pivot (and the hinge of a Lever or Pulley) is two point-to-point constraints on the hinge axis, 2 cm apart:
  pybullet's ``createConstraint`` has no revolute joint between free bodies, and two ball joints on one axis leave
  exactly the rotation about it.
- Ropes (TensionRope, RopePulley) are massless, inextensible, frictionless and do not collide, as in the thesis
  (App. C.1.3). After every step a unilateral length constraint is solved at the velocity level: when the rope is
  taut and its ends move apart, an impulse along the rope (same tension at both ends, torque included) removes the
  stretching velocity, plus a small positional (Baumgarte) correction. A RopePulley's rope passes over the top of
  each pulley wheel (guide point = wheel centre + radius up); the wheel does not spin with the rope.
"""

from __future__ import annotations

import functools
import math
import weakref
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

# The rope impulses feed back into the physics, so they are computed with exactly the arithmetic scipy's Rotation
# uses (its compiled backend, called here without the per-call array-API wrapping that dominated a step's time).
# Without the backend (another scipy layout), Rotation itself does the same work, more slowly.
try:
    from scipy.spatial.transform import _rotation_cy as _rotations
except ImportError:  # pragma: no cover - depends on scipy's private layout
    _rotations = None

from design.contraption.bullet import pybullet
from design.contraption.geometry import Pose, world_poses
from design.contraption.model import Scenario
from design.contraption.primitives import BodySpec, ShapePart, body_specs

_GEOM = {"box": pybullet.GEOM_BOX, "sphere": pybullet.GEOM_SPHERE, "cylinder": pybullet.GEOM_CYLINDER,
         "capsule": pybullet.GEOM_CAPSULE, "plane": pybullet.GEOM_PLANE}

#: Half the distance between the two ball joints of a hinge (m).
HINGE_HALF_SPAN = 0.01


@dataclass
class Body:
    """A rigid body in the world."""

    label: str
    object_name: str
    uid: int
    spec: BodySpec
    static: bool
    initial: Pose
    mass: float


@dataclass
class Rope:
    """A rope between two body anchors through guide points (fixed, or on pulley wheels)."""

    name: str
    ends: tuple[int, int]
    anchors: tuple[np.ndarray, np.ndarray]
    fixed_guides: list[np.ndarray]
    pulley_guides: list[tuple[int, float]]
    length: float = 0.0
    #: When the rope was last found slack: its path length then and the poses of the bodies that carry its ends
    #: and pulley wheels (see :meth:`World.enforce_ropes`).
    slack_since: tuple | None = field(default=None, repr=False, compare=False)

    def guides(self, client) -> list[np.ndarray]:
        if not self.pulley_guides:
            return self.fixed_guides
        points = []
        for uid, radius in self.pulley_guides:
            position, _ = client.getBasePositionAndOrientation(uid)
            points.append(np.asarray(position) + (0.0, 0.0, radius))
        return points


@dataclass
class World:
    """The bodies, joints and ropes of one scenario instance in one pybullet client."""

    client: object
    scenario: Scenario
    bodies: dict[str, Body] = field(default_factory=dict)
    ropes: list[Rope] = field(default_factory=list)
    joined_pairs: set[frozenset[str]] = field(default_factory=set)
    #: Bodies hinged to the world: the hinge's centre (its frame origin turns about it at a fixed distance).
    hinged: dict[str, np.ndarray] = field(default_factory=dict)
    _inertia: dict[int, tuple[float, np.ndarray, Rotation]] = field(default_factory=dict)

    def uid(self, label: str) -> int:
        return self.bodies[label].uid

    def pose(self, label: str) -> Pose:
        position, quaternion = self.client.getBasePositionAndOrientation(self.bodies[label].uid)
        return Pose.from_bullet(position, quaternion)

    def snapshot(self) -> list[tuple[str, str, Pose, BodySpec]]:
        """(label, object name, world pose, body spec) of every body now."""
        return [(b.label, b.object_name, self.pose(b.label), b.spec) for b in self.bodies.values()]

    # -- ropes -----------------------------------------------------------------------------------------------
    def _bound(self, name: str):
        """pybullet's function ``name`` bound to this world's client once (a BulletClient makes a new partial at
        every attribute access)."""
        cache = self.__dict__.setdefault("_functions", {})
        function = cache.get(name)
        if function is None:
            number = getattr(self.client, "_client", None)
            if isinstance(number, int):
                function = functools.partial(getattr(pybullet, name), physicsClientId=number)
            else:
                function = getattr(self.client, name)
            cache[name] = function
        return function

    def rope_path(self, rope: Rope) -> tuple[list[np.ndarray], float]:
        path, length, _ = self._rope_path(rope)
        return path, length

    def _rope_path(self, rope: Rope):
        """The rope's path and length, and each end body's (position, rotation) they were computed from."""
        pose = self._bound("getBasePositionAndOrientation")
        points = []
        ends = []
        for uid, anchor in zip(rope.ends, rope.anchors):
            position, quaternion = pose(uid)
            rotation = _from_quat(quaternion)
            points.append(np.asarray(position) + _apply(rotation, anchor))
            ends.append((position, rotation))
        path = [points[0], *rope.guides(self.client), points[1]]
        length = float(sum(np.linalg.norm(b - a) for a, b in zip(path[:-1], path[1:])))
        return path, length, ends

    def _inverse_inertia(self, uid: int):
        if uid not in self._inertia:
            info = self.client.getDynamicsInfo(uid, -1)
            mass = info[0]
            if mass <= 0:
                self._inertia[uid] = (0.0, np.zeros(3), None)
            else:
                diagonal = np.asarray(info[2], dtype=float)
                inv = np.where(diagonal > 0, 1.0 / np.maximum(diagonal, 1e-300), 0.0)
                self._inertia[uid] = (1.0 / mass, inv, _from_quat(info[4]))
        return self._inertia[uid]

    def enforce_ropes(self, dt: float) -> None:
        """Remove the stretching velocity of every taut rope (unilateral, velocity-level, see module notes)."""
        velocity_of = self._bound("getBaseVelocity")
        set_velocity = self._bound("resetBaseVelocity")
        pose = self._bound("getBasePositionAndOrientation")
        for rope in self.ropes:
            carriers = (*rope.ends, *(uid for uid, _ in rope.pulley_guides))
            poses = [pose(uid) for uid in carriers]
            if rope.slack_since is not None and _still_slack(rope, poses):
                continue  # slack, as the full computation would find
            path, length, ends = self._rope_path(rope)
            stretch = length - rope.length
            if stretch < -1e-4:
                rope.slack_since = (length, poses)
                continue  # slack
            rope.slack_since = None
            terms = []
            rate = 0.0
            k = 0.0
            for end_index, uid in enumerate(rope.ends):
                inv_mass, inv_diag, inertial = self._inverse_inertia(uid)
                point = path[0] if end_index == 0 else path[-1]
                toward = path[1] if end_index == 0 else path[-2]
                direction = toward - point
                norm = np.linalg.norm(direction)
                if norm < 1e-9 or inv_mass == 0.0:
                    continue
                u = direction / norm
                position, rotation = ends[end_index]
                linear, angular = velocity_of(uid)
                r = point - np.asarray(position)
                velocity = np.asarray(linear) + _cross(angular, r)
                rate -= float(u @ velocity)  # dL/dt contribution: the end moving away from its next point
                world_inertial = _compose(rotation, inertial)
                inverse = _inverse(world_inertial)
                rxu_local = _apply(inverse, _cross(r, u))
                k += inv_mass + float(rxu_local @ (inv_diag * rxu_local))
                terms.append((uid, u, r, inv_mass, inv_diag, world_inertial, inverse, linear, angular))
            if k <= 0.0:
                continue
            target = -0.2 * max(stretch, 0.0) / dt
            impulse = (rate - target) / k
            if impulse <= 0.0:
                continue
            for uid, u, r, inv_mass, inv_diag, world_inertial, inverse, linear, angular in terms:
                dv = impulse * inv_mass * u
                dw = _apply(world_inertial, inv_diag * _apply(inverse, _cross(r, impulse * u)))
                set_velocity(uid, list(np.asarray(linear) + dv), list(np.asarray(angular) + dw))


#: Metres added to the slack bound of :func:`_still_slack` for the rounding of the lengths it compares.
_SLACK_ROUNDING = 1e-9


def _still_slack(rope: Rope, poses: list) -> bool:
    """Whether ``rope``, slack when last measured, is certainly still slack with its carriers at ``poses``.

    Its path is its two end points joined through its guides. An end point ``c + R a`` moved at most
    ``|c - c0| + 2 |a| |q - q0|`` (unit quaternions, the closer sign of ``q0``), a pulley's guide point as far as the
    wheel's centre, and a path's length grows at most by its end points' moves plus twice its guides' moves.
    """
    length, before = rope.slack_since
    anchors = (*rope.anchors, *(np.zeros(3) for _ in rope.pulley_guides))
    weights = (1.0, 1.0, *(2.0 for _ in rope.pulley_guides))
    growth = 0.0
    for (c0, q0), (c1, q1), anchor, weight in zip(before, poses, anchors, weights):
        moved = math.sqrt(sum((a - b) ** 2 for a, b in zip(c1, c0)))
        if q0 != q1:
            plus = math.sqrt(sum((a - b) ** 2 for a, b in zip(q1, q0)))
            minus = math.sqrt(sum((a + b) ** 2 for a, b in zip(q1, q0)))
            moved += 2.0 * math.sqrt(float(anchor @ anchor)) * min(plus, minus)
        growth += weight * moved
    return length + growth + _SLACK_ROUNDING < rope.length - 1e-4


def _cross(a, b) -> np.ndarray:
    """``numpy.cross`` of two 3-vectors, bit for bit (the same products and differences), without its overhead."""
    a0, a1, a2 = (float(v) for v in a)
    b0, b1, b2 = (float(v) for v in b)
    return np.array((a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0))


def _from_quat(quaternion):
    """``Rotation.from_quat(quaternion)``: scipy's normalized quaternion, shape (1, 4) (or the Rotation)."""
    if _rotations is None:  # pragma: no cover
        return Rotation.from_quat(quaternion)
    return _rotations.from_quat(np.asarray([quaternion], dtype=float))


def _compose(a, b):
    """``a * b`` of two rotations made by :func:`_from_quat`, normalized as Rotation's product is."""
    if _rotations is None:  # pragma: no cover
        return a * b
    return _rotations.from_quat(np.asarray(_rotations.compose_quat(a, b)))


def _inverse(rotation):
    if _rotations is None:  # pragma: no cover
        return rotation.inv()
    return _rotations.inv(rotation)


def _apply(rotation, vector) -> np.ndarray:
    """``rotation.apply(vector)`` for one rotation and one vector."""
    if _rotations is None:  # pragma: no cover
        return rotation.apply(vector)
    return _rotations.apply(rotation, np.asarray(vector, dtype=float).reshape(1, 3))[0]


def _create_body(client, spec: BodySpec, pose: Pose, mass: float) -> int:
    parts = spec.parts
    visual = -1
    if len(parts) == 1 and parts[0].kind == "plane":
        shape = client.createCollisionShape(pybullet.GEOM_PLANE, planeNormal=[0, 0, 1])
        # Without a visual shape of its own pybullet draws the plane's collision shape for its renderer (a large
        # checkered mesh): 5-20 ms a plane, most of a small scene's building. Pictures come from render.py, never
        # from pybullet's renderer, and visual shapes play no part in the physics.
        visual = client.createVisualShape(pybullet.GEOM_SPHERE, radius=1e-3)
    elif len(parts) == 1 and parts[0].pose.rotation.magnitude() == 0.0 and not parts[0].pose.position.any():
        # A single primitive shape: much cheaper for Bullet than a compound of one child.
        part = parts[0]
        if part.kind == "box":
            shape = client.createCollisionShape(pybullet.GEOM_BOX, halfExtents=list(part.dims))
        elif part.kind == "sphere":
            shape = client.createCollisionShape(pybullet.GEOM_SPHERE, radius=part.dims[0])
        else:
            shape = client.createCollisionShape(_GEOM[part.kind], radius=part.dims[0], height=part.dims[1])
    else:
        shape = client.createCollisionShapeArray(
            shapeTypes=[_GEOM[p.kind] for p in parts],
            radii=[p.dims[0] if p.kind in ("sphere", "cylinder", "capsule") else 0.0 for p in parts],
            halfExtents=[list(p.dims) if p.kind == "box" else [0.0, 0.0, 0.0] for p in parts],
            lengths=[p.dims[1] if p.kind in ("cylinder", "capsule") else 0.0 for p in parts],
            collisionFramePositions=[p.pose.position.tolist() for p in parts],
            collisionFrameOrientations=[list(p.pose.quaternion) for p in parts],
        )
    return client.createMultiBody(
        baseMass=mass,
        baseCollisionShapeIndex=shape,
        baseVisualShapeIndex=visual,
        basePosition=pose.position.tolist(),
        baseOrientation=list(pose.quaternion),
        # Plain rigid bodies (not Featherstone multibodies): several times faster, and they can sleep.
        useMaximalCoordinates=True,
    )


def build_world(client, scenario: Scenario, x=None) -> World:
    """Reset ``client`` and build the scenario instance of layout ``x`` (real units; default layout if None)."""
    settings = scenario.settings
    client.resetSimulation()
    client.setPhysicsEngineParameter(
        fixedTimeStep=settings.time_step,
        numSubSteps=0,
        numSolverIterations=settings.solver_iterations,
        deterministicOverlappingPairs=1,
        # Bullet's default (2 cm) is meant for metre-sized bodies; ours are centimetre-sized.
        contactBreakingThreshold=0.002,
    )
    client.setGravity(0, 0, settings.gravity)
    transforms = scenario.transforms(x)
    frames = world_poses(scenario.objects, transforms)
    world = World(client=client, scenario=scenario)
    for obj, specs in _scenario_specs(scenario):
        if not specs:
            continue
        physics = obj.physics
        static = physics.static or obj.type == "Plane"
        per_body_mass = 0.0 if static else physics.mass
        for spec in specs:
            pose = frames[obj.name] * spec.pose
            uid = _create_body(client, spec, pose, per_body_mass)
            client.changeDynamics(
                uid,
                -1,
                lateralFriction=physics.friction,
                rollingFriction=physics.rolling_friction,
                spinningFriction=physics.spinning_friction,
                restitution=physics.restitution,
                linearDamping=physics.linear_damping,
                angularDamping=physics.angular_damping,
            )
            if obj.starts_asleep and not static:
                client.changeDynamics(uid, -1, activationState=pybullet.ACTIVATION_STATE_SLEEP)
            world.bodies[spec.label] = Body(spec.label, obj.name, uid, spec, static, pose, per_body_mass)
    for obj in scenario.objects:
        if obj.type == "Pivot":
            other = obj.shape.get("other")
            _hinge(world, frames[obj.name], obj.shape["axis"], obj.shape["body"], other)
        elif obj.type == "Lever":
            offset = Pose(obj.shape["pivot"])
            _hinge(world, frames[obj.name] * offset, obj.shape["axis"], obj.name, None)
        elif obj.type == "Pulley":
            _hinge(world, frames[obj.name], (0.0, 1.0, 0.0), obj.name, None)
        elif obj.type == "Fastener":
            labels = obj.shape["bodies"]
            _fasten(world, labels[0], labels[1] if len(labels) > 1 else None)
    for obj in scenario.objects:
        if obj.type in ("TensionRope", "RopePulley"):
            a, b = obj.shape["ends"]
            anchors = tuple(np.asarray(v, dtype=float) for v in obj.shape["anchors"])
            fixed = [frames[obj.name].apply(g) for g in obj.shape.get("guides", ())]
            pulleys = []
            for label in obj.shape.get("pulleys", ()):
                pulley = scenario.object(_object_of(label))
                pulleys.append((world.uid(world_label(world, label)), pulley.shape["radius"]))
            ends = (world.uid(world_label(world, a)), world.uid(world_label(world, b)))
            rope = Rope(obj.name, ends, anchors, fixed, pulleys)
            _, initial_length = world.rope_path(rope)
            rope.length = obj.shape.get("length", initial_length)
            world.ropes.append(rope)
    return world


#: Each scenario's body specs by object, made once per scenario: they do not depend on the layout, and remaking
#: them (a domino run's poses, scipy rotations) is a large share of building a small scene.
_specs: dict[int, tuple[weakref.ref, list]] = {}


def _scenario_specs(scenario: Scenario) -> list:
    key = id(scenario)
    entry = _specs.get(key)
    if entry is not None and entry[0]() is scenario:
        return entry[1]
    value = [(obj, body_specs(obj)) for obj in scenario.objects]
    _specs[key] = (weakref.ref(scenario, lambda _, key=key: _specs.pop(key, None)), value)
    return value


def _object_of(ref: str) -> str:
    return ref.split("[", 1)[0]


def _hinge(world: World, frame: Pose, axis, body_label: str, other_label: str | None) -> None:
    client = world.client
    body_label = world_label(world, body_label)
    axis_world = frame.rotation.apply(np.asarray(axis, dtype=float))
    axis_world /= np.linalg.norm(axis_world)
    body = world.bodies[body_label]
    body_pose = world.pose(body_label)
    other = world.bodies[world_label(world, other_label)] if other_label else None
    for sign in (-1.0, 1.0):
        point = frame.position + sign * HINGE_HALF_SPAN * axis_world
        in_body = body_pose.inverse().apply(point)
        if other is None:
            anchor = _anchor(client, point)
            client.createConstraint(body.uid, -1, anchor, -1, pybullet.JOINT_POINT2POINT, [0, 0, 0],
                                    in_body.tolist(), [0, 0, 0])
        else:
            in_other = world.pose(other.label).inverse().apply(point)
            client.createConstraint(body.uid, -1, other.uid, -1, pybullet.JOINT_POINT2POINT, [0, 0, 0],
                                    in_body.tolist(), in_other.tolist())
    if other is not None:
        client.setCollisionFilterPair(body.uid, other.uid, -1, -1, 0)
        world.joined_pairs.add(frozenset((body.label, other.label)))
    else:
        world.hinged[body.label] = np.array(frame.position, dtype=float)


def _anchor(client, position, quaternion=(0.0, 0.0, 0.0, 1.0)) -> int:
    """A static body without collision shape: the world end of a joint (rigid bodies cannot join the world)."""
    return client.createMultiBody(
        baseMass=0.0,
        baseCollisionShapeIndex=-1,
        basePosition=list(position),
        baseOrientation=list(quaternion),
        useMaximalCoordinates=True,
    )


def _fasten(world: World, a_label: str, b_label: str | None) -> None:
    client = world.client
    a = world.bodies[world_label(world, a_label)]
    a_pose = world.pose(a.label)
    if b_label is None:
        anchor = _anchor(client, a_pose.position, a_pose.quaternion)
        client.createConstraint(a.uid, -1, anchor, -1, pybullet.JOINT_FIXED, [0, 0, 0], [0, 0, 0], [0, 0, 0])
        return
    b = world.bodies[world_label(world, b_label)]
    relative = a_pose.inverse() * world.pose(b.label)
    client.createConstraint(a.uid, -1, b.uid, -1, pybullet.JOINT_FIXED, [0, 0, 0],
                            relative.position.tolist(), [0, 0, 0], list(relative.quaternion), [0, 0, 0, 1])
    client.setCollisionFilterPair(a.uid, b.uid, -1, -1, 0)
    world.joined_pairs.add(frozenset((a.label, b.label)))


def world_label(world: World, ref: str) -> str:
    """The body label of a reference: ``run[-1]`` → ``run[7]`` for a run of 8 dominoes."""
    if ref in world.bodies:
        return ref
    name, _, rest = ref.partition("[")
    index = int(rest.rstrip("]"))
    labels = [b.label for b in world.bodies.values() if b.object_name == name]
    return labels[index]


def part_world_points(pose: Pose, part: ShapePart, n: int = 16) -> np.ndarray:
    return pose.apply(part.surface_points(n))


def angle_between(q_a: Rotation, q_b: Rotation) -> float:
    """Angle (degrees) of the rotation taking orientation a to b, whatever the axis."""
    return math.degrees((q_a.inv() * q_b).magnitude())
