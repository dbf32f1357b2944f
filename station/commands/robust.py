"""``station optimize``, ``station robustness`` and ``station compare``: robust contraption layouts (thesis 4.5-4.8).

Simulations are cached in the station's cache directory (keyed by scenario content and layout), so a repeated or
interrupted command re-simulates nothing it already knows. Ctrl-C stops cleanly and keeps the cache.
"""

from __future__ import annotations

import functools
import json
import math
import signal
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from design.errors import FileFormatError
from design.robust.problem import RobustError
from design.robust.settings import METHODS, PSPSettings, RobustnessSettings
from station.cli_util import check_output_file, emit_json
from station.errors import UsageError
from station.paths import cache_dir

if TYPE_CHECKING:
    from design.robust.executor import SimulationExecutor
    from design.robust.pipeline import Progress

# The work (scikit-learn, scipy, pybullet, Dask) is imported by the commands that run it, so that building the
# parser (every `station` call, --help included) stays light.

#: Simulation budgets measured by the thesis for its own method (Table 4.1), used as the default budget.
THESIS_BUDGETS = {"CAUSALITYSWITCH": 614, "BALLRUN": 1120, "LONGCHAIN": 1915, "TEAPOTADVENTURE": 2420}
DEFAULT_BUDGET = 600
#: The PSP settings one can choose: the thesis's method as published, or ours (see PSPSettings.recommended).
SETTINGS_CHOICES = {
    "thesis": "the thesis's method as published",
    "recommended": "ours: quasi-deterministic test on the uniform start, C/γ by ROC AUC, three verified candidates",
}
#: Ours is the default: at the thesis's budgets it beat the thesis's settings on CAUSALITYSWITCH and BALLRUN (README).
DEFAULT_SETTINGS = "recommended"


def simulation_cache_path() -> Path:
    """The shared simulation cache of every robust-layout command and the TUI."""
    return cache_dir() / "robust-simulations.sqlite3"


def format_duration(seconds: float) -> str:
    """``seconds`` for people: ``45 s``, ``6 min 40 s``, ``1 h 05 min``."""
    seconds = max(0, int(round(seconds)))
    if seconds < 60:
        return f"{seconds} s"
    if seconds < 3600:
        return f"{seconds // 60} min {seconds % 60:02d} s"
    return f"{seconds // 3600} h {seconds % 3600 // 60:02d} min"


