"""``station calibrate bed``: the laser's bed registered to the camera over it (argparse in, text or JSON out; the
work is :mod:`station.services.bed`). The underscore keeps the module from being discovered as a command."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from station.cli_util import check_output_file, emit_json, flag_error, number
from station.errors import ServiceError, UsageError
from station.services.reporting import Reporter

BED_JSON = ('{"homography" (pixels -> machine mm), "residual_rms_mm", "residual_max_mm", "image_size", "marks_mm": '
            '[[[x, y], size]], "camera", "laser", "path", "engraved", "work_offset"}')


def area(text: str) -> tuple[float, float, float, float]:
    """argparse type of ``--area``: ``X0,Y0,X1,Y1`` in work mm."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 4 or not all(abs(v) < 1e6 for v in values):
        raise argparse.ArgumentTypeError(f"expected X0,Y0,X1,Y1 in work mm (e.g. 130,150,270,250), got {text!r}")
    return values  # type: ignore[return-value]


def add_bed_parser(sub) -> None:
    bed = sub.add_parser(
        "bed", help="register the laser's bed to the camera over it (four engraved marks)",
        description="Engrave four small filled squares (5, 6.5, 8 and 9.5 mm) at the corners of --area on a piece "
        "of scrap, grab a frame from the camera over the bed (the station.toml camera with options = { laser = "
        "\"NAME\" }; a simulated laser has its own), find the marks and solve the bed's homography, camera pixels "
        "-> machine mm, from their 16 corners; report its residual in mm and save it under the laser's name "
        "(calibration/beds/LASER.json in the station's data folder). The Machines screen's placement (b) and "
        f"scripts use it. --json prints {BED_JSON}.",
        epilog="examples:\n  station calibrate bed --port 'sim://grbl?profile=laser&clock=virtual'\n"
        "  station calibrate bed --port 'sim://grbl?profile=laser&clock=virtual' --area 120,140,280,260 --power 0.4 "
        "--out bed.png --json")
    bed.add_argument("--laser", metavar="NAME", help="the configured laser (default: the first)")
    bed.add_argument("--port", metavar="URL", help="the laser's port, when not its station.toml URL")
    bed.add_argument("--camera", metavar="URL", help="the camera over the bed (default: the laser's camera)")
    bed.add_argument("--image", metavar="FRAME", help="a frame of the marks already engraved (nothing is "
                     "engraved; the laser is asked only for its work offset)")
    bed.add_argument("--area", type=area, metavar="X0,Y0,X1,Y1",
                     help="the marks' corners in work mm (default: 140 x 100 mm in the middle of the work area)")
    bed.add_argument("--power", type=number(0, 1, above=True, why="a fraction of the laser's maximum"), default=0.3,
                     help="engraving power as a fraction of the maximum (default 0.3)")
    bed.add_argument("--feed", type=number(1, 100000, why="mm/min"), metavar="MM_MIN",
                     help="engraving feed (default: the profile's first material's)")
    bed.add_argument("--no-engrave", action="store_true", help="the marks are there already: grab and register")
    bed.add_argument("--out", metavar="BED.png", help="write the frame with the stock found and the marks drawn")
    bed.add_argument("--json", action="store_true", help="print the registration as JSON")
    bed.set_defaults(func=run_bed)


def run_bed(args) -> int:
    # deferred: the service pulls in OpenCV, which `station --help` and the other commands do not need
    from station.progress_view import ProgressView
    from station.services import bed as service

    out = check_output_file(args.out, {".png"}, "--out") if args.out is not None else None
    if args.image is not None and args.camera is not None:
        raise UsageError("give --image FRAME or --camera URL, not both")
    if args.image is not None and not Path(args.image).is_file():  # before the laser is asked for anything
        raise UsageError(f"--image {args.image!r}: no such file; expected a frame of the engraved marks")

    try:
        with ProgressView(sys.stderr, prefix="calibrate bed: ") as view:
            request = service.BedCalibrationRequest(laser=args.laser, port=args.port, camera=args.camera,
                                                    image=args.image, area=args.area,
                                                    engrave=args.image is None and not args.no_engrave,
                                                    power=args.power, feed=args.feed)
            done = service.calibrate_bed(request, report=Reporter(view))
    except ServiceError as error:
        raise flag_error(error) from None
    if out is not None:
        import cv2

        stock = service.find_stock(done.frame, done.registration)
        marks = [[(x - s / 2, y - s / 2), (x + s / 2, y - s / 2), (x + s / 2, y + s / 2), (x - s / 2, y + s / 2)]
                 for (x, y), s in done.registration.marks_mm]
        picture = service.bed_picture(done.frame, done.registration,
                                      [np.array(m + m[:1]) for m in marks], stock_mm=stock)
        cv2.imwrite(str(out), cv2.cvtColor(picture, cv2.COLOR_RGB2BGR))
    if args.json:
        emit_json(done.to_dict())
        return 0
    for line in service.bed_summary(done):
        print(line)
    if out is not None:
        print(f"wrote {out}")
    return 0
