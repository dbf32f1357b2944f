"""Physical success and expected attempts of a layout (thesis 5.2.3): simulation under the calibrated physics and the
measured placement error.

The probability that one physical attempt succeeds is estimated by ``n`` simulations of the layout (as designed, or
as built from a check) each with its own Gaussian placement error (the check's residual error, else 1 mm /
1 degree; the parameters the check did not measure at least 1 mm / 1 degree) and, when the physics comes with
intervals (a calibrated profile), its own material values drawn from them (normal, the 95 % interval as
±1.96 σ, kept in the scenario's range): the probability then carries the calibration's uncertainty as well as the
placement's. Its 95 % interval is Wilson's (the simulation count's uncertainty). Attempts until the first success
are geometric: expected ``1 / p``, with the interval ``[1 / p_high, 1 / p_low]`` (infinite when ``p_low`` is 0).
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from calibration.errors import CalibrationError
from calibration.sim_fit import Runner
from calibration.sim_runs import YES, OutcomeProblem, noisy_layouts, wilson_interval
from design.contraption.model import Scenario
from design.contraption.validation import with_physics


@dataclass(frozen=True)
class PhysicalPrediction:
    """The success probability of one physical attempt, and the attempts to expect."""

    probability: float
    interval: tuple[float, float]
    attempts: float
    attempts_interval: tuple[float, float]
    samples: int
    successes: int
    events: Mapping[str, float]  #: probability that each event happens
    position_sigma_mm: float
    angle_sigma_deg: float
    physics: Mapping[str, float]  #: the material values (centres) simulated
    #: the design parameters no check measured (placed with at least the unchecked error)
    unmeasured: tuple[str, ...] = ()

    def to_json(self) -> dict[str, Any]:
        finite = lambda v: None if math.isinf(v) else v  # noqa: E731 - JSON has no infinity
        return {"probability": self.probability, "interval": list(self.interval),
                "expected_attempts": finite(self.attempts),
                "attempts_interval": [finite(v) for v in self.attempts_interval],
                "samples": self.samples, "successes": self.successes, "events": dict(self.events),
                "placement_error": {"position_mm": self.position_sigma_mm, "heading_deg": self.angle_sigma_deg,
                                    "unmeasured": list(self.unmeasured)},
                "physics": dict(self.physics)}


def attempts_of(probability: float, interval: tuple[float, float]) -> tuple[float, tuple[float, float]]:
    """Expected attempts ``1/p`` and its interval ``[1/p_high, 1/p_low]`` (infinite where a probability is 0)."""
    inverse = lambda p: math.inf if p <= 0 else 1.0 / p  # noqa: E731
    return inverse(probability), (inverse(interval[1]), inverse(interval[0]))


def predict_success(scenario: Scenario, layout: np.ndarray, *, values: Mapping[str, float] | None = None,
                    intervals: Mapping[str, tuple[float, float]] | None = None, position_sigma_m: float = 0.001,
                    angle_sigma_deg: float = 1.0, samples: int = 200, seed: int = 0,
                    run: Runner | None = None, unmeasured: Collection[str] = (),
                    set_sigma: Mapping[str, float] | None = None) -> PhysicalPrediction:
    """Estimate the physical success probability of ``layout`` (real units) by simulation.

    Parameters
    ----------
    scenario : Scenario
        The scenario (with its own material values; ``values`` replace them).
    layout : array
        As designed or as built (may leave the design ranges a little).
    values, intervals : mapping, optional
        Material values to simulate (a physics profile's) and their 95 % intervals (drawn from when given).
    position_sigma_m, angle_sigma_deg : float
        The placement error (one standard deviation).
    unmeasured : collection of str, optional
        Design parameters no check measured: their error is how they were set (``set_sigma``), else at least the
        unchecked one (1 mm, 1 degree).
    set_sigma : mapping, optional
        ``{parameter: standard deviation}`` (real units) of the error of how the guide told the maker to set each
        (:func:`calibration.sim_runs.placement_sigma`).
    samples, seed : int
        Simulations, and the seed of their placement errors and material draws.
    run : Runner, optional
        Where the simulations run (default inline).
    """
    if int(samples) != samples or samples < 1:
        raise CalibrationError(f"predict: samples must be an integer >= 1, got {samples!r}")
    known = scenario.physics_parameters()
    uncertain = scenario.uncertain_parameters()
    centres = {k: float(v) for k, v in (values or {}).items() if k in known}
    spread = {k: v for k, v in (intervals or {}).items() if k in centres and v[1] > v[0]}
    names = list(spread)
    ranges = {k: uncertain[k][1] if k in uncertain else (0.0, max(2.0 * centres[k], 1.0)) for k in names}
    base = with_physics(scenario, {k: v for k, v in centres.items() if k not in spread})
    rng = np.random.default_rng(seed)
    layouts = noisy_layouts(scenario, np.asarray(layout, dtype=float), samples, position_sigma_m, angle_sigma_deg, rng,
                           unmeasured, set_sigma)
    thetas = np.empty((samples, len(names)))
    for j, name in enumerate(names):
        lo, hi = spread[name]
        draws = rng.normal(centres[name], (hi - lo) / (2 * 1.959964), samples)
        thetas[:, j] = np.clip(draws, *ranges[name])
    if not names:
        thetas = np.empty((samples, 0))
    problem = OutcomeProblem(base, names, ranges)
    own_run = run is None
    run = run or Runner()
    try:
        run.expect(samples)
        out = run(problem, problem.rows(thetas, layouts))
    finally:
        if own_run:
            run.close()
    success, codes, _ = problem.split(out)
    k = int(np.sum(success > 0.5))
    p = k / samples
    interval = wilson_interval(k, samples)
    attempts, attempts_interval = attempts_of(p, interval)
    events = {name: float(np.mean(codes[:, i] == YES)) for i, name in enumerate(problem.event_names)}
    return PhysicalPrediction(p, interval, attempts, attempts_interval, samples, k, events,
                              position_sigma_m * 1000.0, angle_sigma_deg,
                              {**scenario.physics_parameters(), **centres},
                              tuple(n for n in scenario.design_space.names if n in unmeasured))
