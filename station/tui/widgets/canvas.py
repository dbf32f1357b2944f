"""A braille line-drawing canvas: 2x4 dots per terminal cell, so a 80x24 area shows a 160x96 dot drawing.

Rasterization is vectorized: each polyline is resampled at half-dot spacing along its length with ``np.interp`` and
the dots are set in one fancy-indexing assignment; a cell takes the colour of the last layer that touched it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from rich.style import Style
from rich.text import Text
from textual.widget import Widget

# Bit of each dot in a braille cell, indexed [row 0..3][column 0..1] (Unicode braille patterns, U+2800).
_BRAILLE_BITS = np.array([[0x01, 0x08], [0x02, 0x10], [0x04, 0x20], [0x40, 0x80]], dtype=np.uint16)


@dataclass(frozen=True)
class Marker:
    """A highlighted point drawn as a character over the lines (e.g. the pen, a point of interest)."""

    xy: tuple[float, float]
    char: str = "●"
    color: str = "yellow"


def fit_transform(
    bounds: tuple[float, float, float, float], dots_w: int, dots_h: int, margin: float = 0.04
) -> tuple[float, float, float]:
    """Scale and offsets that fit ``bounds`` (xmin, ymin, xmax, ymax) into a dot grid, keeping the aspect ratio.

    Returns ``(scale, x0, y0)`` such that ``dot_x = (x - x0) * scale`` and ``dot_y = (y0 - y) * scale`` (y up).
    """
    xmin, ymin, xmax, ymax = bounds
    span_x = max(xmax - xmin, 1e-12)
    span_y = max(ymax - ymin, 1e-12)
    usable_w = max(dots_w - 1, 1) * (1 - 2 * margin)
    usable_h = max(dots_h - 1, 1) * (1 - 2 * margin)
    scale = min(usable_w / span_x, usable_h / span_y)
    x0 = (xmin + xmax) / 2 - (dots_w - 1) / 2 / scale
    y0 = (ymin + ymax) / 2 + (dots_h - 1) / 2 / scale
    return scale, x0, y0


def densify(points: np.ndarray, step: float) -> np.ndarray:
    """Resample a polyline (in dot units) so consecutive points are at most ``step`` apart."""
    if len(points) < 2:
        return points
    seg = np.hypot(*np.diff(points, axis=0).T)
    arc = np.concatenate(([0.0], np.cumsum(seg)))
    if arc[-1] <= step:
        return points
    s = np.linspace(0.0, arc[-1], int(np.ceil(arc[-1] / step)) + 1)
    return np.column_stack((np.interp(s, arc, points[:, 0]), np.interp(s, arc, points[:, 1])))


def rasterize(
    polylines: Sequence[np.ndarray],
    cells_w: int,
    cells_h: int,
    bounds: tuple[float, float, float, float] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Braille code points and the index of the layer owning each cell.

    Parameters
    ----------
    polylines : sequence of (n, 2) arrays
        Layers, drawn in order; later layers own the cells they touch.
    cells_w, cells_h : int
        Size in terminal cells.
    bounds : (xmin, ymin, xmax, ymax), optional
        World rectangle to show; by default the bounds of all polylines.

    Returns
    -------
    codes : (cells_h, cells_w) uint16 array
        Braille bit patterns (add 0x2800 for the character); 0 is an empty cell.
    owner : (cells_h, cells_w) int array
        Index of the last layer that drew in each cell, -1 where none did.
    """
    codes = np.zeros((cells_h, cells_w), dtype=np.uint16)
    owner = np.full((cells_h, cells_w), -1, dtype=np.int32)
    layers = [np.asarray(p, dtype=float).reshape(-1, 2) for p in polylines]
    layers_finite = [p[np.all(np.isfinite(p), axis=1)] for p in layers]
    if cells_w <= 0 or cells_h <= 0 or not any(len(p) for p in layers_finite):
        return codes, owner
    if bounds is None:
        stacked = np.concatenate([p for p in layers_finite if len(p)])
        bounds = (*stacked.min(axis=0), *stacked.max(axis=0))
    dots_w, dots_h = 2 * cells_w, 4 * cells_h
    scale, x0, y0 = fit_transform(bounds, dots_w, dots_h)
    for index, points in enumerate(layers_finite):
        if not len(points):
            continue
        dots = np.column_stack(((points[:, 0] - x0) * scale, (y0 - points[:, 1]) * scale))
        dots = np.rint(densify(dots, 0.5)).astype(np.int64)
        inside = (dots[:, 0] >= 0) & (dots[:, 0] < dots_w) & (dots[:, 1] >= 0) & (dots[:, 1] < dots_h)
        dx, dy = dots[inside, 0], dots[inside, 1]
        cx, cy = dx // 2, dy // 4
        np.bitwise_or.at(codes, (cy, cx), _BRAILLE_BITS[dy % 4, dx % 2])
        owner[cy, cx] = index
    return codes, owner


