"""What the moving bodies can still reach before the awake events' timeouts: the bound behind the early stop that
does not wait for a timeout once no awake event can still happen.

The bodies are read in one pass (poses, velocities, bounding boxes) and each gets a box that holds it over the
rest of the run (``horizon`` seconds):

- **Fixed**: a static body, or a body at rest (slower than :data:`REST_SPEED` and :data:`REST_ANGULAR` at two
  checks in a row, and moved less than :data:`REST_MOVE` between them) that no moving body can reach. A body at rest
  is in equilibrium and stays there until something touches it; its box is its bounding box now.
- **Moving**: the others, in groups that share energy. Bodies joined by a hinge, a fastener or a rope start in
  one group; any body (moving, or at rest) whose box overlaps a moving group's box joins that group, until nothing
  changes. With no energy coming in, a group's kinetic energy plus the potential energy its bodies can still lose
  (down to the lowest horizontal plane under them, where their frame origin stands at least its distance to the
  body's hull above the plane) bounds what any of its bodies can have: ``m v^2 / 2 <= K`` bounds its speed,
  ``I_min w^2 / 2 <= K`` its angular speed, and its box is a sphere around its centre, the body's radius plus
  ``v_max * horizon`` (so it holds whatever the body's turning).
- **A ball alone on a horizontal plane** (a single sphere, equal linear and angular damping, in a group of its own
  whose box touches no other body nor a plane that is not horizontal): its horizontal velocity stays in the
  triangle of zero, its velocity now and the velocity it rolls at once its slip has gone (``v - 2/7 u``, ``u`` the
  slip at the contact). The contact's friction moves the velocity straight towards that rolling velocity (it keeps
  the angular momentum about the contact point), damping and rolling friction pull both towards zero. So over
  ``horizon`` its centre stays in its position plus ``horizon`` times that triangle, and it rises at most by the
  height its vertical speed gives: a ball rolling away from every body is known not to come back.

The energy is a bound of continuous mechanics; the solver's position corrections and rope impulses are not
exactly energy-conserving, so the energy is taken with a margin (:data:`ENERGY_MARGIN`); the recorded outcomes of
tests/data/simulation check it. An event decides from these boxes whether its condition can still hold
(:meth:`design.contraption.events.Condition.may_hold`).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from design.contraption.primitives import BodySpec
from design.contraption.world import World

#: A body is at rest below these speeds (m/s, rad/s) at two checks in a row, having moved less than REST_MOVE (m)
#: (a pile of fallen dominoes jitters at about 0.02 rad/s).
REST_SPEED = 5e-3
REST_ANGULAR = 5e-2
REST_MOVE = 2e-4
#: How fast a body at rest may creep (m/s, rad/s): its box grows by that over the horizon, its angle turns by that.
REST_CREEP = 1e-3
REST_TURN = 5e-3
#: Extra room around every box (m): Bullet's contact threshold, penetrations, a resting body's creep.
BOX_MARGIN = 2e-3
#: How far a body may sink into the floor (m): the potential energy that releases is counted.
SINK = 1e-4
#: A group's energy is taken this many times over, plus ENERGY_FLOOR (J): numerical energy gains of the solver.
ENERGY_MARGIN = 1.5
ENERGY_FLOOR = 1e-6


class Bounds:
    """Each body's box over the horizon, and the speed bounds of moving bodies (see the module notes)."""

    def __init__(self, horizon: float, index: dict[int, int], lower: np.ndarray, upper: np.ndarray,
                 fixed: np.ndarray, speed: np.ndarray, angular: np.ndarray) -> None:
        self.horizon = horizon
        self._index = index
        self.lower, self.upper = lower, upper
        self._fixed, self._speed, self._angular = fixed, speed, angular

    def box(self, uid: int) -> tuple[np.ndarray, np.ndarray] | None:
        """The box that holds the body over the horizon (None: unknown, e.g. a plane)."""
        i = self._index.get(uid)
        return None if i is None else (self.lower[i], self.upper[i])

    def fixed(self, uid: int) -> bool:
        """The body does not move over the horizon (static, or at rest and out of every moving body's reach)."""
        i = self._index.get(uid)
        return i is not None and bool(self._fixed[i])

    def speed(self, uid: int) -> float:
        i = self._index.get(uid)
        return math.inf if i is None else float(self._speed[i])

    def angular(self, uid: int) -> float:
        i = self._index.get(uid)
        return math.inf if i is None else float(self._angular[i])

    def turn(self, uid: int) -> float:
        """How far the body may turn over the horizon (radians): a body at rest only creeps."""
        if self.fixed(uid):
            return REST_TURN * self.horizon
        return self.angular(uid) * self.horizon

    def creep(self) -> float:
        """How far a body at rest may move over the horizon (m)."""
        return BOX_MARGIN + REST_CREEP * self.horizon

    def apart(self, a: int, b: int, margin: float = 0.0) -> bool:
        """The two bodies' boxes do not overlap (with ``margin``): they cannot touch over the horizon."""
        box_a, box_b = self.box(a), self.box(b)
        if box_a is None or box_b is None:
            return False
        return bool(np.any(box_a[0] > box_b[1] + margin) or np.any(box_b[0] > box_a[1] + margin))


