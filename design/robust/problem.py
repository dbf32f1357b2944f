"""What the robust-layout methods need from a scenario: a small simulator protocol, and synthetic scenarios.

Every method of :mod:`design.robust` works in the normalized design space ``[0, 1]^d`` (thesis 4.3) and talks to a
scenario through :class:`LayoutProblem`:

- ``parameter_names``, ``lower``, ``upper`` (real units), ``to_real`` / ``to_normalized``;
- ``event_names`` and ``event_parents`` (the causal graph, a DAG with one root);
- ``is_valid(U)``: physical validity of a batch of normalized layouts (cheap, no simulation: the impossible region
  D∅ is known a priori);
- ``validity_margins(u)``: a vector that is ``>= 0`` exactly when ``u`` is valid, used as SLSQP constraints, or
  ``None`` when the scenario can only say yes or no; optionally ``validity_jacobian(u)`` (shape ``(1, d)`` per
  margin row) when finite differences at SLSQP's tiny default step would be noise;
- ``simulate(u)``: simulate one valid layout and return one boolean per event (``True`` = the event's final state
  is success);
- ``content_hash``: identifies the scenario's content (cache key with the layout).

A problem must be picklable: worker processes and Dask workers receive it and call ``simulate``. Anything that
cannot be pickled (a pybullet client) is created lazily inside the worker (``prepare_worker``).

:class:`SyntheticProblem` is a scenario whose per-event success regions are analytic (ellipsoids in a few
parameters); tests use it to check the learning, optimization and robustness code against known answers.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from design.errors import DesignError


class RobustError(DesignError):
    """Bad input to a robust-layout method (a setting, a layout, a budget)."""


@runtime_checkable
class LayoutProblem(Protocol):
    """The simulator protocol of :mod:`design.robust` (see the module docstring)."""

    name: str
    content_hash: str
    parameter_names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    event_names: tuple[str, ...]
    event_parents: dict[str, tuple[str, ...]]

    @property
    def dim(self) -> int: ...

    def to_real(self, u: np.ndarray) -> np.ndarray: ...

    def to_normalized(self, x: np.ndarray) -> np.ndarray: ...

    def is_valid(self, U: np.ndarray) -> np.ndarray: ...

    def validity_margins(self, u: np.ndarray) -> np.ndarray | None: ...

    def prepare_worker(self) -> None: ...

    def simulate(self, u: np.ndarray) -> np.ndarray: ...


def topological_events(problem: LayoutProblem) -> list[str]:
    """The events in an order where every parent comes before its children."""
    order: list[str] = []
    remaining = list(problem.event_names)
    while remaining:
        progressed = False
        for name in list(remaining):
            if all(p in order for p in problem.event_parents.get(name, ())):
                order.append(name)
                remaining.remove(name)
                progressed = True
        if not progressed:
            raise RobustError(f"{problem.name}: the causal graph has a cycle among {remaining}")
    return order


def as_layout_batch(problem: LayoutProblem, U: np.ndarray, what: str = "layouts") -> np.ndarray:
    """Check and return ``U`` as a float ``(n, d)`` array of normalized layouts in ``[0, 1]``."""
    U = np.asarray(U, dtype=float)
    if U.ndim == 1:
        U = U[None, :]
    if U.ndim != 2 or U.shape[1] != problem.dim:
        raise RobustError(f"{problem.name}: {what} must have {problem.dim} columns, got shape {U.shape}")
    if not np.all(np.isfinite(U)):
        raise RobustError(f"{problem.name}: {what} must be finite numbers")
    if np.any(U < -1e-9) or np.any(U > 1 + 1e-9):
        raise RobustError(f"{problem.name}: normalized {what} must lie in [0, 1]")
    return np.clip(U, 0.0, 1.0)


@dataclass(frozen=True)
class EllipsoidEvent:
    """An event of a synthetic scenario: success when its parents succeeded and ``u`` is inside an ellipsoid.

    Parameters
    ----------
    name : str
        Event name.
    parents : tuple of str
        Parent events (all must succeed first).
    dims : tuple of int
        The parameters the event depends on (its true subspace).
    center, radii : tuple of float
        The ellipsoid, in normalized units, one value per entry of ``dims``. Empty ``dims`` means "always succeeds
        once its parents did" (a quasi-deterministic event).
    """

    name: str
    parents: tuple[str, ...] = ()
    dims: tuple[int, ...] = ()
    center: tuple[float, ...] = ()
    radii: tuple[float, ...] = ()

    def inside(self, U: np.ndarray) -> np.ndarray:
        if not self.dims:
            return np.ones(len(U), dtype=bool)
        offsets = (U[:, list(self.dims)] - np.asarray(self.center)) / np.asarray(self.radii)
        return np.sum(offsets**2, axis=1) <= 1.0


@dataclass(frozen=True)
class SyntheticProblem:
    """A synthetic scenario with analytic per-event success regions and a spherical impossible region.

    Parameters
    ----------
    name : str
        Scenario name.
    parameter_names : tuple of str
        One name per design parameter.
    lower, upper : tuple of float
        Real-unit bounds of each parameter.
    events : tuple of EllipsoidEvent
        The causal graph, parents first.
    forbidden_center, forbidden_radius :
        The impossible region D∅: layouts closer than ``forbidden_radius`` to ``forbidden_center`` (normalized).
    simulation_seconds : float
        A pause in each :meth:`simulate`, standing in for a physics simulation's cost (tests of stopping a run of
        worker processes need work still running and queued). Not part of the content hash: outcomes are the same.
    """

    name: str
    parameter_names: tuple[str, ...]
    lower_bounds: tuple[float, ...]
    upper_bounds: tuple[float, ...]
    events: tuple[EllipsoidEvent, ...]
    forbidden_center: tuple[float, ...] | None = None
    forbidden_radius: float = 0.0
    content_hash: str = field(default="", compare=False)
    simulation_seconds: float = field(default=0.0, compare=False)

    def __post_init__(self) -> None:
        spec = json.dumps(
            [self.name, self.parameter_names, self.lower_bounds, self.upper_bounds,
             [vars(e) for e in self.events], self.forbidden_center, self.forbidden_radius],
            sort_keys=True, default=list,
        )
        object.__setattr__(self, "content_hash", hashlib.sha256(spec.encode()).hexdigest())

    @property
    def lower(self) -> np.ndarray:
        return np.asarray(self.lower_bounds, dtype=float)

    @property
    def upper(self) -> np.ndarray:
        return np.asarray(self.upper_bounds, dtype=float)

    @property
    def dim(self) -> int:
        return len(self.parameter_names)

    @property
    def event_names(self) -> tuple[str, ...]:
        return tuple(e.name for e in self.events)

    @property
    def event_parents(self) -> dict[str, tuple[str, ...]]:
        return {e.name: e.parents for e in self.events}

    def to_real(self, u: np.ndarray) -> np.ndarray:
        return self.lower + np.asarray(u, dtype=float) * (self.upper - self.lower)

    def to_normalized(self, x: np.ndarray) -> np.ndarray:
        return (np.asarray(x, dtype=float) - self.lower) / (self.upper - self.lower)

    def _forbidden_distance(self, U: np.ndarray) -> np.ndarray:
        if self.forbidden_center is None:
            return np.full(len(U), np.inf)
        return np.linalg.norm(U - np.asarray(self.forbidden_center), axis=1) - self.forbidden_radius

    def is_valid(self, U: np.ndarray) -> np.ndarray:
        U = np.atleast_2d(np.asarray(U, dtype=float))
        inside_box = np.all((U >= 0) & (U <= 1), axis=1)
        return inside_box & (self._forbidden_distance(U) >= 0)

    def validity_margins(self, u: np.ndarray) -> np.ndarray | None:
        if self.forbidden_center is None:
            return None
        return self._forbidden_distance(np.atleast_2d(u))

    def prepare_worker(self) -> None:
        """Nothing to prepare: the synthetic simulator is pure numpy."""

    def simulate(self, u: np.ndarray) -> np.ndarray:
        if self.simulation_seconds > 0:
            time.sleep(self.simulation_seconds)
        return self.simulate_batch(np.atleast_2d(u))[0]

    def simulate_batch(self, U: np.ndarray) -> np.ndarray:
        """Per-event success of each layout: an event succeeds if its parents did and it is in its region."""
        U = np.atleast_2d(np.asarray(U, dtype=float))
        states: dict[str, np.ndarray] = {}
        for event in self.events:
            parents_ok = np.ones(len(U), dtype=bool)
            for parent in event.parents:
                parents_ok &= states[parent]
            states[event.name] = parents_ok & event.inside(U)
        return np.stack([states[e.name] for e in self.events], axis=1)


def synthetic_chain(name: str = "SYNTHETIC") -> SyntheticProblem:
    """A 3-parameter, 4-event synthetic chain with known success regions.

    ``start`` always succeeds (quasi-deterministic); ``first`` depends on parameters 0 and 1 (a disc centred at
    (0.35, 0.5)); ``second`` on parameter 2 only (an interval around 0.6); ``last`` always follows. The global success
    region is the product, and the most robust layout is (0.35, 0.5, 0.6). A ball around (0.8, 0.8, 0.2) is
    impossible.
    """
    return SyntheticProblem(
        name=name,
        parameter_names=("x", "z", "roll"),
        lower_bounds=(-0.15, 0.0, 15.0),
        upper_bounds=(0.0, 0.15, 75.0),
        events=(
            EllipsoidEvent("start"),
            EllipsoidEvent("first", ("start",), (0, 1), (0.35, 0.5), (0.25, 0.3)),
            EllipsoidEvent("second", ("first",), (2,), (0.6,), (0.25,)),
            EllipsoidEvent("last", ("second",)),
        ),
        forbidden_center=(0.8, 0.8, 0.2),
        forbidden_radius=0.2,
    )


def synthetic_branching(name: str = "SYNTHETIC-BRANCHING", dim: int = 6) -> SyntheticProblem:
    """A synthetic scenario with two branches joined by an AND (like BALLRUN), in ``dim`` >= 4 parameters.

    Branch A depends on parameters 0-1, branch B on parameters 2-3; the join needs both; the other parameters are
    irrelevant (the factorized PSP should ignore them).
    """
    if dim < 4:
        raise RobustError(f"synthetic_branching: dim must be an integer >= 4, got {dim!r}")
    names = tuple(f"p{i}" for i in range(dim))
    return SyntheticProblem(
        name=name,
        parameter_names=names,
        lower_bounds=(0.0,) * dim,
        upper_bounds=(1.0,) * dim,
        events=(
            EllipsoidEvent("root"),
            EllipsoidEvent("branch_a", ("root",), (0, 1), (0.3, 0.6), (0.28, 0.28)),
            EllipsoidEvent("branch_b", ("root",), (2, 3), (0.65, 0.4), (0.28, 0.3)),
            EllipsoidEvent("join", ("branch_a", "branch_b")),
        ),
        forbidden_center=(0.9,) * dim,
        forbidden_radius=0.3,
    )


def check_names(problem: LayoutProblem, names: Sequence[str]) -> None:
    """Raise if ``names`` are not the problem's parameter names, in order."""
    if tuple(names) != tuple(problem.parameter_names):
        raise RobustError(
            f"{problem.name}: layout parameters must be {list(problem.parameter_names)}, got {list(names)}"
        )


def check_seed(seed, what: str = "seed") -> int:
    """``seed`` as an int, or RobustError if it is not a non-negative integer.

    numpy's generators and scipy's Sobol engines refuse negative seeds with a bare ValueError deep inside a run;
    checking first gives one clear message before any simulation.
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise RobustError(f"{what} must be a non-negative integer, got {seed!r}")
    return int(seed)
