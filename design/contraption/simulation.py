"""Simulating a scenario instance under the supervision of its causal graph (thesis 4.3), and physical validity.

Supervision, exactly as 4.3: the root event is awake at t = 0, every other event starts asleep. After each time
step, every event that was awake before the step evaluates its condition: success if it holds before its timeout
(``t_e <= t < t_e + timeout``), failure once the timeout has passed. An event wakes when its parents have
succeeded: all of them (``join = "all"``, the thesis's rule) or any one (``join = "any"``, future work 5.2).
A duration event (5.2) succeeds when its condition has held for ``duration`` seconds; it fails if no hold has
started by the timeout, or if a hold that outlives the timeout breaks.

Termination: global success when every leaf event (the end of each branch) has succeeded; global failure as soon as
one leaf can no longer succeed (it failed, or an AND-parent / every OR-parent of it is impossible). For graphs made
only of AND-joins this is 4.3's rule "one event timed out → failure". With ``early_stop=True`` (default) the
simulation stops at termination; with ``early_stop=False`` it runs to ``max_duration`` and the label is read at the
end (the same label, by construction: events only change state while awake and the run is deterministic).

The reach stop (with ``early_stop``, not when recording): a failure is known at an event's timeout, but often
long before it the world can no longer make any awake event happen (a ball rolling away from the domino it had to
hit). Every few checks the bodies' reach over the rest of the run is bounded (design/contraption/reach.py: energy,
rest, a lone ball's rolling) and every awake event asked whether its condition can still hold; when none can, the
physics stops and the supervisor goes on alone, each awake event failing at its timeout, to the verdict it would
have reached. The outcomes are those of the full run; ``steps`` counts the physics steps made, ``duration`` the time
the verdict was reached.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from design.contraption.bullet import direct_client, pybullet
from design.contraption.errors import SimulationError
from design.contraption.events import make_condition
from design.contraption.model import Scenario
from design.contraption.reach import Reach
from design.contraption.world import World, build_world

ASLEEP, AWAKE, SUCCESS, FAILURE = "asleep", "awake", "success", "failure"

#: What a simulation returns depends on this code as well as on the scenario's content and the layout. Caches keyed by
#: the content (the robust executor's simulations, the loop's optimized layouts) carry this number too: bump it with
#: any change that alters outcomes, so results the code no longer gives are not read back.
SIMULATOR_REVISION = 1
#: The revision as problems name it for the executor's cache (``cache_revision``).
SIMULATOR_CACHE_REVISION = f"simulator-{SIMULATOR_REVISION}"
#: How often (s of simulated time) the early stop asks whether an awake event can still happen: first this soon
#: after an event changed state, then REACH_BACKOFF times longer after each check that found one still possible, up
#: to REACH_LONGEST (a check costs a few hundred pybullet queries and a fixed point over the bodies).
REACH_INTERVAL = 0.08
REACH_BACKOFF = 2.0
REACH_LONGEST = 0.32
#: A check that finds no event possible is made again this much later before the run stops: a body counted at rest
#: must be slow then too (a rocking body is slow only at the ends of its swing).
REACH_CONFIRM = 0.02


@dataclass(frozen=True)
class EventOutcome:
    """State of one event at the end of a simulation; ``time`` of success or failure (None otherwise)."""

    state: str
    time: float | None = None
    woke: float | None = None


@dataclass
class SimulationResult:
    """Outcome of one simulation."""

    success: bool
    events: dict[str, EventOutcome]
    duration: float
    steps: int
    early_stopped: bool
    start: list | None = None
    end: list | None = None
    timeline: list[tuple[float, str, str]] = field(default_factory=list)
    ropes_start: list = field(default_factory=list)
    ropes_end: list = field(default_factory=list)

    @property
    def n_successful_events(self) -> int:
        return sum(outcome.state == SUCCESS for outcome in self.events.values())

    def states(self) -> dict[str, str]:
        return {name: outcome.state for name, outcome in self.events.items()}

    def to_dict(self) -> dict:
        return {
            "success": self.success,
            "n_successful_events": self.n_successful_events,
            "duration": self.duration,
            "steps": self.steps,
            "early_stopped": self.early_stopped,
            "events": {
                name: {"state": o.state, "time": o.time, "woke": o.woke} for name, o in self.events.items()
            },
        }


@dataclass(frozen=True)
class ValidityProblem:
    """Why a layout is physically impossible (D∅): two bodies interpenetrate, or a rope is too short.

    ``amount`` is in metres: the penetration depth beyond nothing, or the missing rope length.
    """

    kind: str
    objects: tuple[str, ...]
    amount: float
    tolerance: float
    message: str

    def __str__(self) -> str:
        return self.message


class Supervisor:
    """The causal graph's state machine (see the module notes)."""

    def __init__(self, scenario: Scenario, world: World) -> None:
        self.specs = scenario.event_specs
        self.conditions = {spec.name: make_condition(world, spec) for spec in self.specs}
        self.state = {spec.name: ASLEEP for spec in self.specs}
        self.time: dict[str, float | None] = {spec.name: None for spec in self.specs}
        self.woke: dict[str, float | None] = {spec.name: None for spec in self.specs}
        self.hold_start: dict[str, float | None] = {spec.name: None for spec in self.specs}
        self.spec_of = {spec.name: spec for spec in self.specs}
        self.children = {spec.name: [e for e in self.specs if spec.name in e.after] for spec in self.specs}
        self.leaves = [e.name for e in self.specs if not self.children[e.name]]
        self.timeline: list[tuple[float, str, str]] = []
        root = scenario.root
        self._set(root, AWAKE, 0.0)
        self.woke[root] = 0.0
        self._awake = [root]

    def _set(self, name: str, state: str, t: float) -> None:
        self.state[name] = state
        self.timeline.append((t, name, state))

    def update(self, t: float, idle: bool = False) -> bool:
        """Evaluate the awake events at time ``t``; return True when some state changed. ``idle``: every condition
        is known not to hold (not read from the world)."""
        changed = False
        woken: list[str] = []
        still_awake: list[str] = []
        for name in self._awake:
            spec = self.spec_of[name]
            deadline = self.woke[name] + spec.timeout
            holds = False if idle else self.conditions[name]()
            if spec.duration > 0.0:
                if holds:
                    if self.hold_start[name] is None:
                        self.hold_start[name] = t if t < deadline else None
                    if self.hold_start[name] is not None and t - self.hold_start[name] >= spec.duration - 1e-12:
                        outcome = SUCCESS
                    else:
                        outcome = FAILURE if self.hold_start[name] is None and t >= deadline else None
                else:
                    self.hold_start[name] = None
                    outcome = FAILURE if t >= deadline else None
            elif t >= deadline:
                outcome = FAILURE
            else:
                outcome = SUCCESS if holds else None
            if outcome is None:
                still_awake.append(name)
                continue
            changed = True
            self._set(name, outcome, t)
            self.time[name] = t
            if outcome == SUCCESS:
                for child in self.children[name]:
                    if self.state[child.name] != ASLEEP or child.name in woken:
                        continue
                    parents = [self.state[p] == SUCCESS for p in child.after]
                    if (all(parents) if child.join == "all" else any(parents)):
                        woken.append(child.name)
        for name in woken:
            self._set(name, AWAKE, t)
            self.woke[name] = t
        self._awake = still_awake + woken
        return changed

    def bounded(self) -> bool:
        """Every awake event can tell from reach bounds that its condition cannot hold."""
        return all(self.conditions[name].bounded for name in self._awake)

    def last_deadline(self) -> float:
        """The latest timeout among the awake events."""
        return max(self.woke[name] + self.spec_of[name].timeout for name in self._awake)

    def surely_may_change(self, reach, horizon: float) -> bool:
        """A cheap look: some awake event can happen with a moving body's own energy (no need for the bounds)."""
        return any(self.conditions[name].surely_may_hold(reach, horizon) for name in self._awake)

    def may_change(self, bounds) -> bool:
        """Whether some awake event can still succeed (or its hold go on) within ``bounds``' horizon."""
        for name in self._awake:
            if self.hold_start[name] is not None or self.conditions[name].may_hold(bounds):
                return True
        return False

    def next_deadline_step(self, step: int, dt: float) -> int | None:
        """The first step after ``step`` at which an awake event's timeout has passed (``step * dt``, as the run
        computes its times)."""
        best = None
        for name in self._awake:
            deadline = self.woke[name] + self.spec_of[name].timeout
            k = max(step + 1, math.floor(deadline / dt) - 1)
            while k * dt < deadline:
                k += 1
            best = k if best is None else min(best, k)
        return best

    def awake_events(self) -> list[str]:
        """The events still awake (waiting for their condition or their timeout)."""
        return list(self._awake)

    def _index(self, name: str) -> int:
        for i, spec in enumerate(self.specs):
            if spec.name == name:
                return i
        raise KeyError(name)  # pragma: no cover

    def impossible(self) -> set[str]:
        """Events that can no longer succeed."""
        result: set[str] = set()
        # specs may list a child before its parent: iterate to a fixed point (graphs are small).
        changed = True
        while changed:
            changed = False
            for spec in self.specs:
                if spec.name in result:
                    continue
                state = self.state[spec.name]
                if state == FAILURE:
                    bad = True
                elif state == ASLEEP and spec.after:
                    flags = [p in result for p in spec.after]
                    bad = any(flags) if spec.join == "all" else all(flags)
                else:
                    bad = False
                if bad:
                    result.add(spec.name)
                    changed = True
        return result

    def verdict(self) -> bool | None:
        """True (every leaf succeeded), False (a leaf can no longer succeed) or None (not decided yet)."""
        if all(self.state[leaf] == SUCCESS for leaf in self.leaves):
            return True
        impossible = self.impossible()
        if any(leaf in impossible for leaf in self.leaves):
            return False
        return None

    def outcomes(self) -> dict[str, EventOutcome]:
        return {
            spec.name: EventOutcome(self.state[spec.name], self.time[spec.name], self.woke[spec.name])
            for spec in self.specs
        }


