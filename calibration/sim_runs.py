"""Simulations for simulator calibration and physical prediction: one scenario, material values and layout per run.

:class:`OutcomeProblem` is a scenario seen through the executor's protocol (:mod:`design.robust.executor`), so
these runs go through the same local processes or Dask cluster as the optimizer's and are cached the same way. Its
normalized vector is the material values (over their ranges) followed by the layout (over the design ranges widened
by :data:`WIDEN` on each side: an as-built layout, or a placement error, may leave the designed ranges). Each run
returns numbers (``outcome_dtype = float``): the global success (1 or 0), one outcome code per event
(:data:`YES`, :data:`NO`, :data:`NOT_REACHED`) and one time per event (NaN when it did not happen).

A run simulates until no event is awake (``early_stop="settled"``): a maker ticks every event reached in a
physical run, while the optimizer's rule stops at the first decided leaf and leaves the other branches undecided.

Placement errors (:func:`noisy_layouts`) are Gaussian with one standard deviation for positions (m) and one for
angles (degrees), on the design parameters (the parts the maker places; fixed parts are taken as placed exactly).
A check measures some parameters (its residual error is then theirs) and not others (a part without a tag, a height
or a tilt no camera sees): those are as uncertain as a layout placed with no check, at least
:data:`DEFAULT_POSITION_SIGMA_M` and :data:`DEFAULT_ANGLE_SIGMA_DEG`.
"""

from __future__ import annotations

import hashlib
from collections.abc import Collection, Mapping, Sequence

import numpy as np

from design.contraption.model import Scenario
from design.contraption.schema import ANGLE_KEYS
from design.contraption.simulation import SIMULATOR_CACHE_REVISION
from design.contraption.validation import scenario_from_data, with_physics

YES, NO, NOT_REACHED = 1.0, 0.0, -1.0
#: The export format's words for the codes.
OUTCOME_WORDS = {"yes": YES, "no": NO, "not-reached": NOT_REACHED}
#: How far (in range widths, each side) a layout may leave the design ranges in these runs.
WIDEN = 1.0
#: Placement error assumed where no check measured one: 1 mm and 1 degree (one standard deviation).
DEFAULT_POSITION_SIGMA_M = 0.001
DEFAULT_ANGLE_SIGMA_DEG = 1.0


def widened(scenario: Scenario, factor: float = WIDEN) -> Scenario:
    """``scenario`` with every design range widened by ``factor`` range widths on each side (same names, same
    order, same physics), so layouts a little outside the designed ranges can be simulated."""
    if scenario.data is None:  # pragma: no cover - scenarios are loaded from data
        raise ValueError(f"{scenario.source}: the scenario was built without its content")
    data = dict(scenario.data)
    objects = []
    for obj in data.get("objects", []):
        if "ranges" in obj:
            obj = dict(obj)
            obj["ranges"] = {k: [lo - factor * (hi - lo), hi + factor * (hi - lo)] for k, (lo, hi) in
                             obj["ranges"].items()}
        objects.append(obj)
    data["objects"] = objects
    result = scenario_from_data(data, file=scenario.source)
    object.__setattr__(result, "physics_overrides", dict(scenario.physics_overrides))
    return result


