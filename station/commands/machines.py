"""``station machines`` and ``station pattern``: the drawing machines from the CLI (the work is
:mod:`station.services.machines`)."""

from __future__ import annotations

from pathlib import Path

from station.cli_util import FINITE, add_design_options, check_output_file, design_parameters, emit_json, to_jsonable
from station.errors import UsageError
from station.services.machines import (
    declared_machine_names,
    describe_machines,
    machine_name,
    pattern_document,
    pattern_mechanism,
    write_pattern,
)

OUTPUT_SUFFIXES = {".svg", ".png", ".json"}
MAX_POINTS = 200_000  # arc-length spacing evaluates 8x as many points densely


def register(subparsers) -> None:
    machines = subparsers.add_parser(
        "machines",
        help="list the drawing machines and their parameters",
        description="List the drawing machines with their parameters: kind (discrete gear radius or continuous), "
        "default, bounds and meaning. Lengths are in gear-radius units, angles in radians.",
        epilog="examples:\n  station machines\n  station machines --json > machines.json",
    )
    machines.add_argument("--json", action="store_true", help="print machines, parameters and constraints as JSON")
    machines.set_defaults(func=run_machines)

    pattern = subparsers.add_parser(
        "pattern",
        help="draw one period of a drawing machine's pattern",
        description="Compute one closed period of MACHINE's pattern (missing parameters take their defaults) and "
        "print it as JSON and/or write it as SVG, PNG or JSON. A design that breaks a constraint of the thesis's "
        "Appendix A is refused with the constraint in words and numbers (exit 2).",
        epilog="example: station pattern hoot_nanny --set r_t=10 --set l1=13 --points 4096 --out hn.png",
    )
    pattern.add_argument("machine", metavar="MACHINE", help=f"one of: {', '.join(declared_machine_names())}")
    add_design_options(pattern)
    pattern.add_argument("--points", type=int, default=2048, metavar="N", help="points in the closed curve (2048)")
    pattern.add_argument(
        "--spacing",
        choices=("time", "arclength"),
        default="arclength",
        help="points uniform in arc length (default, what plotters want) or in the driving angle",
    )
    pattern.add_argument("--out", metavar="FILE", help="write the pattern to FILE (.svg, .png or .json)")
    pattern.add_argument(
        "--mechanism",
        type=FINITE,
        metavar="T",
        help="also draw the machine's parts at time T (in the picture; in JSON under 'mechanism')",
    )
    pattern.add_argument("--size", type=int, default=800, metavar="PX", help="picture size in pixels (800)")
    pattern.add_argument("--json", action="store_true", help="print the pattern as JSON on stdout")
    pattern.set_defaults(func=run_pattern)


def run_machines(args) -> int:
    machines = describe_machines()
    if args.json:
        emit_json({"machines": machines})
        return 0
    for machine in machines:
        print(f"{machine['name']}  ({machine['title']}): {machine['description']}")
        for p in machine["parameters"]:
            if p["kind"] == "discrete":
                bounds = f"integer {p['lower']:g}..{p['upper']:g}"
            else:
                bounds = f"{p['lower']:g}..{p['upper']:g} {p['unit']}".rstrip()
            print(f"  {p['name']:<9} {p['kind']:<10} default {p['default']:<6g} {bounds:<24} {p['description']}")
        print()
    return 0


def run_pattern(args) -> int:
    name = machine_name(args.machine)
    if not 3 <= args.points <= MAX_POINTS:
        raise UsageError(f"--points must be an integer in [3, {MAX_POINTS}], got {args.points}")
    if not 16 <= args.size <= 8000:
        raise UsageError(f"--size must be in [16, 8000] pixels, got {args.size}")
    suffix = check_output_file(args.out, OUTPUT_SUFFIXES, "--out").suffix.lower() if args.out is not None else None
    params = design_parameters(args, name)
    document = pattern_document(name, params, args.points, args.spacing)
    shapes = None
    if args.mechanism is not None:
        shapes, jsonable = pattern_mechanism(name, document["params"], args.mechanism)
        document["mechanism"] = {"t": args.mechanism, "shapes": jsonable}

    if suffix is not None:
        write_pattern(Path(args.out), suffix, document, shapes, args.size, to_jsonable=to_jsonable)
    if args.json:
        emit_json(document)
    else:
        values = ", ".join(f"{k}={v:g}" for k, v in document["params"].items())
        print(
            f"{name}: {values}; period {document['period']:.6g} ({document['turns']} turns), "
            f"{document['symmetry_order']}-fold symmetry, {len(document['points'])} points ({args.spacing})"
        )
        if args.out is not None:
            print(f"wrote {args.out}")
    return 0
