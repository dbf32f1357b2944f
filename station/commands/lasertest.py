"""``station lasertest``: a laser material test card (power x feed grid, kerf comb, reference tags), and its burn and
photo on the twin.

    station lasertest card --profile laser --material plywood_3mm --out card
    station lasertest render --card card/card.json --out card/frame.png
    station calibrate material --image card/frame.png --card card/card.json

Argparse in, text or JSON out: the work is :mod:`station.services.lasertest`.
"""

from __future__ import annotations

from pathlib import Path

from station.cli_util import check_output_file, check_output_folder, emit_json, flag_error, number
from station.errors import ServiceError

CARD_JSON = '{"files": {"gcode", "json", "png"}, "card_mm", "cells", "estimate_seconds", "profile", "material"}'
RENDER_JSON = '{"frame", "truth": {"material", "kerf_mm", "kerf_settings", "cells": [{"name", "cut_kerf_mm", ' \
              '"through"}], "camera"}}'


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "lasertest", help="a laser material test card (card: power x feed grid, kerf comb, reference tags) and "
        "its burn and photo on the twins (render)",
        description="`card` writes a material test card as a laser job: a power x feed grid of engraved squares "
        "and cut lines, each cell labelled, a kerf comb (slots cut at nominal widths, with a matching tab) and four "
        "reference tags at the corners; DIR/card.gcode (send it with `station send`: framing and pre-flight as "
        "every job), DIR/card.json (the manifest: cells, settings, nominal geometry) and DIR/card.png (a preview). "
        "`render` burns the card's G-code on the laser twin's simulated material and photographs it, for a round "
        "trip without a laser. Read the burned card with `station calibrate material`.",
        epilog="examples:\n  station lasertest card --profile laser --material plywood_3mm --out card\n"
        "  station lasertest card --profile laser --material mdf_3mm --power 0.3:1:4 --feed 150:2400:6 "
        "--passes 3 --out mdf-card\n"
        "  station lasertest render --card card/card.json --out card/frame.png")
    sub = parser.add_subparsers(dest="lasertest_command", metavar="WHAT")

    card = sub.add_parser(
        "card", help="write a test card's G-code, manifest and preview",
        description="Write a material test card for the profile's material: powers along the columns (evenly "
        "spaced), feeds along the rows (in equal ratios, so a slow cut and a fast engraving fit one card); each "
        "cell engraves a square (one pass) and cuts a line (--passes). The tags and labels are engraved at the "
        "material's engrave settings, the kerf comb and the outline cut at its cut settings. The card lies 5 mm in "
        f"from the work area's front-left corner. --json prints {CARD_JSON}.",
        epilog="examples:\n  station lasertest card --profile laser --material plywood_3mm --out card\n"
        "  station lasertest card --profile laser --material cardboard_2mm --power 0.1:0.6:6 --out cardboard")
    card.add_argument("--profile", default="laser", metavar="PROFILE",
                      help="laser profile: a built-in name (its station copy when calibrate material wrote one) "
                      "or a TOML file (default: laser)")
    card.add_argument("--material", required=True, metavar="NAME", help="a material of the profile's table")
    card.add_argument("--power", metavar="FIRST:LAST:COUNT",
                      help="powers as fractions of max power, evenly spaced (default 0.2:1:5)")
    card.add_argument("--feed", metavar="FIRST:LAST:COUNT",
                      help="feeds in mm/min, in equal ratios (default: 2/3 of the material's cut feed to its "
                      "engrave feed, 5)")
    card.add_argument("--passes", type=int, metavar="N",
                      help="passes of each cut line (default: the material's cut passes)")
    card.add_argument("--out", required=True, metavar="DIR", help="output folder")
    card.add_argument("--json", action="store_true", help="print the summary as JSON")
    card.set_defaults(func=run_card)

    render = sub.add_parser(
        "render", help="burn a card on the laser twin and photograph it (a frame for calibrate material)",
        description="Burn the card's G-code into the twin's simulated material (darkness from the energy per "
        "millimetre, cut through where the beam's dose passes the material's threshold; the twin's true kerf) and "
        "photograph it lying on a light surface, turned a little, with camera noise. Prints the twin's truth (the "
        f"comb's true kerf, which cut lines went through). --json prints {RENDER_JSON}.",
        epilog="examples:\n  station lasertest render --card card/card.json --out card/frame.png")
    render.add_argument("--card", required=True, metavar="CARD.json", help="the card's manifest")
    render.add_argument("--gcode", metavar="FILE", help="the G-code burned (default: the card's, beside card.json)")
    render.add_argument("--out", required=True, metavar="FRAME.png", help="the photo to write")
    render.add_argument("--seed", type=int, default=0, help="seed of the sheet's grain and the camera noise")
    render.add_argument("--noise", type=number(0, 50, why="grey levels"), default=2.0, metavar="SIGMA",
                        help="camera noise, grey levels (default 2)")
    render.add_argument("--px-per-mm", type=number(2, 60, why="camera pixels per mm"), default=20.0, metavar="PX",
                        help="the camera's pixels per card millimetre (default 20: a phone held over the card)")
    render.add_argument("--angle", type=number(-360, 360), default=7.0, metavar="DEG",
                        help="how far the card lies turned (default 7)")
    render.add_argument("--json", action="store_true", help="print the truth as JSON")
    render.set_defaults(func=run_render)


