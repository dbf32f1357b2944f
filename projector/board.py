"""The side camera's reference board: a printed sheet standing upright behind the parts of a table guide.

A camera above the table sees positions and turns on the table; heights and tilts are square to it. A second camera
in front of the table, facing a vertical board behind the parts, sees them in the board's plane: a part's (or its
jig's) tag facing that camera is measured at its depth in front of the board exactly as a top tag is measured at its
height above the table (:mod:`calibration.measure`).

The board's plane (:class:`SideBoard`'s ``plane``, a :class:`~projector.guide.GuidePlane` of view ``"side"``):
``u`` is the table guide's ``u`` (so the board's millimetres along it are the guide's), ``v`` is the height above
the table, the normal points from the board towards the parts and the maker. The sheet stands on the table with its
lower edge on it (so its ``v`` is the height above the table), its face along the guide-plane line
``v = line_v_mm``, its centre mark at ``u = center_u_mm`` (chosen so that its lower tags are not hidden behind a jig
stand). Its four tags take the ids under the table's reference
tags (:data:`BOARD_TAG_IDS`), so neither camera mistakes one board for the other.
"""

from __future__ import annotations

from dataclasses import dataclass
from os import PathLike

import numpy as np

from projector.errors import ProjectorError
from projector.guide import REFERENCE_TAG_IDS, Guide, GuidePlane, ReferenceTag
from projector.pdf_marks import BOLD, FONT, INK, draw_scale_bar, draw_tag
from projector.tiling import PAPERS, PRINTABLE_MM

__all__ = ["BOARD_GAP_MM", "BOARD_TAG_IDS", "BOARD_TAG_MM", "SideBoard", "side_board", "write_board_pdf"]

#: The board's reference tags: the four ids just under the table's (583-586), out of the jigs' range.
BOARD_TAG_IDS = tuple(range(REFERENCE_TAG_IDS[0] - 4, REFERENCE_TAG_IDS[0]))
#: The board tags' black squares (mm): as large as the table's, so that a camera 700 mm away finds the plane to a
#: tenth of a millimetre from four tags on one sheet.
BOARD_TAG_MM = 40.0
#: How far behind the far edge of everything the guide draws the board's face stands (mm): room for a hand.
BOARD_GAP_MM = 30.0


@dataclass(frozen=True)
class SideBoard:
    """Where the reference board stands and what is printed on it (module notes).

    Attributes
    ----------
    plane : GuidePlane
        The board's plane in the scene (view ``"side"``).
    line_v_mm : float
        The guide-plane line ``v = line_v_mm`` its face stands on.
    center_u_mm : float
        Where its centre mark stands along ``u``.
    sheet_mm : tuple of float
        The sheet's width and height (landscape).
    paper : str
    reference_tags : tuple of ReferenceTag
        The four tags, centres in the board's (u, height) mm.
    """

    plane: GuidePlane
    line_v_mm: float
    center_u_mm: float
    sheet_mm: tuple[float, float]
    paper: str
    reference_tags: tuple[ReferenceTag, ...]

    @property
    def extent_mm(self) -> tuple[float, float, float, float]:
        """``(u0, 0, u1, height)`` of the sheet on the board's plane."""
        w, h = self.sheet_mm
        return (self.center_u_mm - w / 2.0, 0.0, self.center_u_mm + w / 2.0, h)

    def words(self) -> str:
        """How to stand it, in the maker's words."""
        return (f"stand the board sheet upright behind the parts, its lower edge on the table, its printed face "
                f"towards you along the line v = {self.line_v_mm:.0f} mm of the guide, its centre mark at "
                f"u = {self.center_u_mm:.0f} mm; the side camera faces it from in front of the table")

    def manifest(self) -> dict:
        """The board in the guide's manifest (``side_board``)."""
        return {"view": "side", "line_v_mm": round(self.line_v_mm, 3), "center_u_mm": round(self.center_u_mm, 3),
                "paper": self.paper, "sheet_mm": [round(s, 3) for s in self.sheet_mm],
                "reference_tags": [{"id": t.id, "center_mm": [round(c, 3) for c in t.center_mm],
                                    "size_mm": round(t.size_mm, 3)} for t in self.reference_tags],
                "words": self.words()}


