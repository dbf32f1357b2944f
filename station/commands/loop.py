"""``station loop``: the whole station loop, unattended, on the simulated world.

What it prints is read by a maker: a line per attempt (what the check found and the simulated maker corrected, how
the run went), then per loop a few short lines and its physics as a small table; every line fits 120 columns.
"""

from __future__ import annotations

import shlex
import sys
import textwrap

from station.cli_util import NON_NEGATIVE, POSITIVE, emit_json, flag_error
from station.commands.robust import ProgressBar, add_command, command
from station.errors import ServiceError
from station.services.reporting import Cancelled, Reporter

#: The longest line the loop prints (a 120-column terminal; a longer line is wrapped, its rest indented).
WIDTH = 118

_FLAGS = {"attempts": "--attempts", "loops": "--loops", "budget": "--budget",
          "reoptimize_budget": "--reoptimize-budget", "candidates": "--candidates",
          "prediction_weight": "--prediction-weight", "rounds": "--rounds",
          "baseline": "--baseline", "predict_samples": "--predict-samples", "fit_draws": "--fit-draws",
          "fit_sobol": "--fit-sobol", "fit_rounds": "--fit-rounds", "fit_prior_width": "--fit-prior-width",
          "camera": "--camera", "side_camera": "--side-camera", "world": "--world",
          "settings": "--settings", "workers": "--workers", "scheduler": "--scheduler"}


def register(subparsers) -> None:
    from station.services.loop import LoopSettings

    defaults = LoopSettings()
    parser = add_command(
        subparsers, "loop", run_loop,
        help="run the whole station loop unattended on the simulated world (optimize, place, check, run, log, "
        "calibrate, re-optimize)",
        description="Run the station's whole loop on the simulated physical world (sim://world: hidden material "
        "values, a maker placing parts with human error). Loop 1 places the optimized layout; every attempt is "
        "placed with the projector highlighting the parts, checked by the simulated camera and corrected until "
        "within tolerance (at most --rounds corrections), run, and logged in the trial log with its check and its "
        "predicted physical success. After each loop the simulator is calibrated from every trial so far and the "
        "layout optimized again under the calibrated physics. Each time the loop places, among the optimizer's "
        "verified candidates and the layouts placed before, the one surest to succeed often under the physics "
        "it knows (loop 1: the scenario's values and ranges; later: the calibrated values and intervals) and, for a "
        "layout placed before, given its record (its prediction counts as --prediction-weight attempts): the "
        "highest lower quartile of its success's Beta posterior, so a layout with a record wins a near tie. "
        "The baseline is the thesis's workflow in the same "
        "world (the optimized layout from the printed sheet: no highlight, no check, no calibration). Everything "
        "is in the station database: the same command again resumes a stopped run and ends with the same figures "
        "(more --loops carry a finished run on).",
        examples=["simple --world 'sim://world?seed=1'",
                  "ballrun --world 'sim://world?seed=3&place_mm=3' --attempts 8 --loops 3 --json",
                  "causalityswitch_ball --world 'sim://world?seed=2&ruler_mm=1' --jigs"],
    )
    parser.add_argument("scenario", help="a scenario file (.toml/.json) or an example name")
    parser.add_argument("--world", required=True, metavar="URL",
                        help="the simulated world: sim://world?seed=S[&place_mm=2&place_deg=2&highlight=0.5"
                        "&ruler_mm=1.5&ruler_deg=2&jig_mm=0.2&jig_deg=0.2&fix_mm=0.5&fix_deg=0.5&friction=0.7,1.3"
                        "&restitution=0.15&damping=0.5,2]: the maker sets each parameter as the guide says (on the "
                        "sheet, with a ruler, on a jig, after a check), each with its own error")
    parser.add_argument("--attempts", type=int, default=defaults.attempts, metavar="N",
                        help="attempts per loop (default %(default)s)")
    parser.add_argument("--loops", type=int, default=defaults.loops, metavar="K", help="loops (default %(default)s)")
    parser.add_argument("--budget", type=int, default=defaults.budget, metavar="N",
                        help="simulations of loop 1's optimization (default: station optimize's, the thesis's "
                        "budget for the scenario; made once and cached for every world)")
    parser.add_argument("--reoptimize-budget", type=int, default=defaults.reoptimize_budget, metavar="N",
                        help="simulations of each later loop's optimization under the calibrated physics "
                        "(default: station optimize's, the thesis's budget for the scenario)")
    parser.add_argument("--candidates", type=int, default=defaults.candidates, metavar="N",
                        help="layouts of each optimization compared by predicted physical success; the loop places "
                        "the best (default %(default)s)")
    parser.add_argument("--prediction-weight", type=POSITIVE, default=defaults.prediction_weight, metavar="W",
                        help="what a layout's predicted success is worth against its record on the table, in "
                        "attempts (default %(default)s: fitted to the bench's loops)")
    parser.add_argument("--uncertain-only", action="store_true",
                        help="treat only the material values the scenario marks uncertain as unknown (default: every "
                        "material value, the plain numbers within a default range, in loop 1's choice and in "
                        "every calibration)")
    parser.add_argument("--rounds", type=int, default=defaults.rounds, metavar="R",
                        help="corrections after the first check at most (default %(default)s)")
    parser.add_argument("--baseline", type=int, default=None, metavar="N",
                        help="attempts of the baseline (default: --attempts; 0: none)")
    parser.add_argument("--predict-samples", type=int, default=defaults.predict_samples, metavar="N",
                        help="simulations per attempt's predicted success (default %(default)s)")
    parser.add_argument("--fit-draws", type=int, default=defaults.fit_draws, metavar="N",
                        help="calibration: placement draws per trial and candidate (default %(default)s)")
    parser.add_argument("--fit-sobol", type=int, default=defaults.fit_sobol, metavar="N",
                        help="calibration: candidates of the initial design (default %(default)s)")
    parser.add_argument("--fit-rounds", type=int, default=defaults.fit_rounds, metavar="N",
                        help="calibration: refinement rounds (default %(default)s)")
    parser.add_argument("--fit-prior-width", type=NON_NEGATIVE, default=defaults.fit_prior_width, metavar="W",
                        help="calibration: the prior around the scenario's values, a share of each range (default "
                        "%(default)s; 0: none, maximum likelihood)")
    parser.add_argument("--camera", default=defaults.camera, metavar="URL",
                        help="the simulated camera (default %(default)s)")
    parser.add_argument("--side-camera", default=defaults.side_camera, metavar="URL",
                        help="the simulated side camera facing the board behind the parts, used with --jigs "
                        "(default %(default)s)")
    parser.add_argument("--settings", default=defaults.settings, choices=("recommended", "thesis"),
                        help="the optimizer's PSP settings (default %(default)s)")
    parser.add_argument("--workers", type=int, default=None, help="local worker processes (default: all cores)")
    parser.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                        help="run simulations on a Dask distributed cluster instead of local processes")
    parser.add_argument("--jigs", action="store_true",
                        help="the loop's attempts use the layout's laser-cut jigs: per loop the simulated maker cuts "
                        "them on the laser twin (their laser job run to its end), lays each on its outline and sets "
                        "its part on it, and every check also uses the side camera (--side-camera): it reads the "
                        "face tag of each jig stand facing the board, measures the heights and tilts of the parts on "
                        "them, and the maker sets those again as it says (the baseline never does)")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")