def run_card(args) -> int:
    from station.services import lasertest as service  # heavy: PIL, cv2, scipy, shapely

    out = check_output_folder(args.out, "--out", "card.gcode, card.json and card.png")
    try:
        output = service.make_card(args.profile, args.material, power=args.power, feed=args.feed,
                                   passes=args.passes)
    except ServiceError as error:
        raise flag_error(error) from None
    files = service.write_card(output, out)
    manifest = output.manifest
    if args.json:
        emit_json({"files": files, "card_mm": manifest["card_mm"], "cells": len(manifest["cells"]),
                   "estimate_seconds": manifest["estimate_seconds"], "profile": manifest["profile"],
                   "material": manifest["material"]})
        return 0
    width, height = manifest["card_mm"]
    powers = ", ".join(f"{100 * p:g}%" for p in manifest["powers"])
    feeds = ", ".join(f"{f:g}" for f in manifest["feeds_mm_min"])
    comb = manifest["comb"]
    source = "" if output.profile.source.startswith("builtin:") else f" ({output.profile.source})"
    print(f"test card for {manifest['material']} on {output.profile.name}{source}: {width:g}x{height:g} mm at "
          f"X{manifest['offset_mm'][0]:g} Y{manifest['offset_mm'][1]:g}, about "
          f"{manifest['estimate_seconds'] / 60:.0f} min")
    print(f"  powers {powers}; feeds {feeds} mm/min; cut lines x{manifest['cut_passes']}")
    slots = ", ".join(f"{slot['nominal_width_mm']:g}" for slot in comb["slots"])
    print(f"  kerf comb: slots {slots} mm and a "
          f"{comb['tab']['nominal_width_mm']:g} mm tab, cut at {100 * comb['power']:g}% {comb['feed_mm_min']:g} "
          f"mm/min x{comb['passes']}")
    for name, path in files.items():
        print(f"  {name}: {path}")
    print(f"next: station send {files['gcode']} (frame it first), then photograph the card on a light surface and "
          f"station calibrate material --image FRAME --card {files['json']}")
    return 0


def run_render(args) -> int:
    from station.services import lasertest as service  # heavy: PIL, cv2, scipy, shapely

    out = check_output_file(args.out, {".png"}, "--out")
    try:
        photo = service.photograph_card(args.card, gcode=args.gcode, seed=args.seed, noise=args.noise,
                                        angle_deg=args.angle, px_per_mm=args.px_per_mm)
    except ServiceError as error:
        raise flag_error(error) from None
    Path(out).write_bytes(service.png_bytes(photo.frame))
    truth = photo.truth
    if args.json:
        emit_json({"frame": out, "truth": truth})
        return 0
    through = [c["name"] for c in truth["cells"] if c["through"]]
    settings = truth["kerf_settings"]
    print(f"burned {args.card} on the twin's {truth['material']} and photographed it: {out} "
          f"({truth['camera']['image_size'][0]}x{truth['camera']['image_size'][1]})")
    print(f"  the twin's truth: kerf {truth['kerf_mm']:.4f} mm at {100 * settings['power']:g}% "
          f"{settings['feed_mm_min']:g} mm/min x{settings['passes']}; cut through: "
          f"{', '.join(through) if through else 'none'}")
    return 0
