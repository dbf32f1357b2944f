"""Pictures of a scenario instance: top (x-y) and side (x-z) views at start and end, objects labelled.

Each body's collision parts are projected on the view plane and drawn as filled convex outlines, farthest first
(painter's order); infinite planes are drawn as a ground line in the side view. Every row is framed on the bodies of
all snapshots (a part thrown off stays in view, up to a limit), everything is clipped to its panel, and the object
names are placed so that no two overlap (farther out with a leader line when the scene is dense). Pillow only.
"""

from __future__ import annotations

import colorsys
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont
from scipy.spatial import ConvexHull, QhullError

from design.contraption.geometry import Pose
from design.contraption.primitives import BodySpec

#: Hue (0-1) of each primitive type, so that kinds of parts read at a glance.
TYPE_HUES = {
    "Ball": 0.0,
    "DominoRun": 0.08,
    "Track": 0.58,
    "Box": 0.12,
    "OpenBox": 0.14,
    "Lever": 0.33,
    "Pulley": 0.45,
    "Goblet": 0.75,
    "Cylinder": 0.5,
    "Capsule": 0.9,
}

Snapshot = Sequence[tuple[str, str, Pose, BodySpec]]

VIEWS = {
    # name: (horizontal axis, vertical axis, depth axis, depth sign: larger depth drawn first)
    "top": (0, 1, 2, -1.0),
    "side": (0, 2, 1, 1.0),
}


def _colour(object_name: str, kind: str) -> tuple[int, int, int]:
    hue = TYPE_HUES.get(kind)
    if hue is None:
        hue = (zlib.crc32(object_name.encode()) % 360) / 360.0
    jitter = (zlib.crc32(object_name.encode()) % 7) / 60.0
    r, g, b = colorsys.hls_to_rgb((hue + jitter) % 1.0, 0.6, 0.55)
    return int(r * 255), int(g * 255), int(b * 255)


def _hull(points: np.ndarray) -> np.ndarray:
    if len(points) < 3:
        return points
    try:
        hull = ConvexHull(points)
    except QhullError:
        # Degenerate (a part seen edge-on): draw its extent as a thin quad.
        lo, hi = points.min(axis=0), points.max(axis=0)
        return np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    return points[hull.vertices]


def _body_bounds(snapshot: Snapshot) -> tuple[np.ndarray, np.ndarray]:
    points = [
        pose.apply(part.surface_points(8))
        for _label, _name, pose, spec in snapshot
        for part in spec.parts
        if part.kind != "plane"
    ]
    if not points:
        return np.full(3, -0.1), np.full(3, 0.1)
    allp = np.concatenate(points)
    return allp.min(axis=0), allp.max(axis=0)


