"""Pictures of a scenario instance: top (x-y) and side (x-z) views at start and end, objects labelled.

Each body's collision parts are projected on the view plane and drawn as filled convex outlines, farthest first
(painter's order); infinite planes are drawn as a ground line in the side view. Pillow only, no GUI.
"""

from __future__ import annotations

import colorsys
import zlib
from collections.abc import Sequence
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
    kinds = {obj.name: obj.type for obj in scenario.objects}
    lo, hi = _body_bounds(snapshots[0][1])
    span = np.maximum(hi - lo, 0.05)
    lo, hi = lo - 0.15 * span, hi + 0.15 * span
    width, height = panel_size
    header = 28
    image = Image.new("RGB", (2 * width, header + len(snapshots) * height), "white")
    draw = ImageDraw.Draw(image)
    font = _font(13)
    small = _font(11)
    draw.text((8, 6), title or f"{scenario.name}", fill="black", font=_font(16))
    for row, (caption, snapshot) in enumerate(snapshots):
        for col, (view, (h_axis, v_axis, d_axis, d_sign)) in enumerate(VIEWS.items()):
            ox, oy = col * width, header + row * height
            draw.rectangle([ox, oy, ox + width - 1, oy + height - 1], outline=(200, 200, 200))
            scale = min((width - 40) / (hi[h_axis] - lo[h_axis]), (height - 50) / (hi[v_axis] - lo[v_axis]))
            cx = ox + width / 2 - scale * (lo[h_axis] + hi[h_axis]) / 2
            cy = oy + 20 + (height - 20) / 2 + scale * (lo[v_axis] + hi[v_axis]) / 2

            def to_px(p, cx=cx, cy=cy, scale=scale, h_axis=h_axis, v_axis=v_axis):
                return np.c_[cx + scale * p[:, h_axis], cy - scale * p[:, v_axis]]

            shapes = []
            labels: dict[str, list[np.ndarray]] = {}
            for _label, name, pose, spec in snapshot:
                for part in spec.parts:
                    if part.kind == "plane":
                        normal = pose.rotation.apply(part.pose.rotation.apply([0.0, 0.0, 1.0]))
                        if view == "side" and abs(normal[2]) > 0.9:
                            z = pose.apply(part.pose.position[None])[0][2]
                            y_px = cy - scale * z
                            if oy + 20 <= y_px <= oy + height:
                                draw.line([ox + 2, y_px, ox + width - 2, y_px], fill=(120, 120, 120), width=2)
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
                    shapes.append((depth, name, _hull(to_px(world))))
                if any(part.kind != "plane" for part in spec.parts):
                    labels.setdefault(name, []).append(pose.position)
            shapes.sort(key=lambda item: -item[0])
            for _depth, name, polygon in shapes:
                fill = _colour(name, kinds.get(name, ""))
                outline = tuple(int(c * 0.55) for c in fill)
                draw.polygon([tuple(p) for p in polygon], fill=fill, outline=outline)
            for rope in (ropes[row] if ropes is not None and row < len(ropes) else []):
                points = to_px(np.asarray(rope, dtype=float))
                draw.line([tuple(p) for p in points], fill=(60, 40, 20), width=1)
            for name, positions in labels.items():
                anchor = np.asarray(positions[0])[None]
                px, py = to_px(anchor)[0]
                if ox <= px <= ox + width and oy + 20 <= py <= oy + height:
                    draw.text((px + 4, py - 14), name, fill=(20, 20, 20), font=small)
            axes = "x right, y up" if view == "top" else "x right, z up"
            draw.text((ox + 6, oy + 4), f"{caption}: {view} view ({axes})", fill="black", font=font)
            bar = _scale_bar(scale)
            draw.line([ox + 10, oy + height - 12, ox + 10 + bar[0], oy + height - 12], fill="black", width=2)
            draw.text((ox + 14 + bar[0], oy + height - 20), bar[1], fill="black", font=small)
    if path is not None:
        image.save(path)
    return image


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
