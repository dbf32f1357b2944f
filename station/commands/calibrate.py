"""``station calibrate``: the ChArUco board PDF, a camera's intrinsics, the plane check.

Argparse in, text or JSON out: the work is :mod:`station.services.calibrate`. ``station calibrate projector``
and ``station calibrate sim`` live in :mod:`station.commands._calibrate_projector` and
:mod:`station.commands._calibrate_sim` (their parsers are added here; the underscore keeps a module from being
discovered as a command of its own).
"""

from __future__ import annotations

import sys

from station.cli_util import check_output_file, emit_json, flag_error, number
from station.commands._calibrate_bed import add_bed_parser
from station.commands._calibrate_material import add_material_parser
from station.commands._calibrate_projector import add_projector_parser
from station.commands._calibrate_sim import add_sim_parser
from station.errors import ServiceError, UsageError
from station.progress_view import ProgressView
from station.services.reporting import Reporter
from station.services.trials import logged_trials

CAMERA_JSON = ('{"camera": {camera file: "camera_matrix", "dist_coeffs", "image_size", "rms_px", "name", "notes"}, '
               '"rms_px", "views": [{"name", "corners", "rms_px", "skipped"}], "coverage", "uncovered_corners", '
               '"k3_fixed", "warnings", "saved"}')
PLANE_JSON = ('{"source", "camera", "guide", "intrinsics": {"name", "rms_px", "notes"}, "plane": {"residual_mm", '
              '"reference_ids", "moved_mm", "rvec", "tvec", "camera_height_mm"} | null, "reference_ids", '
              '"missing_reference_ids", "unknown_ids", "duplicate_ids"}')


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "calibrate", help="calibrate the camera, the guide plane, the projector, the simulator, the laser's bed camera "
        "and laser materials (board, camera, plane, projector, sim, bed, material)",
        description="Calibration for the camera-checked assembly and the simulator: `board` writes the ChArUco "
        "board as a 1:1 PDF to print; `camera` solves the camera's intrinsics from views of it (a folder of images, "
        "or N frames grabbed from the camera while you move the board) and saves them per camera under the "
        "station's data folder (calibration/cameras/NAME.json, OpenCV's names); `plane` finds the guide plane in "
        "one frame through the guide's four reference tags and reports the residual and how far the plane moved "
        "since the last check; `projector` maps the projector's pixels onto the guide plane with the camera, so "
        "that projected guides land at true scale; `sim` fits a scenario's uncertain material values (friction, "
        "restitution, damping) to the logged trials and writes a physics profile for --physics; `bed` registers the "
        "laser's bed camera to machine coordinates; `material` reads a burned laser test card (`station lasertest "
        "card`) from a photo and writes the material's kerf, cut and engrave settings into the laser profile.",
        epilog="examples:\n  station calibrate board --pdf board.pdf\n"
        "  station calibrate camera --images shots/ --name desk\n"
        "  station calibrate plane --image frame.png --guide guide.json\n"
        "  station calibrate projector --camera 'sim://camera?projector=wall' "
        "--projector 'sim://projector?name=wall&area=-300,-190,300,190'\n"
        "  station calibrate sim simple --out simple-physics.toml\n"
        "  station calibrate material --image card/frame.png --card card/card.json")
    sub = parser.add_subparsers(dest="calibrate_command", metavar="WHAT")

    board = sub.add_parser("board", help="the ChArUco calibration board as a 1:1 PDF",
                           description="Write the ChArUco board (7x5 squares of 30 mm, 22 mm DICT_5X5_100 markers, "
                           "landscape) as a 1:1 vector PDF. Print at 100% and check that a square measures 30 mm.",
                           epilog="examples:\n  station calibrate board --pdf board.pdf\n"
                           "  station calibrate board --pdf board.pdf --paper letter")
    board.add_argument("--pdf", required=True, metavar="OUT.pdf", help="the PDF to write")
    board.add_argument("--paper", default="a4", help="a4 (default), letter or a3")
    board.set_defaults(func=run_board)

    camera = sub.add_parser("camera", help="a camera's intrinsics from views of the board",
                            description="Solve the camera's intrinsics (camera matrix, distortion) from 10-20 views "
                            "of the printed board at different angles and places, some with the board in the image's "
                            "corners (else k3 is fixed and the result says which corners lacked views). Prints the "
                            f"RMS and each view's error. --json prints {CAMERA_JSON}.",
                            epilog="examples:\n  station calibrate camera --images shots/ --name desk\n"
                            "  station calibrate camera --capture 15 --camera 0 --out desk.json --json")
    source = camera.add_mutually_exclusive_group()
    source.add_argument("--images", metavar="DIR", help="a folder of board images (png, jpg, ...)")
    source.add_argument("--capture", type=int, metavar="N", help="grab N frames from the camera")
    camera.add_argument("--camera", metavar="URL", help="with --capture: the camera (default: the station's)")
    camera.add_argument("--interval", type=number(0, 60, why="seconds"), default=2.0, metavar="S",
                        help="with --capture: seconds between frames, to move the board (default 2)")
    camera.add_argument("--name", help="the camera's name (default: its device name, or 'camera')")
    camera.add_argument("--out", metavar="CAMERA.json", help="write here instead of the station's "
                        "calibration/cameras/NAME.json")
    camera.add_argument("--json", action="store_true", help="print the result as JSON")
    camera.set_defaults(func=run_camera)

    plane = sub.add_parser("plane", help="find the guide plane in one frame from the reference tags",
                           description="Find the guide plane in one frame through the guide's reference tags "
                           "(ids 583-586; their positions from --guide, the manifest `station guide --json` "
                           "prints; without it only which are seen is checked), report the residual at the tags "
                           "and how far the plane moved since the camera's last check (a bumped camera). "
                           f"--json prints {PLANE_JSON}.",
                           epilog="examples:\n  station calibrate plane --image frame.png --guide guide.json\n"
                           "  station calibrate plane --image frame.png --guide guide.json --name desk --json")
    where = plane.add_mutually_exclusive_group()
    where.add_argument("--camera", metavar="URL", help="grab the frame from this camera (default: the station's)")
    where.add_argument("--image", metavar="FRAME", help="a frame saved as an image file")
    plane.add_argument("--guide", metavar="GUIDE.json", help="the guide's manifest (reference tag positions)")
    plane.add_argument("--intrinsics", metavar="CAMERA.json", help="the camera file (default: the saved one of "
                       "the camera, else a guess)")
    plane.add_argument("--name", help="the camera's name (its saved intrinsics and last plane; default 'camera')")
    plane.add_argument("--json", action="store_true", help="print the result as JSON")
    plane.set_defaults(func=run_plane)

    add_projector_parser(sub)
    add_bed_parser(sub)
    add_sim_parser(sub, trials_source=logged_trials)
    add_material_parser(sub)


