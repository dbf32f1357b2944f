"""Geometry of a guide's drawing shared by its outputs (PDF sheets, SVG): pure shapely and numpy, in guide mm.

What is computed here once is drawn the same way by every output: the tolerance zone round a part, its heading arrow
and angle arc, the hatching of static parts, and where each part's label goes (placed once for the whole guide, so
two sheets that overlap show the same label at the same place).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import shapely
from shapely import affinity, ops
from shapely.geometry import LineString, Point, Polygon, box
from shapely.geometry.base import BaseGeometry

from projector.guide import Guide, GuidePlane, ParameterTolerance, PartDrawing
from projector.parameters import off_plane_text
from vision.tags import TAG_CELLS, tag_cells

__all__ = ["CARE_COLORS", "Label", "arc_points", "arrow", "care_color", "hatch_segments", "heading_length",
           "must_move", "off_sheet_word", "placement_deltas", "place_labels", "polygons", "tag_black_rects", "tag_box",
           "tolerance_axes", "tolerance_text", "tolerance_zone"]

#: Colours of the care levels (RGB 0..1): tight red, normal orange, loose green.
CARE_COLORS = {"tight": (0.85, 0.11, 0.11), "normal": (0.96, 0.55, 0.0), "loose": (0.13, 0.6, 0.2)}
UNKNOWN_CARE_COLOR = (0.45, 0.45, 0.45)

# The world axis a layout parameter moves along (positions) or turns about (rotations: Panda3D's heading about z,
# pitch about x, roll about y).
_POSITION_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
_ROTATION_AXES = {"heading": (0.0, 0.0, 1.0), "pitch": (1.0, 0.0, 0.0), "roll": (0.0, 1.0, 0.0)}


def care_color(care: str | None) -> tuple[float, float, float]:
    """The colour of a care level (grey when unknown)."""
    return CARE_COLORS.get(care or "", UNKNOWN_CARE_COLOR)


def polygons(geometry: BaseGeometry) -> list[Polygon]:
    """The non-empty polygons of a Polygon, MultiPolygon or collection."""
    parts = getattr(geometry, "geoms", [geometry])
    return [p for p in parts if isinstance(p, Polygon) and not p.is_empty]


def tolerance_axes(tolerance: ParameterTolerance, plane: GuidePlane) -> tuple[str, ...]:
    """What a tolerance bounds on the plane: ``("u",)``, ``("v",)``, ``("arc",)`` (the heading) or ``()`` (out of
    the plane, e.g. a height above the table, or a parameter name that is not ``object.x|y|z|heading|pitch|roll``)."""
    component = tolerance.parameter.rsplit(".", 1)[-1]
    if tolerance.unit == "mm" and component in _POSITION_AXES:
        axis = np.asarray(_POSITION_AXES[component])
        return tuple(name for name, vector in (("u", plane.u_axis), ("v", plane.v_axis)) if abs(axis @ vector) > 0.5)
    if tolerance.unit == "deg" and component in _ROTATION_AXES:
        return ("arc",) if abs(np.asarray(_ROTATION_AXES[component]) @ plane.normal) > 0.9 else ()
    return ()


def placement_deltas(part: PartDrawing, plane: GuidePlane) -> tuple[float | None, float | None, float | None]:
    """``(du, dv, dtheta)``: how far the part may be off along u, along v (mm) and in heading (deg) on the plane.

    From its tolerances named ``object.x|y|z|heading|pitch|roll``: a position parameter counts along the guide axis
    its world axis lies on, a rotation counts when it turns about the plane's normal. Parameters out of the plane
    (a height above the table) are listed on the last page only. When two parameters bound the same axis, the
    tighter one is drawn. None: no known tolerance along that axis.
    """
    du = dv = dtheta = None

    def tighter(old, new):
        return new if old is None else min(old, new)

    for tolerance in part.tolerances:
        if tolerance.placement_delta is None or not math.isfinite(tolerance.placement_delta):
            continue  # unknown, or bound only by the range's end: no zone to keep to
        delta = abs(float(tolerance.placement_delta))
        axes = tolerance_axes(tolerance, plane)
        if "u" in axes:
            du = tighter(du, delta)
        if "v" in axes:
            dv = tighter(dv, delta)
        if "arc" in axes:
            dtheta = tighter(dtheta, delta)
    return du, dv, dtheta


#: Off by at least this much, a part with no tolerance on the sheet must move (:func:`must_move`).
UNTOLERATED_MM, UNTOLERATED_DEG = 1.0, 1.0


def must_move(error, within: bool | None) -> bool:
    """The one rule for "this part must move" (the check's count and instructions, the overlays, the Assemble
    screen), from its error ``(du, dv, distance, dheading)`` and whether it is within its tolerance on the sheet
    (None: no tolerance there, then off by :data:`UNTOLERATED_MM` or :data:`UNTOLERATED_DEG` or more)."""
    if within is not None:
        return not within
    return error[2] >= UNTOLERATED_MM or abs(error[3]) >= UNTOLERATED_DEG


def off_sheet_word(tolerance: ParameterTolerance, plane: GuidePlane) -> str:
    """What an out-of-plane tolerance bounds, in the maker's words: ``"height"`` (a position along the plane's
    normal: above the table, or off a backboard), ``"tilt"`` (a turn about an axis in the plane), else the
    parameter's last name."""
    component = tolerance.parameter.rsplit(".", 1)[-1]
    if tolerance.unit == "mm" and component in _POSITION_AXES:
        if abs(np.asarray(_POSITION_AXES[component]) @ plane.normal) > 0.5:
            return "height" if plane.view == "top" else "distance from the board"
    if tolerance.unit == "deg" and component in _ROTATION_AXES:
        return "tilt"
    return component


