"""Placement jigs as a service: a layout's stands and templates, nested on the laser's sheet, with their laser job.

Used by ``station jigs``, ``station guide --jigs`` and the Assemble screen. The geometry is :mod:`design.jigs`
(which parts get which jig and why); this module reads the scenario and the layout through the guide (the jigs stand
on the guide's plane, next to its parts and tags), takes the material's thickness and kerf from the laser profile's
material table, nests the pieces with the fabrication's nesting and writes the files ``station fabricate`` writes:
``jigs.svg``, ``jigs.gcode`` (engraving, then each piece's holes and outline; the beam dark on every travel; checked
against the work area), ``sheet.png``, plus ``jigs.json`` (:func:`jigs_manifest`, a public contract) and a picture
of each jig with its part on it (``jig-J1.png``...).

The plan itself (which part gets which jig, its tag, the guide redrawn with it) is
:mod:`station.services.jig_plan`'s.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cam.laser import material_settings
from common.progress import Reporter
from station.errors import station_errors
from station.jsonable import to_jsonable
from station.services.fabricate import KERF_SOURCES, SheetOutput, laser_sheets
from station.services.guide import GuideRequest, make_guide, portable_name
from station.services.jig_plan import JigOptions, PlannedJigs, attach_jigs, check_options, plan_guide_jigs

__all__ = ["JigsResult", "cut_jigs", "jigs_manifest", "make_jigs", "write_jig_outputs"]

#: Progress stages: planning the jigs (one step), nesting (one step), then the sheets' laser jobs.
PLAN_STAGE, NESTING_STAGE = "planning", "nesting"


@station_errors
@dataclass
class JigsResult:
    """The jigs of a layout, their sheets and pictures: what ``station jigs`` writes."""

    job: Any  # the GuideJob the jigs belong to (its guide draws their footprints)
    planned: PlannedJigs
    sheets: list[SheetOutput]
    pictures: dict[str, bytes]
    summary: dict[str, Any]

    @property
    def plan(self):
        return self.planned.plan


@station_errors
def make_jigs(scenario: str, layout: str | None, options: JigOptions | None = None, *, view: str | None = None,
              tolerances: bool = True, physics: str | None = None,
              report: Reporter | None = None) -> JigsResult:
    """The jigs of ``layout`` for ``scenario`` (read as ``station guide`` reads them), nested and with their laser
    job.

    Raises
    ------
    ServiceError, design.errors.DesignError, projector.errors.ProjectorError, drivers.errors.JobRefused
        Bad input: the message names the value (a sheet, kerf, material, layout, scenario).
    """
    report = Reporter.of(report)
    options = options or JigOptions()
    check_options(options)  # a bad sheet, kerf or material before the guide's work
    job = make_guide(GuideRequest(scenario, layout, view=view, tolerances=tolerances, physics=physics), report=report)
    report(PLAN_STAGE, 0, 1, "planning the jigs")
    planned = plan_guide_jigs(job, options)
    job = attach_jigs(job, planned)
    report(PLAN_STAGE, 1, 1, f"{len(planned.plan.jigs)} jig{'' if len(planned.plan.jigs) == 1 else 's'}")
    return cut_jigs(job, planned, report)


@station_errors
def cut_jigs(job, planned: PlannedJigs, report: Reporter | None = None) -> JigsResult:
    """Nest a plan's pieces on the sheet and make its laser job, its files' contents and the jigs' pictures.

    Raises
    ------
    design.errors.ConstraintViolation
        The pieces need more than four sheets.
    """
    from design.fabrication import Part, nest_sheets  # heavy: cv2
    from design.jigs.render import render_jig  # heavy: PIL

    report = Reporter.of(report)
    plan, settings, profile = planned.plan, planned.settings, planned.profile
    engrave_ops, cut_ops, _ = material_settings(profile, planned.material)
    pieces = [Part(piece.name, piece.shape, piece.engrave) for piece in plan.pieces]
    sheets = []
    if pieces:
        width, height = settings.sheet
        report(NESTING_STAGE, 0, None, f"nesting {len(pieces)} pieces on {width:g}x{height:g} mm sheets")
        sheets = nest_sheets(pieces, width, height, gap=settings.gap, kerf=settings.kerf, max_sheets=4)
    outputs = laser_sheets(sheets, profile, engrave_ops, cut_ops,
                           {"jigs": f"{job.guide.scenario}", "material": planned.material, "profile": profile.name},
                           f"placement jigs of {job.guide.scenario}", report)
    pictures = {jig.id: render_jig(jig) for jig in plan.jigs}
    result = JigsResult(job, planned, outputs, pictures, {})
    result.summary = jigs_manifest(result)
    return result


@station_errors
def jigs_manifest(result: JigsResult) -> dict[str, Any]:
    """``jigs.json``, a public contract (``station jigs --json`` prints it)::

        {"scenario", "content_hash", "view", "units": "mm", "layout", "material", "thickness_mm", "kerf_mm",
         "kerf_source", "sheet_mm": [w, h], "sheet_count",
         "jigs": [{"id", "kind", "part", "step", "parameters", "tag_id", "tag_center_mm", "tag_size_mm",
                   "tag_height_mm", "tag_heading_deg", "thickness_mm", "outline_mm": [[x, y], ...],
                   "support_mm": [[x, y], [x, y]] or null, "footprint_mm": [[u, v], ...], "faces", "stop",
                   "tilt_deg", "words", "notes", "pieces": [{"name", "sheet", "bbox_on_sheet_mm"}], "picture",
                   "face_tag_id", "face_tag_center_mm", "face_tag_size_mm"}],
         "by_hand": [{"part", "step", "parameters", "reason", "how", "set_with": "ruler"}],
         "skipped": [text], "sheets": [{"index", "files", "pieces", "job"}]}

    ``outline_mm``: the cut outline in the jig's own plane (a stand's: x along the table, y up from it, y = 0 the
    edge that stands on the table), as designed (the laser's path runs kerf/2 outside it); ``support_mm``: the
    segment the part rests on, in that frame, left end first; ``footprint_mm``: where the jig lies on the guide
    plane, in the guide's (u, v) mm; ``face_tag_*``: a stand's second tag, engraved on its plate's face in the jig's
    own frame (null where none fits), which the side camera reads (:mod:`station.services.check_side`).
    """
    job, plan, settings = result.job, result.plan, result.planned.settings
    placed = {}
    for output in result.sheets:
        for part, cut in zip(output.sheet.parts, output.sheet.cut_shapes):
            placed[part.name] = (output.index, [round(float(v), 3) for v in cut.bounds])
    layout = job.layout.to_dict()
    if layout.get("source"):
        layout["source"] = portable_name(layout["source"])
    return {
        "scenario": job.guide.scenario,
        "content_hash": job.guide.content_hash,
        "view": plan.view,
        "units": "mm",
        "layout": layout,
        "profile": result.planned.profile.name,
        "material": result.planned.material,
        "thickness_mm": settings.thickness,
        "kerf_mm": settings.kerf,
        "kerf_source": result.planned.kerf_source,
        "sheet_mm": list(settings.sheet),
        "sheet_count": len(result.sheets),
        "jigs": [{
            "id": jig.id,
            "kind": jig.kind,
            "part": jig.part,
            "step": jig.step,
            "parameters": list(jig.parameters),
            "tag_id": jig.tag_id,
            "tag_center_mm": None if jig.tag_center_mm is None else [_r(v) for v in jig.tag_center_mm],
            "tag_size_mm": _r(jig.tag_size_mm),
            "tag_height_mm": _r(jig.tag_height_mm),
            "tag_heading_deg": _r(jig.tag_heading_deg),
            "thickness_mm": jig.thickness_mm,
            "outline_mm": _ring(jig.outline),
            "support_mm": None if jig.support is None else [[_r(x), _r(y)] for x, y in jig.support],
            "footprint_mm": _ring(jig.footprint),
            "faces": jig.faces,
            "stop": jig.stop,
            "tilt_deg": None if jig.tilt_deg is None else _r(jig.tilt_deg),
            "words": jig.words,
            "notes": list(jig.notes),
            "pieces": [{"name": piece.name, "sheet": placed.get(piece.name, (None, None))[0],
                        "bbox_on_sheet_mm": placed.get(piece.name, (None, None))[1]} for piece in jig.pieces],
            "picture": f"jig-{jig.id}.png",
            "face_tag_id": jig.face_tag_id,
            "face_tag_center_mm": None if jig.face_tag_center_mm is None else [_r(v) for v in jig.face_tag_center_mm],
            "face_tag_size_mm": _r(jig.face_tag_size_mm),
        } for jig in plan.jigs],
        "by_hand": [{"part": b.part, "step": b.step, "parameters": list(b.parameters), "reason": b.reason,
                     "how": b.how, "set_with": b.set_with} for b in plan.by_hand],
        "skipped": list(plan.skipped),
        "sheets": [{
            "index": o.index,
            "files": {"svg": f"jigs{o.suffix}.svg", "gcode": f"jigs{o.suffix}.gcode", "png": f"sheet{o.suffix}.png"},
            "pieces": [part.name for part in o.sheet.parts],
            "job": _job(o.job),
        } for o in result.sheets],
    }


def _r(value: float) -> float:
    return round(float(value), 3) + 0.0


def _ring(polygon) -> list[list[float]]:
    return [[_r(x), _r(y)] for x, y in polygon.exterior.coords]


def _job(job) -> dict[str, Any]:
    lo, hi = job.extent()
    return {"paths": len(job.paths), "travel_mm": round(job.travel, 1),
            "estimate_seconds": {k: round(v, 1) for k, v in job.estimate_seconds().items()},
            "extent_mm": [[float(v) for v in lo], [float(v) for v in hi]]}


@station_errors
def write_jig_outputs(result: JigsResult, out: Path) -> dict[str, Path]:
    """Write jigs.svg, jigs.gcode and sheet.png (``-2``... for further sheets), jigs.json and each jig's picture
    (jig-J1.png...) into ``out``; returns them by name."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files: dict[str, Path] = {}
    for o in result.sheets:
        key = "" if o.index == 1 else f" {o.index}"
        for kind, name, content in (("svg", f"jigs{o.suffix}.svg", o.svg), ("gcode", f"jigs{o.suffix}.gcode", o.gcode)):
            files[f"{kind}{key}"] = out / name
            files[f"{kind}{key}"].write_text(content, encoding="utf-8")
        files[f"png{key}"] = out / f"sheet{o.suffix}.png"
        files[f"png{key}"].write_bytes(o.png)
    for jig_id, png in result.pictures.items():
        files[f"picture {jig_id}"] = out / f"jig-{jig_id}.png"
        files[f"picture {jig_id}"].write_bytes(png)
    files["json"] = out / "jigs.json"
    files["json"].write_text(json.dumps(to_jsonable(result.summary), indent=2, allow_nan=False) + "\n",
                             encoding="utf-8")
    return files


#: Words for where the kerf came from (jigs.json's ``kerf_source``), as ``station fabricate`` says them.
KERF_WORDS = KERF_SOURCES
