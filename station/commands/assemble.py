"""``station assemble``: walk a maker through one physical attempt, prompt by prompt.

guide (sheet or projector) -> place -> check (-> fix -> check)* -> run -> what happened -> log. The steps are
:mod:`station.services.assemble`'s (shared with the Assemble screen); this module asks and says. Every answer is
validated, a bad one said in one line and asked again; Ctrl-C or the end of the input leaves having logged nothing.
"""

from __future__ import annotations

import os
import sys

from station.cli_util import check_output_file, flag_error
from station.errors import ServiceError, UsageError
from station.services.reporting import Cancelled, Reporter

FLAGS = {"world": "--world", "camera": "--camera", "physics": "--physics", "samples": "--samples",
         "attempt": "--attempt", "seed": "--seed", "projector": "--projector"}
#: What a maker may answer for an event, and the outcome word it stands for.
ANSWERS = {"y": "yes", "yes": "yes", "n": "no", "no": "no", "u": "not-reached", "not-reached": "not-reached",
           "not reached": "not-reached"}


class Quit(Exception):
    """The maker left (q, the end of the input, Ctrl-C): nothing is logged."""


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "assemble", help="walk through one physical attempt: guide, place, check, run, log the trial",
        description="Walk a maker through one attempt of a layout on the station's devices (station.toml; every "
        "one simulated by default): the guide step by step (--sheet writes the 1:1 PDF sheets to print; "
        "--project shows each step on the projector), placing the parts, the camera check (repeated until every "
        "part is within its tolerance or the maker accepts), the run (the maker says for each event of the causal "
        "graph, in order, whether it happened: y, n, or u for not reached; with a simulated world, --world "
        "sim://world?seed=S, the world places the parts with a maker's error, applies the check's moves, runs "
        "the contraption and reports), and logs the trial with its CHECK.json and physics profile. Before and "
        "after the check and after the run it prints the predicted physical success and the expected attempts. "
        "With --jigs a side camera facing the board sheet behind the parts (`station guide --jigs` prints it) checks "
        "the heights and tilts of the parts on jig stands, as `station check` does with two cameras: give it as a "
        "second --camera, or name both cameras in station.toml; with a simulated world and no side camera named, "
        "the world's own side camera (sim://camera?view=side&height=700&tilt=-20) does. "
        "q, Ctrl-C or the end of the input leave having logged nothing.",
        epilog="examples:\n"
        "  station assemble ballrun ballrun-layout.json --project\n"
        "  station assemble simple success --world 'sim://world?seed=3' --physics simple-physics.toml "
        "--sheet guide.pdf\n"
        "  station assemble causalityswitch_ball success --world 'sim://world?seed=2' --jigs\n"
        "  station assemble simple success --world 'sim://world?seed=3' --jigs --camera sim://camera "
        "--camera 'sim://camera?view=side&height=700&tilt=-20'\n"
        "  printf 's\\n\\na\\n\\ny\\n' | station assemble simple success --world sim://world\n"
        "    (the answers piped: s skips the guide's steps, Enter: placed, a: run as placed, Enter: run, y: log it)",
        formatter_class=__import__("argparse").RawDescriptionHelpFormatter,
    )
    parser.add_argument("scenario", help="scenario file, or an example's name (simple, ballrun, ...)")
    parser.add_argument("layout", help="the layout to build (LAYOUT.json, or a layout named in the scenario)")
    parser.add_argument("--camera", metavar="URL", action="append", help="the camera (default: the station's, "
                        "`station devices`); give it twice for a side camera facing the board (sim://camera?view=side"
                        ", or a real camera whose frame shows the board's tags), as `station check --camera` takes "
                        "them: it measures the heights and tilts of the parts on jig stands (--jigs)")
    parser.add_argument("--projector", metavar="URL", help="the projector (default: the station's) for --project")
    parser.add_argument("--world", metavar="URL", help="a simulated world (sim://world?seed=S): it places, runs and "
                        "reports; default none (a real table: the maker does and says)")
    parser.add_argument("--physics", metavar="PROFILE.toml", help="a physics profile (`station calibrate sim "
                        "--out`): tolerances and predictions use it, the trial stores it")
    guide = parser.add_mutually_exclusive_group()
    guide.add_argument("--sheet", nargs="?", const="", metavar="GUIDE.pdf", help="write the guide's 1:1 PDF "
                       "sheets (default: the station's data folder, guides/) and step through them here (default)")
    guide.add_argument("--project", action="store_true", help="show each step on the projector")
    parser.add_argument("--jigs", action="store_true", help="the guide's steps use the layout's laser-cut jigs "
                        "(`station jigs` writes them; cut them first); with --world the simulated maker cuts them on "
                        "the laser twin and sets the parts on them")
    parser.add_argument("--attempt", type=int, metavar="N", help="this attempt's number (default: one more than "
                        "the scenario's logged trials; a simulated maker's errors are seeded by it)")
    parser.add_argument("--samples", type=int, default=60, metavar="N", help="simulations per prediction "
                        "(default %(default)s)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the predictions' simulations (default 0)")
    parser.add_argument("--workers", type=int, metavar="N", help="simulation processes (default: all cores)")
    parser.add_argument("--who", metavar="NAME", help="who builds it (stored with the trial)")
    parser.add_argument("--max-checks", type=int, default=5, metavar="N", help="checks before the run is only "
                        "possible by accepting the parts as placed (default %(default)s)")
    parser.add_argument("--json", action="store_true", help="say the prompts on stderr and print the logged attempt "
                        "as one JSON document on stdout: scenario, layout, attempt, trial_id, success, outcomes, "
                        "times, checks (each check's CHECK.json), fixes, forecasts")
    parser.set_defaults(func=run_assemble)