class Simulator:
    """Runs many simulations of one scenario in one pybullet DIRECT client (reset between runs).

    Every run resets the client (``resetSimulation``) and rebuilds the scene, so each run is independent of the
    previous ones and deterministic. Rebuilding costs a few milliseconds (pybullet's new physics world and bodies):
    most of a small scenario's run, little of a large one's. A world moved back to a new layout instead (bodies reset
    or remade, their broadphase entries renewed) does not give the same runs: Bullet's broadphase keeps a history
    (its pair list's order, its stale pairs awaiting clean-up) that decides its simulation islands.
    One client per thread: pass ``client`` to share one you own, or let the simulator make its own.

    Parameters
    ----------
    scenario : Scenario
    client : BulletClient, optional
        An existing client (DIRECT). The simulator does not disconnect a client it did not create.
    """

    def __init__(self, scenario: Scenario, client=None) -> None:
        self.scenario = scenario
        self._own_client = client is None
        self.client = client if client is not None else direct_client()
        self.world: World | None = None

    def close(self) -> None:
        if self._own_client and self.client is not None:
            try:
                self.client.disconnect()
            except pybullet.error:  # pragma: no cover - already gone
                pass
        self.client = None

    def __enter__(self) -> Simulator:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def build(self, x=None) -> World:
        if self.client is None:
            raise SimulationError("this simulator is closed")
        try:
            self.world = build_world(self.client, self.scenario, x)
        except pybullet.error as error:
            raise SimulationError(f"{self.scenario.source}: pybullet could not build the scene: {error}") from None
        return self.world

    def check_validity(self, x=None) -> list[ValidityProblem]:
        return validity_problems(self.build(x))

    @staticmethod
    def _fast_forward(supervisor: Supervisor, step: int, n_steps: int, dt: float, settled: bool,
                      on_change) -> tuple[int, bool | None]:
        """Go on with the supervisor alone, every awake event's condition false, from ``step`` to the verdict (or
        to no awake event when ``settled``, or to the last step); return the step reached and the verdict."""
        verdict = None
        while True:
            following = supervisor.next_deadline_step(step, dt)
            if following is None or following > n_steps:
                return n_steps, verdict
            step = following
            t = step * dt
            if supervisor.update(t, idle=True):
                if on_change is not None:
                    on_change(t, dict(supervisor.state))
                verdict = supervisor.verdict()
                if settled:
                    if not supervisor.awake_events():
                        return step, verdict
                elif verdict is not None:
                    return step, verdict

    def run(
        self,
        x=None,
        *,
        early_stop: bool | str = True,
        record: bool = False,
        on_change: Callable[[float, dict[str, str]], None] | None = None,
        max_duration: float | None = None,
    ) -> SimulationResult:
        """Simulate the layout ``x`` (real units; the file's default layout if None).

        Parameters
        ----------
        early_stop : bool or "settled"
            Stop at termination (4.3). False runs to ``max_duration`` (for comparison). ``"settled"`` stops once no
            event is awake (none can change any more), so every event reached has its own outcome, as a maker sees
            them in a physical run (the termination rule stops at the first decided leaf). Both stop the physics
            sooner once no awake event can still happen (the reach stop, see the module notes).
        record : bool
            Keep start and end snapshots of the bodies (for rendering); the physics then runs to the verdict, so
            the end snapshot is the world at that time.
        on_change : callable, optional
            Called with ``(t, states)`` whenever an event changes state (e.g. a UI's progress).
        max_duration : float, optional
            Overrides the scenario's setting.
        """
        world = self.build(x)
        settings = self.scenario.settings
        dt = settings.time_step
        limit = settings.max_duration if max_duration is None else max_duration
        n_steps = int(round(limit / dt))
        start = world.snapshot() if record else None
        ropes_start = [np.array(world.rope_path(rope)[0]) for rope in world.ropes] if record else []
        supervisor = Supervisor(self.scenario, world)
        if on_change is not None:
            on_change(0.0, dict(supervisor.state))
        ropes = bool(world.ropes)
        settled = early_stop == "settled"
        verdict = None
        steps = reached = 0
        step_physics = world._bound("stepSimulation")
        # The reach stop: once no awake event can happen before its timeout, the rest of the run is known without
        # the physics (each awake event fails at its timeout). Not when recording: the end snapshot is the world at
        # the verdict.
        first_gap = max(1, int(round(REACH_INTERVAL / dt)))
        longest_gap = max(first_gap, int(round(REACH_LONGEST / dt)))
        reaching = bool(early_stop) and not record
        reach = None
        confirm_gap = max(1, int(round(REACH_CONFIRM / dt)))
        gap = first_gap
        next_check = first_gap
        last_check = None
        confirming = False
        for step in range(1, n_steps + 1):
            step_physics()
            if ropes:
                world.enforce_ropes(dt)
            steps = reached = step
            t = step * dt
            if supervisor.update(t):
                if on_change is not None:
                    on_change(t, dict(supervisor.state))
                verdict = supervisor.verdict()
                if settled:
                    if not supervisor.awake_events():
                        break
                elif verdict is not None and early_stop:
                    break
                gap = first_gap
                next_check = min(next_check, step + gap)
                confirming = False
            if reaching and step >= next_check:
                if supervisor.bounded():
                    if reach is None:
                        reach = Reach(world)
                    horizon = min(supervisor.last_deadline(), limit) - t
                    if supervisor.surely_may_change(reach, horizon):
                        gap = min(longest_gap, max(gap + 1, int(gap * REACH_BACKOFF)))
                        next_check = step + gap
                        confirming = False
                        continue
                    since = None if last_check is None else (step - last_check) * dt
                    bounds = reach.bounds(t, horizon, since, give_up=supervisor.may_change)
                    last_check = step
                    if bounds is not None and not supervisor.may_change(bounds):
                        if confirming:
                            reached, verdict = self._fast_forward(supervisor, step, n_steps, dt, settled,
                                                                  on_change)
                            break
                        confirming = True
                        next_check = step + confirm_gap
                        continue
                    gap = min(longest_gap, max(gap + 1, int(gap * REACH_BACKOFF)))
                next_check = step + gap
                confirming = False
        if verdict is None or not early_stop or settled:
            verdict = supervisor.verdict()
        end = world.snapshot() if record else None
        ropes_end = [np.array(world.rope_path(rope)[0]) for rope in world.ropes] if record else []
        return SimulationResult(
            success=bool(verdict),
            events=supervisor.outcomes(),
            duration=reached * dt,
            steps=steps,
            early_stopped=steps < n_steps,
            start=start,
            end=end,
            timeline=list(supervisor.timeline),
            ropes_start=ropes_start,
            ropes_end=ropes_end,
        )


