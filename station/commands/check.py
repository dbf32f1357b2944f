"""``station check``: the placed parts seen by the camera against the layout's guide.

Argparse in, text or JSON out: the work is :mod:`station.services.check` (and the camera's calibration,
:mod:`station.services.calibrate`), whose refusals (naming ``guide``, ``image``, ``camera``, ``sim_offset``,
``simulate``...) are reworded here into the flags' words.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from station.cli_util import add_physics_option, check_output_file, emit_json, flag_error
from station.errors import ServiceError, UsageError
from station.progress_view import ProgressView
from station.services.physics import read_profile
from station.services.projectors import configured_projector, open_projector, projector_mapping
from station.services.reporting import Reporter

#: The ``--json`` / CHECK.json contract, quoted in the help text; keep its names.
JSON_SHAPE = ('{"format": "chaos-station check", "version", "scenario", "content_hash", "layout", "view", "plane": '
              '{"residual_mm", "reference_ids", "moved_mm"}, "parts": [{"name", "tag_id", "found", "measured": '
              '{"center_mm", "heading_deg"}, "error": {"du_mm", "dv_mm", "distance_mm", "heading_deg"}, '
              '"within_tolerance", "instruction", "cost"}], "missing_tags", "unknown_tags", "duplicate_tags", '
              '"by_eye", "missing_reference_tags", "as_built", "as_measured", "not_measured", "residual_error", '
              '"predicted_success_as_built", "predicted_success_as_designed", "prediction_note", '
              '"simulated_success_as_built", "physical_success": {"probability", "interval", "expected_attempts", '
              '"attempts_interval", "samples", "successes", "events", "placement_error", "physics"}, "views": '
              '[{"view", "camera", "plane"}], "side_parts": [a part as in "parts", "view": "side", "via_jig"], '
              '"measured_by": {parameter: "top" or "side"}}')
FLAGS = {"guide": "--guide", "image": "--image", "camera": "--camera", "sim_offset": "--sim-offset",
         "sim_side_offset": "--sim-side-offset", "side_image": "--side-image",
         "simulate": "--simulate", "seed": "--seed", "intrinsics": "--intrinsics", "physics": "--physics",
         "predict": "--predict"}


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "check",
        help="check the placed parts with the camera: how far each is off, what to do, success as placed",
        description="Look at the assembled contraption with the camera (or a frame from a file) and say, part by "
        "part, how far each tagged part is from where the layout wants it (du, dv, distance in mm; the turn in "
        "degrees; measured minus designed), whether that is within its tolerance, and what to do in the guide "
        "sheets' words; the parts are ordered by how much their error costs in predicted success. The measured "
        "poses become the as-built layout (what the camera cannot see keeps the layout's value, and is listed), "
        "scored by the layout's success model: predicted success as placed, and as designed. --simulate N also "
        "simulates the as-built layout N times with the measurement's residual error; --predict N (default 48, 0 for "
        "none) gives its physical success with an interval and the attempts to expect (as `station predict` does), "
        "under --physics PROFILE.toml when given. The guide is made again "
        "from the scenario and the layout (default options), or read from --guide (the manifest `station guide "
        "--json` printed, whose tags were stuck on the parts). With the simulated camera (sim://camera, the "
        "default station's) the camera is shown the guide's tags at their designed poses; --sim-offset and "
        "--sim-cover change that simulated scene only (demos and tests). Heights and tilts (a track's, a plank's) "
        "are seen by a second camera: a side camera in front of the table facing the upright board sheet `station "
        "guide --pdf` prints next to the guide (four tags, 579-582), which reads the tag engraved on each jig "
        "stand's face (--jigs: the guide with its jigs); give both with --camera (repeatable; a simulated side camera "
        "is sim://camera?view=side&height=700, height its distance from the board), or name both cameras in "
        "station.toml. Its instructions say how to raise or lower a part's lower end and tilt it steeper or flatter; "
        "CHECK.json says which view measured each parameter. "
        f"--json prints {JSON_SHAPE}.",
        epilog="examples:\n"
        "  station check simple layout.json --image frame.png --intrinsics desk.json\n"
        "  station check simple layout.json --guide guide.json --out check.json --project\n"
        "  station check simple layout.json --camera sim://camera --sim-offset track=3,-1 --simulate 20\n"
        "  station check simple success --jigs --camera sim://camera --camera 'sim://camera?view=side&height=700' "
        "--sim-side-offset track=0,-3,1.5",
    )
    parser.add_argument("scenario", help="scenario file, or an example's name (simple, ballrun, ...)")
    parser.add_argument("layout", help="the layout checked against (LAYOUT.json, {\"parameters\": {...}}, or a "
                        "layout named in the scenario)")
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--image", metavar="FRAME.png", help="check this camera frame (a file)")
    source.add_argument("--camera", metavar="URL", action="append", help="grab the frame from this camera "
                        "(default: the station's cameras, `station devices`); repeat it for a side camera facing the "
                        "board (sim://camera?view=side, or a real camera whose frame shows the board's tags)")
    parser.add_argument("--intrinsics", metavar="CAMERA.json", help="the camera's calibration (`station calibrate "
                        "camera`); default the saved one of the station's camera, else guessed (and said)")
    parser.add_argument("--guide", metavar="GUIDE.json", help="the guide's manifest (`station guide --json`); "
                        "default: made again from the scenario and the layout")
    parser.add_argument("--simulate", type=int, default=0, metavar="N", help="also simulate the as-built layout N "
                        "times with the residual measurement error (default 0)")
    parser.add_argument("--predict", type=int, default=48, metavar="N", help="predict the as-built layout's "
                        "physical success and expected attempts from N simulations (default 48; 0: none)")
    add_physics_option(parser)
    parser.add_argument("--seed", type=int, default=0, help="seed of those simulations (default 0)")
    parser.add_argument("--out", metavar="CHECK.json", help="write the check (what --json prints) to this file")
    parser.add_argument("--overlay", metavar="OUT.png", help="write the camera frame with the check drawn on it (and "
                        "with a side camera, OUT-side.png: its frame with each jig where it is and where it goes)")
    parser.add_argument("--project", action="store_true", help="show the check on the configured projector: an "
                        "arrow per misplaced part to where it must go, a ring at the target")
    parser.add_argument("--sim-offset", action="append", metavar="PART=DU,DV[,DEG]", help="SIMULATION ONLY: with "
                        "a simulated camera, show PART moved by DU, DV mm and turned DEG degrees (repeatable)")
    parser.add_argument("--side-image", metavar="FRAME.png", help="the side camera's frame from a file (a photo of "
                        "the parts in front of the board sheet), with --image or a top --camera")
    parser.add_argument("--side-intrinsics", metavar="CAMERA.json", help="the side camera's calibration for "
                        "--side-image (default its saved one, camera-side, else guessed and said)")
    parser.add_argument("--jigs", action="store_true", help="check against the guide with its laser-cut jigs "
                        "(`station guide --jigs`): the jigs' tags measure the parts they carry")
    parser.add_argument("--sim-side-offset", action="append", metavar="PART=DU,DUP[,DEG]", help="SIMULATION ONLY: "
                        "with a simulated side camera, show PART moved DU mm along the board, DUP mm up and turned "
                        "DEG degrees counter-clockwise as that camera sees it (repeatable)")
    parser.add_argument("--sim-cover", action="append", type=int, metavar="TAG", help="SIMULATION ONLY: with a "
                        "simulated camera, cover tag TAG with a hand (repeatable)")
    parser.add_argument("--json", action="store_true", help=f"print the whole check as JSON: {JSON_SHAPE}")
    parser.set_defaults(func=run_check)


def run_check(args) -> int:
    # heavy: PIL, cv2, scipy, shapely and the simulations' executor, loaded when a check runs
    from station.services import check as service
    from station.services import check_cameras, check_side, images

    out = check_output_file(args.out, {".json"}, "--out") if args.out is not None else None
    overlay = check_output_file(args.overlay, {".png"}, "--overlay") if args.overlay is not None else None
    try:
        offsets = dict(service.parse_offset(text) for text in args.sim_offset or [])
        if args.image is not None:  # a frame of the wrong size is refused before the guide is made
            images.check_image_file(args.image, "image")
        if args.side_image is not None:
            images.check_image_file(args.side_image, "side_image")
        elif args.side_intrinsics is not None:
            raise UsageError("--side-intrinsics goes with --side-image")
        side_offsets = {}
        for text in args.sim_side_offset or []:
            part, offset = service.parse_offset(text)
            side_offsets[part] = offset
        cameras = _cameras(args)
        with ProgressView(sys.stderr, prefix="check: ") as view:
            report = Reporter(view)
            job = service.prepare_check(args.scenario, args.layout, guide=args.guide, report=report, jigs=args.jigs)
            physics = read_profile(args.physics) if args.physics else None
            request = service.CheckRequest(simulate=args.simulate, seed=args.seed, physics=physics,
                                           predict=args.predict)
            if len(cameras) > 1 or side_offsets or args.side_image is not None \
                    or any(check_side.is_side_url(url) for _, url in cameras):
                check = check_cameras.check_views(
                    job, cameras, request, image=args.image, intrinsics=args.intrinsics, offsets=offsets,
                    side_offsets=side_offsets, occluded=tuple(args.sim_cover or ()), side_image=args.side_image,
                    side_intrinsics=args.side_intrinsics, report=report)
            else:
                image, intrinsics, name, previous = service.camera_frame(job.guide, service.FrameSource(
                    image=args.image, camera=cameras[0][1] if cameras else None, intrinsics=args.intrinsics,
                    offsets=offsets, occluded=tuple(args.sim_cover or ())))
                check = service.check_frame(job, image, intrinsics, request, previous=previous, report=report)
                service.remember_plane(name, check)
        if out is not None:
            out.write_text(json.dumps(check.to_json(), indent=1) + "\n", encoding="utf-8")
        if overlay is not None:
            from PIL import Image  # heavy: PIL

            Image.fromarray(service.camera_overlay(check)).save(overlay)
            if check.side is not None:  # the side camera's frame, next to the top one
                side_overlay = overlay.with_name(f"{overlay.stem}-side.png")
                Image.fromarray(check_side.side_overlay(check.side)).save(side_overlay)
        projected = _project(check) if args.project else None
    except ServiceError as error:
        raise flag_error(error, FLAGS) from None
    if args.json:
        emit_json(check.to_json())
        return 0
    _print(check, out, overlay, projected)
    return 0


def _cameras(args) -> list[tuple[str, str]]:
    """The cameras to check with, ``(name, url)``: the ``--camera`` URLs (the first named as the station's camera),
    else with no ``--image`` every camera of station.toml (none configured: the default one)."""
    from station.services.check_cameras import camera_names, configured_cameras  # heavy: PIL, cv2

    if args.camera:
        return camera_names(args.camera)
    if args.image is not None:
        return []
    configured = configured_cameras()
    return configured if len(configured) > 1 else []


def _project(check) -> str:
    from station.services import check as service  # heavy: PIL, cv2, design.robust.executor

    device = configured_projector()
    if device is None:
        raise UsageError("--project: no projector configured (add one to station.toml; see `station devices`)")
    with open_projector(device) as projector:
        mapping = projector_mapping(device.url, tuple(projector.size))
        projector.show(service.overlay_frame(check, tuple(projector.size), mapping.homography))
    return f"projected the check on {device.name} ({device.url}), {mapping.scale_text()}"


def _print(check, out: Path | None, overlay: Path | None, projected: str | None) -> None:
    from station.services import check as service  # heavy: PIL, cv2, design.robust.executor

    report = check.report
    guide_job = check.guide_job
    print(f"{report.scenario}: {guide_job.layout.describe()}, {report.view} view, camera "
          f"{check.intrinsics.name or 'guessed'}")
    for line in service.report_lines(report, check.physical):
        print(line)
    for path, what in ((out, "the check (CHECK.json)"), (overlay, "the camera frame with the check")):
        if path is not None:
            print(f"wrote {what} to {path}")
    if overlay is not None and check.side is not None:
        print(f"wrote the side camera's frame with the check to {overlay.with_name(f'{overlay.stem}-side.png')}")
    if projected:
        print(projected)
