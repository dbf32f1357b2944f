"""The tolerance map of a layout as a service: ``station tolerances`` and the assembly guide.

:func:`tolerance_map` reads a scenario and a layout (through the one layout reader, as ``station robustness``
does), takes the fitted success model the LAYOUT.json carries (``"model"``, :mod:`design.robust.model_io`) and
computes each free parameter's tolerance (:mod:`design.robust.tolerance`); ``verify=N`` simulates N layouts at
±delta per parameter on the shared simulation cache. A layout without a model gets its tolerances by simulation
when ``verify > 0``, else none; the result's ``map.source`` says which. Progress goes to one reporter (a
:class:`design.robust.Progress`, hence a :class:`common.progress.Progress`); refused input is a
:class:`~station.errors.ServiceError` naming the value (``verify``, ``seed``...).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from common.progress import Reporter
from design.contraption import Scenario
from design.contraption.layout_io import layout_from_data, read_layout_data
from design.robust.model_io import layout_model
from design.robust.tolerance import CARE_RULE as CARE_RULE  # re-exported (X as X): the faces word the rule
from design.robust.tolerance import RATIO as RATIO
from design.robust.tolerance import model_tolerances, no_tolerances, simulated_tolerances, verify_tolerances
from station.errors import ServiceError, station_errors
from station.services import robust
from station.services.outlook import disagreement
from station.services.physics import problem_with_physics

if TYPE_CHECKING:
    import numpy as np

    from design.contraption.layout_io import LoadedLayout
    from design.robust.model_io import PortablePSP
    from design.robust.tolerance import ToleranceMap
    from projector.guide import ParameterTolerance

#: Bisection steps per parameter of the search by simulation (no model): delta to 1/16 of the parameter's room.
SIMULATION_STEPS = 4
#: Layouts per step of the search by simulation when the layout's model is too weak to trust (the model and the
#: simulations disagree about the layout): a guide never prints a model's tolerances that do not hold.
WEAK_MODEL_VERIFY = 8


@station_errors
@dataclass(frozen=True)
class Tolerances:
    """A layout's tolerance map and what it was computed from.

    Attributes
    ----------
    problem : ContraptionProblem
        The scenario as a robust-layout problem.
    layout : LoadedLayout
        The layout read (where from, defaulted parameters, warnings).
    u : ndarray
        The layout, normalized.
    map : ToleranceMap
        The tolerances (``map.source``: ``"model"``, ``"simulation"`` or ``"none"``).
    model : PortablePSP or None
        The fitted model the layout file carried.
    verify : int
        Layouts simulated per parameter (0: none).
    layout_data : object
        The layout file's content as read (None for a layout named in the scenario): what else it carries, e.g. the
        physical success ``station optimize`` wrote.
    """

    problem: object
    layout: LoadedLayout
    u: np.ndarray
    map: ToleranceMap
    model: PortablePSP | None
    verify: int
    layout_data: object = field(default=None, repr=False)

    def parameter_tolerances(self) -> dict[str, tuple[ParameterTolerance, ...]]:
        """Per part, its parameters' tolerances as the guide's :class:`projector.guide.ParameterTolerance`."""
        from projector.guide import ParameterTolerance  # heavy: shapely

        return {part: tuple(ParameterTolerance(e.parameter, e.delta, e.unit, e.predicted_ratio, e.measured,
                                               self.map.source, e.bound_limited) for e in entries)
                for part, entries in self.map.by_part().items()}

    def care(self) -> dict[str, str | None]:
        """Per part, ``"tight"``, ``"normal"``, ``"loose"`` or None (:func:`design.robust.tolerance.care_level`)."""
        return self.map.care()

    def to_dict(self) -> dict:
        """What ``station tolerances --json`` prints (the shape its help documents)."""
        return {"scenario": self.problem.name, "layout": self.layout.to_dict(), "verify": self.verify,
                **self.map.to_dict()}


@station_errors
def layout_and_model(layout: str, problem):
    """The layout ``layout`` names and the fitted model its file carries (None for a layout without one), from one
    reading of the file."""
    return _read_layout(layout, problem)[:2]


def _read_layout(layout: str, problem):
    """``(layout, model or None, the file's data or None)``: what :func:`layout_and_model` gives and the data read
    for it (None for a layout named in the scenario)."""
    if not Path(layout).is_file():  # a layout named in the scenario, or a missing file: the reader says which
        return robust.read_layout(layout, problem), None, None
    data = read_layout_data(layout)
    return layout_from_data(data, problem.scenario, file=layout), layout_model(data, problem, file=layout), data


@station_errors
def layout_simulated_success(data) -> float | None:
    """What simulation says of a layout file's success, from its data: its ``physical_success`` probability
    (``station optimize`` writes it), else its ``simulated_success`` (one simulation at the point) as 0 or 1; None
    for a named layout (no data) or a file with neither."""
    if not isinstance(data, dict):
        return None
    physical = data.get("physical_success")
    if isinstance(physical, dict) and isinstance(physical.get("probability"), (int, float)):
        return float(physical["probability"])
    simulated = data.get("simulated_success")
    return float(simulated) if isinstance(simulated, bool) else None


@station_errors
def contraption_problem(scenario):
    """A scenario file or example name, or a loaded :class:`design.contraption.Scenario`, as a problem."""
    from design.robust.contraption import ContraptionProblem  # heavy: pybullet, scipy

    if isinstance(scenario, Scenario):
        return ContraptionProblem(scenario.source, scenario)
    return robust.load_problem(str(scenario))


@station_errors
def tolerance_map(scenario, layout: str, *, verify: int = 0, seed: int = 0, workers: int | None = None,
                  scheduler: str | None = None, report: Reporter | None = None,
                  physics: str | None = None) -> Tolerances:
    """The tolerance map of ``layout`` for ``scenario``.

    Parameters
    ----------
    scenario : str or Scenario
        A scenario file or example name, or the scenario already loaded (:func:`design.contraption.load_scenario`).
    layout : str
        A layout file (a LAYOUT.json with its model, ``{"parameters": {...}}``...) or a layout named in the scenario.
    verify : int
        Layouts to simulate per parameter (half at -delta, half at +delta); 0 simulates nothing. Without a model,
        the number of layouts per step of the search by simulation.
    seed : int
        Seed of the verification layouts.
    workers, scheduler :
        Where the simulations run (:func:`station.services.robust.simulations`).
    report : Reporter, optional
        Stage ``"tolerance map"`` (parameters searched), then ``"verification"`` (simulations); its stop check
        ends the simulations.
    physics : str, optional
        A physics profile: the simulations use its material values (:mod:`station.services.physics`).

    Raises
    ------
    ServiceError
        ``verify`` or ``seed`` negative (``field`` names it).
    common.progress.Cancelled
        Stopped on request or by Ctrl-C; simulations done are kept in the cache.
    """
    from design.robust.pipeline import BudgetedOracle, Progress  # heavy: scipy, sklearn

    if isinstance(verify, bool) or not isinstance(verify, int) or verify < 0:
        raise ServiceError(f"verify must be an integer >= 0 (layouts simulated per parameter), got {verify!r}",
                           field="verify", value=verify)
    robust.check_seed(seed)

    problem = problem_with_physics(contraption_problem(scenario), physics)
    loaded, model, data = _read_layout(str(layout), problem)
    u = np.clip(problem.to_normalized(loaded.x), 0.0, 1.0)
    d = problem.dim
    report = Reporter.of(report)
    report.emit(Progress("tolerance map", 0, d, unit="parameters"))
    note = None
    if model is not None:
        tolerances = model_tolerances(model, problem, u, is_valid=problem.is_valid)
        simulated = layout_simulated_success(data)
        if disagreement(tolerances.layout_psp, simulated) is not None:
            # the model is no guide here: its tolerances are searched again by simulation, or (with --verify)
            # kept with their measured success beside them
            note = (f"the success model is weak at this layout (its score {tolerances.layout_psp:.2f}, the "
                    f"simulations' {simulated:.2f})")
            if verify == 0:
                note += f": tolerances searched by simulation instead ({WEAK_MODEL_VERIFY} layouts a step)"
                tolerances, verify = None, WEAK_MODEL_VERIFY
            else:
                note += ": read the measured success at each delta, not the predicted"
    elif verify == 0:
        tolerances = no_tolerances(problem)
    else:
        tolerances = None
    report.emit(Progress("tolerance map", d, d, unit="parameters"))
    if tolerances is None or verify > 0:
        expected = 1 + d * verify if tolerances is not None else 1 + d * (SIMULATION_STEPS + 1) * verify
        with robust.simulations(problem, workers=workers, scheduler=scheduler, report=report) as executor:
            oracle = BudgetedOracle(executor, None, report=report, expected=expected)
            oracle.phase = "verification"

            def parameter(_index: int, name: str) -> None:
                oracle.report(name)

            if tolerances is None:
                tolerances = simulated_tolerances(problem, u, oracle, verify, steps=SIMULATION_STEPS, seed=seed,
                                                  on_parameter=parameter)
            else:
                tolerances = verify_tolerances(tolerances, problem, u, oracle, verify, seed=seed, model=model,
                                               on_parameter=parameter)
    if note is not None:
        tolerances = replace(tolerances, note=note)
    return Tolerances(problem, loaded, u, tolerances, model, verify, data)
