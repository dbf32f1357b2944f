"""``station guide``: a contraption layout as an assembly guide (1:1 PDF sheets, SVG, projected steps; thesis 4.8.1).

Argparse in, text or JSON out: the work is :mod:`station.services.guide`, whose refusals (naming a value: ``view``,
``verify``, ``paper``, ``step``) are reworded here into the flags' words.
"""

from __future__ import annotations

import sys

from station.cli_util import add_physics_option, check_output_file, check_output_folder, emit_json, flag_error
from station.errors import ServiceError, UsageError
from station.progress_view import ProgressView
from station.services.projectors import open_projector, projector_device, projector_mapping
from station.services.reporting import Reporter

#: The ``--json`` contract (the guide's manifest), quoted in the help text; keep its names.
JSON_SHAPE = ('{"scenario", "content_hash", "view", "units": "mm", "tolerance_source", "pages": [{"index", "label", '
              '"paper", "size_mm", "origin_mm"}], "reference_tags": [{"id", "center_mm", "size_mm"}], "parts": '
              '[{"name", "kind", "step", "tag_id", "center_mm", "heading_deg", "outline_mm", "care", "tolerances", '
              '"parameters": [{"name", "value", "unit", "meaning", "set_with", "role", "tolerance"}]}], "jigs": '
              '[{"id", "part", "kind", "parameters", "words", "footprint_mm", "tag_id", "face_tag_id"}], "layout", '
              '"steps", "side_board": {"line_v_mm", "center_u_mm", "paper", "sheet_mm", "reference_tags", '
              '"hidden_tags", "hidden_tags_raised", "words"} or null}')


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "guide",
        help="an assembly guide of a layout: 1:1 PDF sheets, SVG, projected steps",
        description="Turn a contraption layout (the optimizer's LAYOUT.json, {\"parameters\": {...}}, or a layout "
        "named in the scenario) into what a maker assembles against: every part's true outline on the guide plane "
        "(the table seen from above, or the backboard seen from the front), its assembly number, tag and heading, "
        "the assembly steps in order (every design parameter in the maker's words: a height above the table as "
        "the height of a named point of the part, a tilt in degrees and which way it falls), four reference "
        "AprilTags (ids 583-586) for the camera check, and for every part how carefully it must be placed (its "
        "tolerance, from the layout's success model; --verify N checks each by N simulations). --pdf writes the "
        "sheets at exactly 1:1, tiled over the paper with overlap, join marks and a 100 mm scale bar to check the "
        "print, and a side view of each part lifted or tilted off the sheet (a table guide with --jigs also "
        "NAME-board.pdf: the board sheet, four tags 579-582, that stands upright behind the parts for the side "
        "camera of `station check`, which reads the tag on each jig stand's face; the manifest's side_board says "
        "where); --svg one drawing in mm with a layer "
        "per kind, for a laser or plotter to mark a board. --project shows the steps on the configured projector (or "
        "--projector URL), at true scale through the calibration measured on that projector "
        "(`station calibrate projector`), else fitted to the screen, and says which. --jigs plans the laser-cut "
        "jigs that set the parts' heights and tilts (`station jigs`): the steps say how to use each, the sheets draw "
        "where each stands, and --jigs DIR also writes their laser job there. "
        f"--json prints the guide's manifest: {JSON_SHAPE}.",
        epilog="examples:\n"
        "  station guide ballrun ballrun-layout.json --pdf ballrun.pdf\n"
        "  station guide simple layout.json --pdf simple.pdf --svg simple.svg --paper letter --view top\n"
        "  station guide simple layout.json --pdf simple.pdf --verify 40 --json\n"
        "  station guide simple layout.json --pdf simple-jigs.pdf --jigs simple-jigs\n"
        "  station guide ballrun ballrun-layout.json --project --step 3",
    )
    parser.add_argument("scenario", help="scenario file, or an example's name (simple, ballrun, ...)")
    parser.add_argument("layout", help="layout file (LAYOUT.json, {\"parameters\": {...}}) or a layout named in the "
                        "scenario")
    parser.add_argument("--pdf", metavar="OUT.pdf", help="write the 1:1 sheet set (and a last page of parts, steps "
                        "and tolerances) to this PDF")
    parser.add_argument("--svg", metavar="OUT.svg", help="write the drawing as an SVG in mm, one layer per kind")
    parser.add_argument("--paper", default="a4", help="paper of the PDF sheets: a4 (default), letter or a3")
    parser.add_argument("--view", help="the guide plane: top (the table) or side (the backboard); default: chosen "
                        "from the scenario")
    parser.add_argument("--verify", type=int, default=0, metavar="N", help="check each tolerance by simulating N "
                        "layouts at its +-delta (default 0: none)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the verification's layouts (default 0)")
    parser.add_argument("--no-tolerances", action="store_true", help="draw the guide without tolerances (faster)")
    add_physics_option(parser)
    parser.add_argument("--project", action="store_true", help="show the guide on the configured projector "
                        "(station devices): the calibrate frame, or --step N")
    parser.add_argument("--step", type=int, metavar="N", help="with --project: show step N (1-based)")
    parser.add_argument("--projector", metavar="URL", help="with --project: the projector (default: the station's; "
                        "sim://projector?name=NAME, display:N)")
    parser.add_argument("--jigs", nargs="?", const="", default=None, metavar="DIR",
                        help="use laser-cut jigs for the heights and tilts (the laser profile's default material; "
                        "`station jigs` chooses another): the steps and sheets show them; with DIR, write their "
                        "jigs.svg, jigs.gcode, jigs.json and sheet.png there")
    parser.add_argument("--json", action="store_true", help=f"print the guide's manifest as JSON: {JSON_SHAPE}")
    parser.set_defaults(func=run_guide)


