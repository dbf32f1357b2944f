"""``station optimize``, ``station robustness`` and ``station compare``: robust contraption layouts (thesis 4.5-4.8).

Argparse in, text or JSON out: the work is :mod:`station.services.robust`, whose refusals (naming a value:
``budget``, ``settings``...) are reworded here into the flags' words (``--budget``, ``--settings``). Simulations are
cached in the station's cache directory (keyed by scenario content and layout), so a repeated or interrupted command
re-simulates nothing it already knows. Ctrl-C stops cleanly and keeps the cache.
"""

from __future__ import annotations

import functools
import json
import math
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TextIO

import numpy as np

from station.cli_util import NON_NEGATIVE, add_physics_option, check_output_file, emit_json
from station.commands.contraption import report_layout
from station.errors import ServiceError, UsageError
from station.progress_view import ProgressView
from station.services import robust as service
from station.services.outlook import disagreement, success_headline
from station.services.physics import problem_with_physics
from station.services.reporting import Cancelled, Reporter
from station.services.reporting import Progress as BaseProgress
from station.services.robust import (  # noqa: F401 - re-exported: the work lives in the service
    DEFAULT_BUDGET,
    DEFAULT_SETTINGS,
    METHODS,
    SETTINGS_CHOICES,
    RobustnessSettings,
    StopRequest,
    plot_robustness,
    read_layout,
    simulation_cache_path,
    thesis_budget,
)

#: The flag that gives each value the service may refuse.
FLAGS = {"budget": "--budget", "seed": "--seed", "workers": "--workers", "runs": "--runs", "n_evaluation": "--eval",
         "n_local": "--local", "methods": "--methods", "settings": "--settings", "scheduler": "--scheduler"}


def usage_error(error: ServiceError) -> UsageError | ServiceError:
    """The service's refusal in the command line's words: the value's name becomes its flag (``budget must be an
    integer >= 20, got 3`` → ``--budget must be ...``); an error about another value is kept as it is."""
    flag = FLAGS.get(error.field or "")
    message = str(error)
    if flag is None or not message.startswith(error.field):
        return error
    message = flag + message.removeprefix(error.field)
    if error.field == "scheduler":
        message += "; or leave --scheduler out to simulate on this machine"
    return UsageError(message)


@contextmanager
def flag_words() -> Iterator[None]:
    """Reword the service refusals raised in the block (:func:`usage_error`)."""
    try:
        yield
    except ServiceError as error:
        raise usage_error(error) from None


def psp_settings(choice: str, **changes):
    """:func:`station.services.robust.psp_settings`, its refusals naming ``--settings``."""
    with flag_words():
        return service.psp_settings(choice, **changes)


def default_budget(problem, budget: int | None) -> int:
    """:func:`station.services.robust.default_budget`, a bad budget naming ``--budget``."""
    with flag_words():
        return service.default_budget(problem, budget)


def _load_problem(path: str):
    """A scenario file, or an example by name, as a robust-layout problem (tests replace it with a cheap one)."""
    return service.load_problem(path)


def _problem(args):
    """The problem of ``args.scenario`` under ``args.physics`` (a physics profile) when given."""
    return problem_with_physics(_load_problem(args.scenario), getattr(args, "physics", None))


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


class ProgressBar(ProgressView):
    """The robust commands' progress on stderr: phase, simulations of the budget, and the time left once known.

    A :class:`station.progress_view.ProgressView`: on a terminal rich's bars, with the CV accuracy and the best PSP
    beside them; anywhere else (a log file, a pipe) plain lines, one per phase and one each time the phase passes
    another tenth of its total (``exploration: 10/100 simulations, about 1 min 38 s left``).
    """

    def __init__(self, stream: TextIO | None = None, clock: Callable[[], float] = time.monotonic,
                 tty: bool | None = None) -> None:
        super().__init__(stream, describe=self._describe, tty=tty)
        self._clock = clock
        self._countdown: Countdown | None = None
        self._done: Callable[[BaseProgress], float] = lambda progress: progress.done
        self._what = ""
        self._estimated = False
        self._left = ""

    def expect(self, total: int, what: str, done: Callable[[BaseProgress], float] | None = None) -> None:
        """Estimate the time left of ``total`` units (``what``, e.g. "new simulations") from now on.

        ``done(progress)`` counts the units done (default: the progress's simulations). The first estimate is
        written as a line of its own; the bar and the plain lines then show the time left.
        """
        self._countdown = Countdown(total, self._clock)
        self._done = done or (lambda progress: progress.done)
        self._what = what
        self._estimated = False

    def _time_left(self, progress: BaseProgress) -> str:
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

    def __call__(self, progress: BaseProgress) -> None:
        # Before the view takes its lock: the first estimate is a note of its own.
        self._left = self._time_left(progress)
        super().__call__(progress)

    def _describe(self, progress: BaseProgress) -> str:
        unit = getattr(progress, "unit", "simulations")
        if not self.tty:
            return f"{progress.stage}: {progress.done}/{progress.total} {unit}" + (f", {self._left}" if self._left
                                                                                   else "")
        text = f"{progress.done}/{progress.total} {progress.stage}"
        if getattr(progress, "cv_accuracy", None) is not None:
            text += f"  cv {progress.cv_accuracy:.2f}"
        if getattr(progress, "best_psp", None) is not None:
            text += f"  best PSP {progress.best_psp:.2f}"
        return text + (f"  {self._left}" if self._left else "")


