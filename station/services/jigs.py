"""Placement jigs as a service: a layout's stands and templates, nested on the laser's sheet, with their laser job.

Used by ``station jigs``, ``station guide --jigs`` and the Assemble screen. The geometry is :mod:`design.jigs`
(which parts get which jig and why); this module reads the scenario and the layout through the guide (the jigs stand
on the guide's plane, next to its parts and tags), takes the material's thickness and kerf from the laser profile's
material table, nests the pieces with the fabrication's nesting and writes the files ``station fabricate`` writes:
``jigs.svg``, ``jigs.gcode`` (engraving, then each piece's holes and outline; the beam dark on every travel; checked
against the work area), ``sheet.png``, plus ``jigs.json`` (:func:`jigs_manifest`, a public contract) and a picture
of each jig with its part on it (``jig-J1.png``...).

**Tags**: each jig gets an AprilTag (tag36h11) from :data:`JIG_TAG_IDS`, the ids just under the reference tags
(the side camera's board 579-582, the table's 583-586), and a stand a second one engraved on its plate's face (for
the side camera): the guide numbers the parts' own tags from 0 and skips the ids a scenario gives, so the two ranges
meet only in a guide of 500 tagged parts; an id the guide uses is skipped all the same.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from common.progress import ProgressCallback, Reporter
from station.cli_util import to_jsonable
from station.errors import ServiceError, station_errors
from station.services.fabricate import DEFAULT_GAP, DEFAULT_KERF, KERF_SOURCES, SheetOutput, laser_sheets, parse_sheet

__all__ = ["JIG_TAG_IDS", "JigOptions", "JigsResult", "PlannedJigs", "attach_jigs", "check_options", "cut_jigs",
           "jigs_manifest", "make_jigs", "plan_guide_jigs", "write_jig_outputs"]

#: The AprilTag ids the jigs take, in order (module notes): up to the side camera's board tags (579-582).
JIG_TAG_IDS = tuple(range(500, 579))
#: Progress stages: planning the jigs (one step), nesting (one step), then the sheets' laser jobs.
PLAN_STAGE, NESTING_STAGE = "planning", "nesting"


@dataclass(frozen=True)
class JigOptions:
    """What the jigs are cut from and on: a laser profile (a name or a loaded profile), one of its materials, the
    kerf (None: the material's), the sheet (None: the work area) and the gap between pieces, in mm."""

    profile: Any = "laser"
    material: str | None = None
    kerf: float | None = None
    sheet: tuple[float, float] | str | None = None
    gap: float = DEFAULT_GAP


@dataclass(frozen=True)
class PlannedJigs:
    """A layout's jigs (:class:`design.jigs.JigPlan`) and the material they are planned for."""

    plan: Any
    settings: Any
    profile: Any
    material: str
    kerf_source: str


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


def _profile(profile):
    from drivers.profiles import load_profile

    return load_profile(profile) if isinstance(profile, (str, Path)) else profile


@station_errors
def plan_guide_jigs(job, options: JigOptions | None = None) -> PlannedJigs:
    """The jigs of a guide job's layout (:func:`station.services.guide.make_guide`), for ``options``' material.

    Raises
    ------
    ServiceError
        A bad sheet (``sheet``), kerf (``kerf``) or gap (``gap``).
    drivers.errors.JobRefused, drivers.profiles.ProfileError
        A profile that is not a laser's, or a material it does not have (the message lists them).
    """
    from design.jigs import PartInput, plan_jigs
    from design.robust.tolerance import CARE_RULE
    from vision.tags import tag_cells

    profile, material_name, settings, source = check_options(options)
    guide = job.guide
    parts = [PartInput(p.name, p.step, tuple(p.parameters), p.outline) for p in guide.parts]
    tight = {t.parameter for p in guide.parts for t in p.tolerances
             if t.placement_delta is not None and t.placement_delta < CARE_RULE[t.unit][0]}
    used = {t.id for t in guide.reference_tags} | {p.tag_id for p in guide.parts if p.tag_id is not None} \
        | {b.tag_id for p in guide.parts for b in p.body_tags}
    free = iter([i for i in JIG_TAG_IDS if i not in used])
    plan = plan_jigs(job.scenario, job.layout.x, guide.plane, parts, settings, tight=tight, tag_ids=free,
                     tag_cells=tag_cells)
    return PlannedJigs(plan, settings, profile, material_name, source)


@station_errors
def check_options(options: JigOptions | None = None):
    """``(profile, material name, design.jigs.JigSettings, kerf source)`` of ``options``, refused before any work.

    Raises
    ------
    ServiceError
        A bad sheet (``sheet``), kerf (``kerf``) or gap (``gap``).
    drivers.errors.JobRefused, drivers.profiles.ProfileError
        A profile that is not a laser's, or a material it does not have (the message lists them).
    """
    from cam.laser import material_settings
    from design.jigs import JigSettings

    options = options or JigOptions()
    profile = _profile(options.profile)
    _, _, material_name = material_settings(profile, options.material)
    material = profile.material(material_name)
    kerf, source = _kerf(options.kerf, material.kerf)
    sheet = options.sheet
    if isinstance(sheet, str):
        sheet = parse_sheet(sheet)
    width, height = sheet if sheet is not None else (profile.width, profile.height)
    if isinstance(options.gap, bool) or not isinstance(options.gap, (int, float)) \
            or not 0 <= options.gap < min(width, height) / 4:
        raise ServiceError(f"gap must be a length in mm from 0 to a quarter of the sheet, got {options.gap!r}",
                           field="gap", value=options.gap)
    settings = JigSettings(thickness=float(material.thickness), sheet=(float(width), float(height)),
                           gap=float(options.gap), kerf=float(kerf))
    return profile, material_name, settings, source


def _kerf(given: float | None, material_kerf: float | None) -> tuple[float, str]:
    import math

    if given is None:
        return (DEFAULT_KERF, "default") if material_kerf is None else (float(material_kerf), "material")
    if isinstance(given, bool) or not isinstance(given, (int, float)) or not math.isfinite(given) \
            or not 0 <= given <= 2:
        raise ServiceError(f"kerf must be a width in mm from 0 to 2, got {given!r}", field="kerf", value=given)
    return float(given), "given"


@station_errors
def attach_jigs(job, planned: PlannedJigs):
    """The guide job with its jigs: the parameters they set marked ``set_with: "jig"`` (the guide rebuilt with
    them), each jig's footprint on the guide and its words in its part's step."""
    from dataclasses import replace as replace_job

    from projector.build import build_guide, steps_text, with_jigs
    from projector.guide import JigDrawing

    plan = planned.plan
    set_with = {name: "jig" for jig in plan.jigs for name in jig.parameters}
    guide = job.guide
    if set_with:
        tolerances = {t.parameter: t for p in guide.parts for t in p.tolerances}
        rebuilt = build_guide(job.scenario, job.layout.x, view=guide.view, tolerances=tolerances or None,
                              set_with=set_with)
        guide = replace(rebuilt, tolerance_source=guide.tolerance_source, tolerance_note=guide.tolerance_note,
                        headline=guide.headline, pages=guide.pages)
    drawings = tuple(JigDrawing(id=j.id, part=j.part, kind=j.kind, footprint=j.footprint, parameters=j.parameters,
                                words=j.words, tag_id=j.tag_id, tag_center_mm=j.tag_center_mm,
                                tag_size_mm=j.tag_size_mm, tag_height_mm=j.tag_height_mm,
                                tag_heading_deg=j.tag_heading_deg, face_tag_id=j.face_tag_id)
                     for j in plan.jigs)
    guide = with_jigs(guide, drawings)
    steps = jig_steps(steps_text(guide), guide, plan)
    return replace_job(job, guide=guide, steps=tuple(steps), jigs=planned)


@station_errors
def jig_steps(lines: list[str], guide, plan) -> list[str]:
    """The guide's steps with each jig's words first in its part's step (``"1. Stand jig J1 ...; then: Fix ..."``)
    and, for a part left to a ruler, why no jig sets it."""
    by_step = {part.step: part.name for part in guide.parts}
    jigs = {jig.part: jig for jig in plan.jigs}
    by_hand = {entry.part: entry for entry in plan.by_hand}
    result = []
    for line in lines:
        number, _, rest = line.partition(". ")
        name = by_step.get(int(number)) if number.isdigit() else None
        if name in jigs:
            line = f"{number}. {jigs[name].words}. Then: {rest}"
        elif name in by_hand:
            line = f"{line} (no jig: {by_hand[name].reason})"
        result.append(line)
    return result


@station_errors
def make_jigs(scenario: str, layout: str | None, options: JigOptions | None = None, *, view: str | None = None,
              tolerances: bool = True, physics: str | None = None,
              progress: Reporter | ProgressCallback | None = None) -> JigsResult:
    """The jigs of ``layout`` for ``scenario`` (read as ``station guide`` reads them), nested and with their laser
    job.

    Raises
    ------
    ServiceError, design.errors.DesignError, projector.errors.ProjectorError, drivers.errors.JobRefused
        Bad input: the message names the value (a sheet, kerf, material, layout, scenario).
    """
    from station.services.guide import make_guide

    report = Reporter.of(progress)
    options = options or JigOptions()
    check_options(options)  # a bad sheet, kerf or material before the guide's work
    job = make_guide(scenario, layout, view=view, tolerances=tolerances, physics=physics, progress=report)
    report(PLAN_STAGE, 0, 1, "planning the jigs")
    planned = plan_guide_jigs(job, options)
    job = attach_jigs(job, planned)
    report(PLAN_STAGE, 1, 1, f"{len(planned.plan.jigs)} jig{'' if len(planned.plan.jigs) == 1 else 's'}")
    return cut_jigs(job, planned, report)


@station_errors
def cut_jigs(job, planned: PlannedJigs, progress: Reporter | ProgressCallback | None = None) -> JigsResult:
    """Nest a plan's pieces on the sheet and make its laser job, its files' contents and the jigs' pictures.

    Raises
    ------
    design.errors.ConstraintViolation
        The pieces need more than four sheets.
    """
    from cam.laser import material_settings
    from design.fabrication import Part, nest_sheets
    from design.jigs.render import render_jig

    report = Reporter.of(progress)
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
        from station.services.guide import portable_name

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
