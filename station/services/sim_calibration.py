"""Simulator calibration as a service: fit scenarios' uncertain material values to logged trials, save a profile.

Used by ``station calibrate sim`` and the Calibrate > Simulator panel. The trials come as dicts of the trial log's
JSON export (a public format): from a file (``--trials-json``) or, wired by the station, from the trial store.
The fit itself is :func:`calibration.sim_fit.fit_simulator`; its simulations run where the optimizer's do (local
processes or a Dask scheduler) on the shared simulation cache, so a repeated or interrupted calibration re-simulates
nothing it already ran.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from calibration.errors import CalibrationError
from calibration.sim_fit import FitSettings, Runner, SimFit, fit_simulator
from calibration.sim_trials import export_trials, fit_trials
from common.datafiles import load_json
from common.progress import Cancelled, Reporter
from design.contraption.materials import default_range
from design.contraption.physics_profile import PhysicsProfile, save_profile
from design.contraption.scenario import Scenario
from station.errors import ServiceError, station_errors
from station.services.robust import check_count, connected_executor, stopped_run


@station_errors
@dataclass
class SimCalibration:
    """A finished calibration: the fit, the scenarios it was for, and the profile it makes."""

    fit: SimFit
    scenarios: list[Scenario]
    parameters: list[str]

    def profile(self, name: str | None = None) -> PhysicsProfile:
        """The fitted values as a physics profile (``[fit]`` holds the Brier scores and counts)."""
        names = ", ".join(s.name for s in self.scenarios)
        created = datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
        fit = {k: v for k, v in self.fit.fit_summary().items() if v is not None}
        return PhysicsProfile(name=name or f"calibrated {names}", values=self.fit.values(),
                              intervals=self.fit.intervals(), created=created,
                              source=f"calibrate sim: {self.fit.trials + self.fit.held_out} trials of {names}",
                              fit=fit, scenarios=tuple(s.name for s in self.scenarios))

    def to_json(self) -> dict[str, Any]:
        """Exactly the contract's ``station calibrate sim --json``."""
        return self.fit.to_json()


@station_errors
def read_trials_json(path: str | Path) -> list[dict]:
    """The trials of a trial export file (``station trial export --out FILE.json``)."""
    path = Path(path)
    if not path.is_file():
        raise ServiceError(f"trials_json {path}: no such file (expected a trial export, `station trial export "
                           "--out FILE.json`)", field="trials_json", value=str(path))

    data = load_json(path, "a trial export (\"format\": \"chaos-station trials\")",
                     error=lambda detail: CalibrationError(f"{path}: {detail}"))
    return export_trials(data, str(path))


@station_errors
def material_ranges(scenario: Scenario, every_material: bool = False) -> dict[str, tuple[float, tuple[float, float]]]:
    """``{name: (value, (low, high))}``: the scenario's uncertain material values, and with ``every_material`` its
    other material values too, each in its :func:`~design.contraption.materials.default_range`."""
    ranges = scenario.uncertain_parameters()
    if not every_material:
        return ranges
    return {name: ranges.get(name) or (value, default_range(name, value))
            for name, value in scenario.physics_parameters().items()}


@station_errors
def choose_parameters(scenarios: Sequence[Scenario], params: Sequence[str] | None, *,
                      every_material: bool = False) -> dict[str, tuple[float, tuple[float, float]]]:
    """What to fit: ``params`` (default: every uncertain value of the scenarios; with ``every_material``, every
    material value, those without a range in their default one), each with the scenarios' value and range (the
    intersection where two scenarios give different ranges)."""
    known: dict[str, tuple[float, tuple[float, float]]] = {}
    disjoint: set[str] = set()  # a value the scenarios give ranges without a common part: refused only if fitted
    for scenario in scenarios:
        for name, (value, (lo, hi)) in material_ranges(scenario, every_material).items():
            if name in known:
                _, (lo0, hi0) = known[name]
                lo, hi = max(lo, lo0), min(hi, hi0)
                if not lo < hi:
                    disjoint.add(name)
                    continue
                value = min(max(known[name][0], lo), hi)
            known[name] = (value, (lo, hi))
    if not params:
        if not known:
            raise ServiceError("params: the scenarios have no uncertain material value to fit (give one a range: "
                               "friction = { value = 0.5, range = [0.3, 0.8] })", field="params")
        params = list(known)
    chosen = {}
    for name in params:
        if name not in known:
            have = ", ".join(known) or "none"
            raise ServiceError(f"params: {name!r} is not an uncertain material value of the scenarios; they have: "
                               f"{have} (--all-materials fits the others too)", field="params", value=name)
        if name in disjoint:
            raise ServiceError(f"params: {name} has ranges that do not overlap in the scenarios (fit it per "
                               "scenario, or leave it out with --params)", field="params", value=name)
        chosen[name] = known[name]
    return chosen