class Alone:
    """What one moving body can reach with its own energy (see :meth:`Reach.alone`): a box its centre may reach,
    its speed and angular speed bounds."""

    __slots__ = ("lower", "upper", "speed", "angular")

    def __init__(self, lower, upper, speed, angular) -> None:
        self.lower, self.upper, self.speed, self.angular = lower, upper, speed, angular

    def reaches(self, point) -> bool:
        """The centre may come to ``point``."""
        return all(lo <= p <= hi for lo, p, hi in zip(self.lower, point, self.upper))

    def meets(self, box) -> bool:
        """The centre may come into ``box`` (lower, upper)."""
        return box is not None and all(lo <= b_hi and b_lo <= hi
                                       for lo, hi, b_lo, b_hi in zip(self.lower, self.upper, *box))


def _hull_depth(points: np.ndarray) -> float:
    """The least distance from the origin to the hull's boundary along any direction (negative when the origin is
    outside it): how far the origin stays above a plane the body rests on."""
    farthest = -float(np.max(np.linalg.norm(points, axis=1)))
    try:
        hull = ConvexHull(points)
    except (QhullError, ValueError):
        return farthest
    depth = float(np.min(-hull.equations[:, 3]))
    # Outside the hull the facets' planes can underrate the distance (an edge or corner may be nearer): take the
    # farthest point instead, a bound that holds in every orientation.
    return depth if depth >= 0.0 else farthest


def _components(joined: np.ndarray) -> np.ndarray:
    """Each body's group: the lowest index it is joined to through any chain (``joined`` symmetric), by squaring
    the reachability matrix (a few small matrix products; scipy's graph routines cost more in checks alone)."""
    n = len(joined)
    reach = (joined | np.eye(n, dtype=bool)).astype(np.float32)
    while True:
        wider = (reach @ reach > 0.0).astype(np.float32)
        if np.array_equal(wider, reach):
            return np.argmax(reach > 0.0, axis=1)
        reach = wider


@functools.lru_cache(maxsize=4096)
def _geometry(spec: BodySpec) -> tuple[float, float, bool]:
    """A body's radius around its frame origin, its hull depth (:func:`_hull_depth`), whether it is a centred
    sphere; made once per body spec (a scenario's specs are made once)."""
    parts = spec.parts
    if len(parts) == 1 and parts[0].kind == "sphere" and not parts[0].pose.position.any():
        # The sampled circles' hull lies inside the sphere: its depth would undercut the radius by a few percent.
        return parts[0].dims[0], parts[0].dims[0], True
    points = np.concatenate([p.surface_points(12) for p in parts if p.kind != "plane"])
    return float(np.max(np.linalg.norm(points, axis=1))), _hull_depth(points), False


