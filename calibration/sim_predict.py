"""Physical success and expected attempts of a layout (thesis 5.2.3): simulation under the calibrated physics and the
measured placement error.

The probability that one physical attempt succeeds is estimated by ``n`` simulations of the layout (as designed, or
as built from a check) each with its own Gaussian placement error (the check's residual error, else 1 mm /
1 degree; the parameters the check did not measure at least 1 mm / 1 degree) and, when the physics comes with
intervals (a calibrated profile), its own material values drawn from them (normal, the 95 % interval as
±1.96 σ, kept in the scenario's range): the probability then carries the calibration's uncertainty as well as the
placement's. Its 95 % interval is Wilson's (the simulation count's uncertainty). Attempts until the first success
are geometric: expected ``1 / p``, with the interval ``[1 / p_high, 1 / p_low]`` (infinite when ``p_low`` is 0).

**A layout's record.** Attempts in one workshop share its physics, so a layout that worked (or failed) there says
where in the drawn ranges that physics lies; a Gaussian interval around a calibration's mode keeps the prior's width
along every direction the fit did not pin down, and a layout that works in only part of the ranges is predicted as if
the workshop could be anywhere in them. With ``record`` (its successes and attempts logged before) each material
draw is simulated ``per_physics`` times (independent placements) and the draws are weighted by the record's
likelihood under each (``p^k (1 - p)^(n - k)``, ``p`` a draw's smoothed success rate ``(s + 1/2) / (r + 1)``, as
the calibration smooths a few draws): :attr:`PhysicalPrediction.given_record` is the success that weighted
posterior expects, ``probability`` stays the plain mean of the simulations.
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
    #: per material draw, ``(successes, simulations)`` (one draw per simulation unless ``per_physics``; none without
    #: material draws)
    physics_runs: tuple[tuple[int, int], ...] = ()
    #: the layout's record it was conditioned on, ``(successes, attempts)``
    record: tuple[int, int] = (0, 0)

    @property
    def given_record(self) -> float:
        """The success expected given :attr:`record` (:func:`given_record`); ``probability`` without a record or
        material draws."""
        return given_record(self.probability, self.physics_runs, *self.record)

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


#: Simulations per material draw when a prediction is conditioned on a record (:func:`predict_success`): two
#: placements tell a draw where the layout works from one where it fails by luck, and leave half the simulations'
#: count as distinct draws of the physics.
PER_PHYSICS = 2


def given_record(probability: float, physics_runs, successes: int, attempts: int) -> float:
    """The success of the next attempt given a layout's record (``successes`` of ``attempts`` in the same
    workshop): the mean success of the material draws (``physics_runs``: ``(successes, simulations)`` per draw),
    each weighted by the record's likelihood under it, ``p^k (1 - p)^(n - k)`` with ``p = (s + 1/2) / (r + 1)`` (never
    0 or 1 from a few simulations). ``probability`` unchanged without a record or draws."""
    runs = np.asarray(physics_runs, dtype=float).reshape(-1, 2)
    if not attempts or not len(runs):
        return float(probability)
    s, r = runs[:, 0], runs[:, 1]
    p = (s + 0.5) / (r + 1.0)
    log_w = successes * np.log(p) + (attempts - successes) * np.log1p(-p)
    w = np.exp(log_w - log_w.max())
    return float(np.sum(w * s / r) / np.sum(w))


def predict_success(scenario: Scenario, layout: np.ndarray, *, values: Mapping[str, float] | None = None,
                    intervals: Mapping[str, tuple[float, float]] | None = None, position_sigma_m: float = 0.001,
                    angle_sigma_deg: float = 1.0, samples: int = 200, seed: int = 0,
                    run: Runner | None = None, unmeasured: Collection[str] = (),
                    set_sigma: Mapping[str, float] | None = None, record: tuple[int, int] = (0, 0),
                    per_physics: int = 1) -> PhysicalPrediction:
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
    record : (int, int), optional
        The layout's successes and attempts logged before in the same workshop: the result's ``given_record``.
    per_physics : int
        Simulations per material draw (each with its own placement); 1: every simulation its own draw.
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
    if int(per_physics) != per_physics or per_physics < 1:
        raise CalibrationError(f"predict: per_physics must be an integer >= 1, got {per_physics!r}")
    per_physics = int(per_physics)
    count = -(-samples // per_physics)  # material draws; the last may have fewer simulations
    thetas = np.empty((samples, len(names)))
    for j, name in enumerate(names):
        lo, hi = spread[name]
        draws = rng.normal(centres[name], (hi - lo) / (2 * 1.959964), count)
        thetas[:, j] = np.clip(np.repeat(draws, per_physics)[:samples], *ranges[name])
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
    runs: tuple[tuple[int, int], ...] = ()
    if names:
        draw = np.arange(samples) // per_physics
        runs = tuple((int(np.sum(success[draw == d] > 0.5)), int(np.sum(draw == d))) for d in range(count))
    return PhysicalPrediction(p, interval, attempts, attempts_interval, samples, k, events,
                              position_sigma_m * 1000.0, angle_sigma_deg,
                              {**scenario.physics_parameters(), **centres},
                              tuple(n for n in scenario.design_space.names if n in unmeasured), runs,
                              (int(record[0]), int(record[1])))
