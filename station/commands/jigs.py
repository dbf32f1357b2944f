"""``station jigs``: laser-cut placement jigs that set a layout's heights, tilts and tight positions by touch.

Argparse in, text or JSON out: the work is :mod:`station.services.jigs`, whose refusals (naming a value: ``sheet``,
``kerf``, ``gap``) are reworded here into the flags' words.
"""

from __future__ import annotations

import sys

from station.cli_util import NON_NEGATIVE, add_physics_option, check_output_folder, emit_json, flag_error
from station.commands.fabricate import parse_sheet
from station.errors import ServiceError
from station.progress_view import ProgressView
from station.services.fabricate import KERF_SOURCES
from station.services.reporting import Reporter

#: The ``--json`` contract (jigs.json), quoted in the help text; keep its names.
JSON_SHAPE = ('{"scenario", "view", "units": "mm", "material", "thickness_mm", "kerf_mm", "sheet_mm", "jigs": [{"id", '
              '"kind", "part", "parameters", "tag_id", "thickness_mm", "outline_mm", "support_mm", "footprint_mm", '
              '"words", "face_tag_id", ...}], "by_hand": [{"part", "parameters", "reason", "how", "set_with"}], '
              '"sheets"}')


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "jigs",
        help="laser-cut placement jigs for a layout: stands that set heights and tilts, templates for tight places",
        description="Design the jigs that set a contraption layout by touch, not by eye, and their laser job. Each "
        "part with a height or tilt parameter gets a stand: a plate standing on edge on the table (in the slot of a "
        "base laid on its outline on the guide sheet) whose top edge is the part's underside at the layout, with a "
        "stop at its lower end; on a backboard, a plate pinned flat on its outline. A part on the table whose "
        "in-plane place the tolerance map rates tight gets a template with a pocket it drops into. Material "
        "thickness and kerf come from the laser profile's material table (--kerf overrides the kerf); every cut is "
        "kerf-compensated, the pieces are nested on the sheet and engraved with the jig's name, the way its face "
        "looks and an AprilTag (ids 500-578) the camera check can find (a stand a second one on its plate's face, "
        "for the side camera). A height no jig can hold (a part hanging from a rope, a plate larger than the sheet) "
        "is listed with how to set it by hand. Writes DIR/jigs.svg, "
        "DIR/jigs.gcode (send it with `station send`: framing, laser dark on every travel, pre-flight), "
        "DIR/jigs.json, DIR/sheet.png and DIR/jig-J1.png... (each jig with its part resting on it). "
        f"--json prints jigs.json: {JSON_SHAPE}.",
        epilog="examples:\n"
        "  station jigs simple layout.json --out simple-jigs\n"
        "  station jigs causalityswitch_ball success --out switch-jigs --material mdf_3mm --sheet 300x200\n"
        "  station jigs branching success --out branching-jigs --kerf 0.2 --json\n"
        "  station send switch-jigs/jigs.gcode --port 'sim://grbl?profile=laser&time_scale=0.01'",
    )
    parser.add_argument("scenario", help="scenario file, or an example's name (simple, branching, ...)")
    parser.add_argument("layout", help="layout file (LAYOUT.json, {\"parameters\": {...}}) or a layout named in the "
                        "scenario")
    parser.add_argument("--out", required=True, metavar="DIR", help="output folder")
    parser.add_argument("--profile", default="laser", metavar="PROFILE.toml",
                        help="laser machine profile (a TOML file or a built-in name; default: laser)")
    parser.add_argument("--material", default=None, metavar="NAME",
                        help="material from the profile's [materials.NAME] table: its thickness is the jigs' "
                        "(default plywood_3mm)")
    parser.add_argument("--kerf", type=NON_NEGATIVE, default=None, metavar="MM",
                        help="laser kerf width, compensated on every cut (default: the material's)")
    parser.add_argument("--sheet", default=None, metavar="WxH", help="sheet size in mm (default: the work area)")
    parser.add_argument("--gap", type=NON_NEGATIVE, default=3.0, metavar="MM",
                        help="least distance between pieces and to the sheet's edges (default 3)")
    parser.add_argument("--view", help="the guide plane: top (the table) or side (the backboard); default: the "
                        "guide's choice")
    parser.add_argument("--no-tolerances", action="store_true", help="skip the tolerance map (no templates)")
    add_physics_option(parser)
    parser.add_argument("--json", action="store_true", help=f"print jigs.json on stdout: {JSON_SHAPE}")
    parser.set_defaults(func=run_jigs)


