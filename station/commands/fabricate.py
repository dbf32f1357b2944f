"""``station fabricate``: the laser-cut parts of a drawing machine, nested on a sheet, with the laser job.

    station fabricate spirograph --set r_f=5 --set r_r=3 --set d=2 --scale 8 --out build/spiro

writes ``parts.svg`` (mm, layers engrave/cut), ``laser.gcode`` (GRBL 1.1), ``parts.json`` (parts, sizes, sheet usage,
job estimate) and ``sheet.png`` (preview) into the output folder. Parts that do not fit one sheet go on further
sheets: ``parts-2.svg``, ``laser-2.gcode``, ``sheet-2.png``...
"""

from __future__ import annotations

import sys

from station.cli_util import (
    FINITE,
    NON_NEGATIVE,
    POSITIVE,
    add_design_options,
    check_output_folder,
    design_parameters,
    emit_json,
)
from station.errors import ServiceError, UsageError
from station.progress_view import ProgressView
from station.services.fabricate import (
    DEFAULT_GAP,
    DEFAULT_KERF,
    FABRICABLE_MACHINES,
    KERF_SOURCES,
    FabricationRequest,
    GearSettings,
    Hardware,
    fabricate,
    write_outputs,
)
from station.services.fabricate import parse_sheet as _parse_sheet
from station.services.reporting import Reporter


def parse_sheet(text: str) -> tuple[float, float]:
    """``"300x200"`` → ``(300.0, 200.0)`` mm; the CLI's message names ``--sheet``."""
    try:
        return _parse_sheet(text)
    except ServiceError:
        raise UsageError(f"--sheet {text!r}: expected WIDTHxHEIGHT in mm, e.g. --sheet 300x200") from None


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "fabricate",
        help="laser-cut parts of a drawing machine: gears, arms, plates; SVG, G-code, preview",
        description="Generate the flat parts of a drawing machine (involute and elliptic gears, ring gears, arms, "
                    "base plate) at a physical scale, compensate the kerf, nest them on a sheet, and write "
                    "DIR/parts.svg, DIR/laser.gcode, DIR/parts.json and DIR/sheet.png.",
        epilog="examples:\n"
        "  station fabricate hoot_nanny --design examples/patterns/hoot_nanny_star.json --scale 8 --out parts\n"
        "  station fabricate spirograph --set r_f=7 --set r_r=3 --scale 10 --sheet 300x200 --out spiro-parts",
    )
    parser.add_argument("machine", choices=FABRICABLE_MACHINES, metavar="MACHINE",
                        help=f"one of {', '.join(FABRICABLE_MACHINES)}")
    add_design_options(parser)
    parser.add_argument("--scale", type=POSITIVE, required=True, metavar="MM_PER_UNIT",
                        help="millimetres per model unit (gear radius 1 = this many mm)")
    parser.add_argument("--kerf", type=NON_NEGATIVE, default=None, metavar="MM",
                        help="laser kerf width, compensated on every contour (default: the material's kerf in the "
                        f"profile, else {DEFAULT_KERF})")
    parser.add_argument("--sheet", default=None, metavar="WxH", help="sheet size in mm (default: the work area)")
    parser.add_argument("--max-sheets", type=int, default=4, metavar="N",
                        help="parts that do not fit one sheet go on further sheets, up to N (default 4); "
                             "sheet k > 1 writes parts-k.svg, laser-k.gcode, sheet-k.png")
    parser.add_argument("--gap", type=NON_NEGATIVE, default=DEFAULT_GAP, metavar="MM",
                        help=f"least distance between parts and to the sheet's edges (default {DEFAULT_GAP})")
    parser.add_argument("--profile", default="laser", metavar="PROFILE.toml",
                        help="laser machine profile (a TOML file or a built-in name, which means the station's "
                        "copy of it once `station calibrate material` wrote one; default: laser)")
    parser.add_argument("--material", default=None, metavar="NAME",
                        help="material from the profile's [materials.NAME] table (default plywood_3mm)")
    parser.add_argument("--module", type=POSITIVE, default=1.5, metavar="MM",
                        help="nominal gear module; the one used makes every gear's tooth count an integer")
    parser.add_argument("--pressure-angle", type=FINITE, default=20.0, metavar="DEG", help="default 20")
    parser.add_argument("--backlash", type=NON_NEGATIVE, default=0.15, metavar="MM",
                        help="circumferential backlash of each mesh (default 0.15)")
    parser.add_argument("--pen-hole", type=POSITIVE, default=3.0, metavar="MM", help="pen hole diameter (default 3)")
    parser.add_argument("--axle-hole", type=POSITIVE, default=4.2, metavar="MM",
                        help="axle hole diameter (default 4.2)")
    parser.add_argument("--pin-hole", type=POSITIVE, default=3.2, metavar="MM",
                        help="pivot and slider pin hole diameter (default 3.2)")
    parser.add_argument("--out", required=True, metavar="DIR", help="output folder")
    parser.add_argument("--json", action="store_true", help="print the summary (parts.json) on stdout as JSON")
    parser.set_defaults(func=run_fabricate)