def run_assemble(args) -> int:
    from station.progress_view import ProgressView
    from station.services import assemble as service

    if args.max_checks < 1:
        raise UsageError(f"--max-checks must be an integer >= 1, got {args.max_checks}")
    if args.sheet:  # "" (--sheet alone): the data folder's guides/
        check_output_file(args.sheet, {".pdf"}, "--sheet")
    cameras = args.camera or []
    if len(cameras) > 2:
        raise UsageError(f"--camera: at most two cameras (the table's, and a side camera facing the board), got "
                         f"{len(cameras)}")
    out = sys.stderr if args.json else sys.stdout
    projector_context = None
    assembly = None
    try:
        projector = None
        if args.project:
            projector_context, projector = _open_projector(args.projector)
        with ProgressView(sys.stderr, prefix="guide: ") as view:  # the tolerance map may take a while
            request = service.AssemblyRequest(args.scenario, args.layout, camera=cameras[0] if cameras else None,
                                              side_camera=cameras[1] if len(cameras) > 1 else None, world=args.world,
                                              physics=args.physics, attempt=args.attempt, samples=args.samples,
                                              seed=args.seed, workers=args.workers, jigs=args.jigs)
            assembly = service.open_assembly(request, projector=projector, report=Reporter(view))
        _walk(assembly, args, out)
        if args.json:
            from station.cli_util import emit_json

            emit_json(attempt_json(assembly))
    except ServiceError as error:
        raise flag_error(error, FLAGS) from None
    except (Quit, KeyboardInterrupt, Cancelled) as stop:
        # Ctrl-C (or kill) while a forecast simulates comes back as the runner's Cancelled
        interrupted = not isinstance(stop, Quit)
        out.write(f"\n{'stopped' if interrupted else str(stop) or 'left'}: nothing logged\n")
        return 130 if interrupted else 1
    finally:
        if assembly is not None:
            assembly.close()
        if projector_context is not None:
            projector_context.__exit__(None, None, None)
    return 0