def run_board(args) -> int:
    from station.services import calibrate as service  # heavy: PIL

    path = check_output_file(args.pdf, {".pdf"}, "--pdf")
    try:
        spec = service.write_board(path, args.paper)
    except ServiceError as error:
        raise flag_error(error) from None
    print(f"wrote {path}: {spec.describe()}; print at 100% and check that a square measures {spec.square_mm:g} mm")
    return 0


def run_camera(args) -> int:
    from station.services import calibrate as service  # heavy: PIL

    if args.images is None and args.capture is None:
        raise UsageError("give --images DIR (a folder of board images) or --capture N (frames to grab)")
    if args.camera is not None and args.capture is None:
        raise UsageError("--camera goes with --capture N")
    out = check_output_file(args.out, {".json"}, "--out") if args.out is not None else None
    try:
        with ProgressView(sys.stderr, prefix="calibrate: ") as view:
            request = service.CameraCalibrationRequest(images=args.images, capture=args.capture, camera=args.camera,
                                                       name=args.name, out=out, interval_s=args.interval)
            done = service.calibrate_camera(request, report=Reporter(view))
    except ServiceError as error:
        raise flag_error(error) from None
    if args.json:
        emit_json(done.to_dict())
        return 0
    for line in service.camera_summary(done.result):
        print(line)
    print(f"saved {done.path}")
    return 0


def run_plane(args) -> int:
    from station.services import calibrate as service  # heavy: PIL

    try:
        check = service.plane_check(image=args.image, camera=args.camera, guide=args.guide,
                                    intrinsics=args.intrinsics, name=args.name)
    except ServiceError as error:
        raise flag_error(error) from None
    if args.json:
        emit_json(check.to_dict())
    else:
        for line in service.plane_summary(check):
            print(line)
    return 0 if check.measurement.plane is not None or args.guide is None else 1
