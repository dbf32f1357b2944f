"""Engraved labels: single-stroke (Hershey) text as polylines, placed inside a part's material."""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import shapely
import shapely.affinity as affinity
from shapely.geometry import Polygon, box

__all__ = ["text_polylines", "place_label"]


@lru_cache(maxsize=1)
def _font():
    from HersheyFonts import HersheyFonts

    font = HersheyFonts()
    font.load_default_font("futural")
    # Glyph cell: capitals span y in [2.5, 10] after normalize_rendering(10); we rescale ourselves.
    font.normalize_rendering(10)
    return font


def text_polylines(text: str, height: float) -> list[np.ndarray]:
    """Strokes of ``text`` in a single-stroke font, capitals ``height`` mm tall, centred on the origin (y up)."""
    strokes = [np.asarray(stroke, dtype=float) for stroke in _font().strokes_for_text(text) if len(stroke) >= 2]
    if not strokes:
        return []
    # Capitals run from y = 2.5 to y = 10 in the normalized font.
    factor = height / 7.5
    strokes = [s * factor for s in strokes]
    allpts = np.concatenate(strokes)
    centre = (allpts.min(axis=0) + allpts.max(axis=0)) / 2.0
    return [s - centre for s in strokes]


def _extent(strokes: list[np.ndarray]) -> tuple[float, float]:
    allpts = np.concatenate(strokes)
    size = allpts.max(axis=0) - allpts.min(axis=0)
    return float(size[0]), float(size[1])


def place_label(shape: Polygon, text: str, height: float, near: tuple[float, float] = (0.0, 0.0),
                angle: float | None = None, clearance: float = 1.0, min_height: float = 1.8) -> list[np.ndarray]:
    """Strokes of ``text`` placed in the material of ``shape`` as close as possible to ``near``.

    The label's box (plus ``clearance``) must lie in the material. It is written horizontally, or at ``angle``
    (degrees) when given; when no place fits, the text is shrunk down to ``min_height``, and when it still does not
    fit, there is no label (an empty list).
    """
    rotation_deg = 0.0 if angle is None else float(angle)
    c, s_ = math.cos(math.radians(rotation_deg)), math.sin(math.radians(rotation_deg))
    rotation = np.array([[c, s_], [-s_, c]])
    while height >= min_height:
        strokes = text_polylines(text, height)
        if not strokes:
            return []
        width, tall = _extent(strokes)
        label_box = affinity.rotate(box(-width / 2 - clearance, -tall / 2 - clearance, width / 2 + clearance,
                                        tall / 2 + clearance), rotation_deg, origin=(0, 0))
        # Candidate centres: the material eroded by half the box's height, on a grid, nearest to ``near`` first.
        room = shape.buffer(-(tall / 2 + clearance), quad_segs=8)
        if not room.is_empty:
            minx, miny, maxx, maxy = room.bounds
            step = max(0.5, tall / 4)
            xs, ys = np.meshgrid(np.arange(minx, maxx + step, step), np.arange(miny, maxy + step, step))
            xs, ys = xs.ravel(), ys.ravel()
            inside = shapely.contains_xy(room, xs, ys)
            xs, ys = xs[inside], ys[inside]
            order = np.argsort(np.hypot(xs - near[0], ys - near[1]), kind="stable")
            for i in order[:400]:
                placed = affinity.translate(label_box, xs[i], ys[i])
                if shape.contains(placed):
                    offset = np.array([xs[i], ys[i]])
                    return [stroke @ rotation + offset for stroke in strokes]
        height *= 0.8
    return []