class Reach:
    """The reach bounds of one built world (made once per run; :meth:`bounds` at each check)."""

    def __init__(self, world: World) -> None:
        self.world = world
        client = world.client
        settings = world.scenario.settings
        self.g = abs(float(settings.gravity))
        self._pose = world._bound("getBasePositionAndOrientation")
        self._velocity = world._bound("getBaseVelocity")
        self._aabb = world._bound("getAABB")
        planes, statics, dynamic = [], [], []
        for body in world.bodies.values():
            parts = body.spec.parts
            if len(parts) == 1 and parts[0].kind == "plane":
                normal = body.initial.rotation.apply((0.0, 0.0, 1.0))
                planes.append((normal, body.initial.position.copy()))
            elif body.static or body.mass <= 0.0:
                statics.append(body)
            else:
                dynamic.append(body)
        self.dynamic = dynamic
        horizontal = [p for n, p in planes if n[2] > 1.0 - 1e-9]
        self.tilted = [(n, p) for n, p in planes if n[2] <= 1.0 - 1e-9]
        #: The lowest horizontal plane: no body's hull goes below it (None: nothing holds the bodies up).
        self.floor = min(float(p[2]) for p in horizontal) if horizontal else None
        self.uids = np.array([b.uid for b in dynamic], dtype=int)
        self.mass = np.array([b.mass for b in dynamic], dtype=float)
        radius, depth, ball = [], [], []
        for body in dynamic:
            r, d, sphere = _geometry(body.spec)
            radius.append(r)
            depth.append(d)
            physics = world.scenario.object(body.object_name).physics
            ball.append(sphere and physics.linear_damping == physics.angular_damping)
        self.radius = np.array(radius)
        self.depth = np.array(depth)
        self.ball = np.array(ball, dtype=bool)
        inertia = np.array([client.getDynamicsInfo(int(uid), -1)[2] for uid in self.uids], dtype=float)
        inertia = inertia.reshape(len(dynamic), 3)
        self.inertia_max = inertia.max(axis=1) if len(dynamic) else np.zeros(0)
        self.inertia_min = inertia.min(axis=1) if len(dynamic) else np.zeros(0)
        index = {b.uid: i for i, b in enumerate(dynamic)}
        links: list[tuple[int, int]] = []
        for pair in world.joined_pairs:
            a, b = (world.bodies[label].uid for label in pair)
            if a in index and b in index:
                links.append((index[a], index[b]))
        for rope in world.ropes:
            carriers = [index[u] for u in (*rope.ends, *(uid for uid, _ in rope.pulley_guides)) if u in index]
            links += [(carriers[0], c) for c in carriers[1:]]
        self.links = links
        # Bodies hinged to the world: their frame origin stays on a sphere about the hinge (radius: the arm now).
        self.is_hinged = np.zeros(len(dynamic), dtype=bool)
        self.hinge_lowest = np.full(len(dynamic), -np.inf)
        self.hinge_lower = np.full((len(dynamic), 3), -np.inf)
        self.hinge_upper = np.full((len(dynamic), 3), np.inf)
        for i, body in enumerate(dynamic):
            centre = world.hinged.get(body.label)
            if centre is None:
                continue
            arm = float(np.linalg.norm(body.initial.position - centre))
            self.is_hinged[i] = True
            self.hinge_lowest[i] = centre[2] - arm - SINK
            self.hinge_lower[i] = centre - arm - self.radius[i] - BOX_MARGIN
            self.hinge_upper[i] = centre + arm + self.radius[i] + BOX_MARGIN
        #: How low each body's frame origin can go: its hull depth above the floor, or its arm below its hinge.
        self.lowest = None if self.floor is None else np.maximum(self.floor + self.depth, self.hinge_lowest)
        self.linked = np.zeros((len(dynamic), len(dynamic)), dtype=bool)
        for a, b in links:
            self.linked[a, b] = self.linked[b, a] = True
        n_static = len(statics)
        self.static_uids = np.array([b.uid for b in statics], dtype=int)
        boxes = np.array([np.concatenate(self._aabb(int(uid))) for uid in self.static_uids], dtype=float)
        boxes = boxes.reshape(n_static, 6)
        self.static_lower = boxes[:, :3] - BOX_MARGIN
        self.static_upper = boxes[:, 3:] + BOX_MARGIN
        #: Row of each body (dynamic, then static) in the bounds' arrays.
        self.index = {int(uid): i for i, uid in enumerate(self.uids)}
        self.index.update({int(uid): len(dynamic) + k for k, uid in enumerate(self.static_uids)})
        self._previous: np.ndarray | None = None
        self._previous_slow: np.ndarray | None = None
        self._previous_time: float | None = None

    def bounds(self, t: float, horizon: float, since: float | None, give_up=None) -> Bounds | None:
        """Every body's box over the ``horizon`` seconds after ``t`` (None when no bound holds: no floor). A body
        is at rest when it was slow at the previous check too, ``since`` seconds before (None: no previous check;
        a check further apart, or a gap other than ``since``, does not count).

        ``give_up(bounds)``, when given, is asked at every round of the groups' growth and ends the work (None)
        when it says True: the boxes only grow from round to round, so an event that can still happen with the
        smaller boxes can with the final ones (most checks end there, after one round)."""
        n = len(self.dynamic)
        state = np.array([(*p, *v, *w) for p, v, w in self._states()], dtype=float).reshape(n, 9)
        position, velocity, angular = state[:, :3], state[:, 3:6], state[:, 6:]
        speed = np.linalg.norm(velocity, axis=1)
        spin = np.linalg.norm(angular, axis=1)
        slow = (speed < REST_SPEED) & (spin < REST_ANGULAR)
        if self._previous is None or since is None or abs(t - self._previous_time - since) > 1e-9:
            resting = np.zeros(n, dtype=bool)
        else:
            moved = np.linalg.norm(position - self._previous, axis=1)
            resting = slow & self._previous_slow & (moved < REST_MOVE)
        self._previous, self._previous_slow, self._previous_time = position, slow, t
        if self.floor is None:
            return None
        boxes = np.array([np.concatenate(self._aabb(int(uid))) for uid in self.uids], dtype=float).reshape(n, 6)
        rest_lower = boxes[:, :3] - BOX_MARGIN - REST_CREEP * horizon
        rest_upper = boxes[:, 3:] + BOX_MARGIN + REST_CREEP * horizon
        kinetic = 0.5 * self.mass * speed ** 2 + 0.5 * self.inertia_max * spin ** 2
        drop = position[:, 2] - self.lowest + SINK
        energy = kinetic + self.mass * self.g * np.maximum(drop, 0.0)
        # Which bodies share energy: the links, and every overlap of a moving group's box with another box.
        joined = self.linked.copy()
        ball = self.ball & ~resting
        if ball.any():
            ball_lower, ball_upper = self._ball_boxes(position, velocity, angular, horizon)
        while True:
            roots = _components(joined)
            moving_root = np.zeros(n, dtype=bool)
            moving_root[roots[~resting]] = True
            active = moving_root[roots]
            group_energy = np.bincount(roots, weights=energy, minlength=n)[roots] * ENERGY_MARGIN + ENERGY_FLOOR
            vmax = np.sqrt(2.0 * group_energy / self.mass)
            reach = self.radius + BOX_MARGIN + vmax * horizon
            lower = np.where(active[:, None], position - reach[:, None], rest_lower)
            upper = np.where(active[:, None], position + reach[:, None], rest_upper)
            lower[:, 2] = np.where(active, np.maximum(lower[:, 2], self.floor - BOX_MARGIN), lower[:, 2])
            # The frame origin rises at most by what the group's energy can lift the body.
            rise = position[:, 2] + group_energy / (self.mass * self.g) + self.radius + BOX_MARGIN
            upper[:, 2] = np.where(active, np.minimum(upper[:, 2], rise), upper[:, 2])
            # A hinged body stays within its arm (and its own radius) of the hinge.
            lower = np.where(self.is_hinged[:, None], np.maximum(lower, self.hinge_lower), lower)
            upper = np.where(self.is_hinged[:, None], np.minimum(upper, self.hinge_upper), upper)
            use_ball = ball & active & (np.bincount(roots, minlength=n)[roots] == 1)
            if use_ball.any():
                lower = np.where(use_ball[:, None], ball_lower, lower)
                upper = np.where(use_ball[:, None], ball_upper, upper)
            overlap = np.all((lower[:, None, :] <= upper[None, :, :]) & (lower[None, :, :] <= upper[:, None, :]),
                             axis=2)
            new = overlap & (active[:, None] | active[None, :]) & (roots[:, None] != roots[None, :])
            changed = bool(new.any())
            joined |= new
            # A ball's triangle holds only while nothing but a horizontal plane is in its way.
            if use_ball.any():
                blocked = use_ball & (self._hits_static(lower, upper) | self._hits_tilted_plane(lower, upper))
                if blocked.any():
                    ball &= ~blocked
                    changed = True
            bounds = self._bounds(horizon, lower, upper, active, group_energy, vmax)
            if not changed:
                return bounds
            if give_up is not None and give_up(bounds):
                return None

    def _bounds(self, horizon, lower, upper, active, group_energy, vmax) -> Bounds:
        angular_max = np.where(active, np.sqrt(2.0 * group_energy / np.maximum(self.inertia_min, 1e-12)),
                               REST_ANGULAR)
        speed_max = np.where(active, vmax, REST_SPEED)
        n_static = len(self.static_uids)
        return Bounds(
            horizon, self.index,
            np.concatenate([lower, self.static_lower]), np.concatenate([upper, self.static_upper]),
            np.concatenate([~active, np.ones(n_static, dtype=bool)]),
            np.concatenate([speed_max, np.zeros(n_static)]),
            np.concatenate([angular_max, np.zeros(n_static)]),
        )

    def alone(self, uid: int, horizon: float) -> Alone | None:
        """A cheap look at one moving body (two pybullet queries, plain floats): what its own energy alone lets it
        reach over ``horizon``. The full bounds give it at least that (a moving body stays moving in them, its
        group's energy is at least its own), so an event that can happen with this can happen with them: the check
        is not worth making. None for a body at rest now (the full bounds may hold it fixed) or not a moving one."""
        i = self.index.get(uid)
        if i is None or i >= len(self.dynamic) or self.floor is None:
            return None
        position, _ = self._pose(uid)
        velocity, angular = self._velocity(uid)
        v2 = velocity[0] ** 2 + velocity[1] ** 2 + velocity[2] ** 2
        w2 = angular[0] ** 2 + angular[1] ** 2 + angular[2] ** 2
        if v2 < REST_SPEED ** 2 and w2 < REST_ANGULAR ** 2:
            return None
        mass = float(self.mass[i])
        drop = max(position[2] - float(self.lowest[i]) + SINK, 0.0)
        kinetic = 0.5 * mass * v2 + 0.5 * float(self.inertia_max[i]) * w2
        energy = (kinetic + mass * self.g * drop) * ENERGY_MARGIN + ENERGY_FLOOR
        vmax = math.sqrt(2.0 * energy / mass)
        # The box its centre may reach with its own energy: inside the full bounds' box (which adds the body's
        # radius, and a group's energy at least its own).
        reach = vmax * horizon
        lower = [position[k] - reach for k in range(3)]
        upper = [position[k] + reach for k in range(3)]
        lower[2] = max(lower[2], self.floor)
        upper[2] = min(upper[2], position[2] + energy / (mass * self.g))
        if self.is_hinged[i]:
            lower = [max(a, float(b)) for a, b in zip(lower, self.hinge_lower[i])]
            upper = [min(a, float(b)) for a, b in zip(upper, self.hinge_upper[i])]
        if self.ball[i]:
            # The full bounds may hold a ball to its triangle instead: keep only what both allow.
            r = float(self.radius[i])
            roll_x = velocity[0] - 2.0 / 7.0 * (velocity[0] - r * angular[1])
            roll_y = velocity[1] - 2.0 / 7.0 * (velocity[1] + r * angular[0])
            lower[0] = max(lower[0], position[0] + horizon * min(0.0, velocity[0], roll_x))
            upper[0] = min(upper[0], position[0] + horizon * max(0.0, velocity[0], roll_x))
            lower[1] = max(lower[1], position[1] + horizon * min(0.0, velocity[1], roll_y))
            upper[1] = min(upper[1], position[1] + horizon * max(0.0, velocity[1], roll_y))
            upper[2] = min(upper[2], position[2] + velocity[2] ** 2 / (2.0 * self.g))
        omega = math.sqrt(2.0 * energy / max(float(self.inertia_min[i]), 1e-12))
        return Alone(lower, upper, vmax, omega)

    def core(self, uid: int) -> tuple[list, list] | None:
        """A box surely inside the body's box in any bounds: a static body's bounding box, a moving body's centre
        (when its hull holds it); None when there is none (a plane)."""
        i = self.index.get(uid)
        if i is None:
            return None
        if i >= len(self.dynamic):
            k = i - len(self.dynamic)
            return list(self.static_lower[k] + BOX_MARGIN), list(self.static_upper[k] - BOX_MARGIN)
        if self.depth[i] < 0.0:
            return None
        position, _ = self._pose(uid)
        return list(position), list(position)

    def _states(self):
        pose, velocity = self._pose, self._velocity
        for uid in self.uids:
            position, _ = pose(int(uid))
            linear, angular = velocity(int(uid))
            yield position, linear, angular

    def _ball_boxes(self, position, velocity, angular, horizon):
        """The box a lone ball on a horizontal plane stays in (see the module notes); for every body, used only for
        the balls."""
        r = self.radius
        v = velocity[:, :2]
        # The slip at the contact (v + w x (-r z)) and the velocity the ball rolls at once it has gone.
        slip = np.stack([v[:, 0] - r * angular[:, 1], v[:, 1] + r * angular[:, 0]], axis=1)
        roll = v - 2.0 / 7.0 * slip
        size = (r + BOX_MARGIN)[:, None]
        lower = np.empty_like(position)
        upper = np.empty_like(position)
        lower[:, :2] = position[:, :2] + horizon * np.minimum(np.minimum(v, roll), 0.0) - size
        upper[:, :2] = position[:, :2] + horizon * np.maximum(np.maximum(v, roll), 0.0) + size
        lower[:, 2] = self.floor - BOX_MARGIN
        upper[:, 2] = position[:, 2] + velocity[:, 2] ** 2 / (2.0 * self.g) + size[:, 0]
        return lower, upper

    def _hits_static(self, lower, upper) -> np.ndarray:
        if not len(self.static_uids):
            return np.zeros(len(lower), dtype=bool)
        return np.any(np.all((lower[:, None, :] <= self.static_upper[None, :, :])
                             & (self.static_lower[None, :, :] <= upper[:, None, :]), axis=2), axis=1)

    def _hits_tilted_plane(self, lower, upper) -> np.ndarray:
        hit = np.zeros(len(lower), dtype=bool)
        for normal, point in self.tilted:
            # The box corner deepest along -normal: the box reaches the plane when it is within the margin.
            corner = np.where(normal[None, :] >= 0.0, lower, upper)
            hit |= (corner - point[None, :]) @ normal <= BOX_MARGIN
        return hit
