"""``station trial log|list|show|export|import``: the log of physical runs of contraptions."""

from __future__ import annotations

import sqlite3
import sys

from station.cli_util import emit_json
from station.db import WRITE_PATIENCE_SECONDS
from station.errors import ServiceError, StationError, UsageError
from station.progress_view import ProgressView
from station.services.reporting import Cancelled, Reporter
from station.services.trials import (
    TrialKept,
    build_trial,
    check_photos,
    describe_trial,
    export_trials,
    import_trials,
    load_trial_scenario,
    log_trial,
    open_store,
    parse_outcomes,
    parse_times,
    pending_files,
    read_as_built,
    read_layout_values,
    read_physics,
    trial_line,
)

#: A service field's command-line flag (``outcome.EVENT`` becomes ``--outcome EVENT``).
_FLAGS = {"outcome": "--outcome", "time": "--time", "as_built": "--as-built", "physics": "--physics",
          "photo": "--photo", "out": "--out", "id": "ID", "file": "FILE", "predict": "--predict", "who": "--who",
          "notes": "--notes"}


def _usage(error: ServiceError) -> UsageError:
    """A service refusal as the command line says it: ``outcome.ball_rolls: ...`` -> ``--outcome ball_rolls: ...``."""
    message = str(error)
    head, dot, rest = (error.field or "").partition(".")
    flag = _FLAGS.get(head)
    if flag and message.startswith(error.field or ""):
        message = f"{flag} {rest}{message[len(error.field):]}" if dot else f"{flag}{message[len(head):]}"
    return UsageError(message)