@dataclass(frozen=True)
class Clearance:
    """How far a pair of bodies (or a rope) is from making a layout invalid.

    ``distance`` is the signed distance between the two bodies (negative: interpenetration depth) or, for a rope,
    its length minus the path the layout asks of it. ``margin = distance + tolerance`` is >= 0 exactly when this
    pair is acceptable: a smooth-ish constraint for layout optimization (thesis 4.7).
    """

    kind: str
    objects: tuple[str, ...]
    distance: float
    tolerance: float

    @property
    def margin(self) -> float:
        return self.distance + self.tolerance


def world_clearances(world: World, radius: float = 0.0) -> list[Clearance]:
    """Clearances of the body pairs closer than ``radius`` (m) and of every rope, in a freshly built world."""
    client = world.client
    settings = world.scenario.settings
    ignored = {frozenset(pair) for pair in settings.ignore_overlap}
    client.performCollisionDetection()
    result: list[Clearance] = []
    bodies = list(world.bodies.values())
    sizes = {b.label: b.spec.smallest_dimension() for b in bodies}
    # Broad phase: only pairs whose (grown) bounding boxes overlap can be that close (a big saving with dominoes).
    boxes = np.array([np.concatenate(client.getAABB(b.uid)) for b in bodies]).reshape(len(bodies), 6)
    lower, upper = boxes[:, :3] - radius / 2, boxes[:, 3:] + radius / 2
    overlapping = np.all(
        (lower[:, None, :] <= upper[None, :, :] + 1e-9) & (lower[None, :, :] <= upper[:, None, :] + 1e-9), axis=2
    )
    for i, a in enumerate(bodies):
        for j in np.flatnonzero(overlapping[i, i + 1:]) + i + 1:
            b = bodies[j]
            if frozenset((a.label, b.label)) in world.joined_pairs:
                continue
            if frozenset((a.object_name, b.object_name)) in ignored:
                continue
            points = client.getClosestPoints(a.uid, b.uid, radius)
            if not points:
                continue
            tolerance = settings.overlap_tolerance * min(sizes[a.label], sizes[b.label])
            result.append(Clearance("overlap", (a.label, b.label), min(p[8] for p in points), tolerance))
    for rope in world.ropes:
        _, length = world.rope_path(rope)
        result.append(Clearance("rope", (rope.name,), rope.length - length, 1e-3 * rope.length))
    return result


