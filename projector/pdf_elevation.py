"""A part seen from the side, dimensioned: the drawing the PDF guide gives each part a parameter lifts or tilts.

The sheets show the guide plane at 1:1; a height above the table or a tilt is not on them. For each such part the
last pages draw its :class:`~projector.guide.Elevation`: the part alone seen along its tilt's axis, at 1:1 when it
fits the page (else at the first of 1:2, 1:5, 1:10 that does, said under it), with the table (or the board) as a
hatched line at ``h = 0``, the height of its underside at each end and at the middle dimensioned from the table,
the tilt's angle drawn at the lower end, the two ends named, and a 20 mm bar to check the print's scale.
"""

from __future__ import annotations

import math

import numpy as np
from reportlab.lib.units import mm
from reportlab.platypus import Flowable

from projector.drawing import polygons
from projector.guide import Elevation

__all__ = ["ElevationDrawing", "MAX_HEIGHT_MM", "SCALES"]

#: The scales tried, largest first (1:1 where it fits).
SCALES = (1.0, 0.5, 0.2, 0.1)
#: The tallest drawing on a page (mm of paper), so that the part's words fit under it.
MAX_HEIGHT_MM = 170.0
#: Room round the part for the dimensions and words (mm of paper).
_MARGIN_MM = 14.0
_FONT, _BOLD = "Helvetica", "Helvetica-Bold"
_TEXT_MM = 2.6
_DIM = (0.1, 0.25, 0.65)
_TABLE_BAND_MM = 4.0