def tolerance_text(part: PartDrawing, plane: GuidePlane, off_plane: bool = True) -> str:
    """A short line for the label: the care level and the tightest deltas on the plane (``"tight ±2.1 mm ±1.5°"``,
    the zone the check measures against); when none is on the plane, the deltas out of it named by what they bound
    (``"height ±5.3 mm, tilt ±10.6°"``: set by hand, no camera check sees them), unless ``off_plane`` is False (the
    label's own line gives them, with their values)."""
    du, dv, dtheta = placement_deltas(part, plane)
    mm = [d for d in (du, dv) if d is not None]
    words = [part.care] if part.care else []
    if mm:
        words.append(f"±{min(mm):.1f} mm")
    if dtheta is not None:
        words.append(f"±{dtheta:.1f}°")
    if mm or dtheta is not None or not off_plane:
        return " ".join(words)
    off = [t for t in part.tolerances if t.placement_delta is not None and not tolerance_axes(t, plane)]
    unit = {"mm": " mm", "deg": "°"}
    named = ", ".join(f"{off_sheet_word(t, plane)} ±{abs(t.delta):.1f}{unit.get(t.unit, ' ' + t.unit)}" for t in off)
    return " ".join([*words, named]) if named else " ".join(words)


def tolerance_zone(outline: BaseGeometry, du: float | None, dv: float | None) -> BaseGeometry | None:
    """Where the part's outline may lie: the outline swept over ±du along u and ±dv along v (None: no zone).

    The Minkowski sum of the outline with the box ``[-du, du] x [-dv, dv]``: the union of the outline and of the
    hull of each edge's two ends moved to the box's four corners (exact, concave parts stay concave).
    """
    if du is None and dv is None:
        return None
    du, dv = du or 0.0, dv or 0.0
    corners = np.array([[-du, -dv], [du, -dv], [du, dv], [-du, dv]])
    hulls = []
    for polygon in polygons(outline):
        for ring in (polygon.exterior, *polygon.interiors):  # a hole's edges sweep too: the hole shrinks
            ring = np.asarray(ring.coords)[:, :2]
            ends = np.stack([ring[:-1], ring[1:]], axis=1)  # (edges, 2, 2)
            points = (ends[:, :, None, :] + corners[None, None, :, :]).reshape(len(ends), 8, 2)
            hulls.extend(shapely.convex_hull(shapely.multipoints(points)))
    if not hulls:
        return None
    return shapely.union_all([outline, *hulls]).simplify(0.05)


def hatch_segments(geometry: BaseGeometry, spacing: float = 3.0, angle_deg: float = 45.0) -> list[np.ndarray]:
    """Parallel hatching lines (``(2, 2)`` arrays) clipped to ``geometry``, ``spacing`` mm apart, lines anchored
    on the plane's origin so neighbouring parts' hatching lines up."""
    if geometry.is_empty:
        return []
    minx, miny, maxx, maxy = geometry.bounds
    direction = np.array([math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))])
    normal = np.array([-direction[1], direction[0]])
    corners = np.array([[minx, miny], [maxx, miny], [maxx, maxy], [minx, maxy]])
    offsets = corners @ normal
    along = corners @ direction
    lines = []
    for k in range(math.floor(offsets.min() / spacing), math.ceil(offsets.max() / spacing) + 1):
        base = normal * k * spacing
        lines.append(LineString([base + direction * (along.min() - 1), base + direction * (along.max() + 1)]))
    clipped = shapely.intersection(np.array(lines, dtype=object), geometry)
    segments = []
    for piece in clipped:
        for line in getattr(piece, "geoms", [piece]):
            if isinstance(line, LineString) and not line.is_empty and line.length > 0.2:
                segments.append(np.asarray(line.coords))
    return segments


