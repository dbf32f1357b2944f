"""``station machines`` and ``station pattern``: the drawing machines of :mod:`design.machines` from the CLI."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from design.machines import declared_machine_names, get_machine, machine_names, shapes_to_jsonable
from design.machines.render import shape_polylines, write_png, write_svg
from station.cli_util import FINITE, add_design_options, check_output_file, design_parameters, emit_json, to_jsonable
from station.errors import UsageError

OUTPUT_SUFFIXES = {".svg", ".png", ".json"}
MAX_POINTS = 200_000  # arc-length spacing evaluates 8x as many points densely
PATTERN_COLOR = "#1f3b73"
MECHANISM_COLOR = "#c0392b"


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
    models = [get_machine(name) for name in machine_names()]
    if args.json:
        emit_json({"machines": [model.describe() for model in models]})
        return 0
    for model in models:
        print(f"{model.name}  ({model.title}): {model.description}")
        for p in model.parameters:
            if p.kind == "discrete":
                bounds = f"integer {p.lower:g}..{p.upper:g}"
            else:
                bounds = f"{p.lower:g}..{p.upper:g} {p.unit}".rstrip()
            print(f"  {p.name:<9} {p.kind:<10} default {p.default:<6g} {bounds:<24} {p.description}")
        print()
    return 0


def pattern_document(machine_name: str, params: dict[str, float], points: int, spacing: str) -> dict[str, Any]:
    """The JSON document of ``station pattern --json`` (also what ``--out FILE.json`` writes)."""
    model = get_machine(machine_name)
    values = model.validate(params)
    curve = model.sample(values, n=points, spacing=spacing)
    return {
        "machine": model.name,
        "params": values,
        "period": model.period(values),
        "turns": model.turns(values),
        "symmetry_order": model.symmetry_order(values),
        "spacing": spacing,
        "points": curve.tolist(),
    }


def run_pattern(args) -> int:
    model = get_machine(args.machine)
    if not 3 <= args.points <= MAX_POINTS:
        raise UsageError(f"--points must be an integer in [3, {MAX_POINTS}], got {args.points}")
    if not 16 <= args.size <= 8000:
        raise UsageError(f"--size must be in [16, 8000] pixels, got {args.size}")
    suffix = check_output_file(args.out, OUTPUT_SUFFIXES, "--out").suffix.lower() if args.out is not None else None
    params = design_parameters(args, model.name)
    document = pattern_document(model.name, params, args.points, args.spacing)
    shapes = model.mechanism(document["params"], args.mechanism) if args.mechanism is not None else None
    if shapes is not None:
        document["mechanism"] = {"t": args.mechanism, "shapes": shapes_to_jsonable(shapes)}

    if suffix is not None:
        write_output(Path(args.out), suffix, document, shapes, args.size)
    if args.json:
        emit_json(document)
    else:
        values = ", ".join(f"{k}={v:g}" for k, v in document["params"].items())
        print(
            f"{model.name}: {values}; period {document['period']:.6g} ({document['turns']} turns), "
            f"{document['symmetry_order']}-fold symmetry, {len(document['points'])} points ({args.spacing})"
        )
        if args.out is not None:
            print(f"wrote {args.out}")
    return 0


def write_output(path: Path, suffix: str, document: dict[str, Any], shapes, size: int) -> None:
    """Write the pattern (and the mechanism, if any) as SVG, PNG or JSON."""
    if suffix == ".json":
        with path.open("w", encoding="utf-8") as stream:
            json.dump(to_jsonable(document), stream, allow_nan=False)
            stream.write("\n")
        return
    polylines = [np.asarray(document["points"], dtype=float)]
    colors = [PATTERN_COLOR]
    if shapes:
        parts = shape_polylines(shapes)
        polylines += parts
        colors += [MECHANISM_COLOR] * len(parts)
    if suffix == ".svg":
        with path.open("w", encoding="utf-8") as stream:
            write_svg(stream, polylines, size=size, colors=colors, title=f"{document['machine']} pattern")
    else:
        with path.open("wb") as stream:
            write_png(stream, polylines, size=size, colors=colors)