def view_bounds(snapshots: Sequence[Snapshot], reach: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The box every view frames: the bodies of all snapshots, but at most ``reach`` times the first snapshot's
    extent beyond it on each side (a part thrown far away is cut at the panel's edge instead of shrinking the scene).
    """
    lo, hi = _body_bounds(snapshots[0])
    span = np.maximum(hi - lo, 0.05)
    for snapshot in snapshots[1:]:
        other_lo, other_hi = _body_bounds(snapshot)
        lo = np.minimum(lo, np.maximum(other_lo, lo - reach * span))
        hi = np.maximum(hi, np.minimum(other_hi, hi + reach * span))
    return lo, hi


Box = tuple[float, float, float, float]


@dataclass
class Panel:
    """What one view of one snapshot draws, in image pixels, already clipped to the panel.

    Attributes
    ----------
    frame : (x0, y0, x1, y1)
        The panel's outline (drawn in grey); everything else lies strictly inside it.
    polygons : list of (object name, (n, 2) array)
        Filled outlines, farthest first (painter's order), clipped to the inside of the frame.
    lines : list of ((n, 2) array, colour, width)
        Ground lines and ropes, clipped likewise.
    labels : list of (object name, anchor (x, y), box (x0, y0, x1, y1))
        Object names placed by :func:`place_labels`: no two boxes overlap when the panel has room for them.
    out_of_view : list of str
        Objects drawn entirely outside the panel (named in its footer instead).
    """

    frame: Box
    caption: str
    polygons: list = field(default_factory=list)
    lines: list = field(default_factory=list)
    labels: list = field(default_factory=list)
    out_of_view: list = field(default_factory=list)
    scale: float = 1.0


def render_views(
    scenario,
    snapshots: Sequence[tuple[str, Snapshot]],
    path: str | Path | None = None,
    *,
    panel_size: tuple[int, int] = (560, 420),
    title: str | None = None,
    ropes: Sequence[Sequence[np.ndarray]] | None = None,
) -> Image.Image:
    """Draw each snapshot in top and side views (one row per snapshot) and optionally save a PNG.

    Parameters
    ----------
    scenario : Scenario
    snapshots : sequence of (caption, snapshot)
        E.g. ``[("start", result.start), ("end", result.end)]`` from a run with ``record=True``.
    path : path, optional
        Where to write the PNG.
    ropes : sequence of lists of (n, 3) arrays, optional
        For each snapshot, the polylines of its ropes (drawn as thin dark lines).
    """
    width, height = panel_size
    header = 28
    image = Image.new("RGB", (2 * width, header + len(snapshots) * height), "white")
    draw = ImageDraw.Draw(image)
    font = _font(13)
    small = _font(11)
    kinds = {obj.name: obj.type for obj in scenario.objects}
    draw.text((8, 6), title or f"{scenario.name}", fill="black", font=_font(16))
    for panel in layout_panels(scenario, snapshots, panel_size=panel_size, ropes=ropes, header=header,
                               measure=lambda text: _text_size(draw, text, small)):
        x0, y0, x1, y1 = panel.frame
        draw.rectangle([x0, y0, x1, y1], outline=(200, 200, 200))
        for name, polygon in panel.polygons:
            fill = _colour(name, kinds.get(name, ""))
            outline = tuple(int(c * 0.55) for c in fill)
            draw.polygon([tuple(p) for p in polygon], fill=fill, outline=outline)
        for points, colour, line_width in panel.lines:
            draw.line([tuple(p) for p in points], fill=colour, width=line_width)
        for name, (ax, ay), (bx0, by0, bx1, by1) in panel.labels:
            near = (min(max(ax, bx0), bx1), min(max(ay, by0), by1))
            if np.hypot(ax - near[0], ay - near[1]) > 6:
                # Placed away from its part (a dense panel): a leader line from the part's reference point to the
                # nearest point of the label, so the name still points at its part.
                draw.line([(ax, ay), near], fill=(150, 150, 150), width=1)
                draw.ellipse([ax - 1.5, ay - 1.5, ax + 1.5, ay + 1.5], fill=(90, 90, 90))
            # A white halo keeps a name readable where it lies over a dark part.
            draw.text((bx0, by0), name, fill=(20, 20, 20), font=small, stroke_width=_HALO, stroke_fill="white")
        draw.text((x0 + 6, y0 + 4), panel.caption, fill="black", font=font)
        bar = _scale_bar(panel.scale)
        draw.line([x0 + 10, y1 - 11, x0 + 10 + bar[0], y1 - 11], fill="black", width=2)
        draw.text((x0 + 14 + bar[0], y1 - 19), bar[1], fill="black", font=small)
        if panel.out_of_view:
            note = _fit(f"out of view: {', '.join(panel.out_of_view)}", (x1 - x0) - bar[0] - 90,
                        lambda text: _text_size(draw, text, small)[0])
            draw.text((x1 - 6 - _text_size(draw, note, small)[0], y1 - 19), note, fill=(120, 60, 0), font=small)
    if path is not None:
        image.save(path)
    return image


def layout_panels(
    scenario,
    snapshots: Sequence[tuple[str, Snapshot]],
    *,
    panel_size: tuple[int, int] = (560, 420),
    ropes: Sequence[Sequence[np.ndarray]] | None = None,
    header: int = 28,
    measure=None,
) -> list[Panel]:
    """The panels :func:`render_views` draws (row by row, top view then side view), without drawing them.

    ``measure(text) -> (width, height)`` sizes a label in pixels (default: Pillow's default font at 11 px).
    """
    if measure is None:
        scratch = ImageDraw.Draw(Image.new("RGB", (1, 1)))
        small = _font(11)
        measure = lambda text: _text_size(scratch, text, small)  # noqa: E731
    width, height = panel_size
    lo, hi = view_bounds([snapshot for _caption, snapshot in snapshots])
    span = np.maximum(hi - lo, 0.05)
    lo, hi = lo - 0.15 * span, hi + 0.15 * span
    panels = []
    for row, (caption, snapshot) in enumerate(snapshots):
        for col, (view, (h_axis, v_axis, d_axis, d_sign)) in enumerate(VIEWS.items()):
            ox, oy = col * width, header + row * height
            frame = (ox, oy, ox + width - 1, oy + height - 1)
            # Shapes stay strictly inside the frame; labels also keep off the caption (top) and scale bar (bottom).
            inside = (ox + 1, oy + 1, ox + width - 2, oy + height - 2)
            label_area = (ox + 3, oy + 20, ox + width - 4, oy + height - 24)
            scale = min((width - 40) / (hi[h_axis] - lo[h_axis]), (height - 50) / (hi[v_axis] - lo[v_axis]))
            cx = ox + width / 2 - scale * (lo[h_axis] + hi[h_axis]) / 2
            cy = oy + 20 + (height - 20) / 2 + scale * (lo[v_axis] + hi[v_axis]) / 2

            def to_px(p, cx=cx, cy=cy, scale=scale, h_axis=h_axis, v_axis=v_axis):
                return np.c_[cx + scale * p[:, h_axis], cy - scale * p[:, v_axis]]

            axes = "x right, y up" if view == "top" else "x right, z up"
            panel = Panel(frame, f"{caption}: {view} view ({axes})", scale=scale)
            shapes = []
            anchors: dict[str, np.ndarray] = {}
            seen: dict[str, bool] = {}
            for _label, name, pose, spec in snapshot:
                for part in spec.parts:
                    if part.kind == "plane":
                        normal = pose.rotation.apply(part.pose.rotation.apply([0.0, 0.0, 1.0]))
                        if view == "side" and abs(normal[2]) > 0.9:
                            z = pose.apply(part.pose.position[None])[0][2]
                            y_px = cy - scale * z
                            if oy + 20 <= y_px <= inside[3]:
                                ground = np.array([[ox + 2, y_px], [ox + width - 3, y_px]])
                                panel.lines.append((ground, (120, 120, 120), 2))
                        continue
                    world = pose.apply(part.surface_points(20))
                    if part.kind == "sphere":
                        # A sphere's outline is a circle whatever its rotation.
                        centre = pose.apply(part.pose.position[None])
                        ring = np.linspace(0, 2 * np.pi, 48, endpoint=False)
                        world = np.repeat(centre, 48, axis=0)
                        world[:, h_axis] += part.dims[0] * np.cos(ring)
                        world[:, v_axis] += part.dims[0] * np.sin(ring)
                    depth = d_sign * float(world[:, d_axis].mean())
                    polygon = clip_polygon(_hull(to_px(world)), inside)
                    seen[name] = seen.get(name, False) or len(polygon) >= 3
                    if len(polygon) >= 3:
                        shapes.append((depth, name, polygon))
                        if name not in anchors:
                            anchors[name] = _anchor(to_px(pose.position[None])[0], polygon, label_area)
            shapes.sort(key=lambda item: -item[0])
            panel.polygons = [(name, polygon) for _depth, name, polygon in shapes]
            panel.out_of_view = [name for name, visible in seen.items() if not visible]
            for rope in (ropes[row] if ropes is not None and row < len(ropes) else []):
                for piece in clip_polyline(to_px(np.asarray(rope, dtype=float)), inside):
                    panel.lines.append((piece, (60, 40, 20), 1))
            names = list(anchors)
            boxes = place_labels([anchors[n] for n in names], [measure(n) for n in names], label_area)
            panel.labels = [(n, tuple(anchors[n]), box) for n, box in zip(names, boxes)]
            panels.append(panel)
    return panels


def _anchor(reference: np.ndarray, polygon: np.ndarray, area: Box) -> np.ndarray:
    """Where a part's label points: its reference point, or the middle of what is visible of it when that point is
    outside the label area (a part half out of the panel)."""
    if area[0] <= reference[0] <= area[2] and area[1] <= reference[1] <= area[3]:
        return reference
    middle = polygon.mean(axis=0)
    return np.clip(middle, [area[0], area[1]], [area[2], area[3]])


def place_labels(anchors: Sequence, sizes: Sequence[tuple[float, float]], area: Box, *,
                 max_rings: int = 14) -> list[Box]:
    """Boxes for labels of the given sizes near their anchors, inside ``area``, in order, none overlapping another.

    Each label tries positions around its anchor (right-above first, then the other seven directions), then the
    same directions farther away ring by ring, and keeps the first that overlaps no label placed before and covers no
    other anchor; if none is free, the one with the least overlap. Greedy and deterministic; a dense panel gets
    labels farther out (drawn with a leader line), not labels on top of each other.
    """
    placed: list[Box] = []
    points = [tuple(map(float, a)) for a in anchors]
    for index, ((ax, ay), (w, h)) in enumerate(zip(points, sizes)):
        best, best_cost = None, None
        for box in _candidates(ax, ay, w, h, area, max_rings):
            overlap = sum(_overlap(box, other) for other in placed)
            covered = sum(1 for j, (px, py) in enumerate(points) if j != index
                          and box[0] - 2 <= px <= box[2] + 2 and box[1] - 2 <= py <= box[3] + 2)
            cost = (overlap, covered)
            if cost == (0, 0):
                best = box
                break
            if best_cost is None or cost < best_cost:
                best, best_cost = box, cost
        if best is None:  # the area is smaller than the label: pin it to the area's corner
            best = (area[0], area[1], area[0] + w, area[1] + h)
        placed.append(best)
    return placed


#: Directions tried around an anchor, in order of preference (screen y grows downwards: -1 is above).
_DIRECTIONS = ((1, -1), (1, 1), (-1, -1), (-1, 1), (1, 0), (-1, 0), (0, -1), (0, 1))


def _candidates(ax: float, ay: float, w: float, h: float, area: Box, rings: int):
    step = h + 2
    for ring in range(rings + 1):
        distance = ring * step
        for ux, uy in _DIRECTIONS:
            # The box's corner (or edge middle) nearest the anchor sits 4 px (x) / 2 px (y) plus the ring's distance
            # away from it in the direction (ux, uy).
            x0 = ax + 4 + distance if ux > 0 else ax - 4 - distance - w if ux < 0 else ax - w / 2
            y0 = ay + 2 + distance if uy > 0 else ay - 2 - distance - h if uy < 0 else ay - h / 2
            box = (x0, y0, x0 + w, y0 + h)
            if area[0] <= box[0] and box[2] <= area[2] and area[1] <= box[1] and box[3] <= area[3]:
                yield box


def _overlap(a: Box, b: Box) -> float:
    width = min(a[2], b[2]) - max(a[0], b[0])
    height = min(a[3], b[3]) - max(a[1], b[1])
    return width * height if width > 0 and height > 0 else 0.0


def clip_polygon(polygon: np.ndarray, box: Box) -> np.ndarray:
    """The part of a convex polygon inside an axis-aligned box (Sutherland-Hodgman); fewer than 3 points if none."""
    points = [tuple(p) for p in np.asarray(polygon, dtype=float)]
    x0, y0, x1, y1 = box
    edges = ((0, x0, 1), (0, x1, -1), (1, y0, 1), (1, y1, -1))  # (axis, limit, +1: keep >= limit / -1: keep <=)
    for axis, limit, sign in edges:
        if not points:
            break
        kept = []
        for i, current in enumerate(points):
            previous = points[i - 1]
            current_in = sign * (current[axis] - limit) >= 0
            previous_in = sign * (previous[axis] - limit) >= 0
            if current_in != previous_in:
                t = (limit - previous[axis]) / (current[axis] - previous[axis])
                kept.append(tuple(previous[k] + t * (current[k] - previous[k]) for k in range(2)))
            if current_in:
                kept.append(current)
        points = kept
    return np.array(points, dtype=float).reshape(-1, 2)


def clip_polyline(points: np.ndarray, box: Box) -> list[np.ndarray]:
    """The pieces of a polyline inside an axis-aligned box (each segment clipped by Liang-Barsky)."""
    pieces: list[list[tuple[float, float]]] = []
    x0, y0, x1, y1 = box
    points = np.asarray(points, dtype=float)
    for start, end in zip(points[:-1], points[1:]):
        d = end - start
        t0, t1 = 0.0, 1.0
        for p, q in ((-d[0], start[0] - x0), (d[0], x1 - start[0]), (-d[1], start[1] - y0), (d[1], y1 - start[1])):
            if p == 0:
                if q < 0:
                    t0, t1 = 1.0, 0.0
                continue
            t = q / p
            if p < 0:
                t0 = max(t0, t)
            else:
                t1 = min(t1, t)
        if t0 > t1:
            continue
        a, b = tuple(start + t0 * d), tuple(start + t1 * d)
        if pieces and pieces[-1][-1] == a:
            pieces[-1].append(b)
        else:
            pieces.append([a, b])
    return [np.array(piece) for piece in pieces]


#: Width (px) of the white outline around label text.
_HALO = 1


def _text_size(draw: ImageDraw.ImageDraw, text: str, font, halo: int = _HALO) -> tuple[float, float]:
    """Width and height of ``text`` drawn at (0, 0), its halo included."""
    left, top, right, bottom = draw.textbbox((0, 0), text, font=font, stroke_width=halo)
    return float(right), float(bottom)


def _fit(text: str, width: float, measure) -> str:
    """``text`` cut with an ellipsis to fit ``width`` pixels."""
    if measure(text) <= width:
        return text
    while text and measure(text + "…") > width:
        text = text[:-1]
    return text + "…"


def _scale_bar(scale: float) -> tuple[float, str]:
    bars = ((0.5, "50 cm"), (0.2, "20 cm"), (0.1, "10 cm"), (0.05, "5 cm"), (0.02, "2 cm"), (0.01, "1 cm"))
    for metres, text in bars:
        if metres * scale <= 160:
            return metres * scale, text
    return 0.005 * scale, "5 mm"


def _font(size: int):
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # pragma: no cover - Pillow < 10.1
        return ImageFont.load_default()


def render_result(scenario, result, path: str | Path | None = None) -> Image.Image:
    """Start and end views of a :class:`SimulationResult` recorded with ``record=True``."""
    if result.start is None or result.end is None:
        raise ValueError("render_result needs a result simulated with record=True")
    outcome = "success" if result.success else "failure"
    title = (
        f"{scenario.name}: {outcome}, {result.n_successful_events}/{len(result.events)} events, "
        f"{result.duration:.2f} s simulated"
    )
    return render_views(
        scenario,
        [("start", result.start), (f"end (t = {result.duration:.2f} s)", result.end)],
        path,
        title=title,
        ropes=[result.ropes_start, result.ropes_end],
    )