def validity_problems(world: World) -> list[ValidityProblem]:
    """Interpenetrations beyond tolerance and over-stretched ropes of a freshly built world (see check_validity)."""
    problems: list[ValidityProblem] = []
    for c in world_clearances(world, 0.0):
        if c.margin >= 0.0:
            continue
        amount = -c.distance
        if c.kind == "overlap":
            a, b = c.objects
            message = (
                f"{a} and {b} interpenetrate by {amount * 1000:.2f} mm (tolerance {c.tolerance * 1000:.2f} mm)"
            )
        else:
            rope = next(r for r in world.ropes if r.name == c.objects[0])
            message = (
                f"rope {rope.name} would have to stretch from {rope.length:.4f} m to {rope.length + amount:.4f} m "
                f"(too short by {amount * 1000:.1f} mm)"
            )
        problems.append(ValidityProblem(c.kind, c.objects, amount, c.tolerance, message))
    return problems


def clearances(scenario: Scenario, x_real=None, *, radius: float = 0.005, client=None) -> list[Clearance]:
    """Signed clearances of the body pairs closer than ``radius`` and of the ropes, for layout ``x_real``.

    Every ``margin`` is >= 0 exactly when :func:`check_validity` finds no problem (pairs farther apart than
    ``radius`` are left out: their margin is larger than ``radius``).
    """
    if x_real is not None:
        x_real = scenario.design_space.check_bounds(np.asarray(x_real, dtype=float))
    sim = Simulator(scenario, client=client) if client is not None else _thread_simulator(scenario)
    return world_clearances(sim.build(x_real), radius)