def attempt_json(assembly) -> dict:
    """The ``--json`` document of a logged attempt."""
    job = assembly.job
    return {"scenario": assembly.scenario.name, "layout": job.layout.describe(), "attempt": assembly.attempt,
            "trial_id": assembly.trial_id, "success": assembly.success, "outcomes": dict(assembly.outcomes),
            "times": dict(assembly.times), "checks": [c.to_json() for c in assembly.checks], "fixes": assembly.fixes,
            "forecasts": [f.to_json() for f in assembly.forecasts],
            "jigs": [] if job.jigs is None else [jig.id for jig in job.jigs.plan.jigs]}


def _open_projector(url: str | None):
    from station.services.projectors import open_projector, projector_device

    device = projector_device(url)  # None: the configured one
    if device is None:
        raise UsageError("--project: no projector configured (add one to station.toml, or give --projector URL)")
    context = open_projector(device)
    return context, context.__enter__()


def ask(prompt: str, out, choices: dict[str, str] | None = None) -> str:
    """One answer from the maker (``choices``: accepted words -> what they mean; anything else is said and asked
    again). q leaves; the end of the input leaves too."""
    while True:
        out.write(prompt)
        out.flush()
        line = sys.stdin.readline()
        if not line:
            raise Quit("the input ended")
        if not sys.stdin.isatty():  # piped answers: said after their prompt, so that the transcript reads
            out.write(line if line.endswith("\n") else line + "\n")
        answer = line.strip().lower()
        if answer == "q":
            raise Quit("left")
        if choices is None:
            return answer
        if answer in choices:
            return choices[answer]
        words = ", ".join(repr(k) if k else "Enter" for k in choices)
        out.write(f"  {answer!r} is not an answer here; expected one of: {words}\n")


def _clear(out, assembly) -> None:
    """Clear the terminal between stages (only a terminal: a pipe or a log keeps every line) and say again what is
    built and the last forecast, so that they stay in view."""
    if out.isatty() and os.environ.get("TERM", "dumb") != "dumb":
        out.write("\x1b[2J\x1b[H")
        out.write(f"{assembly.job.guide.scenario}, attempt {assembly.attempt}: {assembly.stage}\n")
        if assembly.forecasts:
            out.write(f"  {assembly.forecasts[-1].line()}\n")
        out.write("\n")


def _forecast(assembly, out) -> None:
    out.write(f"  {assembly.forecast().line()}\n")


def _walk(assembly, args, out) -> None:
    job = assembly.job
    world = f"world {args.world} (a simulated maker places and runs)" if assembly.world is not None else \
        "a real table (you place, run and say)"
    out.write(f"{job.guide.scenario}: {job.layout.describe()}, {len(assembly.parts)} parts, attempt "
              f"{assembly.attempt}; {world}\n")
    if job.jigs is not None:
        made = ", ".join(f"{jig.id} for `{jig.part}`" for jig in job.jigs.plan.jigs) or "none can be made"
        cut = " (the simulated maker cut them on the laser)" if assembly.world is not None and job.jigs.plan.jigs \
            else ""
        out.write(f"laser-cut jigs: {made}{cut}\n")
    cameras = assembly.cameras()
    if len(cameras) > 1:
        out.write(f"cameras: {', '.join(f'{name} ({url})' for name, url in cameras)}: the checks read the table from "
                  "above and the heights and tilts of the parts on jig stands from the side\n")
    _forecast(assembly, out)
    # -- guide
    if not args.project:
        path = assembly.write_sheet(args.sheet or None)  # --sheet alone: the data folder's guides/
        out.write(f"wrote the guide sheets to {path} (print at 100 %; check the 100 mm bar)\n")
    step = 1
    keys = {"": "next", "n": "next", "p": "previous", "s": "skip"}
    while step <= len(assembly.steps):
        assembly.show_step(step)
        _clear(out, assembly)
        out.write(f"step {step}/{len(assembly.steps)}: {assembly.steps[step - 1]}\n")
        answer = ask("  Enter: next step, p: previous, s: skip to placing, q: quit > ", out, keys)
        if answer == "skip":
            break
        step = max(1, step - 1) if answer == "previous" else step + 1
    # -- place
    ask("Place the parts as the guide shows, then press Enter (q: quit) > ", out, {"": ""})
    assembly.placed()
    if assembly.world is not None:
        out.write(f"  the simulated maker placed {len(assembly.parts)} parts"
                  f"{' (the projector highlighting each)' if assembly.projector is not None else ''}\n")
    # -- check
    _check_loop(assembly, args, out)
    # -- run
    _clear(out, assembly)
    if assembly.world is not None:
        ask("Run it: Enter runs the contraption in the simulated world (q: quit) > ", out, {"": ""})
        assembly.run()
    else:
        out.write("Run the contraption now, then say for each event what happened (y: it happened, n: it did not, "
                  "u: not reached).\n")
        _answers(assembly, out)
    for event, outcome in assembly.outcomes.items():
        at = f" at {assembly.times[event]:.2f} s" if event in assembly.times else ""
        out.write(f"  {event:<24} {outcome}{at}\n")
    out.write(f"this attempt: {'SUCCESS' if assembly.success else 'failure'}\n")
    _forecast(assembly, out)
    # -- log
    if ask("Log this trial? [Y/n] > ", out, {"": "yes", "y": "yes", "yes": "yes", "n": "no", "no": "no"}) == "no":
        raise Quit("not logged at your word")
    trial_id = assembly.log(who=args.who)
    out.write(f"logged trial #{trial_id} ({assembly.scenario.name}, "
              f"{'success' if assembly.success else 'failure'}{', as checked' if assembly.check else ''}"
              f"{', physics ' + args.physics if args.physics else ''})\n")


