"""Physical success and expected attempts of a layout, as a service (``station predict``; after a check or a trial).

The layout is the designed one, or the one a check measured (CHECK.json's ``as_built``, with its ``residual_error``
as the placement error); the physics is the scenario's own or a physics profile's (whose intervals are drawn from,
so the calibration's uncertainty is in the probability). See :mod:`calibration.sim_predict`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from calibration.check import not_measured_names
from calibration.sim_predict import PhysicalPrediction, predict_success
from calibration.sim_runs import DEFAULT_ANGLE_SIGMA_DEG, DEFAULT_POSITION_SIGMA_M, residual_sigma
from common.datafiles import load_json
from common.progress import Reporter
from design.contraption.layout_io import LoadedLayout
from design.contraption.physics_profile import PhysicsProfile, apply_profile, profile_from_text
from design.contraption.scenario import Scenario
from design.robust.contraption import ContraptionProblem
from station.errors import ServiceError, station_errors
from station.services.contraption import choose_layout, open_scenario
from station.services.outlook import success_headline
from station.services.physics import read_profile
from station.services.robust import check_count, check_seed
from station.services.sim_calibration import station_runner
from station.services.trials import layout_values, read_check


@station_errors
@dataclass
class Prediction:
    """A prediction with what it was made of."""

    scenario: Scenario
    layout: LoadedLayout
    x: np.ndarray
    as_built: bool
    profile: str | None
    result: PhysicalPrediction

    def to_json(self) -> dict[str, Any]:
        return {"scenario": self.scenario.name, "layout": self.scenario.design_space.as_dict(self.x),
                "as_built": self.as_built, "physics_profile": self.profile, **self.result.to_json()}


@station_errors
def as_built_from_check(check: Any, scenario: Scenario, designed: np.ndarray, file: str
                        ) -> tuple[np.ndarray, float, float, tuple[str, ...]]:
    """The as-built layout, the placement error (m, degrees) of a CHECK.json's content, and the design parameters it
    did not measure (its ``not_measured``: placed with at least the unchecked error), as the trial log reads the same
    file (:func:`station.services.trials.read_check`).

    Raises
    ------
    ServiceError
        Not a check, a check of another scenario or layout, or a field that is not what a check writes
        (``field="as_built"``, the message naming the field).
    """
    def fail(message: str) -> ServiceError:
        return ServiceError(f"as_built {file}: {message}", field="as_built", value=file)

    built = read_check(check, scenario, layout_values(scenario, designed), fail)
    x = np.array([built.values[name] for name in scenario.design_space.names], dtype=float)
    return x, built.position_sigma_m, built.angle_sigma_deg, built.not_measured


@station_errors
def not_measured(check: Any, scenario: Scenario, fail=None) -> tuple[str, ...]:
    """A check's ``not_measured`` design parameters (none when it does not say;
    :func:`calibration.check.not_measured_names`)."""
    return not_measured_names(check, scenario.design_space.names,
                              fail or (lambda m: ServiceError(f"check {m}", field="check")))


@station_errors
def predict(scenario: str | Scenario, layout: str | None, *, physics: str | Path | None = None,
            as_built: str | Path | None = None, samples: int = 200, seed: int = 0, workers: int | None = None,
            scheduler: str | None = None, report: Reporter | None = None) -> Prediction:
    """The physical success probability and expected attempts of ``layout`` (as built when ``as_built`` is given).

    Parameters
    ----------
    scenario : str or Scenario
        A scenario file or example name, or the loaded scenario.
    layout : str or None
        A layout file or a layout named in the scenario (None: the scenario's own).
    physics : path, optional
        A physics profile (its values and intervals replace the scenario's).
    as_built : path, optional
        A CHECK.json of this layout: its ``as_built`` layout and ``residual_error``.
    samples, seed : int
        Simulations, and their seed.
    report : Reporter, optional
        Progress of the simulations, and the stop check.

    Raises
    ------
    ServiceError
        A bad count or seed, a missing file, a check of another scenario or layout.
    common.progress.Cancelled
        Stopped; the simulations done are in the cache.
    """
    check_count(samples, "samples")
    check_seed(seed)
    loaded = open_scenario(scenario) if isinstance(scenario, str) else scenario
    chosen = choose_layout(loaded, layout=layout)
    x = np.asarray(chosen.x, dtype=float)
    position, angle, unmeasured = DEFAULT_POSITION_SIGMA_M, DEFAULT_ANGLE_SIGMA_DEG, ()
    if as_built is not None:
        path = Path(as_built)
        if not path.is_file():
            raise ServiceError(f"as_built {path}: no such file (expected the CHECK.json of `station check --out`)",
                               field="as_built", value=str(path))
        data = load_json(path, "a CHECK.json of `station check`",
                         error=lambda detail: ServiceError(f"as_built {detail}", field="as_built"))
        x, position, angle, unmeasured = as_built_from_check(data, loaded, x, str(path))
    profile = read_profile(physics) if physics is not None else None
    if profile is not None:
        apply_profile(loaded, profile, str(physics))  # refuses a profile for another contraption, names the file
    result = predict_layout(loaded, x, PredictionRequest(
        profile, position, angle, tuple(unmeasured), samples, seed, workers=workers, scheduler=scheduler),
        report=report)
    return Prediction(loaded, chosen, x, as_built is not None, profile.name if profile else None, result)


@dataclass(frozen=True)
class PredictionRequest:
    """How a layout's physical success is predicted (:func:`predict_layout`).

    Parameters
    ----------
    profile : PhysicsProfile, optional
        Values and intervals to draw from (None: the scenario's own values, no draws).
    position_sigma_m, angle_sigma_deg : float
        The placement error (a check's residual; the unchecked error by default).
    unmeasured : tuple of str
        Design parameters a check did not measure (before a check: all): placed with the error of how they were set
        (``set_sigma``), else at least the unchecked error.
    samples, seed : int
        Simulations, and their seed.
    workers, scheduler
        Where the simulations run: local processes, or a Dask scheduler's address.
    set_sigma : mapping, optional
        ``{parameter: standard deviation}`` (real units) of how the guide tells the maker to set each
        (:func:`station.services.world.guide_sigma`).
    """

    profile: PhysicsProfile | None = None
    position_sigma_m: float = DEFAULT_POSITION_SIGMA_M
    angle_sigma_deg: float = DEFAULT_ANGLE_SIGMA_DEG
    unmeasured: tuple[str, ...] = ()
    samples: int = 200
    seed: int = 0
    workers: int | None = None
    scheduler: str | None = None
    set_sigma: Mapping[str, float] | None = None


@station_errors
def predict_layout(scenario: Scenario, x: np.ndarray, request: PredictionRequest = PredictionRequest(), *,
                   report: Reporter | None = None) -> PhysicalPrediction:
    """The prediction for data already in hand (after a check or a logged trial: the scenario, the layout vector,
    the profile, the placement error), on the station's executors and cache."""
    profile = request.profile
    with station_runner(workers=request.workers, scheduler=request.scheduler, report=report) as run:
        return predict_success(scenario, x, values=profile.values if profile else None,
                               intervals=profile.intervals if profile else None,
                               position_sigma_m=request.position_sigma_m, angle_sigma_deg=request.angle_sigma_deg,
                               samples=request.samples, seed=request.seed, run=run,
                               unmeasured=tuple(request.unmeasured), set_sigma=request.set_sigma)


@station_errors
def layout_outlook(problem, x: np.ndarray, *, physics: str | Path | None = None, samples: int = 48, seed: int = 0,
                   workers: int | None = None, scheduler: str | None = None,
                   report: Reporter | None = None) -> PhysicalPrediction | None:
    """The physical success of a layout the maker has not placed yet (after ``station optimize``): simulated
    ``samples`` times placed by the guide with no check (the unchecked error, 1 mm / 1 deg), under the profile at
    ``physics`` when given; None for a problem with no scenario (nothing to place) or ``samples`` 0."""
    if not samples or not isinstance(problem, ContraptionProblem):
        return None
    check_count(samples, "predict")
    profile = read_profile(physics) if physics is not None else None
    return predict_layout(problem.scenario, np.asarray(x, dtype=float),
                          PredictionRequest(profile, samples=samples, seed=seed, workers=workers, scheduler=scheduler),
                          report=report)


@station_errors
def outlook_line(result: PhysicalPrediction) -> str:
    """One line a maker reads after a check or a logged trial: the headline of
    :func:`station.services.outlook.success_headline` with the simulations it came from (``physical success on the
    table 0.82 (95 %: 0.70-0.90): expect 1.2 attempts (1.1-1.4) (48 simulations)``)."""
    return success_headline(result, when=f"{result.samples} simulations")


@station_errors
def predict_trial(scenario: Scenario, trial: Mapping[str, Any], *, samples: int = 48, seed: int = 0,
                  report: Reporter | None = None) -> PhysicalPrediction:
    """The physical success of a logged trial's layout (as built when the trial has one), under the trial's physics
    profile and its check's residual error (the defaults without a check): what the maker may expect next time."""
    check_count(samples, "predict")
    space = scenario.design_space
    values = trial.get("as_built") or trial["layout"]
    x = np.array([float(values.get(name, trial["layout"][name])) for name in space.names], dtype=float)
    profile = None
    if trial.get("physics"):
        profile = profile_from_text(trial["physics"]["content"], trial["physics"].get("name") or "<profile>")
        scenario = apply_profile(scenario, profile)
    unmeasured = not_measured(trial.get("check"), scenario)
    position, angle = residual_sigma(trial.get("check"))
    return predict_layout(scenario, x, PredictionRequest(profile, position, angle, unmeasured, samples, seed),
                          report=report)
