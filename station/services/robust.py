"""Robust contraption layouts as a service (thesis 4.5-4.8): optimize a layout, measure its robustness, compare
methods.

Used by ``station optimize``, ``station robustness``, ``station compare`` and the Robust layouts screen. Every run
simulates through one executor on the station's shared simulation cache (:func:`simulations`), reports progress
to one :class:`common.progress.Reporter` (a :class:`design.robust.Progress`, hence a :class:`common.progress.Progress`)
and stops when the reporter's stop check turns true: a stopped run raises :class:`common.progress.Cancelled`, whose
``new_simulations`` and ``cache`` say how many new simulations the cache kept. Refused input is a
:class:`~station.errors.ServiceError` naming the value (``budget``, ``seed``, ``settings``...); design errors (a
bad scenario or layout) pass as they are.
"""

from __future__ import annotations

import io
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from common.progress import Cancelled, Reporter
from common.signals import HandledSignals
from design.contraption.catalog import resolve_scenario_path
from design.contraption.layout_io import read_layout_data, resolve_layout
from design.robust.problem import RobustError
from design.robust.settings import METHODS, PSPSettings, RobustnessSettings
from station.errors import ServiceError, station_errors
from station.paths import cache_dir

if TYPE_CHECKING:
    import numpy as np

    from design.robust.executor import SimulationExecutor
    from design.robust.pipeline import Comparison, MethodRun, RobustLayout
    from design.robust.problem import LayoutProblem
    from design.robust.robustness import EvaluationSet, RobustnessCurve

# The work (scikit-learn, scipy, pybullet, Dask) is imported by the functions that run it, so that importing this
# module (every `station` call builds the CLI's parser from it) stays light.

#: Simulation budgets measured by the thesis for its own method (Table 4.1), used as the default budget.
THESIS_BUDGETS = {"CAUSALITYSWITCH": 614, "BALLRUN": 1120, "LONGCHAIN": 1915, "TEAPOTADVENTURE": 2420}
DEFAULT_BUDGET = 600
#: The smallest budget a run may have (the PSP's first exploration needs it).
MINIMUM_BUDGET = 20
#: The largest budget a run may have, 8 times the thesis's largest. The simulations are not what limits it (a small
#: scenario simulates about 10 a second) but the success classifiers, refitted as the samples grow: a fit takes
#: about three times as long for twice the samples (36 s for 4000 on one core), so a run much beyond this would
#: take days.
MAXIMUM_BUDGET = 20_000
#: The PSP settings one can choose: the thesis's method as published, or ours (see PSPSettings.recommended).
SETTINGS_CHOICES = {
    "thesis": "the thesis's method as published",
    "recommended": "ours: quasi-deterministic test on the uniform start, C/γ by calibrated log loss, checked "
                   "subspaces, calibrated product, three verified candidates",
}
#: Ours is the default: at the thesis's budgets it beat the thesis's settings on CAUSALITYSWITCH and BALLRUN
#: (docs/results/2026-12-04-robust-layouts.md).
DEFAULT_SETTINGS = "recommended"


@station_errors
def stopped_run(new_simulations: int) -> Cancelled:
    """The :class:`~common.progress.Cancelled` of a simulation run stopped on request (a stop asked for, Ctrl-C):
    it says how many new simulations the shared cache keeps."""
    cache = simulation_cache_path()
    return Cancelled(f"stopped; the {new_simulations} new simulations of this run are kept in the cache ({cache})",
                     new_simulations=new_simulations, cache=cache)


@station_errors
def simulation_cache_path() -> Path:
    """The shared simulation cache of every robust-layout command and the TUI."""
    return cache_dir() / "robust-simulations.sqlite3"


# -- inputs -------------------------------------------------------------------------------------------------------
@station_errors
def check_count(value: int | None, name: str, minimum: int = 1) -> None:
    """Refuse an integer ``value`` (named ``name``) below ``minimum``; None (the default) passes."""
    if value is not None and value < minimum:
        raise ServiceError(f"{name} must be an integer >= {minimum}, got {value}", field=name, value=value)


@station_errors
def check_budget(budget: int | None, name: str = "budget") -> None:
    """Refuse a simulation budget outside [:data:`MINIMUM_BUDGET`, :data:`MAXIMUM_BUDGET`]; None (the default)
    passes."""
    if budget is None:
        return
    if isinstance(budget, bool) or not isinstance(budget, int) or budget < MINIMUM_BUDGET:
        raise ServiceError(f"{name} must be an integer >= {MINIMUM_BUDGET}, got {budget!r}", field=name, value=budget)
    if budget > MAXIMUM_BUDGET:
        raise ServiceError(f"{name} must be at most {MAXIMUM_BUDGET} simulations, got {budget} (the success "
                           "classifiers' fits grow faster than the simulations: a run much larger would take days)",
                           field=name, value=budget)