def _check_loop(assembly, args, out) -> None:
    from station.services.check import report_lines

    checks = 0
    while True:
        checks += 1
        _clear(out, assembly)
        out.write(f"check {checks}: grabbing a frame from the camera{'s' if len(assembly.cameras()) > 1 else ''}..."
                  "\n")
        result = assembly.check_parts()
        out.writelines(f"  {line}\n" for line in report_lines(result.report))
        if assembly.project_check():
            out.write("  the projector shows an arrow per part to move, to where it must go\n")
        _forecast(assembly, out)
        if assembly.within_tolerance:
            answer = ask("No part to move. Enter: run, c: check again > ", out,
                         {"": "run", "r": "run", "a": "run", "c": "check"})
        elif checks >= args.max_checks:
            answer = ask(f"{checks} checks made. a: accept the parts as placed and run (q: quit) > ", out,
                         {"a": "run"})
        else:
            answer = ask("f: I moved them as it says, check again; a: accept as placed and run; c: check again "
                         "> ", out, {"f": "fix", "a": "run", "c": "check"})
        if answer == "run":
            assembly.accept()
            return
        if answer == "fix":
            moves = assembly.fix()
            if assembly.world is not None:
                out.write(f"  the simulated maker moved {len(moves)} part(s)\n")


def _answers(assembly, out) -> None:
    """Ask each event's outcome in the graph's order, skipping those the answers so far imply."""
    scenario = assembly.scenario
    given: dict[str, str] = {}
    event = None
    while True:
        outcomes, problems = assembly.resolve(given)
        # an answer the graph cannot have (a "yes" after a "no"): said, and the event asked again (an event still
        # to be said is a "problem" too, but not one of the answers)
        wrong = [p for p in problems if p.field.partition(".")[2] in given]
        if wrong and event is not None:
            out.write(f"  {str(wrong[0]).replace('outcome.', '', 1)}\n")
            given.pop(event)
            event = None
            continue
        open_events = [e for e in scenario.graph_order if outcomes[e] is None]
        if not open_events:
            break
        event = open_events[0]
        spec = scenario.event(event)
        after = (" & " if spec.join == "all" else " | ").join(spec.after) or "the start"
        given[event] = ask(f"  {event} (after {after}): y / n / u > ", out, ANSWERS)
    assembly.answer(given)