class LoopBar(ProgressBar):
    """The robust commands' bar saying ``stage: done/total unit`` on a terminal too: a loop's stage is a phrase
    ("loop 2: calibrating the simulator from 5 trials") and what it counts changes from stage to stage."""

    def _describe(self, progress) -> str:
        unit = getattr(progress, "unit", "simulations")
        counts = f" {progress.done:g}/{progress.total:g} {unit}" if progress.total else ""
        return f"{progress.stage}:{counts}"


def wrapped(lines) -> list[str]:
    """``lines`` each within :data:`WIDTH`, a long one's rest indented two spaces more than it."""
    out = []
    for line in lines:
        indent = " " * (len(line) - len(line.lstrip(" ")) + 2)
        out += textwrap.wrap(line, WIDTH, subsequent_indent=indent, break_on_hyphens=False) or [""]
    return out


def physics_table(values, indent: str = "    ") -> list[str]:
    """The material values as a compact table: ``name value`` cells, as many a line as fit."""
    if not values:
        return [f"{indent}none uncertain"]
    name_width = max(len(name) for name in values)
    cells = [f"{name:<{name_width}}  {value:<8.3g}" for name, value in values.items()]
    per_line = max(1, (WIDTH - len(indent)) // (len(cells[0]) + 3))
    return [indent + "   ".join(cells[i:i + per_line]).rstrip() for i in range(0, len(cells), per_line)]


def loop_lines(summary) -> list[str]:
    """A loop's figures in short lines: its success rate, the predicted physical success, why its layout was
    placed, the corrections, and its physics as a table."""
    lo, hi = summary.interval
    lines = [f"loop {summary.loop}: {summary.successes} of {summary.attempts} attempts succeeded: success rate "
             f"{summary.success_rate:.2f} (95 % {lo:.2f} to {hi:.2f})"]
    predicted, forecast = summary.predicted_success, summary.forecast_success
    if predicted is not None:
        record = ("" if forecast is None or abs(forecast - predicted) < 5e-3
                  else f"; {forecast:.2f} with the layout's record")
        lines.append(f"  predicted physical success on the table: {predicted:.2f} (the attempts' mean, as checked)"
                     f"{record}")
    # no choice: the optimization had no other candidate that worked in its simulations (or --candidates 1)
    choice = summary.choice.removeprefix("; ") or "the optimizer's own, no other candidate to compare"
    lines.append(f"  layout placed: {choice}")
    lines.append(f"  corrections: {summary.check_rounds:.1f} per attempt after the first check")
    if summary.jigs:
        lines.append("  jigs: cut on the laser, each part one can carry set on it, its height and tilt checked by "
                     "the side camera (each trial's notes name the jigs, the parts no jig can carry and what the side "
                     "camera measured)")
    physics = summary.physics_name or "the scenario's values and ranges (before any trial)"
    lines.append(f"  physics: {physics}")
    return wrapped(lines) + physics_table(summary.physics)


def baseline_lines(result) -> list[str]:
    """The baseline's figures in short lines."""
    lo, hi = result.baseline_interval
    return wrapped([f"baseline: {result.baseline_successes} of {result.baseline_attempts} attempts succeeded: "
                    f"success rate {result.baseline_rate:.2f} (95 % {lo:.2f} to {hi:.2f})",
                    "  the thesis's workflow: the optimized layout placed from the printed sheet, no check, no "
                    "calibration"])


def resume_command(args) -> str:
    """The command that resumes this run: the scenario, the world and every option given a value other than its
    default (the run is keyed by them), quoted for a shell."""
    from station.services.loop import LoopSettings

    defaults = LoopSettings()
    words = ["station", "loop", args.scenario, "--world", args.world]
    for name, flag in _FLAGS.items():
        value = getattr(args, name)
        if name != "world" and value != getattr(defaults, name):
            words += [flag, str(value)]
    words += ["--uncertain-only"] * args.uncertain_only + ["--jigs"] * args.jigs + ["--json"] * args.json
    return shlex.join(words)


def stopped_lines(stopped, args) -> list[str]:
    """What a stopped run says (on stderr): what it logged (the stop's ``partial``, the run's log), what the cache
    keeps, and the command that resumes it."""
    log = stopped.partial
    lines = wrapped([f"station: stopped run {log.run_id}: {log.logged_words()}, each with its trial "
                     "in the trial log"])
    if stopped.new_simulations:
        lines += wrapped([f"station: the {stopped.new_simulations} new simulations of this run are kept in the cache "
                          f"({stopped.cache})"])
    return lines + [f"station: the same command resumes it: {resume_command(args)}"]  # one line, to copy whole


@command
def run_loop(args) -> int:
    from station.services.loop import LoopSettings
    from station.services.loop import run_loop as run

    settings = LoopSettings(attempts=args.attempts, loops=args.loops, budget=args.budget,
                            reoptimize_budget=args.reoptimize_budget, candidates=args.candidates,
                            prediction_weight=args.prediction_weight,
                            every_material=not args.uncertain_only, rounds=args.rounds,
                            baseline=args.baseline, predict_samples=args.predict_samples, fit_draws=args.fit_draws,
                            fit_sobol=args.fit_sobol, fit_rounds=args.fit_rounds,
                            fit_prior_width=args.fit_prior_width, camera=args.camera, side_camera=args.side_camera,
                            settings=args.settings, jigs=args.jigs, workers=args.workers, scheduler=args.scheduler)
    out = sys.stderr if args.json else sys.stdout
    # the command's own bar (the wrapper closes whichever args.bar holds)
    args.bar = LoopBar()

    def say(lines) -> None:
        # the bars of the work said go (on a terminal), so the lines read as the run's record
        args.bar.close(clear=True)
        print("\n".join(lines), file=out, flush=True)

    def started(log) -> None:
        if log.resumed:
            say([log.resuming()])

    try:
        result = run(args.scenario, args.world, settings, report=Reporter(args.bar, stop=args.stop.is_set),
                     on_start=started, on_loop=lambda summary: say(loop_lines(summary)),
                     on_attempt=lambda attempt: say(wrapped([attempt.describe()])))
    except ServiceError as error:
        raise flag_error(error, _FLAGS) from None
    except Cancelled as stopped:
        if stopped.partial is None:
            raise
        args.bar.close(clear=True)
        print("\n".join(stopped_lines(stopped, args)), file=sys.stderr, flush=True)
        raise KeyboardInterrupt from None  # exit 130, as every interrupted command
    args.bar.close(clear=True)
    if result.baseline_attempts:
        say(baseline_lines(result))
    say(wrapped([f"run {result.run_id} in the station database; its trials are in the trial log (station trial "
                 f"list --scenario {result.scenario!r})"]))
    if args.json:
        emit_json(result.to_json())
    return 0