def register(subparsers) -> None:
    trial = subparsers.add_parser(
        "trial", help="the log of physical runs: log, list, show, export, import",
        description="Physical trials of contraptions: what happened to each event of the causal graph in a real "
        "run, the layout as designed and as built, the physics used. `log` records a run, `list` and `show` read "
        "the log, `export` writes it as JSON and `import` reads such a file back. The log lives in the station "
        "database (CHAOS_STATION_DATABASE or [database] url in station.toml: the local SQLite file, or a "
        "PostgreSQL database several stations share).")
    actions = trial.add_subparsers(dest="trial_command", metavar="ACTION")
    log = actions.add_parser(
        "log", help="record a physical run",
        description="Record one physical run of SCENARIO at LAYOUT. Give each event's outcome with --outcome "
        "EVENT=yes|no|not-reached. Implied outcomes may be left out: events after one that did not happen are "
        "not-reached, and the events a 'yes' needed (its parents) happened. Every other event is required. "
        "Success is the goal: every leaf event happened. Prints the trial's id. While another station process "
        f"writes to the database it waits (up to {WRITE_PATIENCE_SECONDS:g} s); a trial the database cannot take "
        "is kept in the data folder (pending-trials/) and logged first by the next `station trial log`.",
        epilog="examples:\n"
        "  station trial log simple success --outcome last_stops=yes --time last_topples=1.4\n"
        "  station trial log simple layout.json --outcome first_topples=no --as-built check.json --who ann "
        "--photo run3.jpg",
    )
    log.add_argument("scenario", metavar="SCENARIO", help="a scenario file (.toml/.json) or an example name")
    log.add_argument("layout", metavar="LAYOUT", help="the layout as designed: a layout file (the LAYOUT.json of "
                     "`station optimize`, {\"parameters\": {...}}) or a layout named in the scenario (success)")
    log.add_argument("--outcome", action="append", default=[], metavar="EVENT=yes|no|not-reached",
                     help="what happened to an event (repeatable)")
    log.add_argument("--time", action="append", default=[], metavar="EVENT=SECONDS",
                     help="when an event that happened happened, seconds from the start, at most the scenario's "
                     "[settings] max_duration (repeatable)")
    log.add_argument("--as-built", metavar="CHECK.json|LAYOUT.json",
                     help="the layout as built: the as-built check's CHECK.json (of this scenario and layout) "
                     "or a layout file")
    log.add_argument("--physics", metavar="PROFILE.toml", help="the physics profile the run was predicted with")
    log.add_argument("--who", metavar="NAME", help="who ran it (plain text: no control or bidirectional characters)")
    log.add_argument("--notes", metavar="TEXT", help="anything worth remembering (new lines and tabs allowed)")
    log.add_argument("--photo", action="append", default=[], metavar="PATH", help="a photo of the run (repeatable)")
    log.add_argument("--predict", type=int, default=48, metavar="N",
                     help="after logging, predict the physical success and expected attempts of the layout (as "
                     "built when --as-built is given, under --physics) from N simulations (default 48; 0: none)")
    log.add_argument("--json", action="store_true",
                     help='print {"id": ...} (with --predict, also "physical_success": what `station predict` says)')
    log.set_defaults(func=run_log)

    listing = actions.add_parser("list", help="list logged trials, oldest first",
                                 description="List the logged trials, oldest first: id, when, scenario, success, "
                                 "events that happened, as designed or as built, physics, who.",
                                 epilog="example: station trial list --scenario SIMPLE --json")
    listing.add_argument("--scenario", metavar="NAME", help="only trials of this scenario (its name)")
    listing.add_argument("--json", action="store_true", help="print a JSON list of trials (the export's form)")
    listing.set_defaults(func=run_list)

    show = actions.add_parser("show", help="one trial in full",
                              description="Show one trial: when, who, success, every event's outcome in the causal "
                              "graph's order with its time, the layout as designed and as built, notes, photos.",
                              epilog="example: station trial show 1")
    show.add_argument("id", metavar="ID", type=int, help="the trial's id (`station trial list`)")
    show.add_argument("--json", action="store_true", help="print the trial as JSON (the export's form)")
    show.set_defaults(func=run_show)

    export = actions.add_parser(
        "export", help="write the log to JSON or CSV",
        description="Write every trial (or one scenario's) to FILE.json (the trial export, which `station trial "
        "import` and simulator calibration read) or FILE.csv (one row per trial, for a spreadsheet: every cell "
        "quoted, and text that a spreadsheet would run as a formula, starting with = + - @, gets a leading ').",
        epilog="example: station trial export --out trials.json")
    export.add_argument("--out", required=True, metavar="FILE.json|FILE.csv", help="the file to write")
    export.add_argument("--scenario", metavar="NAME", help="only trials of this scenario (its name)")
    export.add_argument("--json", action="store_true", help='print {"file": ..., "trials": N}')
    export.set_defaults(func=run_export)

    importing = actions.add_parser(
        "import", help="add the trials of a JSON export",
        description="Add the trials of a JSON export (another station's, a backup). Trials already in the log "
        "(the same uid) are refused, the others added; a file of another format or version adds nothing.",
        epilog="example: station trial import trials.json")
    importing.add_argument("file", metavar="FILE.json", help="a `station trial export` JSON file")
    importing.add_argument("--json", action="store_true", help='print {"added": [ids], "duplicates": [uids]}')
    importing.set_defaults(func=run_import)