@station_errors
def check_seed(seed: int) -> None:
    """Refuse a negative seed before any work (numpy refuses it only once the first random draw is made)."""
    if seed < 0:
        raise ServiceError(f"seed must be a non-negative integer, got {seed}", field="seed", value=seed)


@station_errors
def thesis_budget(name: str) -> int:
    """The thesis's budget for a scenario named like one of Table 4.1 (``CAUSALITYSWITCH (ball faster)``,
    ``causalityswitch_ball``...), else :data:`DEFAULT_BUDGET`."""
    upper = name.upper()
    return next((b for key, b in THESIS_BUDGETS.items() if upper.startswith(key)), DEFAULT_BUDGET)


@station_errors
def default_budget(problem, budget: int | None) -> int:
    """``budget``, checked; None: the thesis's budget for the problem's scenario."""
    if budget is None:
        return thesis_budget(problem.name)
    check_budget(budget)
    return budget


@station_errors
def parse_methods(text: str) -> list[str]:
    """``"ours,b1"`` → ``["ours", "b1"]``: the methods to compare, among :data:`design.robust.settings.METHODS`."""
    methods = [m.strip().lower() for m in text.split(",") if m.strip()]
    if not methods or set(methods) - set(METHODS):
        raise ServiceError(f"methods: expected a comma-separated list among {','.join(METHODS)}, got {text!r}",
                           field="methods", value=text)
    return methods


@station_errors
def psp_settings(choice: str, **changes) -> PSPSettings:
    """The PSP settings named ``choice`` (a key of :data:`SETTINGS_CHOICES`, or a LAYOUT.json's path) with
    ``changes``."""
    if choice in SETTINGS_CHOICES:
        return PSPSettings.recommended(**changes) if choice == "recommended" else PSPSettings(**changes)
    if not choice.lower().endswith(".json"):
        raise ServiceError(f"settings must be one of {', '.join(sorted(SETTINGS_CHOICES))} or a LAYOUT.json, "
                           f"got {choice!r}", field="settings", value=choice)
    return settings_of_layout(choice).with_changes(**changes)


@station_errors
def settings_of_layout(path: str) -> PSPSettings:
    """The PSP settings a LAYOUT.json recorded (``psp_settings``, as planned for its budget).

    A missing file is a :class:`ServiceError` (``field="settings"``); a file that is not a LAYOUT.json with settings
    is a :class:`ServiceError` naming the file and the field.
    """
    try:
        data = read_layout_data(path)
    except FileNotFoundError:
        raise ServiceError(f"settings: no such file {path}", field="settings", value=path) from None
    except OSError as error:
        raise ServiceError(f"{path}: cannot be read ({error})", value=path) from None
    if not isinstance(data, dict) or "psp_settings" not in data:
        raise ServiceError(f"{path}: field 'psp_settings' is missing (expected a LAYOUT.json written by "
                           "'station optimize')", value=path)
    if data["psp_settings"] is None:
        raise ServiceError(f"{path}: field 'psp_settings' is null (the run recorded no settings)", value=path)
    try:
        return PSPSettings.from_mapping(data["psp_settings"], f"{path}: field 'psp_settings'")
    except RobustError as error:
        raise ServiceError(str(error), value=path) from None


@station_errors
def load_problem(path: str):
    """A scenario file, or an example by name (``simple``, ``ballrun``...), as a robust-layout problem."""
    from design.robust.contraption import load_problem as load  # heavy: pybullet, scipy

    return load(resolve_scenario_path(path))


@station_errors
def read_layout(path: str, problem):
    """The layout ``path`` names for the problem's scenario (any form of :mod:`design.contraption.layout_io`: a
    LAYOUT.json, ``{"x": [...]}``, ``{"parameters": {...}}``, or a layout named in the scenario file)."""
    return resolve_layout(path, problem.scenario)


# -- stopping -----------------------------------------------------------------------------------------------------
@station_errors
class StopRequest(HandledSignals):
    """Ctrl-C and SIGTERM during a run, as a request the work polls at safe points (``Reporter(stop=stop.is_set)``).

    Python's default raises KeyboardInterrupt wherever the main thread is, and the station's SIGTERM handler does
    the same; inside a C extension's callback that cannot pass it on, it is printed ("Exception ignored in:
    'scipy.stats._sobol._initialize_v' ... KeyboardInterrupt") and lost: scipy's Sobol engine carried on
    half-initialized, drew one layout over and over, and the command ran to its end on it. Here a signal only sets a
    flag; the executor stops between simulation arrivals, the layout draws between chunks, and the run then raises
    :class:`~common.progress.Cancelled`. A second signal interrupts at once. Off the main thread (a TUI worker) no
    handler is set: :meth:`set` asks for the stop.
    """

    def __init__(self) -> None:
        super().__init__()
        self._event = threading.Event()

    def _handle(self, signum, frame) -> None:
        if self._event.is_set():
            raise KeyboardInterrupt
        self._event.set()

    def set(self) -> None:
        """Ask for a stop (a Stop button)."""
        self._event.set()

    def is_set(self) -> bool:
        """Whether a stop was asked for."""
        return self._event.is_set()

    def check(self) -> None:
        """Raise KeyboardInterrupt here, a safe point, if a stop was asked for."""
        if self._event.is_set():
            raise KeyboardInterrupt