def run_fabricate(args) -> int:
    params = design_parameters(args, args.machine)
    if args.max_sheets < 1:
        raise UsageError(f"--max-sheets must be at least 1, got {args.max_sheets}")
    sheet_size = parse_sheet(args.sheet) if args.sheet is not None else None
    settings = GearSettings(module=args.module, pressure_angle=args.pressure_angle, backlash=args.backlash)
    hardware = Hardware(pen_hole=args.pen_hole, axle_hole=args.axle_hole, pin_hole=args.pin_hole)
    out = check_output_folder(args.out, "--out", "parts.svg, laser.gcode, parts.json and sheet.png")
    # The steps on stderr: bars on a terminal, a "fabricate: ..." line per stage and tenth otherwise.
    with ProgressView(sys.stderr, prefix="fabricate: ") as progress:
        result = fabricate(FabricationRequest(
            args.machine, params, args.scale, kerf=args.kerf, sheet_size=sheet_size, gap=args.gap, profile=args.profile,
            material=args.material, gear_settings=settings, hardware=hardware, max_sheets=args.max_sheets),
            report=Reporter(progress))
    files = write_outputs(result, out)
    summary = result.summary
    if args.json:
        emit_json(summary)
        return 0
    width, height = summary["sheet_mm"]
    count = summary["sheet_count"]
    print(f"{args.machine} at {args.scale:g} mm/unit: {len(summary['parts'])} parts on {count} sheet"
          f"{'' if count == 1 else 's'} of {width:g}x{height:g} mm, sheet usage {100 * summary['sheet_usage']:.1f}%")
    for sheet in summary["sheets"]:
        used = sheet["used_mm"]
        print(f"sheet {sheet['index']}: parts fill {100 * sheet['envelope_usage']:.1f}% of their "
              f"{used[0]:.0f}x{used[1]:.0f} mm corner; laser about "
              f"{sheet['job']['estimate_seconds']['total'] / 60:.1f} min")
        for part in (p for p in summary["parts"] if p["sheet"] == sheet["index"]):
            teeth = f", {part['info']['teeth']} teeth" if "teeth" in part["info"] else ""
            print(f"  {part['name']}: {part['size_mm'][0]:.1f}x{part['size_mm'][1]:.1f} mm{teeth}")
            for note in part["notes"]:
                print(f"    note: {note}")
    job = summary["job"]
    print(f"laser job ({job['material']} on {job['profile']}, kerf {summary['kerf_mm']:g} mm "
          f"{KERF_SOURCES[summary['kerf_source']]}): about {job['estimate_seconds']['total'] / 60:.1f} min, "
          f"travel {job['travel_mm']:.0f} mm (unordered {job['travel_mm_unordered']:.0f} mm)")
    for name, path in files.items():
        print(f"  {name}: {path}")
    return 0
