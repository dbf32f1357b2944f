"""The contraption simulation core (:mod:`design.contraption`) as a :class:`~design.robust.problem.LayoutProblem`.

The problem holds the scenario file's path, not the loaded scenario nor a pybullet client, so it pickles to worker
processes and Dask workers; each worker loads the scenario once and keeps a simulator of it per thread
(:func:`thread_simulator`), so pybullet's client and the scenario's world are made once per worker.
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np

from design.contraption import (
    SUCCESS,
    Scenario,
    Simulator,
    check_validity,
    clearances,
    load_scenario,
    with_physics,
)
from design.contraption.simulation import SIMULATOR_CACHE_REVISION
from design.robust.problem import RobustError

#: Body pairs closer than this (m) enter the validity constraint; the constraint is capped there, so a pair coming
#: into range does not make it jump.
CLEARANCE_RADIUS = 0.005
#: Finite-difference step (normalized units) for the constraint's gradient: Bullet's closest-point distances are
#: accurate to about a micrometre, so SLSQP's default step (1.5e-8) would differentiate noise.
CLEARANCE_STEP = 1e-3

_clients = threading.local()


def _connect_with_fd1_silenced(client_class, pybullet):
    """Connect with file descriptor 1 on /dev/null (pybullet's C banner), whatever ``sys.stdout`` is."""
    import ctypes
    import os

    saved = os.dup(1)
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 1)
        return client_class(connection_mode=pybullet.DIRECT)
    finally:
        try:
            ctypes.CDLL(None).fflush(None)
        except (OSError, AttributeError):  # pragma: no cover
            pass
        os.dup2(saved, 1)
        os.close(saved)
        os.close(null)


def _new_client():
    """A new pybullet DIRECT client, its banner silenced whatever ``sys.stdout`` is.

    The core's :func:`~design.contraption.bullet.direct_client` silences pybullet's banner by duplicating the
    stdout/stderr file descriptors; under a Textual app (whose streams report unusable descriptors) that raises
    ``OSError``, so we then silence file descriptor 1 ourselves around the connection.
    """
    from design.contraption.bullet import BulletClient, direct_client, pybullet

    try:
        return direct_client()
    except OSError:
        return _connect_with_fd1_silenced(BulletClient, pybullet)


def thread_client():
    """This thread's pybullet DIRECT client, made once (validity checks, clearances, pictures)."""
    client = getattr(_clients, "client", None)
    if client is None:
        client = _clients.client = _new_client()
    return client


#: Simulators a thread keeps (one per scenario content; the oldest is closed beyond this).
KEPT_SIMULATORS = 4


def thread_simulator(scenario: Scenario) -> Simulator:
    """This thread's simulator of ``scenario``, made once and kept: a worker pays pybullet's client and the
    scenario's world once, not per simulation.

    Each kept simulator owns its client: the thread's shared client (:func:`thread_client`) is reset by every
    validity check, which would tear down a world the simulator keeps between runs.
    """
    kept = getattr(_clients, "simulators", None)
    if kept is None:
        kept = _clients.simulators = {}
    key = scenario.content_hash
    simulator = kept.pop(key, None)
    if simulator is None or simulator.client is None:
        simulator = Simulator(scenario, client=_new_client())
        while len(kept) >= KEPT_SIMULATORS:
            _close(kept.pop(next(iter(kept))))
    kept[key] = simulator  # most recently used last
    return simulator


def _close(simulator: Simulator) -> None:
    client = simulator.client
    simulator.close()  # a simulator given a client leaves it connected: the client is ours
    if client is not None:
        from design.contraption.bullet import pybullet

        try:
            client.disconnect()
        except pybullet.error:  # pragma: no cover - already gone
            pass