@station_errors
def connected_executor(problem, *, workers: int | None = None, scheduler: str | None = None,
                       chunk_size: int | None = None) -> SimulationExecutor:
    """An executor of ``problem`` on the shared simulation cache, its Dask scheduler (if any) already reached (a
    wrong address is a :class:`ServiceError` naming ``scheduler``)."""
    # heavy: the process pool and its executor, loaded when simulations run (`station optimize --help` imports this)
    from design.robust.executor import SchedulerUnreachable, SimulationExecutor

    executor = SimulationExecutor(problem, workers=workers, scheduler=scheduler, cache_path=simulation_cache_path(),
                                  chunk_size=chunk_size)
    try:
        executor.connect()
    except SchedulerUnreachable as error:
        executor.close()
        raise ServiceError(f"scheduler: {error}", field="scheduler", value=scheduler) from None
    return executor


@contextmanager
@station_errors
def simulations(problem, *, workers: int | None = None, scheduler: str | None = None,
                report: Reporter | None = None) -> Iterator[SimulationExecutor]:
    """An executor on the shared simulation cache, its Dask scheduler (if any) already reached.

    A wrong scheduler address is a :class:`ServiceError` (``field="scheduler"``) within seconds, before any work. A
    stop inside the block (``report``'s stop check true at a safe point, KeyboardInterrupt) raises
    :class:`~common.progress.Cancelled` with the new simulations kept (:func:`stopped_run`); the workers are stopped
    first.
    """
    report = Reporter.of(report)
    check_count(workers, "workers")
    executor: SimulationExecutor | None = None
    try:
        executor = connected_executor(problem, workers=workers, scheduler=scheduler)
        with executor:
            report.check()
            yield executor
    except (KeyboardInterrupt, Cancelled):
        raise stopped_run(executor.n_simulated if executor is not None else 0) from None


# -- the runs -----------------------------------------------------------------------------------------------------
@station_errors
def optimize(problem, budget: int, seed: int, settings: PSPSettings, *, workers: int | None = None,
             scheduler: str | None = None, report: Reporter | None = None) -> RobustLayout:
    """Learn the PSP of ``problem`` from at most ``budget`` simulations and optimize its layout (thesis 4.5-4.7).

    Raises :class:`~common.progress.Cancelled` when stopped, a :class:`ServiceError` for a bad budget, seed or
    scheduler.
    """
    from design.robust.pipeline import optimize_robust_layout  # heavy: scipy, sklearn

    check_seed(seed)
    check_budget(budget)
    with simulations(problem, workers=workers, scheduler=scheduler, report=report) as executor:
        return optimize_robust_layout(problem, executor, budget, seed, settings, report=report)


@station_errors
@dataclass(frozen=True)
class RobustnessPlan:
    """What a robustness measure will simulate, once its layouts are drawn: ``cached`` of ``layouts`` are known."""

    layouts: int
    cached: int

    @property
    def new(self) -> int:
        """Simulations still to run."""
        return self.layouts - self.cached


@dataclass(frozen=True)
class Robustness:
    """A robustness measure: the ρ_l curve and ρ_g of a layout, and the evaluation set it was measured on."""

    curve: RobustnessCurve
    evaluation: EvaluationSet


