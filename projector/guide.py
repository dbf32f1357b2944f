"""The assembly guide as data: what every output (PDF, SVG, projected frames, manifest) draws.

A guide is drawn on one plane of a contraption scenario, the **guide plane**, in millimetres, as the maker sees it
when facing the plane from the side where the parts stand: ``u`` runs to the maker's right, ``v`` away from the
maker (``top``: the table) or up (``side``: the backboard); headings are counter-clockwise as the maker sees them.
Every later step of the assembly (camera check, projector mapping, trials) speaks these coordinates.

This module holds the types only; :mod:`projector.build` makes a :class:`Guide` from a scenario and a layout, and
:mod:`projector.pdf`, :mod:`projector.svg` and :mod:`projector.frames` draw one. The JSON manifest
(:meth:`Guide.manifest`) is a public contract read by other programs: keep its names.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np
from shapely.geometry.base import BaseGeometry

__all__ = [
    "CARE_LEVELS",
    "IN_PLANE_ROLES",
    "SET_WITH",
    "BodyTag",
    "Elevation",
    "FIRST_REFERENCE_TAG",
    "REFERENCE_TAG_IDS",
    "Guide",
    "GuidePage",
    "GuidePlane",
    "JigDrawing",
    "PartDrawing",
    "PartKind",
    "PartParameter",
    "ParameterTolerance",
    "ReferenceTag",
    "where_point",
    "where_text",
    "where_word",
]

#: The reference tags take the top of the family, so they never clash with part tags (numbered from 0).
REFERENCE_TAG_IDS = (583, 584, 585, 586)
FIRST_REFERENCE_TAG = REFERENCE_TAG_IDS[0]
#: How carefully a part must be placed, from its tolerances.
CARE_LEVELS = ("tight", "normal", "loose")
#: How the guide tells the maker to set a parameter: on its outline on the sheet, with a ruler (or protractor), with
#: a laser-cut jig, or on the sheet and then measured by the camera check (a tagged part).
SET_WITH = ("sheet", "ruler", "jig", "check")
#: What a parameter does on the guide plane: moves the part along ``u`` or ``v``, turns it about the plane's normal
#: (these three the sheet shows), or moves it off the plane (``height``: above the table, or in front of the board)
#: or tilts it about an axis in the plane (``tilt``), which no sheet can show.
IN_PLANE_ROLES = ("u", "v", "turn")


@dataclass(frozen=True)
class GuidePlane:
    """A plane of the scene and its (u, v) millimetre frame.

    Parameters
    ----------
    view : str
        ``"top"`` (the table) or ``"side"`` (a backboard).
    origin : ndarray, shape (3,)
        The world point (metres) at ``(u, v) = (0, 0)``.
    u_axis, v_axis : ndarray, shape (3,)
        Unit world vectors of ``u`` (the maker's right) and ``v`` (away, or up).
    normal : ndarray, shape (3,)
        Unit world vector out of the plane towards the side where the parts stand (and the maker); ``u × v``.
    """

    view: str
    origin: np.ndarray
    u_axis: np.ndarray
    v_axis: np.ndarray
    normal: np.ndarray

    def to_plane(self, points_m: np.ndarray) -> np.ndarray:
        """World points (metres, shape (n, 3)) projected on the plane, in (u, v) millimetres (shape (n, 2))."""
        points = np.atleast_2d(np.asarray(points_m, dtype=float)) - self.origin
        return 1000.0 * np.column_stack([points @ self.u_axis, points @ self.v_axis])

    def to_world(self, uv_mm: np.ndarray, height_mm: float = 0.0) -> np.ndarray:
        """Plane points (u, v) mm, at ``height_mm`` above the plane along its normal, as world points in metres."""
        uv = np.atleast_2d(np.asarray(uv_mm, dtype=float)) / 1000.0
        return (self.origin + np.outer(uv[:, 0], self.u_axis) + np.outer(uv[:, 1], self.v_axis)
                + (height_mm / 1000.0) * self.normal)


class PartKind(str, Enum):
    """How a part is drawn: one the maker places, or one that is fixed (a support, a static part, a plane)."""

    PLACED = "placed"
    STATIC = "static"

    def __str__(self) -> str:
        return self.value


@dataclass(frozen=True)
class ParameterTolerance:
    """How far one free layout parameter may be off on its own while the predicted success stays high.

    Parameters
    ----------
    parameter : str
        The layout parameter (``"top_track.x"``).
    delta : float or None
        The largest error ±delta tolerated, in the parameter's guide unit (``unit``); None when unknown (no model).
    unit : str
        ``"mm"`` or ``"deg"``.
    predicted : float or None
        The predicted success at ±delta (the worse side), as a fraction of the layout's predicted success.
    measured : float or None
        With ``--verify N``: the success rate measured by simulation at ±delta (None when not verified).
    source : str
        ``"model"`` (the layout's fitted success model), ``"simulation"`` or ``"none"``.
    bound_limited : bool
        The design space's range ends before the success falls: ``delta`` is then only a lower bound of the
        tolerance (the layout sits at or near the range's end), not a limit the maker must keep to.
    """

    parameter: str
    delta: float | None
    unit: str
    predicted: float | None = None
    measured: float | None = None
    source: str = "model"
    bound_limited: bool = False

    @property
    def placement_delta(self) -> float | None:
        """The ±delta the maker must keep to: None when unknown, or only bound by the range's end."""
        return None if self.bound_limited else self.delta


@dataclass(frozen=True)
class PartParameter:
    """One design parameter of a part, as the guide tells the maker to set it.

    Parameters
    ----------
    name : str
        The layout parameter (``"track.z"``).
    value : float
        Its value at the layout, in ``unit`` (a position in mm, an angle in degrees).
    unit : str
        ``"mm"`` or ``"deg"``.
    role : str
        What it does on the guide plane: ``"u"``, ``"v"``, ``"turn"`` (on the sheet), ``"height"`` or ``"tilt"`` (off
        it; :data:`IN_PLANE_ROLES`).
    meaning : str
        The maker's words: a named point of the part and where it goes, the tilt and which way it falls, the turn.
    set_with : str
        How the guide tells the maker to set it (:data:`SET_WITH`).
    tolerance : ParameterTolerance or None
        Its tolerance, when one is known.
    """

    name: str
    value: float
    unit: str
    role: str
    meaning: str
    set_with: str
    tolerance: ParameterTolerance | None = None

    @property
    def in_plane(self) -> bool:
        """Whether the sheet shows it (a place along u or v, a turn on the plane)."""
        return self.role in IN_PLANE_ROLES


@dataclass(frozen=True)
class Elevation:
    """A part alone seen from the side, for the parameters the sheet cannot show (its height and tilt).

    Coordinates ``(s, h)`` in mm: ``s`` along :attr:`direction_uv` on the guide plane (drawn to the right), ``h`` off
    the plane along its normal (above the table, or in front of the board); ``h = 0`` is the table (the board).

    Parameters
    ----------
    direction_uv : tuple of float
        The unit direction on the guide plane drawn to the right.
    seen_from : str
        Where the maker looks at it from, in words (``"from the front"``).
    profile : shapely geometry
        The part's outline seen that way (the union of its collision parts' projections).
    ends : tuple of two (s, h)
        The underside (the back, on a board) at each end of the part along its length: the lower end first.
    middle : tuple of float
        The underside at the middle between the two ends.
    tilt_deg : float
        The angle between the part's length and the plane (>= 0; 0 when level).
    toward : str
        Which way the lower end points, in words (``"towards `dominoes` (to your right)"``); for a standing part,
        which way its top leans; empty when level (or upright).
    standing : bool
        The part's length is its own up axis (a goblet, a post): it leans :attr:`lean_deg` from upright, its lower
        end its foot.
    axis : tuple of two (s, h), optional
        The part's length as drawn: from the middle of its lower end to the middle of its upper end (the angle is
        measured along it).
    """

    direction_uv: tuple[float, float]
    seen_from: str
    profile: BaseGeometry
    ends: tuple[tuple[float, float], tuple[float, float]]
    middle: tuple[float, float]
    tilt_deg: float
    toward: str = ""
    standing: bool = False
    axis: tuple[tuple[float, float], tuple[float, float]] | None = None

    @property
    def lean_deg(self) -> float:
        """How far a standing part leans from upright (the complement of :attr:`tilt_deg`)."""
        return 90.0 - self.tilt_deg

    @property
    def level(self) -> bool:
        """Level (or, standing, upright) to the printed 0.1 deg: no tilt to set."""
        return (self.lean_deg if self.standing else self.tilt_deg) < 0.05


@dataclass(frozen=True)
class BodyTag:
    """A tag on one body of a part made of many (a domino of a run: the first and the last are tagged).

    Parameters
    ----------
    body : int
        The body's index in the part (0 the first domino).
    tag_id : int
    tag_center_mm : tuple of float
        Where the tag's centre goes, on the plane.
    tag_size_mm, tag_height_mm, tag_heading_deg : float
        As :class:`PartDrawing`'s.
    center_mm : tuple of float
        The body's origin on the plane.
    heading_deg : float
        The body's heading on the plane.
    """

    body: int
    tag_id: int
    tag_center_mm: tuple[float, float]
    tag_size_mm: float
    tag_height_mm: float
    tag_heading_deg: float
    center_mm: tuple[float, float]
    heading_deg: float


@dataclass(frozen=True)
class PartDrawing:
    """One part of the contraption on the guide plane.

    Parameters
    ----------
    name : str
        The scenario object's name.
    kind : PartKind
        Placed by the maker, or static (drawn differently).
    step : int
        Its assembly number (1-based; the order of :attr:`Guide.parts`).
    outline : shapely geometry
        Its true outline on the plane in millimetres: the union of its collision parts' projections (concave where
        the part is), a Polygon or a MultiPolygon (a run of dominoes).
    center_mm : tuple of float
        The part's origin on the plane.
    heading_deg : float
        Its rotation in the plane, counter-clockwise as the maker sees it.
    tag_id : int or None
        The AprilTag stuck on the part (None for a part without one: a ball, a static part).
    tag_center_mm : tuple of float or None
        Where the tag's centre goes, on the plane.
    tag_size_mm : float
        The tag's black square edge.
    tag_height_mm : float
        How far the tag's face stands off the plane (the camera check maps it through a plane at that height).
    tag_heading_deg : float
        The direction of the tag's printed "up" on the plane, counter-clockwise as the maker sees it, 0 = +v: the
        part's heading for a tag the guide places, the scenario tag's own (its ``angle``) otherwise.
    parameters : tuple of str
        The free layout parameters that move this part.
    tolerances : tuple of ParameterTolerance
        Their tolerances (empty when none are known).
    care : str or None
        ``"tight"``, ``"normal"`` or ``"loose"`` from its tolerances; None when unknown.
    body_tags : tuple of BodyTag
        Tags on single bodies of the part (a domino run's first and last), checked in its stead.
    settings : tuple of PartParameter
        Every parameter of :attr:`parameters` as the maker sets it (value, meaning, tolerance, how).
    elevation : Elevation or None
        The part seen from the side, when a parameter moves it off the plane (a height, a tilt).
    solids_mm : tuple of tuples of (u, v, h)
        Its convex collision parts, each as points on its hull in mm: ``(u, v)`` on the plane, ``h`` off it (above the
        table): what of it stands in front of the side camera's board (:mod:`projector.board`).
    """

    name: str
    kind: PartKind
    step: int
    outline: BaseGeometry
    center_mm: tuple[float, float]
    heading_deg: float
    tag_id: int | None = None
    tag_center_mm: tuple[float, float] | None = None
    tag_size_mm: float = 20.0
    tag_height_mm: float = 0.0
    tag_heading_deg: float = 0.0
    parameters: tuple[str, ...] = ()
    tolerances: tuple[ParameterTolerance, ...] = ()
    care: str | None = None
    body_tags: tuple[BodyTag, ...] = ()
    settings: tuple[PartParameter, ...] = ()
    elevation: Elevation | None = None
    solids_mm: tuple[tuple[tuple[float, float, float], ...], ...] = ()

    def tag_views(self) -> tuple[PartDrawing, ...]:
        """Every tag the part carries, each as the part with that tag (its own, then those on its bodies): what the
        sheets, the SVG and the frames draw a tag square for."""
        own = (self,) if self.tag_id is not None and self.tag_center_mm is not None else ()
        return own + tuple(replace(self, tag_id=b.tag_id, tag_center_mm=b.tag_center_mm, tag_size_mm=b.tag_size_mm,
                                   tag_height_mm=b.tag_height_mm, tag_heading_deg=b.tag_heading_deg, body_tags=())
                           for b in self.body_tags)


@dataclass(frozen=True)
class JigDrawing:
    """A laser-cut placement jig on the guide (:mod:`design.jigs`): where it lies and what the maker does with it.

    Parameters
    ----------
    id : str
        ``"J1"``...
    part : str
        The part it sets.
    kind : str
        ``"stand"``, ``"board stand"`` or ``"template"``.
    footprint : shapely Polygon
        Where it lies on the plane (a stand's base, a board stand's plate, a template), mm.
    parameters : tuple of str
        The layout parameters it sets.
    words : str
        What the maker does with it, in the part's step.
    tag_id : int or None
        Its engraved AprilTag; ``tag_center_mm``, ``tag_size_mm``, ``tag_height_mm``, ``tag_heading_deg`` as a
        part's.
    """

    id: str
    part: str
    kind: str
    footprint: BaseGeometry
    parameters: tuple[str, ...] = ()
    words: str = ""
    tag_id: int | None = None
    tag_center_mm: tuple[float, float] | None = None
    tag_size_mm: float = 20.0
    tag_height_mm: float = 0.0
    tag_heading_deg: float = 0.0
    #: A stand's second tag, engraved on its plate's face for the side camera (None: none).
    face_tag_id: int | None = None


@dataclass(frozen=True)
class ReferenceTag:
    """One of the four tags that locate the guide plane (printed on the sheets, seen by the camera)."""

    id: int
    center_mm: tuple[float, float]
    size_mm: float = 40.0


@dataclass(frozen=True)
class GuidePage:
    """One printed sheet of a tiled guide.

    Parameters
    ----------
    index : int
        0-based, in reading order.
    label : str
        Its place in the page map: column letter and row number (``"B2"``).
    paper : str
        ``"a4"``, ``"letter"`` or ``"a3"``.
    size_mm : tuple of float
        The sheet's width and height (its orientation as printed).
    origin_mm : tuple of float
        The guide-plane point under the sheet's lower-left corner.
    """

    index: int
    label: str
    paper: str
    size_mm: tuple[float, float]
    origin_mm: tuple[float, float]


@dataclass(frozen=True)
class Guide:
    """Everything an assembly guide shows, on its guide plane.

    Parameters
    ----------
    scenario : str
        The scenario's name.
    content_hash : str
        The scenario's content hash (the layout belongs to it).
    plane : GuidePlane
        The plane the guide is drawn on.
    parts : tuple of PartDrawing
        In assembly order (``parts[i].step == i + 1``).
    reference_tags : tuple of ReferenceTag
        The four tags near the corners of the layout's extent.
    extent_mm : tuple of float
        ``(u_min, v_min, u_max, v_max)`` of everything drawn (parts and reference tags), in millimetres.
    tolerance_source : str
        Where the tolerances come from: ``"model"``, ``"simulation"`` or ``"none"`` (the sheet says which).
    pages : tuple of GuidePage
        The printed sheets, once tiled (empty before).
    tolerance_note : str or None
        Why the tolerances come from there, when it is not the obvious (the sheet says it).
    headline : str or None
        The layout's physical success on the table, in the station's words, when it is known (the sheet shows it).
    jigs : tuple of JigDrawing
        The laser-cut jigs the steps use (empty unless asked for: ``station guide --jigs``).
    """

    scenario: str
    content_hash: str
    plane: GuidePlane
    parts: tuple[PartDrawing, ...]
    reference_tags: tuple[ReferenceTag, ...]
    extent_mm: tuple[float, float, float, float]
    tolerance_source: str = "none"
    pages: tuple[GuidePage, ...] = field(default=())
    tolerance_note: str | None = None
    headline: str | None = None
    jigs: tuple[JigDrawing, ...] = ()

    @property
    def view(self) -> str:
        return self.plane.view

    def part(self, name: str) -> PartDrawing:
        """The part called ``name`` (KeyError naming it and the known parts)."""
        for part in self.parts:
            if part.name == name:
                return part
        raise KeyError(f"no part {name!r} in the guide; parts: {', '.join(p.name for p in self.parts)}")

    def manifest(self) -> dict:
        """The guide's JSON manifest (``station guide --json``), a public contract::

            {"scenario", "content_hash", "view", "units": "mm", "tolerance_source", "tolerance_note", "headline",
             "pages": [{"index", "label", "paper", "size_mm": [w, h], "origin_mm": [u, v]}],
             "reference_tags": [{"id", "center_mm": [u, v], "size_mm"}],
             "parts": [{"name", "kind", "step", "tag_id", "tag_center_mm", "tag_size_mm", "tag_height_mm",
                        "tag_heading_deg", "center_mm": [u, v], "heading_deg", "outline_mm": [[[u, v], ...], ...],
                        "care", "tolerances": [{"parameter", "delta", "unit", "predicted", "measured", "source",
                                        "bound_limited"}],
                        "body_tags": [{"body", "tag_id", "tag_center_mm", "tag_size_mm", "tag_height_mm",
                                       "tag_heading_deg", "center_mm", "heading_deg"}],
                        "parameters": [{"name", "value", "unit", "meaning", "set_with", "role", "tolerance"}]}],
             "jigs": [{"id", "part", "kind", "parameters", "words", "footprint_mm": [[u, v], ...], "tag_id",
                       "tag_center_mm", "tag_size_mm", "tag_height_mm", "tag_heading_deg", "face_tag_id"}]}

        ``outline_mm`` is a list of polygons, each its exterior ring (holes are not needed to place a part).
        ``parameters``: every design parameter that moves the part, ``value`` in ``unit`` (``"mm"`` or ``"deg"``),
        ``meaning`` in the maker's words, ``set_with`` one of ``sheet``, ``ruler``, ``jig``, ``check``, ``role`` one of
        ``u``, ``v``, ``turn``, ``height``, ``tilt``, ``tolerance`` the ±delta to keep (null when unknown).
        """
        return {
            "scenario": self.scenario,
            "content_hash": self.content_hash,
            "view": self.view,
            "units": "mm",
            "tolerance_source": self.tolerance_source,
            "tolerance_note": self.tolerance_note,
            "headline": self.headline,
            "pages": [
                {"index": p.index, "label": p.label, "paper": p.paper, "size_mm": [*map(_r, p.size_mm)],
                 "origin_mm": [*map(_r, p.origin_mm)]}
                for p in self.pages
            ],
            "reference_tags": [
                {"id": t.id, "center_mm": [*map(_r, t.center_mm)], "size_mm": _r(t.size_mm)}
                for t in self.reference_tags
            ],
            "parts": [_part_manifest(p) for p in self.parts],
            "jigs": [
                {"id": j.id, "part": j.part, "kind": j.kind, "parameters": list(j.parameters), "words": j.words,
                 "footprint_mm": _rings(j.footprint)[0] if not j.footprint.is_empty else [], "tag_id": j.tag_id,
                 "tag_center_mm": None if j.tag_center_mm is None else [*map(_r, j.tag_center_mm)],
                 "tag_size_mm": _r(j.tag_size_mm), "tag_height_mm": _r(j.tag_height_mm),
                 "tag_heading_deg": _r(j.tag_heading_deg), "face_tag_id": j.face_tag_id}
                for j in self.jigs
            ],
        }


def _r(value: float) -> float:
    return round(float(value), 3)


def _rings(outline: BaseGeometry) -> list[list[list[float]]]:
    polygons = getattr(outline, "geoms", [outline])
    return [[[_r(u), _r(v)] for u, v in polygon.exterior.coords] for polygon in polygons if not polygon.is_empty]


def _part_manifest(part: PartDrawing) -> dict:
    return {
        "name": part.name,
        "kind": str(part.kind),
        "step": part.step,
        "tag_id": part.tag_id,
        "tag_center_mm": None if part.tag_center_mm is None else [*map(_r, part.tag_center_mm)],
        "tag_size_mm": _r(part.tag_size_mm),
        "tag_height_mm": _r(part.tag_height_mm),
        "tag_heading_deg": _r(part.tag_heading_deg),
        "center_mm": [*map(_r, part.center_mm)],
        "heading_deg": _r(part.heading_deg),
        "outline_mm": _rings(part.outline),
        "care": part.care,
        "tolerances": [
            {"parameter": t.parameter, "delta": None if t.delta is None else _r(t.delta), "unit": t.unit,
             "predicted": None if t.predicted is None else _r(t.predicted),
             "measured": None if t.measured is None else _r(t.measured), "source": t.source,
             "bound_limited": t.bound_limited}
            for t in part.tolerances
        ],
        "body_tags": [
            {"body": b.body, "tag_id": b.tag_id, "tag_center_mm": [*map(_r, b.tag_center_mm)],
             "tag_size_mm": _r(b.tag_size_mm), "tag_height_mm": _r(b.tag_height_mm),
             "tag_heading_deg": _r(b.tag_heading_deg), "center_mm": [*map(_r, b.center_mm)],
             "heading_deg": _r(b.heading_deg)}
            for b in part.body_tags
        ],
        "parameters": [
            {"name": p.name, "value": _r(p.value), "unit": p.unit, "meaning": p.meaning, "set_with": p.set_with,
             "role": p.role,
             "tolerance": None if p.tolerance is None or p.tolerance.placement_delta is None
             else _r(p.tolerance.placement_delta)}
            for p in part.settings
        ],
    }


def where_point(part: PartDrawing) -> tuple[float, float]:
    """The point the guide gives for a part, on the plane (mm): its centre, or for a run of pieces (dominoes) the
    centroid of their outlines (the run's frame origin and turn mean little to the maker, its outlines
    everything). The steps, the parts list and the projected frames all give this one."""
    if len(getattr(part.outline, "geoms", [part.outline])) > 1:
        middle = part.outline.centroid
        return float(middle.x), float(middle.y)
    return float(part.center_mm[0]), float(part.center_mm[1])


def where_word(part: PartDrawing) -> str:
    """``"around"`` for a run of pieces (:func:`where_point` is their centroid), else ``"centre"``."""
    return "around" if len(getattr(part.outline, "geoms", [part.outline])) > 1 else "centre"


def where_coords(part: PartDrawing) -> str:
    """``"(-60.0, 0.0)"``: :func:`where_point` to 0.1 mm, in mm (a -0.04 reads "0.0", not "-0.0")."""
    u, v = (round(c, 1) + 0.0 for c in where_point(part))
    return f"({u:.1f}, {v:.1f})"


def where_text(part: PartDrawing) -> str:
    """``"centre (-60.0, 0.0) mm"`` or ``"around (35.0, 0.0) mm"``: :func:`where_coords` in words."""
    return f"{where_word(part)} {where_coords(part)} mm"
