"""``station simulate`` and ``station scenario check``: chain-reaction contraptions from scenario files."""

from __future__ import annotations

import argparse
import sys

from station.cli_util import add_physics_option, check_output_file, emit_json
from station.errors import UsageError
from station.progress_view import ProgressView
from station.services.contraption import (
    LoadedLayout,
    Scenario,
    choose_layout,
    example_names,
    open_scenario,
    render,
    scenario_summary,
    simulate,
)
from station.services.physics import physics_note
from station.services.reporting import Reporter


def register(subparsers) -> None:
    examples = ", ".join(example_names()) or "none found"
    simulate = subparsers.add_parser(
        "simulate",
        help="simulate a contraption scenario under its causal graph",
        description="Simulate one layout of a scenario (pybullet) and report the causal graph's outcome. "
        f"SCENARIO is a .toml/.json file or an example name ({examples}). "
        "Exit 0 when the causal graph succeeds, 1 when it fails (or the layout is physically impossible), "
        "2 on bad input.",
        epilog="examples:\n"
        "  station simulate examples/scenarios/simple.toml\n"
        "  station simulate ballrun --layout ballrun-layout.json --render run.png --json",
    )
    simulate.add_argument("scenario", metavar="SCENARIO", help="a scenario file (.toml/.json) or an example name")
    layout = simulate.add_mutually_exclusive_group()
    layout.add_argument(
        "--layout",
        metavar="FILE|NAME",
        help="a layout file: the LAYOUT.json of `station optimize`, {\"x\": [...]} or {\"parameters\": "
        "{\"track.x\": -0.06, ...}} (JSON or TOML; missing parameters take the scenario's defaults), or a layout "
        "named in the scenario (success, failure)",
    )
    layout.add_argument("--x", metavar="V1,V2,...", help="the design parameters in order, real units (m, degrees)")
    simulate.add_argument("--json", action="store_true", help="print the result as JSON on stdout")
    simulate.add_argument("--render", metavar="OUT.png", help="write top and side views at start and end")
    simulate.add_argument("--no-early-stop", action="store_true", help="run to max_duration instead of stopping")
    add_physics_option(simulate)
    simulate.set_defaults(func=run_simulate)

    scenario = subparsers.add_parser(
        "scenario", help="scenario files: check",
        description="Scenario files (a contraption's objects, materials, causal graph and design parameters): "
        "`check` validates one and lists what it holds.",
        epilog="example:\n  station scenario check examples/scenarios/simple.toml")
    actions = scenario.add_subparsers(dest="scenario_command", metavar="ACTION")
    check = actions.add_parser(
        "check",
        help="validate a scenario file and list its design parameters",
        description="Validate a scenario file (errors name the file, the field and what was expected) and print "
        "its objects, causal graph and design parameters with their ranges.",
        epilog="examples:\n  station scenario check examples/scenarios/ballrun.toml\n"
        "  station scenario check examples/scenarios/simple.toml --json",
    )
    check.add_argument("scenario", metavar="SCENARIO", help="a scenario file (.toml/.json) or an example name")
    check.add_argument("--json", action="store_true", help="print the report as JSON")
    check.set_defaults(func=run_scenario_check)
    scenario.set_defaults(func=lambda args: _missing_action(scenario))


def _missing_action(parser: argparse.ArgumentParser) -> int:
    parser.print_help(sys.stderr)
    return 2


def parse_layout(args, scenario: Scenario) -> LoadedLayout:
    """The layout from ``--layout`` / ``--x`` (the scenario's own transforms when neither is given)."""
    if args.x is not None:
        parts = [p for p in args.x.split(",") if p.strip()]
        try:
            values = [float(p) for p in parts]
        except ValueError:
            raise UsageError(f"--x {args.x!r}: expected comma-separated numbers") from None
        return choose_layout(scenario, values=values, what="--x")
    return choose_layout(scenario, layout=args.layout)


def layout_lines(layout: LoadedLayout) -> list[str]:
    """What a command says about the layout it used: where it came from, and what took the scenario's defaults."""
    lines = [f"layout: {layout.describe()}"]
    if layout.defaulted and layout.format != "defaults":
        lines.append(f"  defaulted to the scenario's values: {', '.join(layout.defaulted)}")
    return lines


