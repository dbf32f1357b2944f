"""``station calibrate projector``: map a projector's pixels onto the guide plane with the camera.

Not discovered as a command of its own (the underscore): ``station calibrate`` belongs to
:mod:`station.commands.calibrate`, which calls :func:`add_projector_parser` with its subparsers object. The work is
:mod:`station.services.projector_calibration`.
"""

from __future__ import annotations

import sys

from station.cli_util import check_output_file, emit_json, flag_error, number
from station.errors import ServiceError
from station.progress_view import ProgressView
from station.services import projector_calibration as service
from station.services.reporting import Reporter

__all__ = ["PROJECTOR_JSON", "add_projector_parser", "run_projector"]

PROJECTOR_JSON = ('{"plane_from_pixel": [[...]], "projector_size": [w, h], "landing_error_mm": {"p50", "p95", '
                  '"max", "check_points", "outliers"}, "cells": {"seen", "fitted", "inliers"}, "finest_px", "name", '
                  '"path", "camera", "projector", "device", "frames", "plane_source", "intrinsics_source"}')


def add_projector_parser(calibrate_subparsers) -> None:
    """Add ``projector`` to ``station calibrate``'s subparsers."""
    parser = calibrate_subparsers.add_parser(
        "projector", help="map the projector's pixels onto the guide plane with the camera",
        description="Show Gray code stripes (x and y, each with its inverse: about 30 frames) through the "
        "projector, grab each with the camera, and solve where every projector pixel lands on the guide plane "
        "(a homography, RANSAC over thousands of cells). Reports the landing error at check points kept out of "
        "the fit and saves the map under the station's data folder, kept under the projector it was measured on "
        "(calibration/projectors/KEY.json: the projector's name in station.toml, else a simulated projector's "
        "name=, else display-N), so that the guide's and the check's frames on that projector land at true scale "
        "(and frames on another projector do not use it). The camera's view of the plane comes from --plane, "
        "else its last `station calibrate plane`, else (a simulated camera) its own pose. Darken the room; keep "
        f"the table clear. --json prints {PROJECTOR_JSON}.",
        epilog="examples:\n  station calibrate projector\n"
        "  station calibrate projector --camera 0 --projector display:1 --plane plane.json\n"
        "  station calibrate projector --camera 'sim://camera?projector=wall' "
        "--projector 'sim://projector?name=wall&area=-300,-190,300,190'")
    parser.add_argument("--camera", metavar="URL", help="the camera (default: the station's)")
    parser.add_argument("--projector", metavar="URL", help="the projector (default: the station's)")
    parser.add_argument("--name", help="keep the map as calibration/projectors/NAME.json (default: the "
                        "projector's key; the map records its projector, which finds it under any name)")
    parser.add_argument("--plane", metavar="PLANE.json", help="the camera's plane fix (\"homography\": undistorted "
                        "pixel -> plane mm; default: the camera's last one)")
    parser.add_argument("--intrinsics", metavar="CAMERA.json", help="the camera file (default: the camera's saved "
                        "one)")
    parser.add_argument("--finest", type=int, default=8, metavar="PX",
                        help="the finest stripe in projector pixels (default 8; larger for a far or blurry camera)")
    parser.add_argument("--settle", type=number(0, 10, why="seconds"), metavar="S",
                        help="seconds between a pattern and its frame (default 0.3 for real devices, 0 simulated)")
    parser.add_argument("--out", metavar="MAP.json", help="write the map here instead of the station's "
                        "calibration/projectors/KEY.json (the station does not look for it there)")
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    parser.set_defaults(func=run_projector)


def run_projector(args) -> int:
    out = check_output_file(args.out, {".json"}, "--out") if args.out is not None else None
    try:
        with ProgressView(sys.stderr, prefix="calibrate projector: ") as view:
            request = service.ProjectorCalibrationRequest(camera=args.camera, projector=args.projector, name=args.name,
                                                          plane=args.plane, intrinsics=args.intrinsics,
                                                          finest_px=args.finest, settle_s=args.settle, out=out)
            done = service.calibrate_projector(request, report=Reporter(view))
    except ServiceError as error:
        raise flag_error(error) from None
    if args.json:
        emit_json(done.to_dict())
        return 0
    for line in service.projector_summary(done):
        print(line)
    return 0
