"""``station explore``: guided exploration under visual constraints (thesis 3.5), scriptable.

Finds the Points of Interest of a design, freezes the features given with ``--keep``, then moves invariant-space
sliders with ``--move K=V`` (each move is released: re-projection onto the invariants and a new subspace).
"""

from __future__ import annotations

import math
import sys
from typing import Any

from station.cli_util import add_design_options, check_output_file, design_parameters, emit_json, flag_error
from station.errors import ServiceError, UsageError
from station.services.designs import declared_machine_names, get_machine
from station.services.explore import check_points, explore, parse_keep, write_picture


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "explore",
        help="freeze features of a drawing (PoIs) and explore what remains with invariant-space sliders",
        description="Guided exploration (thesis 3.5). Prints the design's Points of Interest (curvature maxima and "
        "self-intersections: id, type, position, arc length), freezes the features named by --keep, prints the "
        "sliders of the invariant space, then applies each --move K=V: slider K (0-based) is moved to V (clamped "
        "to its bounds, which lie within [-2, 2]) and released, i.e. re-projected onto the invariants. For each "
        "move it prints the new parameters, the tracked PoI features before and after re-projection and the "
        "invariant errors. Coordinates are in the same drawing frame as `station pattern`.",
        epilog="invariant types: position:P, curvature:P (a curvature maximum), angle:P (a crossing), radial:P, "
        "distance:P,Q.  example: station explore hoot_nanny --keep curvature:0 --keep radial:0 --move 0=1.0 --json",
    )
    parser.add_argument("machine", metavar="MACHINE", help=f"one of: {', '.join(declared_machine_names())}")
    add_design_options(parser)
    parser.add_argument(
        "--keep", action="append", default=[], metavar="TYPE:POI[,POI]", help="an invariant (repeatable)"
    )
    parser.add_argument(
        "--move", action="append", default=[], metavar="K=V", help="move slider K to V and release (repeatable)"
    )
    parser.add_argument(
        "--points", type=int, default=None, metavar="N",
        help="curve samples for PoI detection (default: ~400 per turn of the driving gear, 4096 to 20000)",
    )
    parser.add_argument("--out", metavar="FILE.png", help="picture of the first and last designs with their PoIs")
    parser.add_argument("--json", action="store_true", help="print everything as one JSON document")
    parser.set_defaults(func=run_explore)


def parse_move(text: str) -> tuple[int, float]:
    """``K=V`` -> (slider index, value)."""
    index, sep, value = text.partition("=")
    try:
        k = int(index)
        v = float(value)
    except ValueError:
        raise UsageError(f"--move {text!r}: expected K=V with an integer slider index K and a number V") from None
    if not sep or k < 0 or not math.isfinite(v):
        raise UsageError(f"--move {text!r}: expected K=V with K >= 0 and a finite V, e.g. --move 0=1.5")
    return k, v


def run_explore(args) -> int:
    model = get_machine(args.machine)
    try:
        check_points(args.points)
        out = check_output_file(args.out, {".png"}, "--out") if args.out is not None else None
        keeps = [parse_keep(spec) for spec in args.keep]
        moves = [parse_move(text) for text in args.move]
        exploration = explore(model.name, design_parameters(args, model.name), keeps, moves, points=args.points)
    except ServiceError as error:
        raise flag_error(error) from None
    if out is not None:
        write_picture(exploration, out)
    if args.json:
        emit_json(exploration.document)
    else:
        print_text(exploration.document, sys.stdout)
        if out is not None:
            print(f"wrote {out}")
    return 0


def _params_text(params: dict[str, float]) -> str:
    return ", ".join(f"{k}={v:.6g}" for k, v in params.items())


def print_text(document: dict[str, Any], out) -> None:
    print(f"{document['machine']}: {_params_text(document['params'])}  (size {document['size']:.4g})", file=out)
    print(f"{len(document['pois'])} points of interest:", file=out)
    for p in document["pois"]:
        feature = f"curvature {p['curvature']:.4g}" if "curvature" in p else f"angle {p.get('angle_deg', 0):.2f} deg"
        arcs = ", ".join(f"{s:.4g}" for s in p["arclength"])
        print(
            f"  {p['id']:>4}  {p['type']:<12} ({p['xy'][0]:8.4f}, {p['xy'][1]:8.4f})  arc length {arcs:<18} {feature}",
            file=out,
        )
    for inv in document["invariants"]:
        print(f"invariant {inv['label']}: target {', '.join(f'{v:.6g}' for v in inv['target'])}", file=out)
    if document["redundant"]:
        print("the invariants constrain nothing here (redundant): the base parameters are kept", file=out)
    print("sliders:", file=out)
    for s in document["sliders"]:
        direction = ", ".join(f"{k} {v:+.3g}" for k, v in s["direction"].items() if abs(v) > 1e-12)
        print(f"  {s['index']}  {s['name']:<8} [{s['lower']:+.3f}, {s['upper']:+.3f}]  per unit: {direction}", file=out)
    for m in document["moves"]:
        clamp = "" if m["value"] == m["requested"] else f" (clamped from {m['requested']:g})"
        print(f"move slider {m['slider']} to {m['value']:+.4g}{clamp}, released:", file=out)
        print(f"  moved:        {_params_text(m['params_moved'])}", file=out)
        print(f"  re-projected: {_params_text(m['params'])}", file=out)
        for label in m["features_before"]:
            before, after = m["features_before"][label], m["features_after"][label]
            print(f"  {label}: {_feature_text(before)}  ->  {_feature_text(after)}", file=out)
        for b, a in zip(m["invariant_error_before"], m["invariant_error"]):
            print(f"  error {a['invariant']}: {_num(b['error'])} -> {_num(a['error'])} ({a['unit']})", file=out)
        print(f"  drawing changed by {m['shape_change']:.3%} of its size", file=out)
        if m["lost"]:
            print(f"  lost: {', '.join(m['lost'])}", file=out)
        if m["warning"]:
            print(f"  warning: {m['warning']}", file=out)


def _num(value) -> str:
    return "lost" if value is None else f"{value:.3g}"


def _feature_text(f) -> str:
    if f is None:
        return "lost"
    text = f"({f['xy'][0]:.4f}, {f['xy'][1]:.4f})"
    if "curvature" in f:
        text += f" curvature {f['curvature']:.5g}"
    if "angle_deg" in f:
        text += f" angle {f['angle_deg']:.3f} deg"
    return text
