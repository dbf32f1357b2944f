"""``station calibrate sim``: fit scenarios' uncertain material values to logged physical trials.

Not discovered on its own (the underscore): ``station calibrate``'s module calls :func:`add_sim_parser` with its
subparsers to add ``sim`` next to its other actions.
"""

from __future__ import annotations

import sys

from station.cli_util import NON_NEGATIVE, check_output_file, emit_json, flag_error
from station.commands.robust import _where, add_workers, command
from station.errors import ServiceError, UsageError
from station.services.contraption import open_scenario
from station.services.robust import check_seed

#: The flags of the service's fields where they are not ``--`` + the field.
FLAGS = {"trials_json": "--trials-json"}


def add_sim_parser(calibrate_subparsers, trials_source=None) -> None:
    """Add ``sim`` to ``station calibrate``'s subparsers.

    Parameters
    ----------
    calibrate_subparsers
        The ``add_subparsers()`` object of ``station calibrate``.
    trials_source : callable, optional
        ``() -> list of trial dicts`` (the export format) read when no ``--trials-json`` is given: the station's
        trial store. Without it, ``--trials-json`` is required.
    """
    parser = calibrate_subparsers.add_parser(
        "sim",
        help="fit the scenarios' uncertain material values (friction, restitution, damping) to logged trials",
        description="Fit the material values a scenario marks uncertain ({ value = V, range = [MIN, MAX] }) to the "
        "physical trials logged for it (`station trial log`), at their as-built layouts (or designed ones where no "
        "check was made), with the check's placement error: the most probable values given which events happened "
        "(and when, where timed) under the simulator and a prior centred on the scenario's values (a quarter of "
        "each range wide; --prior-width 0 for plain maximum likelihood), found with a Sobol design, a "
        "Gaussian-process surrogate and a local refinement. Prints each value with a 95 % interval, the agreement "
        "per event before and after, and the Brier score of the success probability on held-out trials before "
        "and after; --out saves a physics profile for --physics. --json prints {\"parameters\": [{\"name\", "
        "\"value\", \"interval\"}], \"trials\", \"brier_before\", \"brier_after\"}.",
        epilog="examples:\n  station calibrate sim simple --out simple-physics.toml\n"
        "  station calibrate sim simple ballrun --params wood.friction --draws 2 --trials 40 --json\n"
        "  station calibrate sim examples/scenarios/simple.toml --trials-json trials.json --out simple-physics.toml "
        "--workers 2",
    )
    parser.add_argument("scenarios", nargs="+", metavar="SCENARIO", help="scenario files or example names")
    parser.add_argument("--params", metavar="MATERIAL.PARAM,...", default=None,
                        help="the values to fit (default: every uncertain value of the scenarios)")
    parser.add_argument("--all-materials", action="store_true",
                        help="fit every material value, the plain numbers too (within a factor of 0.5 to 1.5 for "
                        "frictions, +-0.3 for restitution, 0.25 to 4 for damping)")
    parser.add_argument("--trials", type=int, default=None, metavar="N", help="use the last N trials only")
    parser.add_argument("--trials-json", metavar="EXPORT.json", default=None,
                        help="read the trials from a trial export (`station trial export --out`) instead of the "
                        "station's log")
    parser.add_argument("--out", metavar="PROFILE.toml", default=None, help="write the fitted physics profile")
    parser.add_argument("--draws", type=int, default=8, metavar="N",
                        help="placement draws simulated per trial and candidate (default %(default)s)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the placement draws and the design (default 0)")
    parser.add_argument("--prior-width", type=NON_NEGATIVE, default=0.25, metavar="W",
                        help="the prior's standard deviation as a share of each value's range, around the "
                        "scenario's value (default %(default)s; 0: no prior, maximum likelihood)")
    add_workers(parser)
    parser.add_argument("--json", action="store_true", help="print the result as JSON (shape in the description)")
    parser.set_defaults(func=run_calibrate_sim, trials_source=trials_source)


@command
def run_calibrate_sim(args) -> int:
    try:
        return _calibrate_sim(args)
    except ServiceError as error:
        raise flag_error(error, FLAGS) from None


def _calibrate_sim(args) -> int:
    # heavy: design.contraption.simulation, pybullet, scipy, shapely
    from station.services import sim_calibration as service

    check_seed(args.seed)
    if args.physics is not None:
        raise UsageError("--physics: calibrate sim fits the physics; it starts from the scenarios' own values")
    if args.out is not None:
        check_output_file(args.out, {".toml"}, "--out")
    if args.draws < 1:
        raise UsageError(f"--draws must be an integer >= 1, got {args.draws}")
    scenarios = [open_scenario(name) for name in args.scenarios]
    params = [p.strip() for p in args.params.split(",") if p.strip()] if args.params else None
    if args.trials_json is not None:
        trials, source = service.read_trials_json(args.trials_json), args.trials_json
    elif args.trials_source is not None:
        trials, source = args.trials_source(), "the trial log"
    else:
        raise UsageError("--trials-json EXPORT.json is required (this station has no trial log wired in)")
    where = _where(args)
    settings = service.FitSettings(draws=args.draws, seed=args.seed, prior_width=args.prior_width or None)
    request = service.SimCalibrationRequest(tuple(params) if params else None, args.trials, settings, source,
                                            args.all_materials, workers=where["workers"],
                                            scheduler=where["scheduler"])
    result = service.calibrate_sim(scenarios, trials, request, report=where["report"])
    args.bar.close()
    if args.out is not None:
        service.save(result, args.out)
        print(f"wrote {args.out}", file=sys.stderr)
    if args.json:
        emit_json(result.to_json())
        return 0
    print(format_result(result))
    return 0


def format_result(result) -> str:
    """The calibration as text: values with intervals, agreement per event, the predictive check."""
    fit = result.fit
    lines = [f"{', '.join(fit.scenarios)}: {fit.trials} trials fitted, {fit.held_out} held out; "
             f"{fit.simulations} simulations, {fit.candidates} candidate values",
             f"  {'parameter':24s} {'before':>8s} {'fitted':>8s}  95 % interval      range"]
    for p in fit.parameters:
        lines.append(f"  {p.name:24s} {p.before:8.4f} {p.value:8.4f}  [{p.interval[0]:.4f}, {p.interval[1]:.4f}]"
                     f"  [{p.range[0]:g}, {p.range[1]:g}]")
    prior = ("no prior (maximum likelihood)" if fit.prior_width is None
             else f"prior: the scenario's values, sd {fit.prior_width:g} of each range")
    lines.append(f"  log-likelihood {fit.log_likelihood_before:.2f} before, {fit.log_likelihood_after:.2f} after; "
                 f"{prior}")
    lines.append(f"  {'event':32s} {'observed':>8s} {'sim before':>10s} {'sim after':>9s} {'agree before':>12s} "
                 f"{'after':>6s}")
    for a in fit.agreement:
        lines.append(f"  {a.scenario + '.' + a.event:32s} {a.observed_yes:8.2f} {a.predicted_yes_before:10.2f} "
                     f"{a.predicted_yes_after:9.2f} {a.agreement_before:12.2f} {a.agreement_after:6.2f}")
    if fit.brier_before is None:
        lines.append("  predictive check: too few trials to hold some out (5 or more)")
    else:
        verdict = "better" if fit.brier_after < fit.brier_before else "not better"
        lines.append(f"  held-out Brier score of the success probability: {fit.brier_before:.4f} before, "
                     f"{fit.brier_after:.4f} after ({verdict})")
    return "\n".join(lines)