def heading_length(part: PartDrawing) -> float:
    """The heading arrow's length: about half the part's size, 12 to 30 mm."""
    minx, miny, maxx, maxy = part.outline.bounds if not part.outline.is_empty else (0, 0, 0, 0)
    return float(np.clip(0.5 * max(maxx - minx, maxy - miny), 12.0, 30.0))


def arrow(center: tuple[float, float], heading_deg: float, length: float,
          head: float = 3.5) -> tuple[np.ndarray, np.ndarray]:
    """The heading arrow from ``center``: its shaft ``(2, 2)`` and its head triangle ``(3, 2)``."""
    c = np.asarray(center, dtype=float)
    d = np.array([math.cos(math.radians(heading_deg)), math.sin(math.radians(heading_deg))])
    n = np.array([-d[1], d[0]])
    tip = c + d * length
    shaft = np.array([c, tip - d * head * 0.8])
    triangle = np.array([tip, tip - d * head + n * head * 0.45, tip - d * head - n * head * 0.45])
    return shaft, triangle


def arc_points(center: tuple[float, float], radius: float, heading_deg: float, delta_deg: float,
               count: int = 25) -> np.ndarray:
    """Points of the arc ``heading ± delta`` at ``radius`` round ``center`` (counter-clockwise)."""
    angles = np.radians(np.linspace(heading_deg - delta_deg, heading_deg + delta_deg, count))
    return np.asarray(center, dtype=float) + radius * np.column_stack([np.cos(angles), np.sin(angles)])


def tag_box(center: tuple[float, float], size_mm: float, heading_deg: float = 0.0, border: bool = True) -> Polygon:
    """The square a tag covers (with its one-cell white border when ``border``), turned by ``heading_deg``."""
    half = size_mm * (10 / 8 if border else 1.0) / 2
    square = box(-half, -half, half, half)
    return affinity.translate(affinity.rotate(square, heading_deg, origin=(0, 0)), *center)


def tag_black_rects(tag_id: int, center: tuple[float, float], size_mm: float) -> list[tuple[float, ...]]:
    """The black cells of an unturned tag at ``center`` (its black square ``size_mm`` across), as rectangles
    ``(u0, v0, u1, v1)`` in guide mm, one per run of black cells in a row: neighbouring cells drawn as one shape
    leave no hairline seam between them."""
    cells = tag_cells(tag_id)
    cell = size_mm / 8
    left, top = center[0] - cell * TAG_CELLS / 2, center[1] + cell * TAG_CELLS / 2
    rects = []
    for row in range(TAG_CELLS):
        black = np.flatnonzero(np.diff(np.concatenate([[0], ~cells[row], [0]]).astype(int)))
        for start, end in zip(black[::2], black[1::2]):
            rects.append((left + start * cell, top - (row + 1) * cell, left + end * cell, top - row * cell))
    return rects


@dataclass(frozen=True)
class Label:
    """Where a part's label goes: a numbered circle, the name (and its tolerance line) beside it, and a leader line
    from the circle to the part when the label sits outside it (guide mm)."""

    name: str
    number: int
    detail: str
    circle: tuple[float, float]
    radius: float
    text: tuple[float, float]
    box: Polygon
    leader: tuple[tuple[float, float], tuple[float, float]] | None
    #: What the sheet cannot show (a height, a tilt: :func:`projector.parameters.off_plane_text`), a line below the
    #: detail; empty for a part on the plane.
    off_plane: str = ""


#: Sizes of a label (mm): the number's circle, the name's and the detail's text heights.
CIRCLE_MM = 7.0
NAME_MM = 3.2
DETAIL_MM = 2.6


def _default_width(text: str, size: float, bold: bool = False) -> float:
    from reportlab.pdfbase.pdfmetrics import stringWidth

    return stringWidth(text, "Helvetica-Bold" if bold else "Helvetica", size)


