"""A picture of one jig with its part resting on it (PNG): the maker's check that the jig is the right one.

A stand is drawn in its own plane as the maker sees its engraved face: the table line, the base seen edge-on, the
plate in wood colour with its engraving, the part square to the plate (grey) resting on the support (red), the
support's heights above the table at both ends and its slope. A board stand the same, on the board. A template is
drawn from above: the plate with its pocket and the part standing in it.
"""

from __future__ import annotations

import io
import math

import numpy as np
from PIL import Image, ImageDraw, ImageFont
from shapely.geometry.base import BaseGeometry

from design.jigs.plan import BASE_MARGIN_MM, Jig

__all__ = ["render_jig"]

WOOD = (222, 184, 135)
WOOD_EDGE = (150, 105, 60)
PART = (120, 128, 140)
SUPPORT = (220, 0, 0)
ENGRAVE = (40, 40, 160)
TEXT = (20, 20, 20)
DIMENSION = (0, 110, 0)


def _font(size: int):
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # pragma: no cover - Pillow < 10.1
        return ImageFont.load_default()


def render_jig(jig: Jig, max_pixels: int = 1000) -> bytes:
    """The jig's picture as PNG bytes (module notes)."""
    drawn = [jig.outline, jig.silhouette]
    bounds = np.array([g.bounds for g in drawn if not g.is_empty])
    minx, miny = bounds[:, 0].min(), min(bounds[:, 1].min(), 0.0)
    maxx, maxy = bounds[:, 2].max(), bounds[:, 3].max()
    if jig.kind == "stand":
        minx, maxx = minx - BASE_MARGIN_MM, maxx + BASE_MARGIN_MM
    margin_px, header_px = 60, 40
    scale = min(8.0, (max_pixels - 2 * margin_px) / max(maxx - minx, maxy - miny, 1.0))
    width = int(math.ceil((maxx - minx) * scale)) + 2 * margin_px
    height = int(math.ceil((maxy - miny) * scale)) + 2 * margin_px + header_px
    image = Image.new("RGB", (width, height), (250, 250, 247))
    draw = ImageDraw.Draw(image)

    def px(points) -> list[tuple[float, float]]:
        xy = np.asarray(points, dtype=float).reshape(-1, 2)
        return [(float(margin_px + (x - minx) * scale), float(height - margin_px - (y - miny) * scale)) for x, y in xy]

    def fill(geometry: BaseGeometry, colour, outline=None) -> None:
        for polygon in getattr(geometry, "geoms", [geometry]):
            if polygon.is_empty or polygon.geom_type != "Polygon":
                continue
            draw.polygon(px(polygon.exterior.coords), fill=colour, outline=outline)
            for hole in polygon.interiors:
                draw.polygon(px(hole.coords), fill=(250, 250, 247), outline=outline)

    small, large = _font(14), _font(18)
    if jig.kind in ("stand", "board stand"):
        if jig.kind == "stand":
            # the table, and the base lying on it seen edge-on
            draw.line(px([(minx - 20, 0.0), (maxx + 20, 0.0)]), fill=(90, 90, 90), width=2)
            draw.rectangle([*px([(-BASE_MARGIN_MM, jig.thickness_mm)])[0],
                            *px([(jig.outline.bounds[2] + BASE_MARGIN_MM, 0.0)])[0]], fill=WOOD_EDGE)
            draw.text(px([(minx, 0.0)])[0], "table", fill=(90, 90, 90), font=small, anchor="lt")
        fill(jig.outline, WOOD, WOOD_EDGE)
        for stroke in jig.pieces[0].engrave:
            draw.line(px(stroke), fill=ENGRAVE, width=1)
        fill(jig.silhouette, PART)
        (x0, y0), (x1, y1) = jig.support
        draw.line(px([(x0, y0), (x1, y1)]), fill=SUPPORT, width=4)
        if jig.kind == "stand":  # heights above the table (a board stand's place is its outline on the sheet)
            for x, y in ((x0, y0), (x1, y1)):
                draw.line(px([(x, 0.0), (x, y)]), fill=DIMENSION, width=1)
                draw.text(px([(x, y / 2.0)])[0], f"{y:.1f} mm", fill=DIMENSION, font=small,
                          anchor="rm" if x == x0 else "lm")
        middle = ((x0 + x1) / 2.0, (y0 + y1) / 2.0)
        draw.text(px([middle])[0], f"  {abs(jig.tilt_deg or 0.0):.1f} deg", fill=SUPPORT, font=small, anchor="lb")
    else:
        fill(jig.outline, WOOD, WOOD_EDGE)
        for stroke in jig.pieces[0].engrave:
            draw.line(px(stroke), fill=ENGRAVE, width=1)
        fill(jig.silhouette, PART)
    title = f"{jig.id}: {jig.kind} for `{jig.part}` (step {jig.step}), sets {', '.join(jig.parameters) or 'nothing'}"
    draw.text((margin_px / 2, 10), title, fill=TEXT, font=large)
    detail = f"{jig.thickness_mm:g} mm plate" + (f", tag {jig.tag_id}" if jig.tag_id is not None else ", no tag")
    if jig.stop:
        detail += f", {jig.stop} against the stop"
    draw.text((margin_px / 2, 32), detail, fill=TEXT, font=small)
    buffer = io.BytesIO()
    image.save(buffer, format="PNG")
    return buffer.getvalue()