class ContraptionProblem:
    """A scenario file seen through the robust-layout protocol.

    Parameters
    ----------
    path : path
        A scenario file (``examples/scenarios/*.toml``).
    scenario : Scenario, optional
        The already loaded scenario (saves loading it twice in the main process). Its material values set by
        :func:`~design.contraption.validation.with_physics` (a physics profile) are kept: workers load the file
        again and apply them again, and the content hash (the cache key) is that of those values.
    """

    def __init__(self, path: str | Path, scenario: Scenario | None = None) -> None:
        self.path = str(path)
        self._scenario = scenario
        self.physics = dict(scenario.physics_overrides) if scenario is not None else {}
        space = self.scenario.design_space
        if space.dim == 0:
            raise RobustError(f"{self.path}: scenario {self.scenario.name!r} has no design space (no ranges)")
        self.name = self.scenario.name
        self.content_hash = self.scenario.content_hash
        self.cache_revision = SIMULATOR_CACHE_REVISION
        self.parameter_names = tuple(space.names)
        self.lower = np.array(space.lower, dtype=float)
        self.upper = np.array(space.upper, dtype=float)
        self.event_names = tuple(self.scenario.events)
        self.event_parents = {e.name: tuple(e.after) for e in self.scenario.event_specs}
        self.event_joins = {e.name: e.join for e in self.scenario.event_specs}
        self.event_labels = {e.name: e.label or e.name for e in self.scenario.event_specs}

    # -- pickling: workers reload the file ----------------------------------------------------------------------
    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_scenario"] = None
        return state

    @property
    def scenario(self) -> Scenario:
        if self._scenario is None:
            self._scenario = with_physics(load_scenario(self.path), self.physics)
        return self._scenario

    @property
    def dim(self) -> int:
        return len(self.parameter_names)

    def to_real(self, u: np.ndarray) -> np.ndarray:
        return self.lower + np.clip(np.asarray(u, dtype=float), 0.0, 1.0) * (self.upper - self.lower)

    def to_normalized(self, x: np.ndarray) -> np.ndarray:
        return (np.asarray(x, dtype=float) - self.lower) / (self.upper - self.lower)

    def initial_layout(self) -> np.ndarray:
        """The scenario file's own layout, normalized."""
        return np.clip(self.to_normalized(self.scenario.default_layout()), 0.0, 1.0)

    def is_valid(self, U: np.ndarray) -> np.ndarray:
        U = np.atleast_2d(np.asarray(U, dtype=float))
        inside = np.all((U >= 0) & (U <= 1), axis=1)
        client = thread_client()
        return np.array([bool(ok) and not check_validity(self.scenario, self.to_real(u), client=client)
                         for u, ok in zip(U, inside)])

    def validity_margins(self, u: np.ndarray) -> np.ndarray | None:
        """One constraint, ``>= 0`` exactly when the layout is physically valid: the smallest clearance (m).

        The clearance of a body pair is its signed distance plus its interpenetration tolerance; of a rope, its
        slack. Pairs farther apart than :data:`CLEARANCE_RADIUS` are not measured and the value is capped there, so
        the constraint is continuous and tells SLSQP how far the layout is from the wall on the valid side too.
        """
        u = np.clip(np.asarray(u, dtype=float).ravel(), 0.0, 1.0)
        found = clearances(self.scenario, self.to_real(u), radius=CLEARANCE_RADIUS, client=thread_client())
        return np.array([min([CLEARANCE_RADIUS, *(c.margin for c in found)])])

    def validity_jacobian(self, u: np.ndarray) -> np.ndarray:
        """Gradient of :meth:`validity_margins` by central differences of :data:`CLEARANCE_STEP` (one-sided at the
        box's faces), shape ``(1, dim)``."""
        u = np.clip(np.asarray(u, dtype=float).ravel(), 0.0, 1.0)
        gradient = np.zeros((1, self.dim))
        for i in range(self.dim):
            low, high = u.copy(), u.copy()
            low[i] = max(u[i] - CLEARANCE_STEP, 0.0)
            high[i] = min(u[i] + CLEARANCE_STEP, 1.0)
            gradient[0, i] = (self.validity_margins(high)[0] - self.validity_margins(low)[0]) / (high[i] - low[i])
        return gradient

    def prepare_worker(self) -> None:
        """Load the scenario and make this thread's simulator of it (pybullet's import and client, the world), so a
        worker pays its start-up before its first task rather than inside it."""
        thread_simulator(self.scenario).build(self.scenario.default_layout())

    def simulate(self, u: np.ndarray) -> np.ndarray:
        x = self.scenario.design_space.check_bounds(self.to_real(u))
        result = thread_simulator(self.scenario).run(x, early_stop=True)
        return np.array([result.events[name].state == SUCCESS for name in self.event_names], dtype=bool)


def render_layouts(problem: ContraptionProblem, layouts: list[tuple[str, np.ndarray]], path=None,
                   panel_size: tuple[int, int] = (560, 420)):
    """Side views (x-z) of normalized layouts placed side by side (e.g. initial | optimized), as a Pillow image.

    Each layout is drawn on its own (the core's renderer frames every row on the first snapshot's bounds, which
    would crop a layout that moved far), then the side-view panels are pasted next to each other.
    """
    from PIL import Image

    from design.contraption.render import render_views

    panels = []
    with Simulator(problem.scenario, client=thread_client()) as simulator:
        for caption, u in layouts:
            snapshot = simulator.build(problem.to_real(u)).snapshot()
            picture = render_views(problem.scenario, [(caption, snapshot)], panel_size=panel_size)
            # Top view left, side view right: keep the right half.
            panels.append(picture.crop((picture.width - panel_size[0], 0, picture.width, picture.height)))
    combined = Image.new("RGB", (sum(p.width for p in panels), max(p.height for p in panels)), "white")
    left = 0
    for panel in panels:
        combined.paste(panel, (left, 0))
        left += panel.width
    if path is not None:
        combined.save(path)
    return combined


def load_problem(path: str | Path, physics: dict[str, float] | None = None) -> ContraptionProblem:
    """A scenario file as a robust-layout problem (errors of the file are the core's, naming file and field), with
    the material values ``physics`` (``{"wood.friction": 0.42}``) instead of the file's when given."""
    return ContraptionProblem(path, with_physics(load_scenario(path), physics or {}))