@contextlib.contextmanager
@station_errors
def station_runner(*, workers: int | None = None, scheduler: str | None = None,
                   report: Reporter | None = None) -> Iterator[Runner]:
    """A :class:`~calibration.sim_fit.Runner` on the optimizer's executors and shared cache; a stop (``report``'s
    stop check, Ctrl-C) becomes the :class:`~common.progress.Cancelled` of
    :func:`~station.services.robust.stopped_run`, which says how many simulations the cache keeps."""
    check_count(workers, "workers")

    def make(problem):
        # Runs of a small scenario take milliseconds: several per task keep the workers' overhead down.
        return connected_executor(problem, workers=workers, scheduler=scheduler, chunk_size=4)

    runner = Runner(make, report=report)
    try:
        with runner:
            yield runner
    except (KeyboardInterrupt, Cancelled) as stop:
        if isinstance(stop, Cancelled) and stop.cache is not None:
            raise  # already says what the cache keeps
        raise stopped_run(runner.done) from None


@dataclass(frozen=True)
class SimCalibrationRequest:
    """What :func:`calibrate_sim` fits, from which trials, and how.

    Parameters
    ----------
    params : tuple of str, optional
        ``"MATERIAL.PARAM"`` names to fit (default: all uncertain values).
    n_trials : int, optional
        Use only the last ``n_trials`` trials of these scenarios (the most recent runs).
    settings : FitSettings, optional
        The fit's sizes and seed.
    source : str
        Where the trials come from, for messages (a file, "the trial log").
    every_material : bool
        Fit every material value, not only the uncertain ones (those without a range in their default one, see
        :func:`material_ranges`): for when the plain numbers of the scenario may be off too.
    workers, scheduler
        Where the simulations run: local processes, or a Dask scheduler's address.
    """

    params: tuple[str, ...] | None = None
    n_trials: int | None = None
    settings: FitSettings | None = None
    source: str = "<trials>"
    every_material: bool = False
    workers: int | None = None
    scheduler: str | None = None


@station_errors
def calibrate_sim(scenarios: Sequence[Scenario], trials: Sequence[Mapping[str, Any]],
                  request: SimCalibrationRequest = SimCalibrationRequest(), *,
                  report: Reporter | None = None) -> SimCalibration:
    """Fit the scenarios' uncertain material values (or ``request.params``) to their trials among ``trials``.

    Parameters
    ----------
    scenarios : sequence of Scenario
        The scenarios (their trials are those with the same name).
    trials : sequence of dict
        Trials in the export format.
    request : SimCalibrationRequest
        The values to fit, the trials to use, the fit's settings and where its simulations run.

    Raises
    ------
    ServiceError
        No trials of these scenarios, a parameter that is not uncertain in them, a bad count.
    calibration.errors.CalibrationError
        A malformed trial (names the trial and the field).
    common.progress.Cancelled
        Stopped; the simulations done are in the cache.
    """
    n_trials = request.n_trials
    if n_trials is not None and n_trials < 1:
        raise ServiceError(f"trials must be an integer >= 1, got {n_trials}", field="trials", value=n_trials)
    names = {s.name: s for s in scenarios}
    chosen = choose_parameters(scenarios, request.params, every_material=request.every_material)
    usable = fit_trials(trials, names, request.source)
    if not usable:
        raise ServiceError(f"trials: none of the {len(trials)} trials is of {', '.join(names)}; log runs with "
                           "`station trial log`", field="trials")
    if n_trials is not None:
        usable = usable[-n_trials:]
    with station_runner(workers=request.workers, scheduler=request.scheduler, report=report) as run:
        fit = fit_simulator(usable, chosen, run, request.settings)
    return SimCalibration(fit, list(scenarios), list(chosen))


@station_errors
def save(result: SimCalibration, path: str | Path, name: str | None = None) -> Path:
    """Write the calibration's physics profile."""
    return save_profile(result.profile(name), path)
