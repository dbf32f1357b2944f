"""``station retrieve``: find drawing-machine designs from a rough sketch (thesis 3.4).

The sketch (JSON or SVG strokes, optionally one symmetric sector with ``--symmetry K``) is ordered, fitted with a
closed spline and compared with every machine's candidate database (built once, cached in the station's cache
directory). Prints the ranked candidates, one per distinct machine and gear radii.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from station.cli_util import NON_NEGATIVE, check_output_folder, emit_json, flag_error
from station.errors import ServiceError, UsageError
from station.progress_view import ProgressView
from station.services.designs import declared_machine_names
from station.services.reporting import Progress, Reporter
from station.services.sketch import (
    GRID_RANGE,
    REFINE_RANGE,
    SMOOTHING_RANGE,
    TOP_RANGE,
    RetrieveOptions,
    load_sketch,
    retrieve,
    write_contact_sheet,
)


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "retrieve",
        help="find drawing-machine designs that match a rough sketch (JSON or SVG strokes)",
        description="Sketch-based pattern retrieval (thesis 3.4). The strokes are copied K times around the sketch "
        "centre (--symmetry), joined by the shortest closed tour, smoothed by a closed cubic spline and compared "
        "with each machine's candidate designs (every coprime gear radii combination up to 10-12, continuous "
        "parameters on a feasible grid or sampled uniformly over the feasible set) by a symmetric Procrustes "
        "distance, minimized over direction and start point; the best candidates' continuous parameters are then "
        "refined (--refine). A sector sketch is also read as its copies chained in drawing order. "
        "The first run builds the candidate databases (about 20 s of CPU) and caches them.",
        epilog='sketch JSON: [[[x, y], ...], ...] or {"strokes": [...], "symmetry": K, "center": [x, y]}.  '
        "example: station retrieve examples/sketches/trefoil-sector.json --top 5 --out retrieval",
    )
    parser.add_argument("sketch", metavar="SKETCH", help="a .json or .svg sketch file")
    parser.add_argument("--symmetry", type=int, metavar="K", help="rotational symmetry order (copies strokes K times)")
    parser.add_argument("--center", metavar="X,Y", help="centre of the symmetry copies (default: from the file)")
    machines = ", ".join(declared_machine_names())
    parser.add_argument("--machine", action="append", default=[], metavar="NAME",
                        help=f"search only this machine (repeatable; default all: {machines})")
    defaults = RetrieveOptions()
    parser.add_argument("--top", type=int, default=defaults.top, metavar="N",
                        help=f"number of candidates, {_range(TOP_RANGE)} (default {defaults.top})")
    parser.add_argument("--refine", type=int, default=defaults.refine, metavar="N",
                        help=f"refine the continuous parameters of the N best by a local search of the same "
                             f"distance, {_range(REFINE_RANGE)} (default {defaults.refine}; 0: the databases' "
                             "designs as they are)")
    parser.add_argument("--smoothing", type=NON_NEGATIVE, default=defaults.smoothing, metavar="S",
                        help=f"spline smoothing, fraction of the sketch size, {_range(SMOOTHING_RANGE)} "
                             f"(default {defaults.smoothing:g})")
    parser.add_argument("--no-prune", action="store_true", help="compare every candidate (skip the Fourier pruning)")
    parser.add_argument("--mirror", action="store_true", help="also accept mirror images of the patterns")
    parser.add_argument("--grid", type=int, metavar="V",
                        help=f"values per continuous parameter of the grid databases, {_range(GRID_RANGE)} "
                             "(default: Spirograph 12, elliptic 6; the Cycloid Drawing Machine and Hoot-Nanny "
                             "databases sample their feasible sets uniformly and keep theirs)")
    parser.add_argument("--json", action="store_true", help="print [{machine, params, distance}, ...] as JSON")
    parser.add_argument("--out", metavar="DIR", help="also write a contact sheet PNG of the sketch vs the candidates")
    parser.set_defaults(func=run_retrieve)


def _range(bounds: tuple[float, float]) -> str:
    return f"{bounds[0]:g} to {bounds[1]:g}"


def _parse_center(text: str | None) -> tuple[float, float] | None:
    if text is None:
        return None
    parts = text.split(",")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 2 or not all(math.isfinite(v) for v in values):
        raise UsageError(f"--center {text!r}: expected two numbers X,Y, e.g. --center 0,0")
    return values  # type: ignore[return-value]


def _format_params(params: dict[str, float]) -> str:
    return " ".join(f"{k}={v}" if isinstance(v, int) else f"{k}={v:.4g}" for k, v in params.items())


def describe_progress(progress: Progress) -> str:
    """``spirograph: grid 3/12 radii ( 25%)``: the message, and how far its stage is."""
    fraction = progress.fraction
    return progress.message if fraction is None else f"{progress.message} ({100 * fraction:3.0f}%)"


def run_retrieve(args) -> int:
    options = RetrieveOptions(machines=tuple(args.machine), top=args.top, refine=args.refine,
                              smoothing=args.smoothing, prune=not args.no_prune, mirror=args.mirror, grid=args.grid)
    try:
        options.check()
    except ServiceError as error:
        raise flag_error(error) from None
    out_dir = check_output_folder(args.out, "--out", "the contact sheet PNG") if args.out is not None else None
    sketch = load_sketch(args.sketch, symmetry=args.symmetry, center=_parse_center(args.center))
    with ProgressView(describe=describe_progress) as view:
        result = retrieve(sketch, options, report=Reporter(view))
    if out_dir is not None:
        sheet = write_contact_sheet(result, out_dir / f"{Path(args.sketch).stem}-candidates.png")
        print(f"contact sheet: {sheet}", file=sys.stderr)
    if not result.candidates:
        lead = sketch.symmetry if sketch.symmetry > 1 else "the sketch's"
        print(
            f"station: no candidate: no machine's database has a design with leading gear radius {lead} "
            f"(symmetry order); try a smaller --symmetry or --machine with larger radii",
            file=sys.stderr,
        )
        if args.json:
            emit_json([])
        return 1
    if args.json:
        emit_json([c.to_json() for c in result.candidates])
        return 0
    order = result.prepared.order
    print(
        f"sketch: {len(sketch.strokes)} stroke(s), symmetry {sketch.symmetry}, {len(result.prepared.strokes)} after "
        f"copies, tour {order.method}; query {result.timings['total']:.2f} s"
    )
    for report in result.reports:
        how = f"{report.candidates_compared}/{report.candidates_total} compared"
        if report.pruned and report.hypotheses:
            radii = ", ".join("/".join("?" if r is None else str(r) for r in h.radii) for h in report.hypotheses[:4])
            how += f" (radii {radii})"
        print(f"  {report.machine}: {how}")
    for i, candidate in enumerate(result.candidates, start=1):
        flag = " refined" if candidate.refined else ""
        print(f"{i:2d}. {candidate.distance:.4f}  {candidate.machine:24s} {_format_params(candidate.params)}{flag}")
    return 0


__all__ = ["register", "run_retrieve"]