def report_layout(layout: LoadedLayout, stream=None) -> None:
    """The layout's warnings on stderr and, when ``stream`` is given, its :func:`layout_lines` there."""
    for warning in layout.warnings:
        print(f"station: warning: {warning}", file=sys.stderr)
    if stream is not None:
        print("\n".join(layout_lines(layout)), file=stream)


def run_simulate(args) -> int:
    if args.render is not None:
        # Refused now, not after the simulation: the render is what the user waits for.
        check_output_file(args.render, {".png"}, "--render")
    scenario = open_scenario(args.scenario, physics=args.physics)
    layout = parse_layout(args, scenario)
    report_layout(layout)
    report_physics(scenario)
    with ProgressView(describe=lambda progress: progress.message) as view:
        outcome = simulate(scenario, layout.x, early_stop=not args.no_early_stop, record=bool(args.render),
                           report=Reporter(view))
    if not outcome.valid:
        if args.json:
            emit_json(outcome.to_dict(layout))
        else:
            print(f"{scenario.name}: layout is physically impossible:")
            print("\n".join(layout_lines(layout)))
            for problem in outcome.problems:
                print(f"  - {problem.message}")
        return 1
    if args.render is not None:
        render(outcome, args.render)
        print(f"wrote {args.render}", file=sys.stderr)
    if args.json:
        emit_json(outcome.to_dict(layout))
    else:
        print(_result_text(scenario, outcome.result, layout))
    return 0 if outcome.success else 1


def report_physics(scenario: Scenario, stream=None) -> None:
    """Say on stderr which material values a physics profile set (nothing for the scenario's own)."""
    note = physics_note(scenario)
    if note:
        print(note, file=stream or sys.stderr)


def _fmt_time(value) -> str:
    return "-" if value is None else f"{value:.3f} s"


def _result_text(scenario: Scenario, result, layout: LoadedLayout) -> str:
    lines = [
        f"{scenario.name}: {'SUCCESS' if result.success else 'FAILURE'} "
        f"({result.n_successful_events}/{len(result.events)} events, {result.duration:.3f} s simulated, "
        f"{result.steps} steps{', stopped early' if result.early_stopped else ''})",
        *layout_lines(layout),
        "",
        f"{'event':<24} {'state':<8} {'woke':>9} {'at':>9}  label",
    ]
    for name in scenario.events:
        outcome = result.events[name]
        label = scenario.event(name).label
        lines.append(
            f"{name:<24} {outcome.state:<8} {_fmt_time(outcome.woke):>9} {_fmt_time(outcome.time):>9}  {label}"
        )
    return "\n".join(lines)


def run_scenario_check(args) -> int:
    scenario = open_scenario(args.scenario)
    space = scenario.design_space
    if args.json:
        emit_json(scenario_summary(scenario))
        return 0
    settings = scenario.settings
    lines = [
        f"{scenario.source}: valid scenario {scenario.name!r}",
        f"  {scenario.description}" if scenario.description else "",
        f"  settings: time step {settings.time_step:g} s, event timeout {settings.event_timeout:g} s, "
        f"max duration {settings.max_duration:g} s",
        f"  content hash: {scenario.content_hash[:16]}",
        f"  objects ({len(scenario.objects)}): "
        + ", ".join(f"{o.name} ({o.type})" for o in scenario.objects),
        f"  causal graph ({len(scenario.events)} events, root {scenario.root}):",
    ]
    for event in scenario.event_specs:
        after = ""
        if event.after:
            joined = " & " if event.join == "all" else " | "
            after = f" after {joined.join(event.after)}"
        extra = f", holds {event.duration:g} s" if event.duration else ""
        lines.append(f"    {event.name} [{event.type}]{after}{extra}: {event.label}")
    lines.append(f"  design parameters ({space.dim}):")
    for name, lo, hi, default in zip(space.names, space.lower, space.upper, space.default):
        unit = "deg" if name.rsplit(".", 1)[1] in ("heading", "pitch", "roll") else "m"
        lines.append(f"    {name:<28} [{lo:g}, {hi:g}] {unit}   default {default:g}")
    if scenario.layouts:
        lines.append(f"  named layouts: {', '.join(sorted(scenario.layouts))}")
    print("\n".join(line for line in lines if line))
    return 0
