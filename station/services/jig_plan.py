"""A guide's jigs planned: which parts get a laser-cut stand or template, for which laser profile and material (its
thickness and kerf), on which sheet, and the guide redrawn with them (each jig's footprint on its sheets, its words
in its part's step). :func:`station.services.guide.make_guide` plans them on request; cutting them (nesting, the
laser job, the files) is :mod:`station.services.jigs`'s.

**Tags**: each jig gets an AprilTag (tag36h11) from :data:`JIG_TAG_IDS`, the ids just under the reference tags
(the side camera's board 579-582, the table's 583-586), and a stand a second one engraved on its plate's face (for
the side camera): the guide numbers the parts' own tags from 0 and skips the ids a scenario gives, so the two ranges
meet only in a guide of 500 tagged parts; an id the guide uses is skipped all the same.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from cam.laser import material_settings
from design.jigs import JigSettings, PartInput, plan_jigs
from design.robust.tolerance import CARE_RULE
from drivers.profiles import load_profile
from projector.build import build_guide, steps_text, with_jigs
from projector.guide import JigDrawing
from station.errors import ServiceError, station_errors
from station.services.fabricate import DEFAULT_GAP, DEFAULT_KERF, parse_sheet
from vision.tags import tag_cells

__all__ = ["JIG_TAG_IDS", "JigOptions", "PlannedJigs", "attach_jigs", "check_options", "jig_steps", "plan_guide_jigs"]

#: The AprilTag ids the jigs take, in order (module notes): up to the side camera's board tags (579-582).
JIG_TAG_IDS = tuple(range(500, 579))


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


def _profile(profile):
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
    return replace(job, guide=guide, steps=tuple(steps), jigs=planned)


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