def side_board(guide: Guide, paper: str = "a4") -> SideBoard | None:
    """The reference board of a table guide (None for a board guide: its own plane is vertical already)."""
    if guide.view != "top":
        return None
    if paper not in PAPERS:
        raise ProjectorError(f"paper: expected one of {', '.join(PAPERS)}, got {paper!r}")
    short, long = PAPERS[paper]
    u0, _, u1, v1 = guide.extent_mm
    line_v = float(v1) + BOARD_GAP_MM
    inset = PRINTABLE_MM + BOARD_TAG_MM * 10.0 / 8.0 / 2.0  # the tag's white border inside the printable area
    centre_u = _clear_centre((float(u0) + float(u1)) / 2.0, long / 2.0 - inset, BOARD_TAG_MM * 10.0 / 8.0 / 2.0,
                             [j.footprint.bounds for j in guide.jigs if j.kind == "stand"], long)
    plane = guide.plane
    origin = plane.to_world(np.array([[0.0, line_v]]))[0]
    board_plane = GuidePlane("side", origin, np.asarray(plane.u_axis, float), np.asarray(plane.normal, float),
                             -np.asarray(plane.v_axis, float))
    tags = tuple(ReferenceTag(tag_id, (centre_u + su * (long / 2.0 - inset), h), BOARD_TAG_MM)
                 for tag_id, (su, h) in zip(BOARD_TAG_IDS, ((-1, inset), (1, inset), (1, short - inset),
                                                            (-1, short - inset))))
    return SideBoard(board_plane, line_v, float(centre_u), (long, short), paper, tags)


def _clear_centre(middle: float, reach: float, half: float, stands, span: float) -> float:
    """Where along u to centre the board so that its lower tags (at ``middle +- reach``, ``half`` wide each side)
    stand clear of every jig stand's plate as the side camera sees it (the plate nearer the camera looks larger: its
    extent along u widened by a quarter, and 10 mm): the nearest whole millimetre to ``middle`` within ``span``,
    else ``middle`` (the check then finds the plane from the tags it sees: two are enough)."""
    shadows = [((a + b) / 2.0 - 0.625 * (b - a) - 10.0, (a + b) / 2.0 + 0.625 * (b - a) + 10.0)
               for a, _, b, _ in stands]
    for step in range(int(span) + 1):
        for centre in (round(middle) + step, round(middle) - step):
            tags = [(centre + side * reach - half, centre + side * reach + half) for side in (-1, 1)]
            if not any(lo < t1 and t0 < hi for t0, t1 in tags for lo, hi in shadows):
                return float(centre)
    return float(round(middle))


def write_board_pdf(board: SideBoard, path: str | PathLike, title: str = "") -> None:
    """The board sheet at 1:1 (landscape): its four tags, the centre mark on its lower edge, a 100 mm scale bar and
    how to stand it."""
    from reportlab.lib.units import mm
    from reportlab.pdfgen.canvas import Canvas

    w, h = board.sheet_mm
    canvas = Canvas(str(path), pagesize=(w * mm, h * mm))
    canvas.scale(mm, mm)
    u0 = board.center_u_mm - w / 2.0
    for tag in board.reference_tags:
        draw_tag(canvas, tag.id, (tag.center_mm[0] - u0, tag.center_mm[1]), tag.size_mm)
        canvas.setFillColorRGB(*INK)
        canvas.setFont(FONT, 2.4)
        canvas.drawCentredString(tag.center_mm[0] - u0, tag.center_mm[1] - tag.size_mm * 0.625 - 3.0,
                                 f"board tag {tag.id}")
    canvas.setStrokeColorRGB(*INK)
    canvas.setLineWidth(0.3)
    path_mark = canvas.beginPath()  # the centre mark: a triangle pointing down at the lower edge
    path_mark.moveTo(w / 2.0, 0.0)
    path_mark.lineTo(w / 2.0 - 3.0, 5.0)
    path_mark.lineTo(w / 2.0 + 3.0, 5.0)
    path_mark.close()
    canvas.drawPath(path_mark, stroke=1, fill=1)
    canvas.setFont(BOLD, 4.0)
    canvas.drawCentredString(w / 2.0, h - 20.0, "SIDE CAMERA BOARD" + (f": {title}" if title else ""))
    canvas.setFont(FONT, 2.8)
    lines = [f"centre mark at u = {board.center_u_mm:.0f} mm; face along v = {board.line_v_mm:.0f} mm of the guide",
             "lower edge of this sheet ON THE TABLE (heights are measured from it); the sheet upright and flat",
             "print at actual size (100 %), not \u201cfit to page\u201d; units: mm"]
    for i, line in enumerate(lines):
        canvas.drawCentredString(w / 2.0, h - 28.0 - 4.0 * i, line)
    draw_scale_bar(canvas, w / 2.0 - 50.0, 20.0)
    canvas.showPage()
    canvas.save()