def command(run: Callable[..., int]) -> Callable[..., int]:
    """A command run under a :class:`StopRequest` (given to it as ``args.stop``), its service refusals in the flags'
    words; a stopped run closes its progress bar (``args.bar``), says what the cache keeps and becomes
    KeyboardInterrupt for ``main`` (exit 130)."""

    @functools.wraps(run)
    def wrapper(args) -> int:
        args.bar = ProgressBar()
        with StopRequest() as stop:
            args.stop = stop
            try:
                with flag_words():
                    return run(args)
            except Cancelled as stopped:
                args.bar.close()
                kept = (f"; the {stopped.new_simulations} new simulations of this run are kept in the cache "
                        f"({stopped.cache})" if stopped.cache is not None else "")
                print(f"\nstation: stopping{kept}", file=sys.stderr)
                raise KeyboardInterrupt from None
            finally:
                args.bar.close()

    return wrapper


def _where(args) -> dict:
    """Where the simulations run, and their reporter (the command's bar, its stop request): the keyword arguments
    every run of the service takes."""
    return {"workers": args.workers, "scheduler": args.scheduler, "report": Reporter(args.bar, stop=args.stop.is_set)}


def add_common(parser, budget: bool = True) -> None:
    parser.add_argument("scenario", help="scenario file or example name (e.g. simple, examples/scenarios/simple.toml)")
    if budget:
        parser.add_argument("--budget", type=int, default=None,
                            help=f"simulation budget (default: the thesis's Table 4.1 budget, else {DEFAULT_BUDGET})")
    parser.add_argument("--seed", type=int, default=0, help="seed of every random process (default 0)")
    add_workers(parser)


def add_scenario_and_layout(parser) -> None:
    """The positional ``scenario`` and ``layout`` of a command about one layout of a scenario."""
    parser.add_argument("scenario", help="a scenario file (.toml/.json) or an example name")
    parser.add_argument("layout", help="a layout file (the LAYOUT.json of `station optimize`, {\"x\": [...]} or "
                        "{\"parameters\": {...}}) or a layout named in the scenario")


def add_workers(parser) -> None:
    """``--workers N`` and ``--scheduler tcp://HOST:PORT``: where the simulations run; and ``--physics``, the
    material values they run with."""
    add_physics_option(parser)
    parser.add_argument("--workers", type=int, default=None, help="local worker processes (default: all cores)")
    parser.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                        help="run simulations on a Dask distributed cluster instead of local processes")


def add_sampling(parser, around: str) -> None:
    """``--eval N`` and ``--local N``: the sizes of a robustness measure (``around``: what the local ones are
    around)."""
    defaults = RobustnessSettings()
    parser.add_argument("--eval", type=int, default=defaults.n_evaluation, metavar="N",
                        help="size of the Sobol evaluation set (default %(default)s)")
    parser.add_argument("--local", type=int, default=defaults.n_local, metavar="N",
                        help=f"layouts simulated around {around} (ball thickness, default %(default)s)")


def add_command(subparsers, name: str, run: Callable[..., int], help: str, description: str,
                examples: list[str]):
    """The parser of command ``name`` (running ``run``) with its examples as the epilog."""
    parser = subparsers.add_parser(name, help=help, description=description,
                                   epilog="examples:\n" + "".join(f"  station {name} {e}\n" for e in examples))
    parser.set_defaults(func=run)
    return parser


