"""``station loop``: the whole station loop, unattended, on the simulated world (issue 21)."""

from __future__ import annotations

import sys

from station.cli_util import emit_json, flag_error
from station.commands.robust import add_command, command
from station.services.errors import ServiceError

_FLAGS = {"attempts": "--attempts", "loops": "--loops", "budget": "--budget",
          "reoptimize_budget": "--reoptimize-budget", "candidates": "--candidates",
          "prediction_weight": "--prediction-weight", "rounds": "--rounds",
          "baseline": "--baseline", "predict_samples": "--predict-samples", "fit_draws": "--fit-draws",
          "fit_sobol": "--fit-sobol", "fit_rounds": "--fit-rounds", "fit_prior_width": "--fit-prior-width",
          "camera": "--camera", "world": "--world",
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
                  "ballrun --world 'sim://world?seed=3&place_mm=3' --attempts 8 --loops 3 --json"],
    )
    parser.add_argument("scenario", help="a scenario file (.toml/.json) or an example name")
    parser.add_argument("--world", required=True, metavar="URL",
                        help="the simulated world: sim://world?seed=S[&place_mm=2&place_deg=2&fix_mm=0.5&fix_deg=0.5"
                        "&highlight=0.5&friction=0.7,1.3&restitution=0.15&damping=0.5,2]")
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
    parser.add_argument("--prediction-weight", type=float, default=defaults.prediction_weight, metavar="W",
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
    parser.add_argument("--fit-prior-width", type=float, default=defaults.fit_prior_width, metavar="W",
                        help="calibration: the prior around the scenario's values, a share of each range (default "
                        "%(default)s; 0: none, maximum likelihood)")
    parser.add_argument("--camera", default=defaults.camera, metavar="URL",
                        help="the simulated camera (default %(default)s)")
    parser.add_argument("--settings", default=defaults.settings, choices=("recommended", "thesis"),
                        help="the optimizer's PSP settings (default %(default)s)")
    parser.add_argument("--workers", type=int, default=None, help="local worker processes (default: all cores)")
    parser.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                        help="run simulations on a Dask distributed cluster instead of local processes")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")


def _physics(values) -> str:
    return ", ".join(f"{k} {v:.3g}" for k, v in values.items()) or "none uncertain"


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
                            fit_prior_width=args.fit_prior_width, camera=args.camera,
                            settings=args.settings, workers=args.workers, scheduler=args.scheduler)
    out = sys.stderr if args.json else sys.stdout

    def said(summary) -> None:
        args.bar.close()
        lo, hi = summary.interval
        predicted, forecast = summary.predicted_success, summary.forecast_success
        with_record = ("" if forecast is None or predicted is None or abs(forecast - predicted) < 5e-3
                       else f", {forecast:.2f} with its record")
        print(f"loop {summary.loop}: {summary.attempts} attempts, {summary.successes} successes: success rate "
              f"{summary.success_rate:.2f} (95 % {lo:.2f} to {hi:.2f}), predicted "
              f"{'-' if predicted is None else f'{predicted:.2f}'}{with_record}; {summary.check_rounds:.1f} "
              f"corrections per attempt; physics: {summary.physics_name or 'the scenario'} "
              f"({_physics(summary.physics)}){summary.choice}", file=out)

    try:
        result = run(args.scenario, args.world, settings, progress=args.bar, should_stop=args.stop.is_set,
                     on_loop=said)
    except ServiceError as error:
        raise flag_error(error, _FLAGS) from None
    args.bar.close()
    if result.baseline_attempts:
        print(f"baseline (optimized layout, printed sheet, no check, no calibration): {result.baseline_attempts} "
              f"attempts, {result.baseline_successes} successes: success rate {result.baseline_rate:.2f}", file=out)
    print(f"run {result.run_id} in the station database; its trials are in the trial log (station trial list "
          f"--scenario {result.scenario!r})", file=out)
    if args.json:
        emit_json(result.to_json())
    return 0
