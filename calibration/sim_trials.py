"""Logged physical trials (the trial log's JSON export, a public format) as the data of simulator calibration.

A trial of the export (``{"format": "chaos-station trials", "version": 1, "trials": [...]}``) names its scenario
with the content that was built (``scenario.content``), the layout as designed and as built (from a check, when one
was made), the check itself (whose ``residual_error`` is the placement error of the measurement), and what happened:
``outcomes`` (``"yes"``, ``"no"`` or ``"not-reached"`` for every event) and optional ``times`` (seconds).

:func:`fit_trials` turns them into :class:`FitTrial`: the scenario to simulate, the layout to simulate it at (as
built, else as designed), the placement error around it, and the outcomes as codes in the scenario's event order.
A bad trial is refused in one line naming ``trials[i]`` and the field.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from calibration.check import not_measured_names
from calibration.errors import CalibrationError
from calibration.sim_runs import OUTCOME_WORDS, residual_sigma
from design.contraption.model import Scenario
from design.errors import DesignError

EXPORT_FORMAT = "chaos-station trials"
EXPORT_VERSION = 1


@dataclass(frozen=True)
class FitTrial:
    """One physical run, ready to be compared with simulations.

    Attributes
    ----------
    id : int or str
        The trial's id in the log (for messages).
    scenario : Scenario
        The scenario as built in that run.
    layout : ndarray
        The layout simulated: as built where a check measured it, else as designed (real units, design order).
    as_built : bool
        Whether ``layout`` is a measured one.
    position_sigma_m, angle_sigma_deg : float
        The placement error around ``layout`` (the check's residual error, else 1 mm and 1 degree).
    unmeasured : tuple of str
        The design parameters the check did not measure (its ``not_measured``): placed as with no check, at least
        1 mm and 1 degree (:func:`calibration.sim_runs.placement_sigma`).
    codes : ndarray
        One outcome code per event of ``scenario`` (:data:`~calibration.sim_runs.YES`, ``NO``, ``NOT_REACHED``).
    times : ndarray
        One time per event (s), NaN where none was logged.
    success : bool
        Whether the goal events happened.
    """

    id: Any
    scenario: Scenario
    layout: np.ndarray
    as_built: bool
    position_sigma_m: float
    angle_sigma_deg: float
    codes: np.ndarray
    times: np.ndarray
    success: bool
    unmeasured: tuple[str, ...] = ()


def export_trials(data: Any, file: str = "<trials>") -> list[dict]:
    """The ``trials`` list of a trial export, its format and version checked."""
    if isinstance(data, list):  # a bare list of trial dicts (what the trial store's API returns)
        return data
    if not isinstance(data, Mapping):
        raise CalibrationError(f"{file}: expected a trial export (a JSON object with \"format\": "
                               f"\"{EXPORT_FORMAT}\"), got {type(data).__name__}")
    if data.get("format") != EXPORT_FORMAT:
        raise CalibrationError(f"{file}: format: expected {EXPORT_FORMAT!r}, got {data.get('format')!r}")
    if data.get("version") != EXPORT_VERSION:
        raise CalibrationError(f"{file}: version: expected {EXPORT_VERSION} (this station reads version "
                               f"{EXPORT_VERSION}), got {data.get('version')!r}")
    trials = data.get("trials")
    if not isinstance(trials, list):
        raise CalibrationError(f"{file}: trials: expected a list of trials")
    return trials


def fit_trials(trials: Sequence[Mapping[str, Any]], scenarios: Mapping[str, Scenario],
               file: str = "<trials>") -> list[FitTrial]:
    """The trials of the named scenarios (``scenarios``: name -> scenario), in the log's order.

    A trial whose scenario is not among ``scenarios`` is left out. Its logged content is what is simulated (the
    contraption as it was built, even if the file changed since); a trial without content uses the named scenario.

    Raises
    ------
    CalibrationError
        A malformed trial (``FILE: trials[i].FIELD: expected ...``).
    """
    parsed: dict[str, Scenario] = {}
    result = []
    for i, trial in enumerate(trials):
        where = f"{file}: trials[{i}]"
        if not isinstance(trial, Mapping):
            raise CalibrationError(f"{where}: expected a trial object")
        header = trial.get("scenario")
        if not isinstance(header, Mapping) or not isinstance(header.get("name"), str):
            raise CalibrationError(f"{where}.scenario.name: expected the scenario's name")
        if header["name"] not in scenarios:
            continue
        scenario = _scenario_of(header, scenarios[header["name"]], parsed, where)
        result.append(_fit_trial(trial, scenario, where))
    return result


def _scenario_of(header: Mapping, named: Scenario, parsed: dict[str, Scenario], where: str) -> Scenario:
    content = header.get("content")
    if not content:
        return named
    if not isinstance(content, str):
        raise CalibrationError(f"{where}.scenario.content: expected the scenario file's text")
    key = str(header.get("content_hash") or hash(content))
    if key not in parsed:
        from design.contraption.validation import parse_text, scenario_from_data

        source = f"{where}.scenario.content"
        suffix = ".json" if content.lstrip().startswith("{") else ".toml"
        try:
            parsed[key] = scenario_from_data(parse_text(content.encode("utf-8"), source, suffix), file=source)
        except DesignError as error:
            raise CalibrationError(str(error)) from None
    return parsed[key]


def _fit_trial(trial: Mapping, scenario: Scenario, where: str) -> FitTrial:
    space = scenario.design_space
    as_built = trial.get("as_built")
    values = as_built if isinstance(as_built, Mapping) and as_built else trial.get("layout") or {}
    if not isinstance(values, Mapping):
        raise CalibrationError(f"{where}.layout: expected {{parameter: value}}")
    layout = space.default.copy().astype(float)
    for name, value in values.items():
        if name not in space.names:
            raise CalibrationError(f"{where}.{'as_built' if as_built else 'layout'}.{name}: not a design parameter "
                                   f"of {scenario.name!r} (expected one of {', '.join(space.names)})")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
            raise CalibrationError(f"{where}.layout.{name}: expected a number, got {value!r}")
        layout[space.names.index(name)] = float(value)
    check = trial.get("check")
    position, angle = residual_sigma(check)
    unmeasured = not_measured_names(check, space.names, lambda m: CalibrationError(f"{where}.check.{m}"))
    outcomes = trial.get("outcomes")
    if not isinstance(outcomes, Mapping):
        raise CalibrationError(f"{where}.outcomes: expected {{event: \"yes\" | \"no\" | \"not-reached\"}}")
    codes = np.empty(len(scenario.events))
    for k, event in enumerate(scenario.events):
        word = outcomes.get(event)
        if word not in OUTCOME_WORDS:
            got = "nothing" if word is None else repr(word)
            raise CalibrationError(f"{where}.outcomes.{event}: expected yes, no or not-reached, got {got}")
        codes[k] = OUTCOME_WORDS[word]
    times = np.full(len(scenario.events), np.nan)
    for event, value in (trial.get("times") or {}).items():
        if event not in scenario.events:
            raise CalibrationError(f"{where}.times.{event}: not an event of {scenario.name!r}")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0:
            raise CalibrationError(f"{where}.times.{event}: expected seconds >= 0, got {value!r}")
        times[scenario.events.index(event)] = float(value)
    success = trial.get("success")
    if not isinstance(success, bool):
        raise CalibrationError(f"{where}.success: expected true or false, got {success!r}")
    return FitTrial(trial.get("id", where), scenario, layout, bool(as_built), position, angle, codes, times, success,
                    unmeasured)


