"""Pattern pictures: SVG (svgwrite) written to a text stream, PNG (Pillow, antialiased by supersampling).

Both take a list of (n, 2) polylines in drawing units, fit them in the picture with a margin (y up, as in the
thesis's figures) and draw them with the given colors.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import BinaryIO, TextIO

import numpy as np

DEFAULT_COLORS = ("#1f3b73", "#c0392b", "#888888", "#27ae60")


def shape_polylines(shapes, *, circle_points: int = 97, marker: float = 0.0) -> list[np.ndarray]:
    """Polylines of mechanism shapes (:meth:`DrawingMachine.mechanism`): outlines of circles and ellipses,
    segments, and small crosses for points (``marker`` is the cross's half size; 0 picks 1.5% of the extent).
    """
    lines: list[np.ndarray] = []
    points: list[tuple[float, float]] = []
    angles = np.linspace(0.0, 2.0 * np.pi, circle_points)
    for shape in shapes:
        if callable(getattr(shape, "polyline", None)):
            lines.append(np.asarray(shape.polyline(circle_points), dtype=float))
        elif hasattr(shape, "radius"):
            cx, cy = shape.center
            lines.append(np.column_stack([cx + shape.radius * np.cos(angles), cy + shape.radius * np.sin(angles)]))
        elif hasattr(shape, "start"):
            lines.append(np.array([shape.start, shape.end], dtype=float))
        elif hasattr(shape, "position"):
            points.append(tuple(shape.position))
    if points:
        everything = np.concatenate(lines + [np.array(points)])
        size = marker or 0.015 * float(np.ptp(everything, axis=0).max() or 1.0)
        for x, y in points:
            lines.append(np.array([[x - size, y], [x + size, y]]))
            lines.append(np.array([[x, y - size], [x, y + size]]))
    return lines


def _frame(polylines: Sequence[np.ndarray], size: int, margin: float) -> tuple[np.ndarray, float, float]:
    """Center and scale mapping drawing units to pixels (same scale on both axes, y pointing up)."""
    points = np.concatenate([np.asarray(p, dtype=float).reshape(-1, 2) for p in polylines])
    lo, hi = points.min(axis=0), points.max(axis=0)
    center = (lo + hi) / 2.0
    extent = float(max(hi[0] - lo[0], hi[1] - lo[1], 1e-12))
    scale = size * (1.0 - 2.0 * margin) / extent
    return center, scale, size / 2.0


def _to_pixels(polyline: np.ndarray, center: np.ndarray, scale: float, half: float) -> np.ndarray:
    p = (np.asarray(polyline, dtype=float) - center) * scale
    return np.column_stack([half + p[:, 0], half - p[:, 1]])


def _colored_pixels(
    polylines: Sequence[np.ndarray], size: int, margin: float, colors: Sequence[str]
) -> Iterator[tuple[np.ndarray, str]]:
    """Each polyline in pixels of a ``size`` x ``size`` picture (fitted with ``margin``), with its color."""
    center, scale, half = _frame(polylines, size, margin)
    for index, polyline in enumerate(polylines):
        yield _to_pixels(polyline, center, scale, half), colors[index % len(colors)]


# Both writers take the same picture options (size in px, margin as a fraction of it, colors cycled over polylines).
def write_svg(
    stream: TextIO, polylines: Sequence[np.ndarray], *, size: int = 800, margin: float = 0.05,
    colors: Sequence[str] = DEFAULT_COLORS, stroke_width: float = 1.2, title: str = "",
) -> None:  # fmt: skip
    """Write the polylines as an SVG document (size x size px, white background) to ``stream``."""
    import svgwrite

    drawing = svgwrite.Drawing(size=(f"{size}px", f"{size}px"), viewBox=f"0 0 {size} {size}")
    if title:
        drawing.set_desc(title=title)
    drawing.add(drawing.rect((0, 0), (size, size), fill="white"))
    for pixels, color in _colored_pixels(polylines, size, margin, colors):
        drawing.add(
            drawing.polyline(
                [(round(x, 3), round(y, 3)) for x, y in pixels],
                fill="none",
                stroke=color,
                stroke_width=stroke_width,
                stroke_linejoin="round",
            )
        )
    drawing.write(stream, pretty=False)
    stream.write("\n")


def write_png(
    stream: BinaryIO, polylines: Sequence[np.ndarray], *, size: int = 800, margin: float = 0.05,
    colors: Sequence[str] = DEFAULT_COLORS, line_width: float = 1.5, supersample: int = 4,
) -> None:  # fmt: skip
    """Draw the polylines with Pillow at ``supersample`` times the size, then downsample (antialiasing)."""
    from PIL import Image, ImageDraw

    big = size * supersample
    image = Image.new("RGB", (big, big), "white")
    draw = ImageDraw.Draw(image)
    width = max(1, int(round(line_width * supersample)))
    for pixels, color in _colored_pixels(polylines, big, margin, colors):
        draw.line([tuple(p) for p in pixels.tolist()], fill=color, width=width, joint="curve")
    image = image.resize((size, size), Image.Resampling.LANCZOS)
    image.save(stream, format="PNG")