def run_jigs(args) -> int:
    from station.services import jig_plan  # heavy: scipy, shapely
    from station.services import jigs as service  # heavy: scipy, shapely

    sheet = parse_sheet(args.sheet) if args.sheet is not None else None
    options = jig_plan.JigOptions(profile=args.profile, material=args.material, kerf=args.kerf,
                                 sheet=sheet, gap=args.gap)
    try:
        jig_plan.check_options(options)  # a material the profile lacks, a kerf or gap out of range: before any work
    except ServiceError as error:
        raise flag_error(error) from None
    out = check_output_folder(args.out, "--out", "jigs.svg, jigs.gcode, jigs.json, sheet.png and a picture of "
                              "each jig")
    try:
        with ProgressView(sys.stderr, prefix="jigs: ") as view:
            result = service.make_jigs(args.scenario, args.layout, options, view=args.view,
                                       tolerances=not args.no_tolerances, physics=args.physics, report=Reporter(view))
    except ServiceError as error:
        raise flag_error(error) from None
    files = service.write_jig_outputs(result, out)
    summary = result.summary
    if args.json:
        emit_json(summary)
        return 0
    _print_summary(summary, files)
    return 0


def _print_summary(summary: dict, files: dict) -> None:
    jigs, by_hand = summary["jigs"], summary["by_hand"]
    print(f"{summary['scenario']}: {len(jigs)} jig{'' if len(jigs) == 1 else 's'} in {summary['material']} "
          f"({summary['thickness_mm']:g} mm, kerf {summary['kerf_mm']:g} mm {_kerf_words(summary['kerf_source'])}), "
          f"{summary['view']} view")
    for jig in jigs:
        tag = f"tag {jig['tag_id']}" if jig["tag_id"] is not None else "no tag"
        sets = ", ".join(jig["parameters"]) or "nothing"
        extra = ""
        if jig["support_mm"] is not None and jig["kind"] == "stand":
            (_, y0), (_, y1) = jig["support_mm"]
            extra = f"; support {y0:.1f} to {y1:.1f} mm above the table, {abs(jig['tilt_deg']):.1f} deg"
        print(f"  {jig['id']} {jig['kind']} for `{jig['part']}` (step {jig['step']}): sets {sets}; {tag}{extra}")
        print(f"     {jig['words']}")
        for note in jig["notes"]:
            print(f"     note: {note}")
    for entry in by_hand:
        print(f"  no jig for `{entry['part']}` ({', '.join(entry['parameters'])}): {entry['reason']}; "
              f"{entry['how']}")
    for line in summary["skipped"]:
        print(f"  no jig: {line}")
    for sheet in summary["sheets"]:
        count = len(sheet["pieces"])
        print(f"sheet {sheet['index']}: {count} piece{'' if count == 1 else 's'}, laser about "
              f"{sheet['job']['estimate_seconds']['total'] / 60:.1f} min")
    if not jigs:
        print("nothing to cut: " + ("no jig can be made for this layout (above: why, and how to set it by hand)"
                                    if by_hand or summary["skipped"] else
                                    "no part of this layout has a height or tilt to set, nor a tight place"))
    for name, path in files.items():
        print(f"  {name}: {path}")


def _kerf_words(source: str) -> str:
    return KERF_SOURCES.get(source, source)
