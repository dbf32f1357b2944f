"""``station tolerances``: how far each part of a layout may be off, from its fitted success model.

Argparse in, text or JSON out: the work is :mod:`station.services.tolerances`. Simulations (``--verify``) go through
the robust commands' shared cache, progress bar and clean Ctrl-C (:func:`station.commands.robust.command`).
"""

from __future__ import annotations

import sys

from station.cli_util import emit_json
from station.commands.contraption import report_layout
from station.commands.robust import add_command, add_workers, command
from station.errors import UsageError
from station.services import tolerances as service
from station.services.reporting import Reporter
from station.services.tolerances import CARE_RULE, RATIO

JSON_SHAPE = (
    '--json prints {"scenario", "layout": {source, format, name, defaulted, warnings}, "verify": N, '
    '"source": "model"|"simulation"|"none", "layout_psp": P or null, "ratio": 0.9, "layout_success": bool or null, '
    '"entries": [{"parameter", "part", "kind": "position"|"angle", "delta" (in unit, or null), "unit": "mm"|"deg", '
    '"predicted_ratio", "predicted", "measured", "measured_minus", "measured_plus", "bound_limited", '
    '"limited_by": "success"|"collision"|"bound", "in_model", "minus", "plus", "simulations"}], '
    '"care": {part: "tight"|"normal"|"loose"|null}}.'
)


def register(subparsers) -> None:
    tight, loose = CARE_RULE["mm"]
    parser = add_command(
        subparsers, "tolerances", run_tolerances,
        help="how far each layout parameter may be off on its own (the tolerance map)",
        description=f"For each free parameter of a layout, the largest error ±delta it tolerates on its own (the "
        f"others fixed) while the predicted success stays >= {RATIO:.0%} of the layout's, from the fitted success "
        "model a LAYOUT.json of `station optimize` carries; positions in mm, angles in degrees. Each part gets a care "
        f"level: tight (a delta under {tight:g} mm or {tight:g} deg), loose (all over {loose:g} mm / {loose:g} deg) "
        "or normal. --verify N simulates N layouts at ±delta per parameter and prints the measured success next to "
        "the predicted one. A layout without a model (hand-written) gets tolerances by simulation with --verify N, "
        "else none. " + JSON_SHAPE,
        examples=["examples/scenarios/simple.toml layout.json",
                  "simple layout.json --verify 20 --seed 1 --json"],
    )
    parser.add_argument("scenario", help="a scenario file (.toml/.json) or an example name")
    parser.add_argument("layout", help="a layout file: the LAYOUT.json of `station optimize` (with its model), or "
                        "{\"parameters\": {...}} (no model: tolerances by simulation with --verify), or a layout "
                        "named in the scenario")
    parser.add_argument("--verify", type=int, default=0, metavar="N",
                        help="simulate N layouts per parameter at ±delta (N/2 each side) and print the measured "
                        "success rate (default 0: none)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the verification layouts (default 0)")
    add_workers(parser)
    parser.add_argument("--json", action="store_true", help="print the map as JSON (shape in the description)")


def _number(value, text: str = "{:.2f}") -> str:
    return "-" if value is None else text.format(value)


def describe_limit(entry) -> str:
    """What set an entry's delta, in words."""
    words = {"bound": "range end", "collision": "parts collide", "success": "success"}.get(entry.limited_by, "")
    return words + (" (the model ignores it)" if entry.in_model is False else "")


@command
def run_tolerances(args) -> int:
    if args.verify < 0:
        raise UsageError(f"--verify must be an integer >= 0 (layouts simulated per parameter), got {args.verify}")

    bar = args.bar
    result = service.tolerance_map(args.scenario, args.layout, verify=args.verify, seed=args.seed,
                                   workers=args.workers, scheduler=args.scheduler,
                                   report=Reporter(bar, stop=args.stop.is_set), physics=args.physics)
    bar.close()
    report_layout(result.layout, sys.stderr)
    if args.json:
        emit_json(result.to_dict())
        return 0
    tolerance_map = result.map
    source = {"model": "from the layout's fitted success model",
              "simulation": (f"by simulation ({result.verify} layouts per step)" if result.model is not None else
                             f"by simulation (no model in the layout; {result.verify} layouts per step)"),
              "none": "none: the layout carries no fitted model (give --verify N to search by simulation)"}
    print(f"{result.problem.name}: tolerances of {result.layout.describe()} {source[tolerance_map.source]}")
    if tolerance_map.note:
        print(f"  note: {tolerance_map.note}")
    if tolerance_map.layout_psp is not None and tolerance_map.source == "model":
        print(f"  the success model's score of the layout {tolerance_map.layout_psp:.3f}; each delta keeps >= "
              f"{tolerance_map.ratio:.0%} of it")
    if tolerance_map.layout_success is not None:
        print(f"  the layout itself {'succeeds' if tolerance_map.layout_success else 'FAILS'} in simulation")
    if tolerance_map.source == "none":
        return 0
    print(f"  {'parameter':24s} {'±delta':>12s} {'ratio':>6s} {'predicted':>9s} {'measured':>9s} {'(-/+)':>11s}"
          "  limited by")
    for entry in tolerance_map.entries:
        delta = "unknown" if entry.delta is None else f"{entry.delta:.2f} {entry.unit}"
        sides = "" if entry.measured_plus is None else \
            f"{_number(entry.measured_minus)}/{_number(entry.measured_plus)}"
        print(f"  {entry.parameter:24s} {delta:>12s} {_number(entry.predicted_ratio):>6s} "
              f"{_number(entry.predicted):>9s} {_number(entry.measured):>9s} {sides:>11s}  {describe_limit(entry)}")
    tight, loose = CARE_RULE["mm"]
    print(f"  care per part (tight: a delta < {tight:g} mm / {tight:g} deg; loose: all > {loose:g} mm / {loose:g} "
          "deg; a range end is a lower bound):")
    for part, level in result.care().items():
        print(f"    {part:22s} {level or 'unknown'}")
    return 0