class Countdown:
    """Time left of ``total`` units of work, from the rate since the first unit done (start-up left out).

    Worker processes take seconds to start and prepare their simulator; timing from the first result on measures
    the work itself. An estimate is given once ``max(4, total // 50)`` units followed the first one.
    """

    def __init__(self, total: int, clock: Callable[[], float] = time.monotonic) -> None:
        self.total = total
        self.done = 0
        self._clock = clock
        self._first: tuple[float, int] | None = None

    def advance(self, done: int) -> None:
        if self._first is None and done > 0:
            self._first = (self._clock(), done)
        self.done = done

    def seconds_left(self) -> float | None:
        """None until enough units were timed."""
        if self._first is None:
            return None
        started, first = self._first
        timed = self.done - first
        elapsed = self._clock() - started
        if timed < max(4, self.total // 50) or elapsed <= 0:
            return None
        return max(0, self.total - self.done) * elapsed / timed


class ProgressBar:
    """Progress on stderr: phase, simulations of the budget, CV accuracy, best PSP, and the time left if known.

    On a terminal, one bar redrawn in place; anywhere else (a log file, a pipe), plain lines: one per phase and one
    each time the phase passes another tenth of its total, never a carriage return.
    """

    def __init__(self, stream=None, width: int = 28, interval: float = 0.1,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.stream = stream or sys.stderr
        self.width = width
        self.interval = interval
        self._clock = clock
        self._last = 0.0
        self._shown = False
        self._phase = None
        self._tenth = 0
        self._tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._countdown: Countdown | None = None
        self._done: Callable[[Progress], int] = lambda progress: progress.simulations
        self._what = ""
        self._estimated = False

    def expect(self, total: int, what: str, done: Callable[[Progress], int] | None = None) -> None:
        """Estimate the time left of ``total`` units (``what``, e.g. "new simulations") from now on.

        ``done(progress)`` counts the units done (default: the progress's simulations). The first estimate is
        written as a line of its own; the bar and the plain lines then show the time left.
        """
        self._countdown = Countdown(total, self._clock)
        self._done = done or (lambda progress: progress.simulations)
        self._what = what
        self._estimated = False

    def _time_left(self, progress: Progress) -> str:
        if self._countdown is None:
            return ""
        self._countdown.advance(self._done(progress))
        left = self._countdown.seconds_left()
        if left is None or self._countdown.done >= self._countdown.total:
            return ""
        left = math.ceil(left)  # "about 0 s left" while work remains would be wrong
        if not self._estimated:
            self._estimated = True
            self.note(f"estimate: about {format_duration(left)} left for the {self._countdown.total} {self._what}")
        return f"about {format_duration(left)} left"

    def __call__(self, progress: Progress) -> None:
        left = self._time_left(progress)
        fraction = min(progress.simulations / progress.budget, 1.0) if progress.budget else 0.0
        if not self._tty:
            # A log file, not a terminal: a line per phase and per tenth instead of a redrawn bar.
            tenth = int(fraction * 10)
            if progress.phase != self._phase or tenth > self._tenth:
                self._phase, self._tenth = progress.phase, tenth
                self.stream.write(f"{progress.phase}: {progress.simulations}/{progress.budget} {progress.unit}"
                                  + (f", {left}" if left else "") + "\n")
                self.stream.flush()
            return
        now = self._clock()
        if now - self._last < self.interval and progress.phase != "done":
            return
        self._last = now
        filled = int(round(fraction * self.width))
        bar = "#" * filled + "." * (self.width - filled)
        extra = ""
        if progress.cv_accuracy is not None:
            extra += f"  cv {progress.cv_accuracy:.2f}"
        if progress.best_psp is not None:
            extra += f"  best PSP {progress.best_psp:.2f}"
        if left:
            extra += f"  {left}"
        line = f"\r[{bar}] {progress.simulations}/{progress.budget} {progress.phase}{extra}"
        self.stream.write(line.ljust(100)[:100])
        self.stream.flush()
        self._shown = True

    def note(self, text: str) -> None:
        """A line of its own above the bar (the bar is redrawn by the next progress report)."""
        if self._shown:
            self.stream.write("\r" + " " * 100 + "\r")
            self._shown = False
        self.stream.write(text + "\n")
        self.stream.flush()

    def close(self) -> None:
        if self._shown:
            self.stream.write("\n")
            self.stream.flush()
            self._shown = False


def _load_problem(path: str):
    """A scenario file, or an example by name (``simple``, ``ballrun``...), as a robust-layout problem."""
    from design.contraption.catalog import resolve_scenario_path
    from design.robust.contraption import load_problem

    return load_problem(resolve_scenario_path(path))


def _positive(value: int | None, option: str, minimum: int = 1) -> None:
    if value is not None and value < minimum:
        raise UsageError(f"{option} must be an integer >= {minimum}, got {value}")


def _check_seed(seed: int) -> None:
    # Checked before any work: numpy refuses a negative seed only once the first random draw is made.
    if seed < 0:
        raise UsageError(f"--seed must be a non-negative integer, got {seed}")


def _executor(problem, args) -> SimulationExecutor:
    """The executor of a command, its Dask scheduler (``--scheduler``) already reached: a wrong address is one line
    within seconds, before any work."""
    from design.robust.executor import SchedulerUnreachable, SimulationExecutor

    _positive(args.workers, "--workers")
    executor = SimulationExecutor(problem, workers=args.workers, scheduler=args.scheduler,
                                  cache_path=simulation_cache_path(), chunk_size=1)
    try:
        executor.connect()
    except SchedulerUnreachable as error:
        executor.close()
        raise UsageError(f"--scheduler: {error}; or leave --scheduler out to simulate on this machine") from None
    except BaseException:
        executor.close()
        raise
    return executor


def _interrupted(executor: SimulationExecutor | None) -> None:
    new = executor.n_simulated if executor is not None else 0
    print(f"\nstation: stopping; the {new} new simulations of this run are kept in the cache "
          f"({simulation_cache_path()})", file=sys.stderr)


class StopRequest:
    """Ctrl-C and SIGTERM during a robust-layout command, as a request the work polls at safe points.

    Python's default raises KeyboardInterrupt wherever the main thread is, and the station's SIGTERM handler does
    the same; inside a C extension's callback that cannot pass it on, it is printed ("Exception ignored in:
    'scipy.stats._sobol._initialize_v' ... KeyboardInterrupt") and lost: scipy's Sobol engine carried on
    half-initialized, drew one layout over and over, and the command ran to its end on it. Here a signal only sets a
    flag; the executor stops between simulation arrivals (``should_stop``), the layout draws between chunks
    (:meth:`check`), and the command then stops as before. A second signal interrupts at once.
    """

    def __init__(self) -> None:
        self._event = threading.Event()
        self._previous: dict[int, object] = {}

    def __enter__(self) -> StopRequest:
        if threading.current_thread() is threading.main_thread():  # handlers can be set there only
            for signum in (signal.SIGINT, signal.SIGTERM):
                self._previous[signum] = signal.signal(signum, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)
        self._previous.clear()

    def _handle(self, signum, frame) -> None:
        if self._event.is_set():
            raise KeyboardInterrupt
        self._event.set()

    def is_set(self) -> bool:
        """Whether a stop was asked for."""
        return self._event.is_set()

    def check(self) -> None:
        """Raise KeyboardInterrupt here, a safe point, if a stop was asked for."""
        if self._event.is_set():
            raise KeyboardInterrupt


def stoppable(run: Callable) -> Callable:
    """A command run under a :class:`StopRequest`, given to it as ``args.stop``."""

    @functools.wraps(run)
    def wrapper(args) -> int:
        with StopRequest() as stop:
            args.stop = stop
            return run(args)

    return wrapper


def _stopped(error: BaseException, bar: ProgressBar, executor: SimulationExecutor | None,
             stop: StopRequest) -> BaseException:
    """What to raise when a command's work ended with ``error``, KeyboardInterrupt or the executor's
    SimulationCancelled: a stop by Ctrl-C or SIGTERM closes the bar, says what the cache keeps and becomes
    KeyboardInterrupt for ``main`` (exit 130); anything else is raised as it is."""
    from design.robust.executor import SimulationCancelled

    if isinstance(error, SimulationCancelled) and not stop.is_set():
        return error
    bar.close()
    _interrupted(executor)
    return KeyboardInterrupt()


def add_common(parser, budget: bool = True) -> None:
    parser.add_argument("scenario", help="scenario file or example name (e.g. simple, examples/scenarios/simple.toml)")
    if budget:
        parser.add_argument("--budget", type=int, default=None,
                            help=f"simulation budget (default: the thesis's Table 4.1 budget, else {DEFAULT_BUDGET})")
    parser.add_argument("--seed", type=int, default=0, help="seed of every random process (default 0)")
    parser.add_argument("--workers", type=int, default=None, help="local worker processes (default: all cores)")
    parser.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                        help="run simulations on a Dask distributed cluster instead of local processes")


def register(subparsers) -> None:
    optimize = subparsers.add_parser(
        "optimize", help="find a robust layout of a contraption scenario (PSP + optimization, thesis 4.5-4.7)",
        description="Learn the parametric success probability of a scenario from simulations and optimize its "
        "layout; writes LAYOUT.json (content hash, parameters real and normalized, predicted probabilities).",
        epilog="examples:\n"
        "  station optimize examples/scenarios/simple.toml --budget 40 --seed 1 --out layout.json\n"
        "  station optimize ballrun --settings thesis --workers 2 --out ballrun-layout.json",
    )
    add_common(optimize)
    optimize.add_argument("--out", required=True, metavar="LAYOUT.json", help="output layout file")
    optimize.add_argument("--global-psp", action="store_true", help="one classifier of global success (no per-event "
                          "factorization, thesis 4.5 instead of 4.6)")
    optimize.add_argument("--placement-error", type=float, default=None, metavar="EPS",
                          help="optimize the mean success probability under a uniform placement error of EPS "
                          "(normalized units, e.g. 0.1) instead of at the point (default: the settings', 0 in "
                          "thesis and recommended)")
    add_settings_choice(optimize)
    optimize.add_argument("--json", action="store_true", help="also print the layout as JSON on stdout")
    optimize.set_defaults(func=run_optimize)

    robustness = subparsers.add_parser(
        "robustness", help="local robustness curve ρ_l and global robustness ρ_g of a layout (thesis 4.8.3)",
        description="Measure how robust a layout is (thesis 4.8.3): simulate --local N layouts in balls around it "
        "and a Sobol evaluation set of --eval N layouts over the design space, then print the local robustness "
        "curve ρ_l(ε) (success rate within a normalized distance ε) and the global robustness ρ_g. Simulations are "
        "cached, so a second run of the same layout is quick. It says up front how many simulations it needs.",
        epilog="examples:\n"
        "  station robustness examples/scenarios/simple.toml layout.json --eval 128 --local 10\n"
        "  station robustness ballrun layout.json --plot rho.png --json",
    )
    robustness.add_argument("scenario", help="a scenario file (.toml/.json) or an example name")
    robustness.add_argument("layout", help="a layout file (the LAYOUT.json of `station optimize`, {\"x\": [...]} or "
                            "{\"parameters\": {...}}) or a layout named in the scenario")
    robustness.add_argument("--eval", type=int, default=RobustnessSettings().n_evaluation, metavar="N",
                            help="size of the Sobol evaluation set (default %(default)s)")
    robustness.add_argument("--local", type=int, default=RobustnessSettings().n_local, metavar="N",
                            help="layouts simulated around the layout (ball thickness, default %(default)s)")
    robustness.add_argument("--seed", type=int, default=0, help="seed of the local samples (default 0)")
    robustness.add_argument("--workers", type=int, default=None, help="local worker processes (default: all cores)")
    robustness.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT", help="Dask scheduler")
    robustness.add_argument("--plot", metavar="OUT.png", help="draw the ρ_l curve")
    robustness.add_argument("--json", action="store_true", help="print the result as JSON")
    robustness.set_defaults(func=run_robustness)

    compare = subparsers.add_parser(
        "compare", help="ours vs baselines B1-B3 at the same simulation budget (thesis Table 4.2, Figure 4.18)",
        description="Run our method and the baselines B1-B3 of thesis 4.8.3 on one scenario over --runs seeds at "
        "the same simulation budget, and print each method's global robustness ρ_g (mean and standard error), "
        "simulations and time; each run is reported as it ends, so a stopped comparison keeps its figures.",
        epilog="examples:\n"
        "  station compare simple --runs 3 --budget 60 --eval 128 --local 10\n"
        "  station compare causalityswitch_ball --seed 10 --runs 5 --plot curves.png --json",
    )
    add_common(compare)
    compare.add_argument("--methods", default=",".join(METHODS), help="comma-separated among ours,b1,b2,b3")
    compare.add_argument("--runs", type=int, default=5, metavar="T", help="seeds per method (default 5)")
    compare.add_argument("--eval", type=int, default=RobustnessSettings().n_evaluation, metavar="N",
                         help="size of the Sobol evaluation set (default %(default)s)")
    compare.add_argument("--local", type=int, default=RobustnessSettings().n_local, metavar="N",
                         help="layouts simulated around each result (ball thickness, default %(default)s)")
    add_settings_choice(compare)
    compare.add_argument("--plot", metavar="OUT.png", help="draw the mean ρ_l curves (Figure 4.18)")
    compare.add_argument("--json", action="store_true", help="print the table as JSON")
    compare.set_defaults(func=run_compare)


def thesis_budget(name: str) -> int:
    """The thesis's budget for a scenario named like one of Table 4.1 (``CAUSALITYSWITCH (ball faster)``,
    ``causalityswitch_ball``...), else :data:`DEFAULT_BUDGET`."""
    upper = name.upper()
    return next((b for key, b in THESIS_BUDGETS.items() if upper.startswith(key)), DEFAULT_BUDGET)


def default_budget(problem, budget: int | None) -> int:
    if budget is None:
        return thesis_budget(problem.name)
    _positive(budget, "--budget", 20)
    return budget


def add_settings_choice(parser) -> None:
    """``--settings thesis|recommended|LAYOUT.json`` (and ``--recommended``, short for ``--settings recommended``)."""
    parser.add_argument("--settings", default=DEFAULT_SETTINGS, metavar="NAME|LAYOUT.json",
                        help="PSP settings of ours: " + "; ".join(f"{k}: {v}" for k, v in SETTINGS_CHOICES.items())
                        + "; or a LAYOUT.json of an earlier run, to repeat it with its settings (give its --seed "
                        "and --budget too) (default %(default)s; figures of both in the README)")
    parser.add_argument("--recommended", dest="settings", action="store_const", const="recommended",
                        help="short for --settings recommended")


def psp_settings(choice: str, **changes) -> PSPSettings:
    """The PSP settings named ``choice`` (a key of :data:`SETTINGS_CHOICES`, or a LAYOUT.json's path) with
    ``changes``."""
    if choice in SETTINGS_CHOICES:
        return PSPSettings.recommended(**changes) if choice == "recommended" else PSPSettings(**changes)
    if not choice.lower().endswith(".json"):
        raise UsageError(f"--settings must be one of {', '.join(sorted(SETTINGS_CHOICES))} or a LAYOUT.json, "
                         f"got {choice!r}")
    return settings_of_layout(choice).with_changes(**changes)


def _layout_json(path: str):
    """The parsed content of a LAYOUT.json, read as every layout file is (:mod:`design.contraption.layout_io`): text
    that is not UTF-8 or not JSON raises FileFormatError naming the file; OSError passes."""
    from design.contraption.layout_io import read_layout_data

    return read_layout_data(path)


def settings_of_layout(path: str) -> PSPSettings:
    """The PSP settings a LAYOUT.json recorded (``psp_settings``, as planned for its budget)."""
    try:
        data = _layout_json(path)
    except FileNotFoundError:
        raise UsageError(f"--settings: no such file {path}") from None
    except OSError as error:
        raise FileFormatError(f"{path}: cannot be read ({error})") from None
    if not isinstance(data, dict) or "psp_settings" not in data:
        raise FileFormatError(f"{path}: field 'psp_settings' is missing (expected a LAYOUT.json written by "
                              "'station optimize')")
    if data["psp_settings"] is None:
        raise FileFormatError(f"{path}: field 'psp_settings' is null (the run recorded no settings)")
    try:
        return PSPSettings.from_mapping(data["psp_settings"], f"{path}: field 'psp_settings'")
    except RobustError as error:
        raise FileFormatError(str(error)) from None


@stoppable
def run_optimize(args) -> int:
    from design.robust.executor import SimulationCancelled
    from design.robust.pipeline import optimize_robust_layout

    _check_seed(args.seed)
    out = check_output_file(args.out, {".json"}, "--out")
    problem = _load_problem(args.scenario)
    budget = default_budget(problem, args.budget)
    changes = {}
    if args.global_psp:
        changes["factorize"] = False
    if args.placement_error is not None:
        changes["placement_error"] = args.placement_error
    settings = psp_settings(args.settings, **changes)
    bar = ProgressBar()
    executor = None
    try:
        with _executor(problem, args) as executor:
            args.stop.check()
            result = optimize_robust_layout(problem, executor, budget, args.seed, settings, progress=bar,
                                            should_stop=args.stop.is_set)
    except (KeyboardInterrupt, SimulationCancelled) as error:
        raise _stopped(error, bar, executor, args.stop) from None
    bar.close()
    payload = result.to_json(problem)
    out.write_text(json.dumps(payload, indent=2) + "\n", encoding="utf-8")
    if args.json:
        emit_json(payload)
    else:
        print(f"{problem.name}: predicted PSP {result.psp:.3f}, simulated "
              f"{'success' if result.simulated_success else 'FAILURE'}, {result.n_simulations} simulations "
              f"({result.n_new_simulations} new), {result.seconds:.1f} s -> {out}")
        for name, value in zip(problem.parameter_names, problem.to_real(result.u)):
            print(f"  {name:24s} {value: .5g}")
        for name, p in zip(result.factor_names, result.factor_probabilities):
            print(f"  P({name}) = {p:.3f}")
        _print_verification(result)
    return 0 if result.simulated_success else 1


def _print_verification(result) -> None:
    """Which candidates were simulated before one was kept, and why that one (a maker's "where did this come from")."""
    report = result.optimizer.get("verification", [])
    if not report:
        return
    settings = result.settings
    radius = f", radius {settings.verification_radius:g}" if settings is not None else ""
    score = "estimated rho_g" if settings is not None and settings.verification_score == "rho_g" else "score"
    print(f"  checked {len(report)} candidate(s), {report[0]['simulations']} simulation(s) each{radius}:")
    for row in report:
        source = "optimum" if row["source"] == "model" else "start layout"
        mark = "  <- kept" if row.get("kept") else ""
        print(f"    {source:12s} {'works' if row['success'] else 'fails':5s}  local success "
              f"{row['local_success_rate']:4.2f}  {score} {row['score']:.3f}{mark}")
    if "fallback" in result.optimizer:
        print("    none worked: kept the best simulated sample")


def read_layout(path: str, problem):
    """The layout ``path`` names for the problem's scenario (any form of :mod:`design.contraption.layout_io`: a
    LAYOUT.json, ``{"x": [...]}``, ``{"parameters": {...}}``, or a layout named in the scenario file)."""
    from design.contraption.layout_io import resolve_layout

    return resolve_layout(path, problem.scenario)


@stoppable
def run_robustness(args) -> int:
    from design.robust.executor import SimulationCancelled
    from design.robust.pipeline import BudgetedOracle, Progress
    from design.robust.plot import plot_robustness
    from design.robust.robustness import evaluation_layouts, evaluation_set, local_layouts, robustness_curve

    _check_seed(args.seed)
    _positive(args.eval, "--eval")
    if args.plot:
        check_output_file(args.plot, {".png"}, "--plot")
    problem = _load_problem(args.scenario)
    layout = read_layout(args.layout, problem)
    from station.commands.contraption import report_layout

    report_layout(layout, sys.stderr)
    u = np.clip(problem.to_normalized(layout.x), 0.0, 1.0)
    _positive(args.local, "--local")
    settings = RobustnessSettings(n_evaluation=args.eval, n_local=args.local)
    n_evaluation, n_local = settings.n_evaluation, settings.n_local
    # Minutes at the defaults on a small machine: say what will run and how to make it shorter before starting.
    print(f"{problem.name}: {n_evaluation} evaluation layouts + {n_local} local ones = {n_evaluation + n_local} "
          "simulations at most (cached ones are not run again); fewer, and faster, with --eval N and --local N",
          file=sys.stderr)
    bar = ProgressBar()
    executor = None
    try:
        with _executor(problem, args) as executor:
            args.stop.check()
            bar.expect(n_evaluation, "valid evaluation layouts")

            def checked(n_checked: int, n_valid: int) -> None:
                args.stop.check()  # the draws are seconds long for a contraption: stop between their chunks
                bar(Progress("evaluation layouts", n_valid, n_evaluation, unit="valid layouts"))

            U = evaluation_layouts(problem, n_evaluation, on_checked=checked)
            local = local_layouts(problem, u, settings, seed=args.seed)
            new = executor.count_new(np.concatenate([U, local]))
            bar.note(f"{len(U) + len(local) - new} of the {len(U) + len(local)} simulations are cached; "
                     f"{new} to run")
            bar.expect(new, "new simulations", done=lambda progress: executor.n_simulated)
            oracle = BudgetedOracle(executor, None, bar, should_stop=args.stop.is_set, expected=n_evaluation + n_local)
            oracle.phase = "evaluation set"
            evaluation = evaluation_set(problem, oracle, n_evaluation, layouts=U)
            oracle.phase = "local samples"
            curve = robustness_curve(problem, oracle, evaluation, u, settings, seed=args.seed, local=local)
    except (KeyboardInterrupt, SimulationCancelled) as error:
        raise _stopped(error, bar, executor, args.stop) from None
    bar.close()
    if args.plot:
        plot_robustness({"layout": (curve.epsilon, curve.local, np.zeros_like(curve.local))}, args.plot,
                        f"{problem.name}: {Path(args.layout).name}")
    payload = {"scenario": problem.name, "valid": curve.valid, "rho_g": curve.global_robustness,
               "epsilon": curve.epsilon, "rho_l": curve.local, "evaluation_size": len(evaluation.U),
               "evaluation_success_rate": float(evaluation.success.mean())}
    if args.json:
        emit_json(payload)
    else:
        print(f"{problem.name}: rho_g = {curve.global_robustness:.3f} over {len(evaluation.U)} evaluation layouts"
              f" ({100 * evaluation.success.mean():.0f}% succeed)" + ("" if curve.valid else "; layout INVALID"))
        for eps, rho in list(zip(curve.epsilon, curve.local))[::3]:
            print(f"  eps {eps:4.2f}  rho_l {rho:5.3f}  {'#' * int(round(40 * rho))}")
    return 0


@stoppable
def run_compare(args) -> int:
    from design.robust.executor import SimulationCancelled
    from design.robust.pipeline import compare_methods
    from design.robust.plot import plot_robustness

    methods = [m.strip().lower() for m in args.methods.split(",") if m.strip()]
    unknown = sorted(set(methods) - set(METHODS))
    if unknown or not methods:
        raise UsageError(f"--methods: expected a comma-separated list among {','.join(METHODS)}, got {args.methods!r}")
    _check_seed(args.seed)
    _positive(args.runs, "--runs")
    _positive(args.eval, "--eval")
    if args.plot:
        check_output_file(args.plot, {".png"}, "--plot")
    _positive(args.local, "--local")
    robustness = RobustnessSettings(n_evaluation=args.eval, n_local=args.local)
    problem = _load_problem(args.scenario)
    budget = default_budget(problem, args.budget)
    bar = ProgressBar()
    executor = None
    try:
        with _executor(problem, args) as executor:
            args.stop.check()
            comparison = compare_methods(
                problem, executor, methods, args.runs, budget, args.seed, settings=psp_settings(args.settings),
                robustness=robustness, progress=bar, should_stop=args.stop.is_set,
                on_run=lambda run: bar.note(f"{run.method} seed {run.seed}: rho_g {run.curve.global_robustness:.3f}, "
                                            f"{run.n_simulations} simulations, {run.seconds:.1f} s"))
    except (KeyboardInterrupt, SimulationCancelled) as error:
        raise _stopped(error, bar, executor, args.stop) from None
    bar.close()
    rows = comparison.table()
    if args.plot:
        title = f"{problem.name} (T = {args.runs}, B = {comparison.budget})"
        plot_robustness(comparison.mean_curves(), args.plot, title)
    if args.json:
        emit_json({"scenario": problem.name, "budget": comparison.budget,
                   "evaluation_size": comparison.evaluation_size, "methods": rows})
        return 0
    print(f"{problem.name}: d = {problem.dim}, budget B = {comparison.budget}, T = {args.runs} runs, "
          f"evaluation set {comparison.evaluation_size}")
    print(f"  {'method':6s} {'rho_g mean ± s.e.':>20s} {'time (s)':>9s} {'sims':>7s}")
    for row in rows:
        print(f"  {row['method']:6s} {row['rho_g_mean']:12.3f} ± {row['rho_g_sem']:.3f} {row['seconds_mean']:9.1f} "
              f"{row['simulations_mean']:7.0f}")
    return 0