_local = threading.local()


def _thread_simulator(scenario: Scenario) -> Simulator:
    """A per-thread simulator whose client is reused across calls of :func:`simulate` without ``client``."""
    sim = getattr(_local, "simulator", None)
    if sim is None or sim.client is None:
        sim = Simulator(scenario)
        _local.simulator = sim
    sim.scenario = scenario
    return sim


def simulate(scenario: Scenario, x_real=None, *, early_stop: bool | str = True, client=None,
             **kwargs) -> SimulationResult:
    """Simulate one layout of ``scenario`` (real units; the file's layout if None) under its causal graph.

    With ``client=None`` a per-thread DIRECT client is reused across calls (reset between runs), so calling this in
    a loop is cheap. Keyword arguments go to :meth:`Simulator.run` (``record``, ``on_change``, ``max_duration``).
    """
    if x_real is not None:
        x_real = scenario.design_space.check_bounds(np.asarray(x_real, dtype=float))
    if client is not None:
        return Simulator(scenario, client=client).run(x_real, early_stop=early_stop, **kwargs)
    return _thread_simulator(scenario).run(x_real, early_stop=early_stop, **kwargs)


def check_validity(scenario: Scenario, x_real=None, *, client=None) -> list[ValidityProblem]:
    """Physical validity of a layout before simulating it (thesis D∅): an empty list means valid.

    Two distinct bodies (not joined by a Pivot or Fastener, not listed in ``settings.ignore_overlap``) may not
    interpenetrate deeper than ``settings.overlap_tolerance`` times the smaller body's smallest dimension; a rope may
    not be shorter than the path the layout asks of it.
    """
    if x_real is not None:
        x_real = scenario.design_space.check_bounds(np.asarray(x_real, dtype=float))
    if client is not None:
        return Simulator(scenario, client=client).check_validity(x_real)
    return _thread_simulator(scenario).check_validity(x_real)
