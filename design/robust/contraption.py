"""The contraption simulation core (:mod:`design.contraption`) as a :class:`~design.robust.problem.LayoutProblem`.

The problem holds the scenario file's path, not the loaded scenario nor a pybullet client, so it pickles to worker
processes and Dask workers; each worker loads the scenario once and simulates with its own per-thread pybullet
client (the core's :func:`~design.contraption.simulate` reuses one DIRECT client per thread).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from design.contraption import SUCCESS, Scenario, check_validity, load_scenario, simulate
from design.robust.problem import RobustError


class ContraptionProblem:
    """A scenario file seen through the robust-layout protocol.

    Parameters
    ----------
    path : path
        A scenario file (``examples/scenarios/*.toml``).
    scenario : Scenario, optional
        The already loaded scenario (saves loading it twice in the main process).
    """

    def __init__(self, path: str | Path, scenario: Scenario | None = None) -> None:
        self.path = str(path)
        self._scenario = scenario
        space = self.scenario.design_space
        if space.dim == 0:
            raise RobustError(f"{self.path}: scenario {self.scenario.name!r} has no design space (no ranges)")
        self.name = self.scenario.name
        self.content_hash = self.scenario.content_hash
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
            self._scenario = load_scenario(self.path)
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

    def _excess(self, u: np.ndarray) -> float:
        problems = check_validity(self.scenario, self.to_real(u))
        return float(sum(max(p.amount - p.tolerance, 0.0) for p in problems)) + (1e-6 if problems else 0.0)

    def is_valid(self, U: np.ndarray) -> np.ndarray:
        U = np.atleast_2d(np.asarray(U, dtype=float))
        inside = np.all((U >= 0) & (U <= 1), axis=1)
        return np.array([bool(ok) and not check_validity(self.scenario, self.to_real(u)) for u, ok in zip(U, inside)])

    def validity_margins(self, u: np.ndarray) -> np.ndarray | None:
        """One constraint: minus the total interpenetration / rope stretch beyond tolerance (metres), 0 if valid.

        The core reports only the problems of a layout, not distances between separate bodies, so the margin is
        flat (0) on the valid side; the optimizer's pull-back along the segment to its start does the rest.
        """
        return np.array([-self._excess(np.clip(np.asarray(u, dtype=float).ravel(), 0.0, 1.0))])

    def prepare_worker(self) -> None:
        """Load the scenario in this process (the core creates a pybullet client per thread on first use)."""
        _ = self.scenario

    def simulate(self, u: np.ndarray) -> np.ndarray:
        result = simulate(self.scenario, self.to_real(u), early_stop=True)
        return np.array([result.events[name].state == SUCCESS for name in self.event_names], dtype=bool)


def load_problem(path: str | Path) -> ContraptionProblem:
    """A scenario file as a robust-layout problem (errors of the file are the core's, naming file and field)."""
    return ContraptionProblem(path, load_scenario(path))
