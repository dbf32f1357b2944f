"""Build an assembly :class:`~projector.guide.Guide` from a contraption scenario and a layout (pure computation).

:func:`build_guide` poses every part at the layout as the simulator would (the scene graph of
:func:`design.contraption.geometry.world_poses` and each body's pose in its object, as
:func:`design.contraption.world.build_world` does, without pybullet), chooses the guide plane
(:mod:`projector.plane`), draws each part's true outline (:mod:`projector.outline`), orders the parts
(:mod:`projector.order`), gives tags to the parts the maker places and puts the four reference tags around the
layout. :func:`steps_text` writes the steps out.

**Which view** (when none is asked for), first rule that decides:

1. the scenario has a vertical Plane (a backboard): ``side``;
2. it has a DominoRun: ``top`` (dominoes stand on the table along a path in x-y that only a top sheet shows);
3. its free layout parameters move parts more in one plane: ``side`` for z and roll, ``top`` for y and heading;
4. the view in which the parts' outlines overlap least (a sheet on which parts lie over each other is hard to
   build against).

**Tags**: a part the scenario gives a ``tag`` keeps it (id, place, size, and heading: its printed "up" is the part's
local +y in the top view, +z in the side view, turned by the tag's ``angle``); a domino run whose scenario tags sit on
its dominoes (the first and the last) carries them as :attr:`~projector.guide.PartDrawing.body_tags` and no tag of its
own. Every other part that the maker places or that a free layout parameter moves, except a ball, gets the next
free id from 0 in step order, printed turned with the part (ids the scenario uses and the reference ids 583-586 are
skipped), the largest size of 25/20/15/10 mm whose square, with a margin of
an eighth of its edge (tag36h11's white border) and at least 2 mm, fits inside its outline, at the part's centre
where it fits, else at the inside point farthest from the outline's edge, and where no other part stands in front
of it (between it and the maker, at its centre and corners); a part too small for 10 mm, or hidden, gets none.
The tag's centre lies on the part's face towards the maker; ``tag_height_mm`` is that face's distance off the plane.

**Reference tags** 583 (lower left), 584 (lower right), 585 (upper right), 586 (upper left), counter-clockwise
from the lower left as the maker sees the plane, just outside the corners of the parts' extent: their white
borders 10 mm clear of the box around every outline, so they overlap no part.

**Care** of a part from its tolerances (the smallest known delta of each unit): ``tight`` when some delta is under
2 mm or 2 deg, ``loose`` when every delta is over 6 mm or 6 deg, else ``normal``; None when none is known.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace

import numpy as np
import shapely

from design.contraption.errors import LayoutError
from design.contraption.geometry import world_poses
from design.contraption.model import Scenario
from design.contraption.primitives import body_specs
from design.contraption.schema import TRANSFORM_KEYS
from design.robust.tolerance import care_level  # the station's one rule (the tolerance table says the same)
from projector.errors import ProjectorError
from projector.guide import (
    REFERENCE_TAG_IDS,
    BodyTag,
    Guide,
    GuidePlane,
    ParameterTolerance,
    PartDrawing,
    PartKind,
    ReferenceTag,
    where_text,
)
from projector.order import PartFacts, assembly_order, part_kind
from projector.outline import PlacedBody, Surface, fit_tag, part_outline
from projector.parameters import check_set_with, describe_parts, how_text
from projector.plane import VIEWS, guide_plane, heading_in_plane, plane_normals, range_axes

__all__ = ["AUTO_TAG_SIZES_MM", "build_guide", "choose_view", "steps_text", "with_jigs"]

#: The tag sizes tried, largest first (the black square's edge, mm). None under 15 mm: a camera 1 m above the
#: plane at f = 1400 px sees a 10 mm tag 14 px across, too few for the detector to decode it reliably
#: (bench/bench_check_accuracy.py); a part with no room for 15 mm is checked by eye.
AUTO_TAG_SIZES_MM = (25.0, 20.0, 15.0)
#: Clear space between a tag's square and its part's outline, at least (mm); more for a large tag (its border).
TAG_MARGIN_MM = 2.0
#: Clear space between the parts' extent and the reference tags' white borders (mm).
REFERENCE_GAP_MM = 10.0
#: The top view's frame, for the footprints the assembly order reads (gravity is along world -z in every view).
_FLOOR = GuidePlane("top", np.zeros(3), np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]),
                    np.array([0.0, 0.0, 1.0]))


def build_guide(scenario: Scenario, x=None, *, view: str | None = None,
                tolerances: Mapping[str, ParameterTolerance] | None = None, tag_size_mm: float | None = None,
                reference_tag_size_mm: float = 40.0, set_with: Mapping[str, str] | None = None) -> Guide:
    """The assembly guide of ``scenario`` at layout ``x``.

    Parameters
    ----------
    scenario : Scenario
    x : array_like, optional
        The layout in real units (m, degrees), in design-space order; None for the scenario's default layout.
    view : {"top", "side"}, optional
        The guide plane; None chooses it from the scenario (module notes).
    tolerances : mapping of str to ParameterTolerance, optional
        Per layout parameter name (``"top_track.x"``); each part gets those of the parameters that move it.
    tag_size_mm : float, optional
        One size for every automatic part tag (a part it does not fit gets none); None picks per part.
    reference_tag_size_mm : float
        The reference tags' black square edge.
    set_with : mapping of str to str, optional
        Per layout parameter, how the guide tells the maker to set it (``"jig"`` for one a laser-cut jig sets);
        the others as :mod:`projector.parameters` says.

    Raises
    ------
    ProjectorError
        A layout outside the design space, an unknown view, tolerance or ``set_with`` parameter, a bad size or way
        of setting, a scenario tag id that is a reference tag's.
    """
    if tag_size_mm is not None:
        _check_size(tag_size_mm, "tag_size_mm")
    _check_size(reference_tag_size_mm, "reference_tag_size_mm")
    tolerances = dict(tolerances or {})
    unknown = sorted(set(tolerances) - set(scenario.design_space.names))
    if unknown:
        raise ProjectorError(f"tolerances: unknown layout parameter {unknown[0]!r}; expected one of "
                             f"{', '.join(scenario.design_space.names) or '(none: the scenario has no ranges)'}")
    check_set_with(set_with, tuple(scenario.design_space.names))
    try:
        transforms = scenario.transforms(x)
    except LayoutError as error:
        raise ProjectorError(str(error)) from error
    frames = world_poses(scenario.objects, transforms)
    bodies = {obj.name: [PlacedBody(spec.label, frames[obj.name] * spec.pose, spec) for spec in body_specs(obj)]
              for obj in scenario.objects if obj.type != "Plane" and body_specs(obj)}
    if not bodies:
        raise ProjectorError(f"{scenario.source}: the scenario has no parts to draw (only planes and frames)")
    points = np.concatenate([b.world_points() for group in bodies.values() for b in group])
    view = choose_view(scenario, frames, bodies, points) if view is None else view
    plane = guide_plane(scenario, frames, view, points)

    facts = _facts(scenario, bodies, frames)
    order = assembly_order(scenario, facts)
    drawings = []
    for step, name in enumerate(order, start=1):
        own = tuple(_parameters(scenario, name))
        known = tuple(tolerances[p] for p in own if p in tolerances)
        drawings.append(PartDrawing(
            name=name, kind=facts[name].kind, step=step, outline=part_outline(bodies[name], plane),
            center_mm=_pair(plane.to_plane(frames[name].position)[0]),
            heading_deg=heading_in_plane(frames[name].rotation, plane), parameters=own, tolerances=known,
            care=care_level(known), solids_mm=_solids(bodies[name], plane)))
    drawings = _with_tags(scenario, frames, bodies, plane, drawings, tag_size_mm)
    drawings = describe_parts(scenario, x, frames, bodies, plane, drawings, set_with)
    references = _reference_tags(drawings, reference_tag_size_mm)
    return Guide(scenario=scenario.name, content_hash=scenario.content_hash, plane=plane, parts=tuple(drawings),
                 reference_tags=references, extent_mm=_extent(drawings, references),
                 tolerance_source=_source(tolerances))


def with_jigs(guide: Guide, jigs) -> Guide:
    """The guide with the laser-cut jigs its steps use (:class:`~projector.guide.JigDrawing`): the reference tags
    move out to clear their footprints too (a stand's base reaches past its part), and the extent takes them in."""
    jigs = tuple(jigs)
    size = guide.reference_tags[0].size_mm if guide.reference_tags else 40.0
    drawn = [*guide.parts, *(_Outline(j.footprint) for j in jigs if not j.footprint.is_empty)]
    references = _reference_tags(drawn, size)
    return replace(guide, jigs=jigs, reference_tags=references, extent_mm=_extent(drawn, references))


class _Outline:
    """Something drawn on the plane with an outline (a jig's footprint), for the extent and the reference tags."""

    def __init__(self, outline) -> None:
        self.outline = outline


def choose_view(scenario: Scenario, frames, bodies: Mapping[str, list[PlacedBody]], points: np.ndarray) -> str:
    """``top`` or ``side`` for the scenario at this layout, by the module notes' rules."""
    if any(abs(normal[2]) < 0.1 for _, _, normal in plane_normals(scenario, frames)):
        return "side"
    if any(obj.type == "DominoRun" for obj in scenario.objects):
        return "top"
    axes = range_axes(scenario)
    if axes["top"] != axes["side"]:
        return "top" if axes["top"] > axes["side"] else "side"
    overlap = {}
    for view in VIEWS:
        plane = guide_plane(scenario, frames, view, points)
        outlines = [part_outline(group, plane) for group in bodies.values()]
        total = sum(o.area for o in outlines)
        overlap[view] = 1.0 - shapely.union_all(outlines).area / total if total else 0.0
    return "side" if overlap["side"] < overlap["top"] else "top"


def steps_text(guide: Guide) -> list[str]:
    """The assembly steps in words, one line per part, e.g.::

        3. Fix `bottom_track`: centre (-50.0, 60.0) mm, turned -15.0 deg, tolerance +-2.1 mm / +-1.5 deg
        1. Fix `track` (tag 0): centre (-60.0, 0.0) mm, turned 0.0 deg (...), tolerance +-4.0 mm; height above the
           table: its underside at the middle 58.7 mm (+-5.3 mm), with a ruler; tilt: 30.0 deg (+-10.6 deg), lower
           end towards `dominoes` (to your right): its underside 33.7 mm above the table at the lower end, 83.7 mm
           at the upper end, with a ruler

    Static parts are fixed, the others placed; a domino run's dominoes are stood on their outlines. The angle is
    the part's heading on the sheet, counter-clockwise as the maker sees it (said once, in the first line that has
    one; none for a ball). A run of pieces (dominoes) is stood on its outlines, located by their centroid. The
    tolerance clause gives the tightest tolerances on the sheet (left out when none is known); each parameter off
    the sheet (a height, a tilt) follows in the maker's words (:mod:`projector.parameters`) with its tolerance and
    how to set it.
    """
    facing = "seen from above" if guide.view == "top" else "facing the board"
    lines, said = [], False
    for part in guide.parts:
        verb = "Fix" if part.kind is PartKind.STATIC else "Place"
        what = f"`{part.name}`"
        if part.tag_id is not None:
            what += f" (tag {part.tag_id})"
        words = [where_text(part)]
        pieces = len(getattr(part.outline, "geoms", [part.outline]))
        if pieces > 1:
            verb, what = "Stand", f"the {pieces} pieces of {what} on their outlines"
        elif not _round(part.outline):
            angle = f"turned {part.heading_deg:.1f} deg"
            if not said:
                angle += f" (counter-clockwise, {facing})"
                said = True
            words.append(angle)
        off = {s.name for s in part.settings if not s.in_plane}
        clause = _tolerance_clause([t for t in part.tolerances if t.parameter not in off])
        if clause:
            words.append(clause)
        line = f"{part.step}. {verb} {what}: {', '.join(words)}"
        for setting in part.settings:
            if not setting.in_plane:
                line += f"; {setting.meaning}, {how_text(setting.set_with)}"
        lines.append(line)
    return lines


def _point(uv) -> str:
    # round first and add 0.0, so that -0.04 mm reads "0.0", not "-0.0"
    return "({:.1f}, {:.1f})".format(*(round(float(c), 1) + 0.0 for c in uv))


def _tolerance_clause(tolerances) -> str:
    parts = []
    for unit in ("mm", "deg"):
        deltas = [t.placement_delta for t in tolerances if t.unit == unit and t.placement_delta is not None]
        if deltas:
            parts.append(f"+-{min(deltas):.1f} {unit}")
    return "tolerance " + " / ".join(parts) if parts else ""


def _round(outline) -> bool:
    """A round outline (a ball seen from anywhere) has no heading worth saying."""
    return outline.geom_type == "Polygon" and outline.area > 0.99 * math.pi * (outline.length / (2 * math.pi)) ** 2


def _check_size(value, name: str) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise ProjectorError(f"{name}: expected a size in mm > 0, got {value!r}")


def _pair(values) -> tuple[float, float]:
    return float(values[0]), float(values[1])


def _facts(scenario: Scenario, bodies, frames) -> dict[str, PartFacts]:
    facts = {}
    for name, group in bodies.items():
        obj = scenario.object(name)
        parent = obj.parent
        while parent is not None and parent not in bodies:
            parent = scenario.object(parent).parent
        world = np.concatenate([b.world_points() for b in group])
        axes_up = np.abs(frames[name].rotation.as_matrix()[2])
        facts[name] = PartFacts(obj=obj, kind=part_kind(scenario, obj), parent=parent,
                                footprint=part_outline(group, _FLOOR), z_min=float(world[:, 2].min()),
                                z_max=float(world[:, 2].max()), axes_up=axes_up)
    return facts


def _solids(group, plane: GuidePlane) -> tuple[tuple[tuple[float, float, float], ...], ...]:
    """A part's convex collision parts as hull points on the plane's frame, ``(u, v, h)`` mm, to a tenth of a mm (a
    circle sampled at 12 points: enough for what it hides from a camera)."""
    solids = []
    for body in group:
        for part in body.solid_parts:
            world = body.pose.apply(part.surface_points(12))
            uv = plane.to_plane(world)
            h = 1000.0 * (world - np.asarray(plane.origin, float)) @ np.asarray(plane.normal, float)
            solids.append(tuple((round(float(u), 1), round(float(v), 1), round(float(z), 1))
                                for (u, v), z in zip(uv, h)))
    return tuple(solids)


def _parameters(scenario: Scenario, name: str):
    """The layout parameters that move part ``name``: its own, and those of the Empty frames it hangs from."""
    names = set(scenario.design_space.names)
    current: str | None = name
    while current is not None:
        obj = scenario.object(current)
        if current != name and obj.type != "Empty":
            break  # a parent part's parameters belong to that part's step
        for key in TRANSFORM_KEYS:
            if f"{current}.{key}" in names:
                yield f"{current}.{key}"
        current = obj.parent


def _source(tolerances: Mapping[str, ParameterTolerance]) -> str:
    # "model", "simulation", or both joined ("model+simulation") when the caller mixed them; "none" without any.
    sources = sorted({t.source for t in tolerances.values() if t.source != "none"})
    return "+".join(sources) if sources else "none"


def _with_tags(scenario, frames, bodies, plane, drawings, tag_size_mm) -> list[PartDrawing]:
    given = {obj.name: obj.tag for obj in scenario.objects if obj.tag is not None and obj.name in bodies}
    clash = sorted(name for name, tag in given.items() if tag.id in REFERENCE_TAG_IDS)
    if clash:
        raise ProjectorError(f"{scenario.source}: objects {clash[0]!r}: tag.id {given[clash[0]].id} is a reference "
                             f"tag's; expected an id other than {', '.join(map(str, REFERENCE_TAG_IDS))}")
    on_bodies = {obj.name: obj.body_tags for obj in scenario.objects if obj.body_tags and obj.name in bodies}
    used = {tag.id for tag in given.values()} | {t.id for tags in on_bodies.values() for t in tags} \
        | set(REFERENCE_TAG_IDS)
    next_id = 0
    sizes = AUTO_TAG_SIZES_MM if tag_size_mm is None else (float(tag_size_mm),)
    surfaces = {name: Surface(group, plane) for name, group in bodies.items()}
    result = []
    for part in drawings:
        obj = scenario.object(part.name)
        if part.name in on_bodies:  # a run's first and last dominoes carry its tags
            result.append(replace(part, body_tags=tuple(_body_tag(bodies[part.name][tag.body], tag, plane)
                                                        for tag in on_bodies[part.name])))
            continue
        if part.name in given:
            tag = given[part.name]
            world = frames[part.name].apply([tag.x, tag.y, tag.z])
            centre = plane.to_plane(world)[0]
            height = 1000.0 * float((world - plane.origin) @ plane.normal)
            result.append(replace(part, tag_id=tag.id, tag_center_mm=_pair(centre), tag_size_mm=1000.0 * tag.size,
                                  tag_height_mm=height, tag_heading_deg=_tag_heading(frames[part.name], plane,
                                                                                     part.heading_deg, tag.angle)))
            continue
        wants = obj.type != "Ball" and (part.kind is PartKind.PLACED or part.parameters)
        group = bodies[part.name]
        fit = None
        if wants:
            centre = plane.to_plane(group[0].pose.position)[0] if len(group) == 1 else part.center_mm
            others = [(other.outline, surfaces[other.name]) for other in drawings if other.name != part.name]
            fit = _fit(part, surfaces[part.name], others, centre, sizes)
        if fit is None:
            result.append(part)
            continue
        while next_id in used:
            next_id += 1
        (u, v), size = fit
        result.append(replace(part, tag_id=next_id, tag_center_mm=(u, v), tag_size_mm=size,
                              tag_height_mm=_face_height(surfaces[part.name], group, (u, v)),
                              tag_heading_deg=part.heading_deg))  # printed turned with the part (the sheets' square)
        used.add(next_id)
    return result


def _body_tag(body: PlacedBody, tag, plane: GuidePlane) -> BodyTag:
    """A scenario tag on one body of a part (its place in the body's frame)."""
    world = body.pose.apply([tag.x, tag.y, tag.z])
    heading = heading_in_plane(body.pose.rotation, plane)
    return BodyTag(body=int(tag.body), tag_id=tag.id, tag_center_mm=_pair(plane.to_plane(world)[0]),
                   tag_size_mm=1000.0 * tag.size,
                   tag_height_mm=1000.0 * float((np.ravel(world) - plane.origin) @ plane.normal),
                   tag_heading_deg=_tag_heading(body.pose, plane, heading, tag.angle),
                   center_mm=_pair(plane.to_plane(body.pose.position)[0]), heading_deg=heading)


def _tag_heading(frame, plane: GuidePlane, heading: float, angle: float) -> float:
    """A scenario tag's heading on the plane: its printed "up" is the part's local +y (top view) or +z (side view)
    seen on the plane, turned by ``angle``; the part's ``heading`` when that axis points at the camera."""
    up = frame.rotation.apply([0.0, 1.0, 0.0] if plane.view == "top" else [0.0, 0.0, 1.0])
    along_u, along_v = float(up @ plane.u_axis), float(up @ plane.v_axis)
    base = math.degrees(math.atan2(-along_u, along_v)) if math.hypot(along_u, along_v) > 1e-6 else heading
    heading = (base + float(angle) + 180.0) % 360.0 - 180.0
    return 180.0 if heading == -180.0 else heading


def _face_height(surface: Surface, group, uv) -> float:
    height = surface.height(uv)
    if height is None:  # the ray slipped past a sampled curve: the part's top is the face
        plane = surface.plane
        height = max(1000.0 * float(np.max((b.world_points() - plane.origin) @ plane.normal)) for b in group)
    return height


def _fit(part: PartDrawing, surface: Surface, others, centre, sizes):
    """Where the largest tag fits on the part and no other part hides it from the maker (centre and corners)."""

    def visible(square) -> bool:
        u, v = square.centroid.x, square.centroid.y
        face = surface.height((u, v))
        if face is None:
            return False  # the square's centre misses the part's surface (between two walls, say)
        near = [other for outline, other in others if outline.intersects(square)]  # only these can hide it
        for point in [(u, v), *list(square.exterior.coords)[:4]]:
            for other in near:
                above = other.height(point)
                if above is not None and above > face + 0.5:
                    return False
        return True

    for size in sizes:
        margin = max(TAG_MARGIN_MM, size / 8.0)
        fit = fit_tag(part.outline, [centre], [size], part.heading_deg, margin, visible)
        if fit is not None:
            return fit
    return None


def _reference_tags(drawings, size: float) -> tuple[ReferenceTag, ...]:
    u0, v0, u1, v1 = shapely.union_all([d.outline for d in drawings]).bounds
    offset = REFERENCE_GAP_MM + size / 8.0 + size / 2.0  # gap, white border, half the black square
    corners = [(u0 - offset, v0 - offset), (u1 + offset, v0 - offset), (u1 + offset, v1 + offset),
               (u0 - offset, v1 + offset)]
    return tuple(ReferenceTag(id=tag_id, center_mm=corner, size_mm=float(size))
                 for tag_id, corner in zip(REFERENCE_TAG_IDS, corners))


def _extent(drawings, references) -> tuple[float, float, float, float]:
    u0, v0, u1, v1 = shapely.union_all([d.outline for d in drawings]).bounds
    for tag in references:
        half = tag.size_mm / 2.0 + tag.size_mm / 8.0
        u0, v0 = min(u0, tag.center_mm[0] - half), min(v0, tag.center_mm[1] - half)
        u1, v1 = max(u1, tag.center_mm[0] + half), max(v1, tag.center_mm[1] + half)
    return float(u0), float(v0), float(u1), float(v1)