class OutcomeProblem:
    """A scenario's runs under chosen material values, for :class:`~design.robust.executor.SimulationExecutor`.

    Parameters
    ----------
    scenario : Scenario
        The scenario as logged (its content is what is pickled to workers).
    physics : sequence of str
        The material values that vary, ``"wood.friction"``; each must be a material value of the scenario.
    ranges : mapping
        ``name -> (low, high)`` of each of ``physics``: the normalized coordinates span them.
    """

    outcome_dtype = float

    def __init__(self, scenario: Scenario, physics: Sequence[str], ranges: Mapping[str, tuple[float, float]]):
        self._data = scenario.data
        self._file = scenario.source
        self._base_overrides = dict(scenario.physics_overrides)
        self.physics = tuple(physics)
        self.name = scenario.name
        self.event_names = tuple(scenario.events)
        self.event_parents = {e.name: tuple(e.after) for e in scenario.event_specs}
        self.layout_names = tuple(scenario.design_space.names)
        space = scenario.design_space
        width = np.asarray(space.upper, dtype=float) - np.asarray(space.lower, dtype=float)
        lower = [ranges[p][0] for p in self.physics] + list(np.asarray(space.lower) - WIDEN * width)
        upper = [ranges[p][1] for p in self.physics] + list(np.asarray(space.upper) + WIDEN * width)
        self.lower = np.array(lower, dtype=float)
        self.upper = np.array(upper, dtype=float)
        self.parameter_names = self.physics + self.layout_names
        self.n_outputs = 1 + 2 * len(self.event_names)
        key = f"{scenario.content_hash}|outcomes v1|settled|{self.physics}|{self.lower.tolist()}|{self.upper.tolist()}"
        self.content_hash = hashlib.sha256(key.encode()).hexdigest()
        self.cache_revision = SIMULATOR_CACHE_REVISION
        self._scenario: Scenario | None = None
        self._by_values: dict[tuple, Scenario] = {}

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_scenario"] = None
        state["_by_values"] = {}
        return state

    @property
    def dim(self) -> int:
        return len(self.parameter_names)

    @property
    def n_physics(self) -> int:
        return len(self.physics)

    def to_real(self, u: np.ndarray) -> np.ndarray:
        return self.lower + np.clip(np.asarray(u, dtype=float), 0.0, 1.0) * (self.upper - self.lower)

    def to_normalized(self, x: np.ndarray) -> np.ndarray:
        return np.clip((np.asarray(x, dtype=float) - self.lower) / (self.upper - self.lower), 0.0, 1.0)

    def rows(self, values: np.ndarray, layouts: np.ndarray) -> np.ndarray:
        """Normalized rows for material values ``(n, n_physics)`` (or one row for all) and layouts ``(n, d)``."""
        layouts = np.atleast_2d(np.asarray(layouts, dtype=float))
        values = np.broadcast_to(np.atleast_2d(np.asarray(values, dtype=float)), (len(layouts), self.n_physics))
        return self.to_normalized(np.hstack([values, layouts]))

    def is_valid(self, U: np.ndarray) -> np.ndarray:
        return np.ones(len(np.atleast_2d(U)), dtype=bool)

    def validity_margins(self, u: np.ndarray) -> None:
        return None

    def prepare_worker(self) -> None:
        self._base()

    def _base(self) -> Scenario:
        if self._scenario is None:
            scenario = with_physics(scenario_from_data(self._data, file=self._file), self._base_overrides)
            self._scenario = widened(scenario)
        return self._scenario

    def scenario_for(self, values: np.ndarray) -> Scenario:
        """The (widened) scenario with these material values; the last few are kept (runs come in batches of one
        set of values and many layouts)."""
        key = tuple(round(float(v), 12) for v in values)
        scenario = self._by_values.get(key)
        if scenario is None:
            if len(self._by_values) > 32:
                self._by_values.clear()
            scenario = with_physics(self._base(), dict(zip(self.physics, key)))
            self._by_values[key] = scenario
        return scenario

    def simulate(self, u: np.ndarray) -> np.ndarray:
        from design.contraption.simulation import ASLEEP, SUCCESS, Simulator
        from design.robust.contraption import thread_client

        x = self.to_real(u)
        scenario = self.scenario_for(x[: self.n_physics])
        with Simulator(scenario, client=thread_client()) as simulator:
            result = simulator.run(x[self.n_physics:], early_stop="settled")
        codes, times = [], []
        for name in self.event_names:
            outcome = result.events[name]
            if outcome.state == SUCCESS:
                codes.append(YES)
                times.append(outcome.time)
            else:
                codes.append(NOT_REACHED if outcome.state == ASLEEP else NO)
                times.append(np.nan)
        return np.array([1.0 if result.success else 0.0, *codes, *times], dtype=float)

    def split(self, out: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Runs' numbers ``(n, n_outputs)`` as (success ``(n,)``, codes ``(n, E)``, times ``(n, E)``)."""
        n_events = len(self.event_names)
        return out[:, 0], out[:, 1 : 1 + n_events], out[:, 1 + n_events :]


def residual_sigma(check: Mapping | None) -> tuple[float, float]:
    """The placement error (m, degrees) a CHECK.json's ``residual_error`` gives the parameters it measured; the
    unchecked defaults where it gives none (no check, a missing or non-positive value)."""
    residual = check.get("residual_error") if isinstance(check, Mapping) else None
    residual = residual if isinstance(residual, Mapping) else {}
    position, angle = residual.get("position_mm"), residual.get("heading_deg")
    number = lambda v: isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0  # noqa: E731
    return (float(position) / 1000.0 if number(position) else DEFAULT_POSITION_SIGMA_M,
            float(angle) if number(angle) else DEFAULT_ANGLE_SIGMA_DEG)


def placement_sigma(scenario: Scenario, position_sigma_m: float, angle_sigma_deg: float,
                    unmeasured: Collection[str] = (), set_sigma: Mapping[str, float] | None = None) -> np.ndarray:
    """One standard deviation per design parameter (real units, design order): ``position_sigma_m`` on x, y, z and
    ``angle_sigma_deg`` on heading, pitch and roll, and on the ``unmeasured`` ones (a check's residual error says
    nothing of a parameter it did not measure) the error of how each was set, ``set_sigma[name]`` (real units: how
    the guide told the maker to set it), else at least the unchecked defaults."""
    names = scenario.design_space.names
    angle = np.array([name.rsplit(".", 1)[1] in ANGLE_KEYS for name in names])
    unseen = np.array([name in unmeasured for name in names], dtype=bool)
    measured = np.where(angle, angle_sigma_deg, position_sigma_m)
    unchecked = np.where(angle, max(angle_sigma_deg, DEFAULT_ANGLE_SIGMA_DEG),
                         max(position_sigma_m, DEFAULT_POSITION_SIGMA_M))
    if set_sigma:
        unchecked = np.array([float(set_sigma.get(name, default)) for name, default in zip(names, unchecked)])
    return np.where(unseen, unchecked, measured).astype(float)


def noisy_layouts(scenario: Scenario, layout: np.ndarray, n: int, position_sigma_m: float, angle_sigma_deg: float,
                  rng: np.random.Generator, unmeasured: Collection[str] = (),
                  set_sigma: Mapping[str, float] | None = None) -> np.ndarray:
    """``n`` placements of ``layout`` (real units) with Gaussian errors (:func:`placement_sigma`). Shape
    ``(n, d)``."""
    sigma = placement_sigma(scenario, position_sigma_m, angle_sigma_deg, unmeasured, set_sigma)
    return np.asarray(layout, dtype=float)[None, :] + rng.standard_normal((n, len(sigma))) * sigma[None, :]


def wilson_interval(successes: float, n: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson's score interval of a binomial proportion (95 % by default); ``(0, 1)`` when ``n`` is 0."""
    if n <= 0:
        return 0.0, 1.0
    p = successes / n
    denominator = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denominator
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denominator
    # rounding puts the bound a hair inside p when every (or no) trial succeeded: the interval must hold p
    return float(max(0.0, min(p, centre - half))), float(min(1.0, max(p, centre + half)))