def run_log(args) -> int:
    try:
        outcomes = parse_outcomes(args.outcome)
        times = parse_times(args.time)
        scenario = load_trial_scenario(args.scenario)
        layout = read_layout_values(scenario, args.layout)
        as_built, check = read_as_built(args.as_built, scenario, layout) if args.as_built else (None, None)
        physics = read_physics(args.physics) if args.physics else None
        record = build_trial(scenario, layout, outcomes, times=times, as_built=as_built, check=check,
                             physics=physics, who=args.who, notes=args.notes, photos=check_photos(args.photo))
    except ServiceError as error:
        raise _usage(error) from None
    if args.predict < 0:
        raise UsageError(f"--predict: expected a number of simulations >= 0, got {args.predict}")
    try:
        logged = log_trial(record, on_wait=lambda message: print(f"station: {message}", file=sys.stderr))
    except TrialKept as kept:  # what the maker typed is in a file (or, failing that, on stdout): say where
        if kept.path is None:
            emit_json(kept.document)
        print(f"station: error: {kept}", file=sys.stderr)
        return 130 if kept.interrupted else 2
    trial_id = logged.id
    for line in logged.problems:
        print(f"station: {line}", file=sys.stderr)
    if logged.delivered:
        print(f"station: also logged {len(logged.delivered)} trial(s) kept by an earlier run (ids "
              f"{', '.join(map(str, logged.delivered))})", file=sys.stderr)
    if not args.json:  # the id first: a prediction that fails or is stopped loses no run, nor its id
        print(trial_id, flush=True)
    outlook = _outlook(scenario, record, args.predict)
    if args.json:
        emit_json({"id": trial_id} if outlook is None else {"id": trial_id, "physical_success": outlook.to_json()})
    elif outlook is not None:
        # heavy: design.contraption.simulation, pybullet, scipy, shapely
        from station.services.predict import outlook_line

        print(f"trial {trial_id}: {outlook_line(outlook)}", file=sys.stderr)
    return 0


def _outlook(scenario, record, samples: int):
    """The physical success of the trial's layout, as built (``--predict N`` simulations; None for 0)."""
    if not samples:
        return None
    from station.services.predict import predict_trial  # heavy: design.contraption.simulation, pybullet, scipy, shapely

    try:
        with ProgressView(sys.stderr, prefix="predict: ") as view:
            return predict_trial(scenario, record, samples=samples, report=Reporter(view))
    except StationError as error:  # the trial is logged: say why there is no prediction, and go on
        print(f"no prediction: {error}", file=sys.stderr)
    except sqlite3.Error as error:  # the simulation cache, kept busy by another process
        print(f"no prediction: the simulation cache: {error}", file=sys.stderr)
    except (Cancelled, KeyboardInterrupt):
        print("no prediction: stopped (the trial is logged)", file=sys.stderr)
    return None


def run_list(args) -> int:
    with open_store() as store:
        trials = store.trials(scenario=args.scenario)
        where = store.where
    kept = pending_files()
    if kept:  # trials a busy or unreachable database could not take yet
        print(f"station: {len(kept)} trial(s) kept in {kept[0].parent} wait to be logged (the next `station trial "
              "log` logs them)", file=sys.stderr)
    if args.json:
        emit_json(trials)
        return 0
    if not trials:
        print(f"no trials{' of ' + args.scenario if args.scenario else ''} yet (database {where})")
        return 0
    for trial in trials:
        print(trial_line(trial))
    return 0


def run_show(args) -> int:
    try:
        with open_store() as store:
            trial = store.get(args.id)
    except ServiceError as error:
        raise _usage(error) from None
    if args.json:
        emit_json(trial)
    else:
        print("\n".join(describe_trial(trial)))
    return 0


def run_export(args) -> int:
    try:
        with open_store() as store:
            count = export_trials(store, args.out, scenario=args.scenario)
    except ServiceError as error:
        raise _usage(error) from None
    if args.json:
        emit_json({"file": args.out, "trials": count})
    else:
        print(f"{count} trial(s) written to {args.out}")
    return 0


def run_import(args) -> int:
    try:
        with open_store() as store:
            added, duplicates = import_trials(store, args.file)
    except ServiceError as error:
        raise _usage(error) from None
    if args.json:
        emit_json({"added": added, "duplicates": duplicates})
        return 0
    print(f"{len(added)} trial(s) added" + (f" (ids {added[0]}-{added[-1]})" if added else ""))
    if duplicates:
        print(f"{len(duplicates)} refused: already in the log ({', '.join(duplicates[:5])}"
              f"{', ...' if len(duplicates) > 5 else ''})")
    return 0
