"""Placement jigs for a contraption layout: what to cut so that a maker sets heights, tilts and tight positions by
touch, not by eye (pure geometry, millimetres).

Three kinds, each cut from the laser's sheet material (thickness ``t``):

**Stand** (a guide seen from above, for a part with a height or tilt parameter). A *plate* stands on edge on the
table in the vertical plane through the part's middle, along the part's tilted axis (its local x or y, the one that
leaves the table most; for a level part the longer one). Its top edge is the part's underside, cut through the
part's collision shapes at the layout (:mod:`design.jigs.section`): the part rests on it at its height and tilt. At
the part's lower end a *stop* rises past the edge, as tall as the part's own section there (at most
:data:`STOP_MAX_MM`), so the part cannot slide off and nothing rolling along the part meets it (a track's stop is
its floor's thickness). The plate stands in the slot of a *base* laid flat on the table on its outline drawn on the
guide sheet; the slot is the plate's length and thickness, so the plate's foot stands on the table itself and the
heights do not depend on the material's thickness. The base carries the jig's AprilTag beside the part (where the
camera above sees it, on the side where fewer other parts stand) and the jig's name.

**Board stand** (a guide on a backboard, for a part with a height or tilt parameter). One plate pinned flat on the
board on its outline drawn on the sheet: its top edge is the part's underside at the plate's depth, with the stop at
the lower end, the tag and name engraved below. A part that stands further off the board than the plate is thick
cannot rest on it (its values are drawn on the sheet).

**Template** (a guide seen from above, for a part on the table whose in-plane parameter the tolerance map rates
tight). A plate laid flat on its outline on the sheet with a *pocket* through it: the part's section just above the
table, plus :data:`POCKET_CLEARANCE_MM` all round. The part is set in the pocket and the template lifted off.

**Jig frame** (``outline``, ``support``): a stand's plate in its own plane, x along the table (to the right as seen
from its engraved face), y up, y = 0 the edge that stands on the table, so a support point's y is its height above
the table. A board stand's: x along the board (the guide's u), y up, y = 0 its lower edge. A template's: x, y along
the guide's u, v, from its lower-left corner. ``footprint`` is where the jig lies on the guide plane, in (u, v) mm.

What cannot get a jig gets a :class:`ByHand` entry saying why and how to set the value: a part hanging from a rope,
a plate larger than the sheet, a part too low for a base under it, a stand that would pass through another part, a
piece that would come out empty, in several pieces or with an outline crossing itself (checked before it is cut or
combined), and any other shape shapely cannot compute for that part's jig (its message in the reason): one part's
jig never stops the plan.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import shapely
import shapely.affinity as affinity
from shapely.errors import GEOSException
from shapely.geometry import Polygon, box
from shapely.geometry.base import BaseGeometry
from shapely.geometry.polygon import orient

from design.contraption.geometry import world_poses
from design.contraption.model import Scenario
from design.contraption.primitives import body_specs
from design.errors import ParameterError
from design.fabrication.labels import place_label
from design.jigs.engrave import tag_strokes
from design.jigs.section import PlaneFrame, SolidPart, part_solids, section, solid_heights

__all__ = ["BASE_MARGIN_MM", "ByHand", "Jig", "JigPlan", "JigSettings", "PartInput", "Piece", "POCKET_CLEARANCE_MM",
           "SLOT_CLEARANCE_MM", "STOP_MAX_MM", "STOP_WIDTH_MM", "plan_jigs"]

#: Material of the base all round the slot, and of a template all round its pocket (mm).
BASE_MARGIN_MM = 8.0
#: Extra length and width of a base's slot over the plate (mm): a snug fit that still lets the plate down to the
#: table (the laser's path is kerf-compensated, so the slot comes out at this size).
SLOT_CLEARANCE_MM = 0.1
#: Clearance of a template's pocket round the part (mm, each side).
POCKET_CLEARANCE_MM = 0.2
#: The stop's length along the support (mm) and its largest height over it.
STOP_WIDTH_MM = 5.0
STOP_MAX_MM = 8.0
#: Least height of a stand's support over the base's top (mm): a part lower than this rests on the base instead.
MIN_CLEARANCE_MM = 2.0
#: Below this tilt (degrees) the part is level: the stop goes at its right end as seen from the engraved face.
LEVEL_DEG = 0.5
#: Height of engraved names (mm); they shrink to fit small plates.
LABEL_MM = 4.0
#: Room round an engraved tag: its white border (an eighth of its edge) plus this much (mm).
TAG_ROOM_MM = 2.0
#: The keys of a layout parameter in and out of each view's plane.
OUT_OF_PLANE = {"top": ("z", "roll", "pitch"), "side": ("y", "heading", "pitch")}
IN_PLANE = {"top": ("x", "y", "heading"), "side": ("x", "z", "roll")}
#: Primitives that tie a part to a rope: a part at one of their ends hangs.
ROPES = ("TensionRope", "RopePulley")


@dataclass(frozen=True)
class PartInput:
    """A part of the guide: its name, step, the layout parameters that move it and its outline on the guide plane."""

    name: str
    step: int
    parameters: tuple[str, ...]
    outline: BaseGeometry


@dataclass(frozen=True)
class JigSettings:
    """The sheet material and sizes the jigs are cut for (mm)."""

    thickness: float
    sheet: tuple[float, float]
    gap: float = 3.0
    kerf: float = 0.15
    tag_size: float = 20.0

    def __post_init__(self) -> None:
        for name, value in (("thickness", self.thickness), ("tag_size", self.tag_size)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ParameterError(f"jigs: {name} must be a positive length in mm, got {value!r}")


@dataclass(frozen=True)
class Piece:
    """One flat piece to cut: its shape (as designed, before kerf compensation) and strokes to engrave, in its own
    frame (mm)."""

    name: str
    shape: Polygon
    engrave: tuple[np.ndarray, ...] = ()


@dataclass(frozen=True)
class Jig:
    """One jig (module notes: kinds and frames).

    Attributes
    ----------
    id : str
        ``"J1"``, ``"J2"``... in step order.
    kind : str
        ``"stand"``, ``"board stand"`` or ``"template"``.
    part, step : str, int
        The part it sets and that part's step.
    parameters : tuple of str
        The design parameters it sets.
    outline : Polygon
        The plate's outline in the jig frame (as designed; the laser's path is kerf-compensated).
    support : tuple of two (x, y) or None
        The segment the part rests on, in the jig frame, left end first (None for a template).
    footprint : Polygon
        Where it lies on the guide plane, (u, v) mm (a stand's base, a board stand's plate, a template).
    section : geometry
        The part's own section in the jig frame (what rests on the support).
    silhouette : geometry
        The whole part seen square to the jig's plane, in the jig frame (pictures of the part resting on it).
    pieces : tuple of Piece
        What to cut: the plate, and a stand's base.
    faces : str or None
        Which way the plate's engraved face looks, in the guide's words (``"front"``: towards the maker).
    stop : str or None
        The part's end the stop holds, in the maker's words (``"lower end"``, ``"right end"``).
    tilt_deg : float or None
        The support's slope in the jig frame, counter-clockwise from +x.
    words : str
        The step's words for the maker.
    """

    id: str
    kind: str
    part: str
    step: int
    parameters: tuple[str, ...]
    thickness_mm: float
    outline: Polygon
    support: tuple[tuple[float, float], tuple[float, float]] | None
    footprint: Polygon
    section: BaseGeometry
    silhouette: BaseGeometry
    pieces: tuple[Piece, ...]
    words: str
    tag_id: int | None = None
    tag_center_mm: tuple[float, float] | None = None
    tag_size_mm: float = 20.0
    tag_height_mm: float = 0.0
    tag_heading_deg: float = 0.0
    faces: str | None = None
    stop: str | None = None
    tilt_deg: float | None = None
    notes: tuple[str, ...] = ()
    #: A stand's second tag, engraved on its plate's face (jig frame, mm): a camera facing that face (the side
    #: camera's board) measures the plate's height and tilt through it.
    face_tag_id: int | None = None
    face_tag_center_mm: tuple[float, float] | None = None
    face_tag_size_mm: float = 20.0
    #: A stand's jig frame in the scene, on its engraved face: ``(origin, x axis, y axis, face normal)``, the origin
    #: in metres (the plate's lower left end as seen from that face), the axes unit vectors.
    face_frame: tuple[tuple[float, float, float], ...] | None = None


@dataclass(frozen=True)
class ByHand:
    """Parameters no jig sets: why, and how the maker sets them."""

    part: str
    step: int
    parameters: tuple[str, ...]
    reason: str
    how: str
    set_with: str = "ruler"


@dataclass(frozen=True)
class JigPlan:
    """The jigs of a layout, and the parameters left to a ruler."""

    view: str
    jigs: tuple[Jig, ...]
    by_hand: tuple[ByHand, ...] = ()
    skipped: tuple[str, ...] = field(default=())

    @property
    def pieces(self) -> list[Piece]:
        return [piece for jig in self.jigs for piece in jig.pieces]


class _NoJig(Exception):
    """Why a part gets no jig (the reason, in words)."""


def plan_jigs(scenario: Scenario, x, plane, parts: Sequence[PartInput], settings: JigSettings, *,
              tight: frozenset[str] | set[str] = frozenset(), tag_ids: Iterator[int] | None = None,
              tag_cells: Callable[[int], np.ndarray] | None = None) -> JigPlan:
    """The jigs of ``scenario`` at layout ``x`` on the guide ``plane``.

    Parameters
    ----------
    scenario, x
        The scenario and its layout (real units), as the guide was built from.
    plane
        The guide plane: ``view`` (``"top"`` or ``"side"``), ``origin``, ``u_axis``, ``v_axis``, ``normal`` (world)
        and ``to_plane`` (world m to (u, v) mm), e.g. a :class:`projector.guide.GuidePlane`.
    parts : sequence of PartInput
        The guide's parts in step order.
    settings : JigSettings
    tight : set of str
        In-plane layout parameters whose tolerance is tight: their parts get a template.
    tag_ids : iterator of int, optional
        Free AprilTag ids for the jigs, in the order to use them (none: no tags).
    tag_cells : callable, optional
        ``tag_cells(id)``: the tag's 10 x 10 cells, True white (``vision.tags.tag_cells``).
    """
    transforms = scenario.transforms(x)
    frames = world_poses(scenario.objects, transforms)
    solids = {obj.name: part_solids((frames[obj.name] * spec.pose, spec) for spec in body_specs(obj))
              for obj in scenario.objects if obj.type != "Plane" and body_specs(obj)}
    view = plane.view
    context = _Context(scenario, frames, solids, plane, parts, settings, tag_ids, tag_cells)
    jigs: list[Jig] = []
    by_hand: list[ByHand] = []
    skipped: list[str] = []
    for part in parts:
        obj = scenario.object(part.name)
        if obj.type == "Ball" or part.name not in solids:
            continue
        keys = {name: name.rsplit(".", 1)[1] for name in part.parameters}
        shaping = tuple(name for name, key in keys.items() if key in OUT_OF_PLANE[view]) if view == "top" else \
            tuple(name for name, key in keys.items() if key in ("z", "roll"))
        out_of_plane = tuple(name for name, key in keys.items() if key in OUT_OF_PLANE[view])
        if shaping:
            try:
                jig = _made(context.stand if view == "top" else context.board_stand, part, f"J{len(jigs) + 1}")
            except _NoJig as reason:
                if out_of_plane:
                    by_hand.append(ByHand(part.name, part.step, out_of_plane, str(reason),
                                          _by_hand_words(part.name, out_of_plane, view)))
                else:
                    skipped.append(f"{part.name}: {reason}")
                continue
            jigs.append(_after(jig, jigs))
            continue
        if out_of_plane:
            by_hand.append(ByHand(part.name, part.step, out_of_plane,
                                  "no jig holds a part at a depth in front of the board",
                                  _by_hand_words(part.name, out_of_plane, view)))
        wanted = tuple(name for name in part.parameters if name in tight and keys[name] in IN_PLANE[view])
        if wanted and view == "top":
            try:
                jigs.append(_after(_made(context.template, part, f"J{len(jigs) + 1}"), jigs))
            except _NoJig as reason:
                skipped.append(f"{part.name}: {reason}")
    return JigPlan(view, tuple(jigs), tuple(by_hand), tuple(skipped))


def _made(make: Callable[[PartInput, str], Jig], part: PartInput, jig_id: str) -> Jig:
    """``make(part, jig_id)``; a shape shapely cannot compute for it refused as any other reason, with its message."""
    try:
        return make(part, jig_id)
    except GEOSException as error:
        raise _NoJig(f"its jig's shape cannot be computed at this layout (shapely: {str(error).split('. ')[0]})") \
            from error


def _piece(shape: BaseGeometry, what: str) -> Polygon:
    """``shape`` as one piece to cut, or the reason it cannot be: empty, in several pieces, or an outline that
    crosses itself (which shapely refuses to combine with anything)."""
    if shape.is_empty or shape.area <= 0.0:
        raise _NoJig(f"its {what} would be empty")
    if not isinstance(shape, Polygon):
        raise _NoJig(f"its {what} would come out in {len(shape.geoms)} pieces")
    if not shape.is_valid:
        raise _NoJig(f"its {what}'s outline would cross itself ({shapely.is_valid_reason(shape)})")
    return shape


def _after(jig: Jig, earlier: Sequence[Jig]) -> Jig:
    """``jig``, with a note when it lies where an earlier jig lies (that one must be taken away first)."""
    taken = [other.id for other in earlier if other.footprint.intersection(jig.footprint).area > 1.0]
    if not taken:
        return jig
    return replace(jig, notes=(*jig.notes, f"it lies where jig {', '.join(taken)} lies: take that one away first"))


def _by_hand_words(part: str, parameters: Sequence[str], view: str) -> str:
    keys = [name.rsplit(".", 1)[1] for name in parameters]
    tools = []
    if any(k in ("z", "y") for k in keys):
        tools.append("a ruler (height above the table)" if view == "top" else "a ruler (depth in front of the board)")
    if any(k in ("roll", "pitch", "heading") for k in keys):
        tools.append("a protractor (tilt)")
    return f"set `{part}` with {' and '.join(tools) or 'a ruler'} to the values the guide gives"


class _Context:
    """What every jig of one plan reads: the scene at the layout, the plane, the other parts, the settings."""

    def __init__(self, scenario, frames, solids, plane, parts, settings: JigSettings, tag_ids, tag_cells) -> None:
        self.scenario = scenario
        self.frames = frames
        self.solids: Mapping[str, list[SolidPart]] = solids
        self.plane = plane
        self.parts = parts
        self.settings = settings
        self.tag_ids = tag_ids
        self.tag_cells = tag_cells
        self.origin = np.asarray(plane.origin, dtype=float)
        self.normal = np.asarray(plane.normal, dtype=float)
        self.u_axis = np.asarray(plane.u_axis, dtype=float)
        self.v_axis = np.asarray(plane.v_axis, dtype=float)
        self.heights = {name: solid_heights(group, self.origin, self.normal) for name, group in solids.items()}

    # -- shared checks -------------------------------------------------------------------------------------------

    def _hanging(self, name: str) -> bool:
        for obj in self.scenario.objects:
            if obj.type in ROPES:
                ends = obj.shape.get("ends", ())
                if any(end == name or str(end).startswith(name + "[") for end in ends):
                    return True
        return False

    def _fits_sheet(self, shape: Polygon) -> bool:
        minx, miny, maxx, maxy = shape.bounds
        w, h = maxx - minx, maxy - miny
        room = 2.0 * self.settings.gap + self.settings.kerf
        sheet_w, sheet_h = self.settings.sheet
        return (w + room <= sheet_w and h + room <= sheet_h) or (h + room <= sheet_w and w + room <= sheet_h)

    def _too_large(self, shape: Polygon, what: str) -> _NoJig:
        minx, miny, maxx, maxy = shape.bounds
        sheet_w, sheet_h = self.settings.sheet
        return _NoJig(f"its {what} would be {maxx - minx:.0f} x {maxy - miny:.0f} mm, larger than the "
                      f"{sheet_w:g} x {sheet_h:g} mm sheet")

    def _next_tag(self) -> int | None:
        if self.tag_ids is None or self.tag_cells is None:
            return None
        return next(self.tag_ids, None)

    def _table_outlines(self, name: str) -> BaseGeometry:
        """The guide outlines of the other parts that lie on the plane (where a base or template would lie)."""
        limit = self.settings.thickness + 1.0
        shapes = [p.outline for p in self.parts
                  if p.name != name and p.name in self.heights and self.heights[p.name][0] < limit]
        return shapely.union_all(shapes) if shapes else Polygon()

    def _silhouette(self, name: str, frame: PlaneFrame) -> BaseGeometry:
        """The part's solids projected square onto ``frame``'s plane (mm)."""
        hulls = [shapely.MultiPoint(frame.coordinates(s.points)).convex_hull for s in self.solids[name]]
        return shapely.union_all([h for h in hulls if isinstance(h, Polygon)])

    def _dynamic(self, name: str) -> bool:
        return not self.scenario.object(name).physics.static

    # -- the plate under a part (stands on the table and on a board) --------------------------------------------

    def _stand_axis(self, name: str) -> np.ndarray:
        """The horizontal direction of the stand: the part's tilted axis (local x or y), else its longer one."""
        rotation = self.frames[name].rotation
        axes = [rotation.apply([1.0, 0.0, 0.0]), rotation.apply([0.0, 1.0, 0.0])]
        rise = [abs(float(a @ self.normal)) for a in axes]
        points = np.concatenate([s.points for s in self.solids[name]])
        extent = [float(np.ptp(points @ a)) for a in axes]
        if max(rise) > math.sin(math.radians(LEVEL_DEG)):
            order = [0, 1] if rise[0] >= rise[1] else [1, 0]
        else:
            order = [0, 1] if extent[0] >= extent[1] else [1, 0]
        for index in order:
            flat = axes[index] - float(axes[index] @ self.normal) * self.normal
            if np.linalg.norm(flat) > 0.2:
                flat /= np.linalg.norm(flat)
                along_u, along_v = float(flat @ self.u_axis), float(flat @ self.v_axis)
                # x runs to the right as the maker sees the engraved face: towards +u, or away (+v) when across
                if along_u < -1e-9 or (abs(along_u) <= 1e-9 and along_v < 0):
                    flat = -flat
                return flat
        raise _NoJig("it stands upright: no edge of a plate can carry it")

    def _support(self, name: str, cut: BaseGeometry, frame: PlaneFrame) -> tuple[np.ndarray, np.ndarray]:
        """The longest downward-facing edge of the section's hull, left end first; refused when it is only a sliver
        of the part (a rim cut by the plate's plane)."""
        if cut.is_empty:
            raise _NoJig("its shape does not cross the jig's plane")
        hull = orient(cut.convex_hull.simplify(0.01), 1.0)  # collinear hull points split an edge in two
        coords = np.asarray(hull.exterior.coords)
        best, best_length = None, 0.0
        for a, b in zip(coords[:-1], coords[1:]):
            edge = b - a
            length = float(np.hypot(*edge))
            if length < 1e-9:
                continue
            outward = np.array([edge[1], -edge[0]]) / length
            if outward[1] < -0.5 and length > best_length:
                best, best_length = (a, b), length
        if best is None or best_length < 5.0:
            raise _NoJig("it has no flat underside to rest on an edge")
        a, b = best
        a, b = (a, b) if a[0] <= b[0] else (b, a)
        direction = (b - a) / best_length
        world = direction[0] * frame.e1 + direction[1] * frame.e2
        points = np.concatenate([s.points for s in self.solids[name]])
        extent = 1000.0 * float(np.ptp(points @ world))
        if best_length < 0.4 * extent:
            raise _NoJig(f"only {best_length:.0f} mm of its {extent:.0f} mm underside reaches the jig's plane")
        return a, b

    def _blocked(self, name: str, plate: Polygon, frame: PlaneFrame) -> list[tuple[float, float, str]]:
        """Where along the plate (x intervals, with 2 mm of room) another part's section meets it, and which."""
        half = self.settings.thickness / 2000.0
        blocked = []
        for other, group in self.solids.items():
            if other == name or self._child_of(other, name):
                continue
            for offset in (-half, 0.0, half):
                cut = section(group, frame.shifted(offset))
                if not cut.is_empty and cut.intersection(plate).area > 0.5:
                    minx, _, maxx, _ = cut.bounds
                    blocked.append((minx - 2.0, maxx + 2.0, other))
        return blocked

    def _plate(self, name: str, cut: BaseGeometry, frame: PlaneFrame, band: float | None = None):
        """The plate under the part's underside, cut back from other parts, with its stop: down to the table
        (y = 0), or with ``band`` a strip that deep under the support (a board stand).

        Returns (plate, A, B, stop end ``"a"``, ``"b"`` or None, the lower end, tilt in degrees, notes); A and B the
        support's ends.
        """
        a, b = self._support(name, cut, frame)
        if band is None and min(a[1], b[1]) < 0.0:  # no plate stands between the table and a part under its top
            raise _NoJig(f"its underside reaches {-min(a[1], b[1]):.1f} mm below the table top: the layout puts "
                         "it through the table")

        def ground(x: float) -> float:
            if band is None:
                return 0.0
            return float(a[1] + (x - a[0]) * (b[1] - a[1]) / (b[0] - a[0]) - band)

        tilt = math.degrees(math.atan2(b[1] - a[1], b[0] - a[0]))
        # the stop holds the lower end; a level part's right end (as seen from the engraved face)
        lower = ("b" if b[1] < a[1] else "a") if abs(tilt) >= LEVEL_DEG else "b"
        full = _piece(Polygon([(a[0], ground(a[0])), (b[0], ground(b[0])), tuple(b), tuple(a)]), "plate")
        blocked = self._blocked(name, full, frame)
        notes = []
        start, end = float(a[0]), float(b[0])
        if blocked:
            free = _free_intervals(start, end, [(lo, hi) for lo, hi, _ in blocked])
            longest = max(free, key=lambda i: i[1] - i[0], default=None)
            if longest is None or longest[1] - longest[0] < max(20.0, 0.4 * (end - start)):
                raise _NoJig(f"a stand under it would pass through `{blocked[0][2]}`")
            names = sorted({other for _, _, other in blocked})
            notes.append(f"its plate is cut back to clear {', '.join(f'`{n}`' for n in names)}")
            start, end = longest
        along = (b - a) / np.linalg.norm(b - a)

        def at(s: float) -> np.ndarray:
            return a + (s - a[0]) / along[0] * along

        a2, b2 = at(start), at(end)
        free_ends = [e for e, clipped in (("a", start > a[0] + 1e-6), ("b", end < b[0] - 1e-6)) if not clipped]
        order = [lower, "a" if lower == "b" else "b"]
        stop = next((e for e in order if e in free_ends), None)
        base = Polygon([(a2[0], ground(a2[0])), (b2[0], ground(b2[0])), tuple(b2), tuple(a2)])
        plate = base
        if stop is not None:
            with_stop = self._with_stop(base, cut, a2 if stop == "a" else b2, along if stop == "b" else -along,
                                        ground)
            if self._blocked(name, with_stop, frame):
                notes.append("it has no stop: another part stands where the stop would")
                stop = None
            else:
                plate = with_stop
        return _piece(orient(shapely.simplify(plate, 0.005), 1.0), "plate"), a2, b2, stop, lower, tilt, notes

    @staticmethod
    def _with_stop(plate: Polygon, cut: BaseGeometry, end: np.ndarray, outward: np.ndarray,
                   ground: Callable[[float], float]) -> Polygon:
        """The plate with a stop past ``end``: a tab as tall as the part's section there (at most STOP_MAX_MM)."""
        up = np.array([-outward[1], outward[0]])
        if up[1] < 0:
            up = -up
        inward = -outward
        strip = Polygon([end - 0.01 * inward - 1.0 * up, end + 2.0 * inward - 1.0 * up,
                         end + 2.0 * inward + 100.0 * up, end - 0.01 * inward + 100.0 * up])
        near = cut.intersection(strip)
        rise = 1.0
        if not near.is_empty:
            polygons = [g for g in getattr(near, "geoms", [near]) if isinstance(g, Polygon)]
            if polygons:
                points = np.concatenate([np.asarray(g.exterior.coords) for g in polygons])
                rise = float(np.max((points - end) @ up))
        height = min(max(rise, 1.0), STOP_MAX_MM)
        tab = [end, end + STOP_WIDTH_MM * outward, end + STOP_WIDTH_MM * outward + height * up, end + height * up]
        under = shapely.MultiPoint([*tab, *[(p[0], ground(p[0])) for p in tab]]).convex_hull
        union = shapely.union_all([plate, Polygon(tab).buffer(0), under])
        union = union.buffer(0.001, join_style="mitre").buffer(-0.001, join_style="mitre")
        return union if isinstance(union, Polygon) else max(union.geoms, key=lambda g: g.area)

    def _stop_words(self, stop: str | None, lower: str, tilt: float) -> str:
        if stop is None:
            return ""
        if abs(tilt) < LEVEL_DEG:
            return "right end" if stop == "b" else "left end"
        return "lower end" if stop == lower else "upper end"

    # -- stands on the table -------------------------------------------------------------------------------------

    def stand(self, part: PartInput, jig_id: str) -> Jig:
        name, t = part.name, self.settings.thickness
        if self._hanging(name):
            raise _NoJig("it hangs from a rope: nothing can stand under it")
        d = self._stand_axis(name)
        f = np.cross(self.normal, d)  # across the plate, towards its back; the engraved face looks to -f
        centre = self.frames[name].position
        foot = centre - float((centre - self.origin) @ self.normal) * self.normal
        frame = PlaneFrame(foot, d, self.normal)
        cut = section(self.solids[name], frame)
        plate, a, b, stop, lower, tilt, notes = self._plate(name, cut, frame)
        low = min(a[1], b[1])
        if low < t + MIN_CLEARANCE_MM:
            raise _NoJig(f"its underside comes down to {low:.1f} mm above the table: no room for a stand's base "
                         "under it")
        if not self._fits_sheet(plate):
            raise self._too_large(plate, "stand")
        x0 = plate.bounds[0]
        outline = affinity.translate(plate, -x0, 0.0)
        support = ((float(a[0] - x0), float(a[1])), (float(b[0] - x0), float(b[1])))
        length = outline.bounds[2]
        # the base's frame: x along the plate from its left end, y across it towards f; on the plane:
        d_uv = np.array([d @ self.u_axis, d @ self.v_axis])
        f_uv = np.array([f @ self.u_axis, f @ self.v_axis])
        origin_uv = self.plane.to_plane(foot)[0] + x0 * d_uv
        to_uv = np.array([[d_uv[0], f_uv[0]], [d_uv[1], f_uv[1]]])
        inverse = np.linalg.inv(to_uv)

        def uv_of(geometry: BaseGeometry) -> BaseGeometry:
            return affinity.affine_transform(geometry, [*to_uv.ravel(), *origin_uv])

        def base_of(geometry: BaseGeometry) -> BaseGeometry:
            return affinity.affine_transform(geometry, [*inverse.ravel(), *(-inverse @ origin_uv)])

        shadow = base_of(part.outline)
        across = np.concatenate([np.asarray(g.exterior.coords)[:, 1] for g in getattr(shadow, "geoms", [shadow])])
        half = t / 2.0
        slot = box(-SLOT_CLEARANCE_MM, -half - SLOT_CLEARANCE_MM / 2, length + SLOT_CLEARANCE_MM,
                   half + SLOT_CLEARANCE_MM / 2)
        rect = box(-BASE_MARGIN_MM, -half - BASE_MARGIN_MM, length + BASE_MARGIN_MM, half + BASE_MARGIN_MM)
        size = self.settings.tag_size
        room = size * 1.25 / 2.0 + TAG_ROOM_MM
        others = base_of(self._table_outlines(name))
        choices = []
        for side in (-1.0, 1.0):  # the maker's side of the plate first
            edge = max(float(across.max()), half) if side > 0 else min(float(across.min()), -half)
            tag_centre = (length / 2.0, edge + side * (room + 1.0))
            tag_box = box(tag_centre[0] - room, tag_centre[1] - room, tag_centre[0] + room, tag_centre[1] + room)
            reach = box(tag_box.bounds[0], min(0.0, tag_box.bounds[1]), tag_box.bounds[2], max(0.0, tag_box.bounds[3]))
            shape = shapely.union_all([rect, reach])
            clash = shape.intersection(others).area if not others.is_empty else 0.0
            choices.append((clash, side, shape, tag_centre, tag_box))
        clash, side, shape, tag_centre, tag_box = min(choices, key=lambda c: c[0])
        if clash > 0.0:
            shape = shape.difference(others.buffer(1.0))
            shape = max(getattr(shape, "geoms", [shape]), key=lambda g: g.intersection(slot).area)
            # the slot may open at an end where another part stands: the plate is still held along most of it
            if shape.buffer(-1.5).intersection(slot).area < 0.7 * slot.area:
                raise _NoJig("no room on the table for the stand's base beside the other parts")
            notes.append("its base is cut back where other parts stand")
        tag_id = self._next_tag() if shape.contains(tag_box) else None
        base_shape = _piece(orient(shape.difference(slot), 1.0), "base")
        free = base_shape.difference(tag_box) if tag_id is not None else base_shape
        engrave = tag_strokes(self.tag_cells(tag_id), size, tag_centre) if tag_id is not None else []
        label = place_label(free, f"{jig_id} {name}", LABEL_MM, near=(length / 2.0, -side * (half + 4.0)))
        engrave += label
        if stop is not None:
            engrave += place_label(free.difference(_strokes_box(label)), "STOP", 3.0,
                                   near=(length if stop == "b" else 0.0, -side * (half + 4.0)))
        plate_face = _compass(-f_uv)
        face_tag, face_size, face_box = self._face_tag(outline, affinity.translate(self._silhouette(name, frame),
                                                                                   -x0, 0.0))
        face = outline.difference(face_box) if face_tag is not None else outline
        plate_label = place_label(face, f"{jig_id} {name}", LABEL_MM, near=(length / 2.0, 0.0))
        plate_engrave = list(tag_strokes(self.tag_cells(face_tag[0]), face_size, face_tag[1])) \
            if face_tag is not None else []
        plate_engrave += plate_label + place_label(face.difference(_strokes_box(plate_label)),
                                                  f"this face {plate_face}", 3.0, near=(length / 2.0, 0.0))
        end_words = self._stop_words(stop, lower, tilt)
        rest = f"{end_words} against the stop" if stop else "its ends over its outline on the sheet"
        words = (f"Stand jig {jig_id} on its outline (drawn on the sheet), its plate in the base's slot with the "
                 f"engraved face to the {plate_face}; rest `{name}` on it, {rest}"
                 + ("; fix its mount, then lift the jig away" if self._dynamic(name) else "; leave the jig under it"))
        heading = math.degrees(math.atan2(-f_uv[0], f_uv[1]))
        tag_uv = tuple(float(c) for c in (to_uv @ np.asarray(tag_centre) + origin_uv)) if tag_id is not None else None
        parameters = tuple(p for p in part.parameters if p.rsplit(".", 1)[1] in OUT_OF_PLANE["top"]
                           or (stop is not None and self._along(p, d)))
        return Jig(jig_id, "stand", name, part.step, parameters, t, outline, support, orient(uv_of(shape), 1.0),
                   affinity.translate(cut, -x0, 0.0), affinity.translate(self._silhouette(name, frame), -x0, 0.0),
                   (Piece(jig_id, outline, tuple(plate_engrave)), Piece(f"{jig_id} base", base_shape, tuple(engrave))),
                   words, tag_id=tag_id, tag_center_mm=tag_uv, tag_size_mm=size, tag_height_mm=t,
                   tag_heading_deg=_angle(heading), faces=plate_face, stop=end_words or None, tilt_deg=tilt,
                   notes=tuple(notes), face_tag_id=None if face_tag is None else face_tag[0],
                   face_tag_center_mm=None if face_tag is None else face_tag[1], face_tag_size_mm=face_size,
                   face_frame=self._face_frame(foot, x0, d, f))

    def _face_frame(self, foot: np.ndarray, x0: float, d: np.ndarray, f: np.ndarray) -> tuple:
        """The stand's jig frame on its engraved face, in the scene (:attr:`Jig.face_frame`)."""
        origin = np.asarray(foot, float) + (x0 * d - self.settings.thickness / 2.0 * f) / 1000.0
        return tuple(tuple(float(c) for c in vector) for vector in (origin, d, self.normal, -f))

    def _face_tag(self, outline: Polygon, silhouette: BaseGeometry):
        """Where a tag fits on a stand's face: ``((id, centre), size, box)`` in the jig frame, clear of the base's
        slot (the plate's lowest thickness) and of the part resting on it; ``(None, size, empty)`` when none fits (the
        settings' size first, then 15 mm) or no id is free."""
        t = self.settings.thickness
        for size in dict.fromkeys((self.settings.tag_size, min(self.settings.tag_size, 15.0))):
            room = size * 1.25 / 2.0 + TAG_ROOM_MM
            free = outline.difference(box(-1e3, -1e3, 1e4, t + 1.0))
            if not silhouette.is_empty:
                free = free.difference(silhouette.buffer(1.0))
            centres = free.buffer(-room, join_style="mitre")
            if centres.is_empty:
                continue
            # the centres' region nearest the plate's tall end, low down: the tag sits where the plate is widest
            biggest = max(getattr(centres, "geoms", [centres]), key=lambda g: g.area)
            centre = biggest.representative_point() if biggest.area < 1.0 else biggest.centroid
            if not biggest.contains(centre):
                centre = biggest.representative_point()
            tag_box = box(centre.x - room, centre.y - room, centre.x + room, centre.y + room)
            if not free.contains(tag_box):
                continue
            tag_id = self._next_tag()
            if tag_id is None:
                break
            return (tag_id, (float(centre.x), float(centre.y))), size, tag_box
        return None, self.settings.tag_size, Polygon()

    def _along(self, parameter: str, d: np.ndarray) -> bool:
        """Whether an in-plane position parameter moves the part along the stand (its stop then sets it)."""
        obj_name, key = parameter.rsplit(".", 1)
        if key not in ("x", "y"):
            return False
        parent = self.scenario.object(obj_name).parent
        axis = np.array([1.0, 0.0, 0.0] if key == "x" else [0.0, 1.0, 0.0])
        world = self.frames[parent].rotation.apply(axis) if parent is not None else axis
        return abs(float(world @ d)) > math.cos(math.radians(5.0))

    def _child_of(self, name: str, parent: str) -> bool:
        obj = self.scenario.object(name)
        while obj.parent is not None:
            if obj.parent == parent:
                return True
            obj = self.scenario.object(obj.parent)
        return False

    # -- stands on a board ---------------------------------------------------------------------------------------

    def board_stand(self, part: PartInput, jig_id: str) -> Jig:
        name, t = part.name, self.settings.thickness
        if self._hanging(name):
            raise _NoJig("it hangs from a rope: nothing can stand under it")
        near, _ = self.heights[name]
        if near >= t:
            raise _NoJig(f"it stands {near:.0f} mm in front of the board, beyond a {t:g} mm plate lying on it")
        depth = min(max(t / 2.0, near + 0.5), t - 0.05)
        frame = PlaneFrame(self.origin + depth / 1000.0 * self.normal, self.u_axis, self.v_axis)
        cut = section(self.solids[name], frame)
        size = self.settings.tag_size
        room = size * 1.25 / 2.0 + TAG_ROOM_MM
        a, b = self._support(name, cut, frame)
        slope = abs(float((b[1] - a[1]) / (b[0] - a[0])))
        # deep enough for the tag's square in the sloping strip; where another part lies under the part on the board,
        # a strip just deep enough for the name (no tag)
        for band in (2.0 * room * (1.0 + slope) + 6.0, LABEL_MM + 8.0):
            try:
                plate, a, b, stop, lower, tilt, notes = self._plate(name, cut, frame, band)
                break
            except _NoJig as refused:
                reason = refused
        else:
            raise reason
        if not self._fits_sheet(plate):
            raise self._too_large(plate, "plate")
        x0, ground = plate.bounds[0], plate.bounds[1]
        outline = affinity.translate(plate, -x0, -ground)
        support = ((float(a[0] - x0), float(a[1] - ground)), (float(b[0] - x0), float(b[1] - ground)))
        middle = ((support[0][0] + support[1][0]) / 2.0, (support[0][1] + support[1][1]) / 2.0 - band / 2.0)
        tag_box = box(middle[0] - room, middle[1] - room, middle[0] + room, middle[1] + room)
        tag_id = self._next_tag() if outline.contains(tag_box) else None
        tag_centre = middle
        engrave = tag_strokes(self.tag_cells(tag_id), size, tag_centre) if tag_id is not None else []
        free = outline.difference(tag_box) if tag_id is not None else outline
        engrave += place_label(free, f"{jig_id} {name}", LABEL_MM, near=(middle[0] - room - 30.0, middle[1]))
        end_words = self._stop_words(stop, lower, tilt)
        rest = f"{end_words} against the stop" if stop else "its ends over its outline on the sheet"
        words = (f"Pin jig {jig_id} flat on its outline on the sheet, engraved face out; rest `{name}` on its top "
                 f"edge, {rest}" + ("; fix its mount, then take the jig away" if self._dynamic(name) else ""))
        tag_uv = (float(tag_centre[0] + x0), float(tag_centre[1] + ground)) if tag_id is not None else None
        parameters = tuple(p for p in part.parameters if p.rsplit(".", 1)[1] in ("z", "roll")
                           or (stop is not None and p.rsplit(".", 1)[1] == "x"))
        return Jig(jig_id, "board stand", name, part.step, parameters, t, outline, support,
                   orient(plate, 1.0), affinity.translate(cut, -x0, -ground),
                   affinity.translate(self._silhouette(name, frame), -x0, -ground),
                   (Piece(jig_id, outline, tuple(engrave)),), words, tag_id=tag_id, tag_center_mm=tag_uv,
                   tag_size_mm=size, tag_height_mm=t, tag_heading_deg=0.0, faces="out", stop=end_words or None,
                   tilt_deg=tilt, notes=tuple(notes))

    # -- templates -----------------------------------------------------------------------------------------------

    def template(self, part: PartInput, jig_id: str) -> Jig:
        name, t = part.name, self.settings.thickness
        low, high = self.heights[name]
        if low > 1.0:
            raise _NoJig(f"it stands {low:.0f} mm above the table, where a template cannot lie")
        level = min(t / 2.0, max(high - low, 0.2) / 2.0) + max(low, 0.0)
        frame = PlaneFrame(self.origin + level / 1000.0 * self.normal, self.u_axis, self.v_axis)
        cut = section(self.solids[name], frame)
        if cut.is_empty:
            raise _NoJig("its shape does not reach the table")
        pocket = shapely.union_all([Polygon(g.exterior) for g in getattr(cut, "geoms", [cut])
                                    if isinstance(g, Polygon)]).buffer(POCKET_CLEARANCE_MM, join_style="mitre")
        body = pocket.convex_hull.buffer(BASE_MARGIN_MM + 4.0, join_style="mitre")
        size = self.settings.tag_size
        room = size * 1.25 / 2.0 + TAG_ROOM_MM
        others = self._table_outlines(name)
        minx, miny, maxx, maxy = body.bounds
        middle = ((minx + maxx) / 2.0, (miny + maxy) / 2.0)
        choices = []
        for centre in ((middle[0], miny - room + 1.0), (middle[0], maxy + room - 1.0),
                       (minx - room + 1.0, middle[1]), (maxx + room - 1.0, middle[1])):
            tag_box = box(centre[0] - room, centre[1] - room, centre[0] + room, centre[1] + room)
            shape = shapely.union_all([body, tag_box.buffer(1.0, join_style="mitre")]).convex_hull
            clash = shape.intersection(others).area if not others.is_empty else 0.0
            choices.append((clash, centre, tag_box, shape))
        clash, tag_centre, tag_box, shape = min(choices, key=lambda c: c[0])
        notes = []
        if clash > 0.0:
            shape = shape.difference(others.buffer(1.0))
            shape = max(getattr(shape, "geoms", [shape]), key=lambda g: g.intersection(pocket).area)
            if not shape.buffer(-1.0).contains(pocket):
                raise _NoJig("no room on the table for a template round it")
            notes.append("it is cut back where other parts stand")
        if not self._fits_sheet(shape):
            raise self._too_large(shape, "template")
        tag_id = self._next_tag() if shape.contains(tag_box) else None
        plate = _piece(orient(shape.difference(pocket), 1.0), "template")
        u0, v0 = plate.bounds[0], plate.bounds[1]
        outline = affinity.translate(plate, -u0, -v0)
        engrave = []
        if tag_id is not None:
            engrave += tag_strokes(self.tag_cells(tag_id), size, (tag_centre[0] - u0, tag_centre[1] - v0))
        free = outline.difference(affinity.translate(tag_box, -u0, -v0)) if tag_id is not None else outline
        engrave += place_label(free, f"{jig_id} {name}", LABEL_MM, near=(middle[0] - u0, middle[1] - v0))
        keys = IN_PLANE["top"]
        parameters = tuple(p for p in part.parameters if p.rsplit(".", 1)[1] in keys)
        words = (f"Lay jig {jig_id} on its outline (drawn on the sheet), engraved face up; set `{name}` in its "
                 "pocket, then lift the jig off")
        return Jig(jig_id, "template", name, part.step, parameters, t, outline, None, plate,
                   affinity.translate(cut, -u0, -v0),
                   affinity.translate(self._silhouette(name, frame), -u0, -v0),
                   (Piece(jig_id, outline, tuple(engrave)),), words,
                   tag_id=tag_id, tag_center_mm=(float(tag_centre[0]), float(tag_centre[1]))
                   if tag_id is not None else None, tag_size_mm=size, tag_height_mm=t, tag_heading_deg=0.0,
                   faces="up", notes=tuple(notes))


def _free_intervals(start: float, end: float, blocked: Sequence[tuple[float, float]]) -> list[tuple[float, float]]:
    """The parts of ``[start, end]`` outside every blocked interval."""
    free = [(start, end)]
    for low, high in blocked:
        free = [piece for a, b in free for piece in ((a, min(b, low)), (max(a, high), b)) if piece[1] > piece[0]]
    return free


def _strokes_box(strokes: Sequence[np.ndarray]) -> BaseGeometry:
    """The box round a label's strokes, with a millimetre of room (empty for no label)."""
    if not strokes:
        return Polygon()
    points = np.concatenate(strokes)
    return box(*points.min(axis=0), *points.max(axis=0)).buffer(1.0, join_style="mitre")


def _compass(direction: np.ndarray) -> str:
    """A direction on the guide plane in the maker's words: front (towards the maker), back, left or right."""
    u, v = float(direction[0]), float(direction[1])
    if abs(v) >= abs(u):
        return "front" if v < 0 else "back"
    return "left" if u < 0 else "right"


def _angle(degrees: float) -> float:
    value = (degrees + 180.0) % 360.0 - 180.0
    return 180.0 if value == -180.0 else value + 0.0