def place_labels(guide: Guide, width: Callable[..., float] = _default_width, *,
                 avoid: BaseGeometry | None = None) -> dict[str, Label]:
    """One :class:`Label` per part, placed in step order where it covers the least of the drawing.

    A label goes inside its part when it fits there, else beside it (candidates round the outline, scored by how
    much of the other parts, tags and labels already placed they cover, then by distance), with a leader line.
    ``width(text, size_mm, bold)`` measures text (Helvetica metrics by default). ``avoid``: where a label should
    rather not go (the PDF passes the sheets' edges, so a label is not cut in two).
    """
    obstacles = [p.outline for p in guide.parts]
    obstacles += [tag_box(t.center_mm, t.size_mm) for t in guide.reference_tags]
    obstacles += [tag_box(p.tag_center_mm, p.tag_size_mm, p.heading_deg) for p in guide.parts
                  if p.tag_center_mm is not None]
    drawn = shapely.union_all(obstacles) if obstacles else Polygon()
    # Heading arrows and centre crosses: a label must not hide them (a label inside its part included).
    marks = shapely.union_all([LineString(arrow(p.center_mm, p.heading_deg, heading_length(p))[0]).buffer(1.5)
                               for p in guide.parts] + [Point(p.center_mm).buffer(2.0) for p in guide.parts])
    placed: list[Polygon] = []
    inside_extent = box(*guide.extent_mm).buffer(5.0, join_style="mitre")  # labels stay on the sheets
    labels: dict[str, Label] = {}
    radius = CIRCLE_MM / 2
    for part in guide.parts:
        off_plane = off_plane_text(part, guide.view, symbols=True)
        detail = tolerance_text(part, guide.plane, off_plane=not off_plane)
        text_w = max(width(part.name, NAME_MM, True), width(detail, DETAIL_MM) if detail else 0.0,
                     width(off_plane, DETAIL_MM) if off_plane else 0.0)
        box_w, box_h = CIRCLE_MM + 1.2 + text_w + 1.0, CIRCLE_MM + 1.0 + (DETAIL_MM + 0.6 if off_plane else 0.0)
        anchor = part.outline.representative_point() if not part.outline.is_empty else Point(part.center_mm)
        target = part.outline if not part.outline.is_empty else anchor  # what the label points at
        candidates = _candidates(part.outline, anchor, box_w, box_h)
        best, best_cost = None, math.inf
        taken = shapely.union_all(placed) if placed else Polygon()
        for (x0, y0), inside in candidates:
            rect = box(x0, y0, x0 + box_w, y0 + box_h)
            if inside:
                fits = part.outline.contains(rect) and not rect.intersects(taken) and not rect.intersects(marks)
                cost = 0.0 if fits else math.inf
            else:
                cost = (rect.intersection(drawn).area + 20.0 * rect.intersection(taken).area
                        + 10.0 * rect.intersection(marks).area + 20.0 * rect.difference(inside_extent).area
                        + (0.0 if avoid is None else 10.0 * rect.intersection(avoid).area)
                        + 0.05 * rect.distance(target) * box_h)
            if cost < best_cost:
                best, best_cost = ((x0, y0), inside), cost
        (x0, y0), inside = best
        rect = box(x0, y0, x0 + box_w, y0 + box_h)
        placed.append(rect)
        circle = (x0 + 0.5 + radius, y0 + box_h - 0.5 - radius)
        leader = None
        if not inside:
            end = ops.nearest_points(target, Point(circle))[0]
            if end.distance(Point(circle)) > radius + 0.5:
                leader = ((circle[0], circle[1]), (end.x, end.y))
        labels[part.name] = Label(part.name, part.step, detail, circle, radius,
                                  (x0 + CIRCLE_MM + 1.7, circle[1]), rect, leader, off_plane)
    return labels


def _candidates(outline: BaseGeometry, anchor: Point, box_w: float,
                box_h: float) -> list[tuple[tuple[float, float], bool]]:
    """Lower-left corners to try: inside the part at ``anchor`` first, then round the outline at 3 mm."""
    inside = [((anchor.x - CIRCLE_MM / 2 - 0.5, anchor.y - box_h / 2), True)]
    if outline.is_empty:
        return inside + [((anchor.x + 3.0, anchor.y + 3.0), False)]
    ring = shapely.convex_hull(outline).buffer(3.0).exterior
    around = []
    for fraction in np.linspace(0.0, 1.0, 24, endpoint=False):
        p = ring.interpolate(fraction, normalized=True)
        # Put the box on the outward side of that point: to its right, left, above or below.
        c = shapely.centroid(outline)
        dx, dy = p.x - c.x, p.y - c.y
        x0 = p.x if dx >= 0 else p.x - box_w
        y0 = p.y if dy >= 0 else p.y - box_h
        if abs(dx) * box_h > abs(dy) * box_w:
            y0 = p.y - box_h / 2
        else:
            x0 = p.x - box_w / 2
        around.append(((x0, y0), False))
    return inside + around
