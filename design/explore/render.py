"""PNG pictures of explored designs: curves (before in light, after in dark) with their PoIs marked (Pillow)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import BinaryIO

import numpy as np

from design.explore.poi import CURVATURE, PointOfInterest


def write_png(
    stream: BinaryIO,
    curves: Sequence[np.ndarray],
    pois: Sequence[Sequence[PointOfInterest]] = (),
    *,
    highlight: Sequence[int] = (),
    size: int = 800,
    colors: Sequence[str] = ("#f0b400", "#1f3b73", "#27ae60"),
    title: str = "",
) -> None:
    """Draw ``curves`` (first = original, in the thesis's yellow; then blue) and their PoIs.

    Curvature maxima are circles, crossings squares; PoIs of the last curve whose ids are in ``highlight`` are red
    and larger. One frame for all curves, y up.
    """
    from PIL import Image, ImageDraw

    supersample = 2
    big = size * supersample
    points = np.concatenate([np.asarray(c, dtype=float) for c in curves])
    lo, hi = points.min(axis=0), points.max(axis=0)
    center = (lo + hi) / 2
    scale = big * 0.9 / max(float(np.max(hi - lo)), 1e-12)

    def px(xy):
        xy = (np.asarray(xy, dtype=float) - center) * scale
        return np.column_stack([big / 2 + xy[..., 0], big / 2 - xy[..., 1]]) if xy.ndim == 2 else (
            big / 2 + xy[0], big / 2 - xy[1])

    image = Image.new("RGB", (big, big), "white")
    draw = ImageDraw.Draw(image)
    for index, curve in enumerate(curves):
        draw.line([tuple(p) for p in px(curve)], fill=colors[index % len(colors)], width=2 * supersample)
    for index, found in enumerate(pois):
        last = index == len(pois) - 1
        for poi in found:
            x, y = px(poi.xy)
            marked = last and poi.id in highlight
            r = (7 if marked else 4) * supersample
            fill = "#d62728" if marked else colors[index % len(colors)]
            box = (x - r, y - r, x + r, y + r)
            if poi.kind == CURVATURE:
                draw.ellipse(box, outline=fill, width=supersample * (2 if marked else 1))
            else:
                draw.rectangle(box, outline=fill, width=supersample * (2 if marked else 1))
    if title:
        draw.text((10 * supersample, 10 * supersample), title, fill="black")
    image = image.resize((size, size), Image.LANCZOS)
    image.save(stream, format="PNG")