def register(subparsers) -> None:
    optimize = add_command(
        subparsers, "optimize", run_optimize,
        help="find a robust layout of a contraption scenario (PSP + optimization, thesis 4.5-4.7)",
        description="Learn the parametric success probability of a scenario from simulations and optimize its "
        "layout; writes LAYOUT.json (content hash, parameters real and normalized, predicted probabilities).",
        examples=["examples/scenarios/simple.toml --budget 40 --seed 1 --out layout.json",
                  "ballrun --settings thesis --workers 2 --out ballrun-layout.json"],
    )
    add_common(optimize)
    optimize.add_argument("--out", required=True, metavar="LAYOUT.json", help="output layout file")
    optimize.add_argument("--global-psp", action="store_true", help="one classifier of global success (no per-event "
                          "factorization, thesis 4.5 instead of 4.6)")
    optimize.add_argument("--placement-error", type=NON_NEGATIVE, default=None, metavar="EPS",
                          help="optimize the mean success probability under a uniform placement error of EPS "
                          "(normalized units, e.g. 0.1) instead of at the point (default: the settings', 0 in "
                          "thesis and recommended)")
    add_settings_choice(optimize)
    optimize.add_argument("--json", action="store_true", help="also print the layout as JSON on stdout")
    optimize.add_argument("--predict", type=int, default=48, metavar="N",
                          help="the optimized layout's physical success on the table and the attempts to expect, "
                          "from N simulations placed by the guide with no check (1 mm / 1 deg), written to "
                          "LAYOUT.json's physical_success (default %(default)s; 0: none)")

    robustness = add_command(
        subparsers, "robustness", run_robustness,
        help="local robustness curve ρ_l and global robustness ρ_g of a layout (thesis 4.8.3)",
        description="Measure how robust a layout is (thesis 4.8.3): simulate --local N layouts in balls around it "
        "and a Sobol evaluation set of --eval N layouts over the design space, then print the local robustness "
        "curve ρ_l(ε) (success rate within a normalized distance ε) and the global robustness ρ_g. Simulations are "
        "cached, so a second run of the same layout is quick. It says up front how many simulations it needs.",
        examples=["examples/scenarios/simple.toml layout.json --eval 128 --local 10",
                  "ballrun ballrun-layout.json --plot rho.png --json"],
    )
    add_scenario_and_layout(robustness)
    add_sampling(robustness, "the layout")
    robustness.add_argument("--seed", type=int, default=0, help="seed of the local samples (default 0)")
    add_workers(robustness)
    robustness.add_argument("--plot", metavar="OUT.png", help="draw the ρ_l curve")
    robustness.add_argument("--json", action="store_true", help="print the result as JSON")

    compare = add_command(
        subparsers, "compare", run_compare,
        help="ours vs baselines B1-B3 at the same simulation budget (thesis Table 4.2, Figure 4.18)",
        description="Run our method and the baselines B1-B3 of thesis 4.8.3 on one scenario over --runs seeds at "
        "the same simulation budget, and print each method's global robustness ρ_g (mean and standard error), "
        "simulations and time; each run is reported as it ends, so a stopped comparison keeps its figures.",
        examples=["simple --runs 3 --budget 60 --eval 128 --local 10",
                  "causalityswitch_ball --seed 10 --runs 5 --plot curves.png --json"],
    )
    add_common(compare)
    compare.add_argument("--methods", default=",".join(METHODS), help="comma-separated among ours,b1,b2,b3")
    compare.add_argument("--runs", type=int, default=5, metavar="T", help="seeds per method (default 5)")
    add_sampling(compare, "each result")
    add_settings_choice(compare)
    compare.add_argument("--plot", metavar="OUT.png", help="draw the mean ρ_l curves (Figure 4.18)")
    compare.add_argument("--json", action="store_true", help="print the table as JSON")


def add_settings_choice(parser) -> None:
    """``--settings thesis|recommended|LAYOUT.json`` (and ``--recommended``, short for ``--settings recommended``)."""
    parser.add_argument("--settings", default=DEFAULT_SETTINGS, metavar="NAME|LAYOUT.json",
                        help="PSP settings of ours: " + "; ".join(f"{k}: {v}" for k, v in SETTINGS_CHOICES.items())
                        + "; or a LAYOUT.json of an earlier run, to repeat it with its settings (give its --seed "
                        "and --budget too) (default %(default)s; figures of both: "
                        "docs/results/2026-12-04-robust-layouts.md)")
    parser.add_argument("--recommended", dest="settings", action="store_const", const="recommended",
                        help="short for --settings recommended")