class ElevationDrawing(Flowable):
    """The dimensioned side view of one part (a reportlab flowable, drawn in mm of paper).

    Parameters
    ----------
    elevation : Elevation
    view : str
        The guide's view: ``"top"`` (heights above the table) or ``"side"`` (depths in front of the board).
    """

    def __init__(self, elevation: Elevation, view: str = "top") -> None:
        super().__init__()
        self.elevation = elevation
        self.view = view
        x0, _, x1, y1 = elevation.profile.bounds if not elevation.profile.is_empty else (0.0, 0.0, 1.0, 1.0)
        s = [x0, x1, *(p[0] for p in elevation.ends)]
        self.s_range = (min(s), max(s))
        self.h_top = max(y1, *(p[1] for p in elevation.ends), 1.0)
        self.scale = SCALES[-1]
        self.size_mm = (0.0, 0.0)

    def _size(self, scale: float) -> tuple[float, float]:
        width = (self.s_range[1] - self.s_range[0]) * scale + 2 * _MARGIN_MM
        height = max(self.h_top, 0.0) * scale + _MARGIN_MM + _TABLE_BAND_MM + 8.0
        return width, height

    def wrap(self, avail_width, avail_height):
        room = avail_width / mm
        for scale in SCALES:
            width, height = self._size(scale)
            if width <= room and height <= MAX_HEIGHT_MM:
                break
        self.scale = scale
        self.size_mm = self._size(scale)
        return self.size_mm[0] * mm, self.size_mm[1] * mm

    @property
    def scale_text(self) -> str:
        return "1:1" if self.scale == 1.0 else f"1:{1 / self.scale:g}"

    def draw(self) -> None:
        canvas = self.canv
        canvas.saveState()
        canvas.scale(mm, mm)
        width, height = self.size_mm
        scale = self.scale
        base = 8.0 + _TABLE_BAND_MM  # the table line's height on the paper (the scale bar and band below it)

        def at(s: float, h: float) -> tuple[float, float]:
            return _MARGIN_MM + (s - self.s_range[0]) * scale, base + h * scale

        e = self.elevation
        surface = "board" if self.view == "side" else "table"
        # the table (or the board): a line with hatching under it
        canvas.setStrokeColorRGB(0, 0, 0)
        canvas.setLineWidth(0.5)
        canvas.line(2.0, base, width - 2.0, base)
        canvas.setLineWidth(0.2)
        for x in np.arange(3.0, width - 3.0, 2.5):
            canvas.line(x, base, x - 2.0, base - 2.0)
        canvas.setFont(_FONT, _TEXT_MM)
        canvas.setFillColorRGB(0, 0, 0)
        canvas.drawRightString(width - 2.0, base - _TABLE_BAND_MM + 0.4 - _TEXT_MM, surface)
        # the part
        canvas.setFillGray(0.88)
        canvas.setStrokeColorRGB(0, 0, 0)
        canvas.setLineWidth(0.4)
        for polygon in polygons(e.profile):
            path = canvas.beginPath()
            ring = [at(s, h) for s, h in polygon.exterior.coords]
            path.moveTo(*ring[0])
            for point in ring[1:]:
                path.lineTo(*point)
            path.close()
            canvas.drawPath(path, stroke=1, fill=1)
        # heights from the table: at each end and at the middle
        canvas.setStrokeColorRGB(*_DIM)
        canvas.setFillColorRGB(*_DIM)
        (s_low, h_low), (s_high, h_high) = e.ends
        if e.standing:  # a goblet, a post: its foot and its top, and how far it leans from upright
            marks = [(s_low, h_low, "foot"), (s_high, h_high, "top")]
        else:
            marks = [(s_low, h_low, "lower end" if not e.level else "end"),
                     (s_high, h_high, "upper end" if not e.level else "end"), (*e.middle, "middle")]
        for s, h, name in marks:
            left = s < max(s_low, s_high) if e.standing else s < e.middle[0] or name == "middle"
            self._height(canvas, at(s, 0.0), at(s, h), f"{h:.1f}", name, left)
        if not e.level:
            (a0, b0), (a1, b1) = e.axis or e.ends  # the angle runs along the part's length
            self._angle(canvas, at(s_low, h_low), math.atan2(b1 - b0, a1 - a0),
                        e.lean_deg if e.standing else e.tilt_deg, e.standing)
        # a 20 mm bar to check the scale
        canvas.setFillColorRGB(0, 0, 0)
        canvas.rect(2.0, 1.5, 20.0 * scale, 1.2, stroke=0, fill=1)
        canvas.setFont(_FONT, 2.2)
        canvas.drawString(3.0 + 20.0 * scale, 1.5, f"20 mm at {self.scale_text}")
        canvas.restoreState()

    @staticmethod
    def _height(canvas, foot, top, text: str, name: str, left: bool) -> None:
        """A vertical dimension from the table to a point of the underside, with its value and the point's name."""
        x, y0 = foot
        _, y1 = top
        canvas.setLineWidth(0.25)
        canvas.line(x, y0, x, y1)
        for y, sign in ((y0, 1.0), (y1, -1.0)):  # arrowheads pointing at the table and at the part
            head = canvas.beginPath()
            head.moveTo(x, y)
            head.lineTo(x - 0.7, y + sign * 1.8)
            head.lineTo(x + 0.7, y + sign * 1.8)
            head.close()
            canvas.drawPath(head, stroke=0, fill=1)
        canvas.setFont(_BOLD, _TEXT_MM)
        middle = y0 + 0.3 * (y1 - y0) + 2.0  # low down: the tilt's angle is drawn at the lower end's height
        if left:
            canvas.drawRightString(x - 1.0, middle, text)
            canvas.setFont(_FONT, 2.2)
            canvas.drawRightString(x - 1.0, middle - 2.8, name)
        else:
            canvas.drawString(x + 1.0, middle, text)
            canvas.setFont(_FONT, 2.2)
            canvas.drawString(x + 1.0, middle - 2.8, name)

    @staticmethod
    def _angle(canvas, low, along: float, degrees: float, upright: bool = False) -> None:
        """The tilt at the lower end ``low``: a level line the way the part rises (``upright``: a plumb line up from
        its foot) and the arc from it to the part's length (at ``along`` radians on the paper), with its angle."""
        x0, y0 = low
        reach = 20.0
        start = math.pi / 2 if upright else (0.0 if math.cos(along) >= 0 else math.pi)
        canvas.setLineWidth(0.25)
        canvas.setDash(1.2, 0.8)
        canvas.line(x0, y0, x0 + 1.15 * reach * math.cos(start), y0 + 1.15 * reach * math.sin(start))
        canvas.setDash()
        angles = np.linspace(start, along, 24)
        points = [(x0 + reach * math.cos(a), y0 + reach * math.sin(a)) for a in angles]
        path = canvas.beginPath()
        path.moveTo(*points[0])
        for point in points[1:]:
            path.lineTo(*point)
        canvas.drawPath(path, stroke=1, fill=0)
        middle = (start + along) / 2
        tx, ty = x0 + (reach + 1.5) * math.cos(middle), y0 + (reach + 1.5) * math.sin(middle) - 1.0
        canvas.setFont(_BOLD, _TEXT_MM)
        text = f"{degrees:.1f}\u00b0" + (" from upright" if upright else "")
        (canvas.drawString if math.cos(middle) >= 0 else canvas.drawRightString)(tx, ty, text)