@station_errors
@dataclass
class RobustnessRun:
    """How robust a layout is (thesis 4.8.3), in two steps: :meth:`draw` the layouts, then :meth:`simulate` them.

    The steps are apart so that a front end can say what will run (:class:`RobustnessPlan`) before it runs.

    Parameters
    ----------
    problem : LayoutProblem
    u : ndarray
        The layout, normalized.
    settings : RobustnessSettings
        Sizes of the evaluation set and of the local samples.
    seed : int
        Seed of the local samples.
    executor : SimulationExecutor
        From :func:`simulations`.
    report : Reporter, optional
        Progress and the stop check.
    """

    problem: LayoutProblem
    u: np.ndarray
    settings: RobustnessSettings
    seed: int
    executor: SimulationExecutor
    report: Reporter | None = None
    _evaluation_layouts: np.ndarray | None = field(default=None, init=False, repr=False)
    _local_layouts: np.ndarray | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        check_seed(self.seed)

    def draw(self) -> RobustnessPlan:
        """Draw the evaluation layouts (seconds for a contraption; progress "evaluation layouts" counts the valid
        ones) and the local ones, and count those the cache already knows."""
        from design.robust.pipeline import Progress  # heavy: scipy, sklearn
        from design.robust.robustness import evaluation_layouts, local_layouts  # heavy: scipy

        n_evaluation = self.settings.n_evaluation

        def checked(n_checked: int, n_valid: int) -> None:
            # the draws are seconds long for a contraption: a stop is honoured between their chunks
            Reporter.of(self.report).emit(Progress("evaluation layouts", n_valid, n_evaluation, unit="valid layouts"))

        self._evaluation_layouts = evaluation_layouts(self.problem, n_evaluation, on_checked=checked)
        self._local_layouts = local_layouts(self.problem, self.u, self.settings, seed=self.seed)
        layouts = len(self._evaluation_layouts) + len(self._local_layouts)
        new = self.executor.count_new(np.concatenate([self._evaluation_layouts, self._local_layouts]))
        return RobustnessPlan(layouts, layouts - new)

    def simulate(self) -> Robustness:
        """Simulate the evaluation set, then the local samples (phases "evaluation set", "local samples")."""
        from design.robust.pipeline import BudgetedOracle  # heavy: scipy, sklearn
        from design.robust.robustness import evaluation_set, robustness_curve  # heavy: scipy

        if self._evaluation_layouts is None:
            self.draw()
        settings = self.settings
        oracle = BudgetedOracle(self.executor, None, report=self.report,
                                expected=settings.n_evaluation + settings.n_local)
        oracle.phase = "evaluation set"
        evaluation = evaluation_set(self.problem, oracle, settings.n_evaluation, layouts=self._evaluation_layouts)
        oracle.phase = "local samples"
        curve = robustness_curve(self.problem, oracle, evaluation, self.u, settings, seed=self.seed,
                                 local=self._local_layouts)
        return Robustness(curve, evaluation)


@dataclass(frozen=True)
class ComparisonRequest:
    """A comparison of ours and the baselines B1-B3 (thesis Table 4.2): each method run from ``runs`` seeds.

    Parameters
    ----------
    budget : int
        Simulations per run, the same for every method (:func:`default_budget` gives the thesis's).
    settings : PSPSettings
        Our method's settings (:func:`psp_settings`).
    methods : sequence of str
        Among :data:`~design.robust.settings.METHODS` (:func:`parse_methods` reads them from words).
    runs : int
        Seeds per method, ``seed``, ``seed + 1``...
    seed : int
        The first seed.
    robustness : RobustnessSettings
        Sizes of the evaluation set and of the local samples each run's layout is measured on.
    workers, scheduler
        Where the simulations run: local processes, or a Dask scheduler's address.
    """

    budget: int
    settings: PSPSettings
    methods: tuple[str, ...] = tuple(METHODS)
    runs: int = 5
    seed: int = 0
    robustness: RobustnessSettings = field(default_factory=RobustnessSettings)
    workers: int | None = None
    scheduler: str | None = None


@station_errors
def compare(problem, request: ComparisonRequest, *, report: Reporter | None = None,
            on_run: Callable[[MethodRun], None] | None = None) -> Comparison:
    """Ours and the baselines B1-B3 over ``request.runs`` seeds at the same budget (thesis Table 4.2); ``on_run`` is
    called with each run as it ends, so a stopped comparison has reported what it finished."""
    from design.robust.pipeline import compare_methods  # heavy: scipy, sklearn

    check_seed(request.seed)
    check_count(request.runs, "runs")
    check_budget(request.budget)
    with simulations(problem, workers=request.workers, scheduler=request.scheduler, report=report) as executor:
        return compare_methods(problem, executor, list(request.methods), request.runs, request.budget, request.seed,
                               settings=request.settings, robustness=request.robustness, report=report,
                               on_run=on_run)


@station_errors
def layouts_picture(problem, optimized) -> bytes:
    """A PNG of ``problem``'s initial layout beside the ``optimized`` one (normalized), in side view."""
    from design.robust.contraption import render_layouts  # pybullet: loaded when a picture is drawn

    picture = io.BytesIO()
    render_layouts(problem, [("initial", problem.initial_layout()), ("optimized", optimized)]).save(picture,
                                                                                                    format="PNG")
    return picture.getvalue()


@station_errors
def plot_robustness(curves, path: str | Path, title: str = "") -> Path:
    """A PNG of robustness curves (Figure 4.18): ``curves`` maps a label to ``(epsilon, mean rho_l, its s.e.)``."""
    from design.robust.plot import plot_robustness as plot  # Pillow: loaded when a plot is drawn, not for --help

    return plot(curves, path, title)