@command
def run_optimize(args) -> int:
    service.check_seed(args.seed)
    out = check_output_file(args.out, {".json"}, "--out")
    problem = _problem(args)
    budget = default_budget(problem, args.budget)
    changes = {}
    if args.global_psp:
        changes["factorize"] = False
    if args.placement_error is not None:
        changes["placement_error"] = args.placement_error
    settings = psp_settings(args.settings, **changes)
    from station.services.predict import layout_outlook  # simulation code: deferred so that --help stays quick

    service.check_count(args.predict, "predict", 0)
    result = service.optimize(problem, budget, args.seed, settings, **_where(args))
    outlook = layout_outlook(problem, problem.to_real(result.u), physics=getattr(args, "physics", None),
                             samples=args.predict, seed=args.seed, **_where(args))
    args.bar.close()
    payload = result.to_json(problem)
    if outlook is not None:
        payload["physical_success"] = outlook.to_json()
    out.write_text(json.dumps(payload, indent=2) + "\n", encoding="utf-8")
    if args.json:
        emit_json(payload)
    else:
        _print_optimized(problem, result, outlook, out)
    return 0 if result.simulated_success else 1


def _print_optimized(problem, result, outlook, out) -> None:
    """The optimized layout as a maker reads it: the physical success on the table first, the model's score last."""
    if outlook is not None:
        print(f"{problem.name}: " + success_headline(outlook, when=f"placed by the guide, {outlook.samples} "
                                                     "simulations"))
    lead = f"{problem.name}:" if outlook is None else " "
    works = "works" if result.simulated_success else "FAILS"
    print(f"{lead} the layout {works} in simulation; {result.n_simulations} simulations "
          f"({result.n_new_simulations} new), {result.seconds:.1f} s -> {out}")
    for name, value in zip(problem.parameter_names, problem.to_real(result.u)):
        print(f"  {name:24s} {value: .5g}")
    _print_verification(result)
    warning = disagreement(result.psp, outlook.probability if outlook is not None else
                           float(result.simulated_success), outlook.samples if outlook is not None else None)
    if warning:
        print(f"note: {warning}")
    print(f"detail: the success model's own score (predicted PSP) {result.psp:.3f}, per event:")
    for name, p in zip(result.factor_names, result.factor_probabilities):
        print(f"  P({name}) = {p:.3f}")


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


@command
def run_robustness(args) -> int:
    service.check_seed(args.seed)
    service.check_count(args.eval, "n_evaluation")
    if args.plot is not None:
        check_output_file(args.plot, {".png"}, "--plot")
    problem = _problem(args)
    layout = read_layout(args.layout, problem)
    report_layout(layout, sys.stderr)
    u = np.clip(problem.to_normalized(layout.x), 0.0, 1.0)
    service.check_count(args.local, "n_local")
    settings = RobustnessSettings(n_evaluation=args.eval, n_local=args.local)
    n_evaluation, n_local = settings.n_evaluation, settings.n_local
    # Minutes at the defaults on a small machine: say what will run and how to make it shorter before starting.
    print(f"{problem.name}: {n_evaluation} evaluation layouts + {n_local} local ones = {n_evaluation + n_local} "
          "simulations at most (cached ones are not run again); fewer, and faster, with --eval N and --local N",
          file=sys.stderr)
    bar = args.bar
    where = _where(args)
    with service.simulations(problem, **where) as executor:
        run = service.RobustnessRun(problem, u, settings, args.seed, executor, report=where["report"])
        bar.expect(n_evaluation, "valid evaluation layouts")
        plan = run.draw()
        bar.note(f"{plan.cached} of the {plan.layouts} simulations are cached; {plan.new} to run")
        bar.expect(plan.new, "new simulations", done=lambda progress: executor.n_simulated)
        measured = run.simulate()
    bar.close()
    curve, evaluation = measured.curve, measured.evaluation
    if args.plot is not None:
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


@command
def run_compare(args) -> int:
    methods = service.parse_methods(args.methods)
    service.check_seed(args.seed)
    service.check_count(args.runs, "runs")
    service.check_count(args.eval, "n_evaluation")
    if args.plot is not None:
        check_output_file(args.plot, {".png"}, "--plot")
    service.check_count(args.local, "n_local")
    robustness = RobustnessSettings(n_evaluation=args.eval, n_local=args.local)
    problem = _problem(args)
    budget = default_budget(problem, args.budget)
    bar = args.bar
    request = service.ComparisonRequest(budget, psp_settings(args.settings), tuple(methods), args.runs, args.seed,
                                        robustness, workers=args.workers, scheduler=args.scheduler)
    comparison = service.compare(
        problem, request, report=_where(args)["report"],
        on_run=lambda run: bar.note(f"{run.method} seed {run.seed}: rho_g {run.curve.global_robustness:.3f}, "
                                    f"{run.n_simulations} simulations, {run.seconds:.1f} s"))
    bar.close()
    rows = comparison.table()
    if args.plot is not None:
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