def run_guide(args) -> int:
    from station.services import guide as service  # heavy: scipy, shapely

    if args.pdf is None and args.svg is None and not (args.project or args.json):
        raise UsageError("nothing to write: give --pdf OUT.pdf, --svg OUT.svg, --project or --json")
    if args.step is not None and not args.project:
        raise UsageError("--step goes with --project")
    if args.projector is not None and not args.project:
        raise UsageError("--projector goes with --project")
    pdf = check_output_file(args.pdf, {".pdf"}, "--pdf") if args.pdf is not None else None
    svg = check_output_file(args.svg, {".svg"}, "--svg") if args.svg is not None else None
    jigs_dir = check_output_folder(args.jigs, "--jigs", "jigs.svg, jigs.gcode, jigs.json and sheet.png") \
        if args.jigs else None
    try:
        service.check_paper(args.paper)  # before any simulation
        with ProgressView(sys.stderr, prefix="guide: ") as view:
            request = service.GuideRequest(args.scenario, args.layout, view=args.view, verify=args.verify,
                                           seed=args.seed, tolerances=not args.no_tolerances, physics=args.physics,
                                           jigs=args.jigs is not None)
            job = service.make_guide(request, report=Reporter(view))
        job = service.export_guide(job, pdf=pdf, svg=svg, paper=args.paper)
        if jigs_dir is not None:
            from station.services.jigs import cut_jigs, write_jig_outputs  # heavy: scipy, shapely

            written = write_jig_outputs(cut_jigs(job, job.jigs), jigs_dir)
        if args.project:
            _project(job, args.step, args.projector)
    except ServiceError as error:
        raise flag_error(error) from None
    if args.json:
        emit_json(job.manifest())
        return 0
    _print_summary(job, pdf, svg)
    if jigs_dir is not None:
        count = len(job.guide.jigs)
        print(f"wrote {count} jig{'' if count == 1 else 's'} to {jigs_dir}: "
              + (f"{written['gcode'].name} (send it with `station send`), " if "gcode" in written else "")
              + "jigs.json and a picture of each")
    return 0


def _project(job, step: int | None, url: str | None) -> None:
    from station.services import guide as service  # heavy: scipy, shapely

    device = projector_device(url)
    if device is None:
        raise UsageError("--project: no projector configured (add one to station.toml, or give --projector URL)")
    with open_projector(device) as projector:
        mapping = projector_mapping(device.url, tuple(projector.size))
        service.show_step(job, projector, step, homography=mapping.homography)
        shown = "the calibrate frame" if step is None else f"step {step} of {len(job.guide.parts)}"
        print(f"projected {shown} on {device.name} ({device.url}), {mapping.scale_text()}")


def _print_summary(job, pdf, svg) -> None:
    guide = job.guide
    print(f"{guide.scenario}: {job.layout.describe()}, {guide.view} view, {len(guide.parts)} parts")
    if job.layout.defaulted and job.layout.format != "defaults":
        print(f"  defaulted: {', '.join(job.layout.defaulted)}")
    for line in job.steps:
        print(f"  {line}")
    source = {"model": "from the layout's success model", "simulation": "by simulation",
              "none": "none (the layout carries no success model; --verify N estimates them by simulation)"}
    print(f"tolerances: {source.get(guide.tolerance_source, guide.tolerance_source)}")
    if guide.tolerance_note:
        print(f"  note: {guide.tolerance_note}")
    if guide.headline:
        print(guide.headline)
    if pdf is not None:
        pages = guide.pages
        columns = max((ord(p.label[0]) - ord("A") + 1 for p in pages), default=0)
        rows = max((int(p.label[1:]) for p in pages), default=0)
        print(f"wrote {pdf}: {len(pages)} sheets ({columns} x {rows}) of {pages[0].paper if pages else '?'} and a "
              "page of parts, steps and tolerances; check that the scale bar measures 100 mm")
        from station.services.guide import board_pdf_path, board_words  # heavy: scipy, shapely

        words = board_words(guide)
        if words is not None:
            print(f"wrote {board_pdf_path(pdf)}: the side camera's board sheet ({words})")
    if svg is not None:
        print(f"wrote {svg}")