def cells_of(
    xy: np.ndarray, cells_w: int, cells_h: int, bounds: tuple[float, float, float, float]
) -> tuple[np.ndarray, np.ndarray]:
    """Columns and rows of the cells showing world points ``xy`` (n, 2); may fall outside the grid."""
    scale, x0, y0 = fit_transform(bounds, 2 * cells_w, 4 * cells_h)
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    finite = np.all(np.isfinite(xy), axis=1)
    columns = np.full(len(xy), -1, dtype=np.int64)
    rows = np.full(len(xy), -1, dtype=np.int64)
    columns[finite] = np.rint((xy[finite, 0] - x0) * scale).astype(np.int64) // 2
    rows[finite] = np.rint((y0 - xy[finite, 1]) * scale).astype(np.int64) // 4
    return columns, rows


def world_to_cell(
    xy: tuple[float, float], cells_w: int, cells_h: int, bounds: tuple[float, float, float, float]
) -> tuple[int, int] | None:
    """The (column, row) of the cell showing world point ``xy``, or None when outside."""
    scale, x0, y0 = fit_transform(bounds, 2 * cells_w, 4 * cells_h)
    col = int(np.rint((xy[0] - x0) * scale)) // 2
    row = int(np.rint((y0 - xy[1]) * scale)) // 4
    if 0 <= col < cells_w and 0 <= row < cells_h:
        return col, row
    return None


class PatternCanvas(Widget):
    """Draws polylines and markers with braille characters, fitted to the widget with the aspect ratio kept.

    Call :meth:`set_polylines` to change what is shown; the widget re-renders at its current size.
    """

    DEFAULT_CSS = """
    PatternCanvas { width: 1fr; height: 1fr; min-height: 8; }
    """

    def __init__(self, *, name: str | None = None, id: str | None = None, classes: str | None = None) -> None:
        super().__init__(name=name, id=id, classes=classes)
        self._polylines: list[np.ndarray] = []
        self._colors: list[str] = []
        self._markers: list[Marker] = []
        self._bounds: tuple[float, float, float, float] | None = None

    @property
    def polylines(self) -> list[np.ndarray]:
        return list(self._polylines)

    @property
    def markers(self) -> list[Marker]:
        return list(self._markers)

    def set_polylines(
        self,
        polylines: Sequence[np.ndarray],
        colors: Sequence[str] | None = None,
        markers: Sequence[Marker] = (),
        bounds: tuple[float, float, float, float] | None = None,
    ) -> None:
        """Replace the drawing.

        Parameters
        ----------
        polylines : sequence of (n, 2) arrays
            World coordinates, y up.
        colors : sequence of str, optional
            A Rich colour per polyline (default: white for all).
        markers : sequence of Marker
            Characters drawn over the lines.
        bounds : (xmin, ymin, xmax, ymax), optional
            World rectangle to fit; by default the polylines' bounds (pass it to keep a steady frame while animating).
        """
        self._polylines = [np.asarray(p, dtype=float).reshape(-1, 2) for p in polylines]
        self._colors = list(colors) if colors is not None else ["white"] * len(self._polylines)
        if len(self._colors) != len(self._polylines):
            raise ValueError(f"PatternCanvas: {len(self._polylines)} polylines but {len(self._colors)} colors")
        self._markers = list(markers)
        self._bounds = bounds
        self.refresh()

    def current_bounds(self) -> tuple[float, float, float, float] | None:
        if self._bounds is not None:
            return self._bounds
        finite = [p[np.all(np.isfinite(p), axis=1)] for p in self._polylines]
        finite = [p for p in finite if len(p)]
        if not finite:
            return None
        stacked = np.concatenate(finite)
        return (*stacked.min(axis=0), *stacked.max(axis=0))

    def render(self) -> Text:
        width, height = self.size.width, self.size.height
        return self.render_text(width, height)

    def render_text(self, width: int, height: int) -> Text:
        """The drawing as Rich text of ``height`` lines of ``width`` cells."""
        bounds = self.current_bounds()
        codes, owner = rasterize(self._polylines, width, height, bounds)
        chars = np.where(codes > 0, codes.astype(np.uint32) + 0x2800, ord(" "))
        overlay: dict[tuple[int, int], Marker] = {}
        if bounds is not None and self._markers:
            # One fit for all markers (thousands of points of interest are common on busy patterns).
            columns, rows = cells_of(np.array([m.xy for m in self._markers], dtype=float), width, height, bounds)
            for marker, col, row in zip(self._markers, columns, rows):
                if 0 <= col < width and 0 <= row < height:
                    overlay[(int(col), int(row))] = marker
        styles = [Style(color=c) for c in self._colors]
        # Markers take their cell: give them a layer index of their own past the polylines.
        marker_styles = {}
        for (col, row), marker in overlay.items():
            chars[row, col] = ord(marker.char[:1] or " ")
            owner[row, col] = len(styles) + len(marker_styles)
            marker_styles[owner[row, col]] = Style(color=marker.color, bold=True)
        text = Text(no_wrap=True, overflow="crop")
        for row in range(height):
            line_chars = "".join(map(chr, chars[row]))
            owners = owner[row]
            # Runs of equal owner become one styled span.
            cuts = np.flatnonzero(np.diff(owners)) + 1
            for begin, end in zip(np.concatenate(([0], cuts)), np.concatenate((cuts, [width]))):
                layer = int(owners[begin])
                style = styles[layer] if 0 <= layer < len(styles) else marker_styles.get(layer)
                text.append(line_chars[begin:end], style)
            if row < height - 1:
                text.append("\n")
        return text
