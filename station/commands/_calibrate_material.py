"""``station calibrate material``: read a burned laser test card from a camera frame and write the material's
measured settings (kerf, cut, engrave) into the profile.

Not discovered on its own (the underscore): ``station calibrate``'s module calls :func:`add_material_parser`.
"""

from __future__ import annotations

from pathlib import Path

from station.cli_util import check_output_file, emit_json, flag_error, number
from station.errors import ServiceError, UsageError

MATERIAL_JSON = ('{"card", "frame", "material", "profile", "tags_found", "tag_fit_mm", "levels", "kerf_mm", '
                 '"kerf_uncertainty_mm", "kerf_settings", "slots": [...], "cells": [{"name", "power", '
                 '"feed_mm_min", "darkness", "square_through", "cut_through", ...}], "chosen": {"cut", "engrave", '
                 '...}, "report", "profile_file", "profile_written"}')


def add_material_parser(calibrate_subparsers) -> None:
    """Add ``material`` to ``station calibrate``'s subparsers."""
    parser = calibrate_subparsers.add_parser(
        "material", help="read a burned laser test card from a photo: kerf, cut and engrave settings",
        description="Read a test card (`station lasertest card`) burned on the laser, photographed from above on a "
        "light surface (what is cut through must show): the card's plane from its four reference tags, each "
        "square's engraving darkness, which cut lines went through, and the kerf from the comb (each slot's "
        "opening less its nominal width). Chooses the cut (the fastest feed that went through, one power step "
        "above its weakest line that did) and the engraving (the fastest square near --darkness), writes them with "
        "the kerf into the profile's [materials.NAME] table with a [materials.NAME.measured] record (values, "
        "uncertainty, card, frame), and draws the measured values on the card (--report). A built-in profile is "
        "written as the station's own copy (its data folder's profiles/NAME.toml, which --profile NAME then means); "
        f"a profile file of yours only with --yes. --json prints {MATERIAL_JSON}.",
        epilog="examples:\n  station calibrate material --image card/frame.png --card card/card.json\n"
        "  station calibrate material --image card/frame.png --card card/card.json --darkness 0.5 --dry-run --json")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--image", metavar="FRAME", help="a photo of the card (png, jpg, ...)")
    where.add_argument("--camera", metavar="URL", help="grab the frame from this camera")
    parser.add_argument("--card", required=True, metavar="CARD.json", help="the card's manifest")
    parser.add_argument("--profile", metavar="PROFILE",
                        help="the profile to write (default: the one the card was made for)")
    parser.add_argument("--darkness", type=number(0, 1, above=True, why="0 bare wood, 1 char"), default=None,
                        metavar="D", help="the engraving darkness wanted, 0..1 (default 0.6)")
    parser.add_argument("--report", metavar="REPORT.png",
                        help="the card with the measured values drawn on it (default: card-report.png beside the "
                        "card's manifest)")
    parser.add_argument("--yes", action="store_true", help="write the settings into a profile file of yours")
    parser.add_argument("--dry-run", action="store_true", help="measure and report, write no profile")
    parser.add_argument("--json", action="store_true", help="print the measurement as JSON")
    parser.set_defaults(func=run_material)


def run_material(args) -> int:
    from station.services import lasertest as service  # heavy: PIL, cv2, scipy, shapely

    if args.image is None and args.camera is None:
        raise UsageError("give --image FRAME (a photo of the card) or --camera URL (grab one)")
    if args.darkness is not None and args.darkness >= 1:
        raise UsageError(f"--darkness {args.darkness:g}: expected a number between 0 and 1 (0 bare wood, 1 char)")
    report = args.report or str(Path(args.card).with_name("card-report.png"))
    report_path = check_output_file(report, {".png"}, "--report")
    try:
        measurement = service.measure_material(
            args.card, image=args.image, camera=args.camera,
            darkness=service.DEFAULT_DARKNESS if args.darkness is None else args.darkness)
    except ServiceError as error:
        raise flag_error(error) from None
    report_path.write_bytes(measurement.report_png)
    update = None if args.dry_run else service.update_profile(measurement, args.profile, yes=args.yes)
    result = measurement.to_dict()
    if args.json:
        emit_json({**result, "report": report_path, "profile_file": None if update is None else update.path,
                   "profile_written": bool(update and update.written)})
        return 0
    reading, chosen = result, result["chosen"]
    print(f"card {reading['card']}: tags {len(reading['tags_found'])}/4 found, fit {reading['tag_fit_mm']:.3f} mm, "
          f"{reading['frame_px_per_mm']:.1f} px per mm; "
          f"under the card grey {reading['levels']['under_card']:.0f}, wood {reading['levels']['wood']:.0f}")
    for note in reading["warnings"]:
        print(f"  note: {note}")
    if reading["kerf_mm"] is None:
        print("  kerf: not measured (no comb slot opened: was the comb cut through?)")
    else:
        opened = sum(s["kerf_mm"] is not None for s in reading["slots"])
        print(f"  kerf {reading['kerf_mm']:.3f} ± {reading['kerf_uncertainty_mm']:.3f} mm from {opened} comb slots")
    through = [c["name"] for c in reading["cells"] if c["cut_through"]]
    print(f"  cut lines through: {', '.join(through) if through else 'none'}")
    for what in ("cut", "engrave"):
        settings = chosen[what]
        if settings is None:
            print(f"  {what}: {chosen[what + '_why']}")
        else:
            print(f"  {what}: {100 * settings['power']:g}% {settings['feed_mm_min']:g} mm/min x{settings['passes']} "
                  f"(cell {chosen[what + '_cell']}: {chosen[what + '_why']})")
    print(f"  report: {report_path}")
    if update is None:
        print("  profile not written (--dry-run)")
    elif update.written:
        where = "the station's copy of the built-in profile" if update.station_copy else "profile"
        print(f"wrote [materials.{reading['material']}] into {where}: {update.path}")
    else:
        print(f"not written: {update.path} is your file; add --yes to write these settings into it:")
        print(update.block.rstrip())
    return 0
