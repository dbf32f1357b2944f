"""Tiling a guide at 1:1 over sheets of paper: which sheets, where each one lies on the guide plane.

A sheet of paper ``W x H`` mm keeps a white ``printable`` margin all round (printers cannot print to the edge) and a
``footer`` band at the bottom (title, page map, scale bar); the rest is its **drawing area**, the guide at 1:1.
Neighbouring drawing areas overlap by ``overlap`` mm so the maker can lay one sheet over the next and match the grid.
A sheet point ``(x, y)`` mm from the sheet's lower-left corner is the guide-plane point ``origin_mm + (x, y)``.

Sheets are labelled like a map: column letters from the left (A, B, ...), row numbers from the top (1, 2, ...),
``A1`` top-left; their indices run in reading order (row by row, left to right).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from projector.errors import ProjectorError
from projector.guide import Guide, GuidePage

__all__ = ["PAPERS", "SheetFormat", "choose_format", "column_letters", "grid_shape", "page_format", "sheet_format",
           "tile", "tile_pages"]

#: Paper sizes in portrait (width, height) mm.
PAPERS: dict[str, tuple[float, float]] = {"a4": (210.0, 297.0), "letter": (215.9, 279.4), "a3": (297.0, 420.0)}
#: Defaults: white margin all round (most printers need 4-6 mm; 10 mm is safe with any), the footer band, the overlap
#: between neighbouring sheets, the white margin kept round the guide's extent, and the most sheets worth printing.
PRINTABLE_MM = 10.0
FOOTER_MM = 24.0
OVERLAP_MM = 15.0
MARGIN_MM = 10.0
MAX_SHEETS = 60


@dataclass(frozen=True)
class SheetFormat:
    """One sheet's geometry: its size as printed and where its drawing area and footer lie (sheet mm)."""

    paper: str
    size_mm: tuple[float, float]
    printable_mm: float = PRINTABLE_MM
    footer_mm: float = FOOTER_MM
    overlap_mm: float = OVERLAP_MM

    @property
    def orientation(self) -> str:
        return "landscape" if self.size_mm[0] > self.size_mm[1] else "portrait"

    @property
    def drawing_box(self) -> tuple[float, float, float, float]:
        """``(x0, y0, x1, y1)`` of the drawing area on the sheet."""
        w, h = self.size_mm
        p = self.printable_mm
        return (p, p + self.footer_mm, w - p, h - p)

    @property
    def footer_box(self) -> tuple[float, float, float, float]:
        w, _ = self.size_mm
        p = self.printable_mm
        return (p, p, w - p, p + self.footer_mm - 3.0)

    @property
    def step_mm(self) -> tuple[float, float]:
        """How far the drawing area moves on the guide plane from one sheet to the next (column, row)."""
        x0, y0, x1, y1 = self.drawing_box
        return (x1 - x0 - self.overlap_mm, y1 - y0 - self.overlap_mm)


def sheet_format(paper: str, orientation: str = "portrait", *, overlap_mm: float = OVERLAP_MM) -> SheetFormat:
    """The :class:`SheetFormat` of ``paper`` (a4, letter, a3) in ``orientation`` (portrait, landscape)."""
    key = str(paper).lower()
    if key not in PAPERS:
        raise ProjectorError(f"paper: expected one of {', '.join(PAPERS)}, got {paper!r}")
    if orientation not in ("portrait", "landscape"):
        raise ProjectorError(f"orientation: expected portrait or landscape, got {orientation!r}")
    if not isinstance(overlap_mm, (int, float)) or not 0.0 <= overlap_mm <= 50.0:
        raise ProjectorError(f"overlap_mm: expected a number of millimetres from 0 to 50, got {overlap_mm!r}")
    w, h = PAPERS[key]
    size = (h, w) if orientation == "landscape" else (w, h)
    return SheetFormat(key, size, overlap_mm=float(overlap_mm))


def column_letters(column: int) -> str:
    """0 → A, 25 → Z, 26 → AA (a spreadsheet's column names)."""
    letters = ""
    column += 1
    while column:
        column, rest = divmod(column - 1, 26)
        letters = chr(ord("A") + rest) + letters
    return letters


def _count(span: float, step: float, overlap: float) -> int:
    # n drawing areas moved by ``step`` cover n * step + overlap millimetres.
    return max(1, math.ceil((span - overlap) / step - 1e-9))


def tile_pages(extent_mm: tuple[float, float, float, float], fmt: SheetFormat,
               margin_mm: float = MARGIN_MM) -> tuple[tuple[GuidePage, ...], tuple[int, int]]:
    """The sheets of ``fmt`` covering ``extent_mm`` plus ``margin_mm`` all round, and ``(columns, rows)``.

    The grid of sheets is centred on the extent, so the white left over is shared between the sides.
    """
    u0, v0, u1, v1 = (float(e) for e in extent_mm)
    span_u, span_v = u1 - u0 + 2 * margin_mm, v1 - v0 + 2 * margin_mm
    step_u, step_v = fmt.step_mm
    columns, rows = _count(span_u, step_u, fmt.overlap_mm), _count(span_v, step_v, fmt.overlap_mm)
    x0, y0, _, _ = fmt.drawing_box
    cover_u, cover_v = columns * step_u + fmt.overlap_mm, rows * step_v + fmt.overlap_mm
    left = (u0 + u1) / 2 - cover_u / 2
    top = (v0 + v1) / 2 + cover_v / 2
    height = fmt.drawing_box[3] - fmt.drawing_box[1]
    pages = []
    for row in range(rows):
        for column in range(columns):
            area_u = left + column * step_u
            area_v = top - height - row * step_v
            pages.append(GuidePage(index=len(pages), label=f"{column_letters(column)}{row + 1}", paper=fmt.paper,
                                   size_mm=fmt.size_mm, origin_mm=(area_u - x0, area_v - y0)))
    return tuple(pages), (columns, rows)


def _check_extent(extent_mm) -> tuple[float, float, float, float]:
    try:
        values = tuple(float(e) for e in extent_mm)
    except (TypeError, ValueError):
        values = ()
    if len(values) != 4 or not all(math.isfinite(v) for v in values) or values[2] < values[0] \
            or values[3] < values[1]:
        raise ProjectorError(f"guide extent_mm: expected (u_min, v_min, u_max, v_max) finite with min <= max, "
                             f"got {extent_mm!r}")
    return values  # type: ignore[return-value]


def choose_format(extent_mm, paper: str = "a4", orientation: str | None = None, *, overlap_mm: float = OVERLAP_MM,
                  margin_mm: float = MARGIN_MM) -> SheetFormat:
    """The sheet format to tile ``extent_mm`` with: ``orientation``, or the one that needs fewer sheets (portrait
    when both need as many)."""
    extent = _check_extent(extent_mm)
    if orientation is not None:
        return sheet_format(paper, orientation, overlap_mm=overlap_mm)
    formats = [sheet_format(paper, o, overlap_mm=overlap_mm) for o in ("portrait", "landscape")]
    return min(formats, key=lambda f: len(tile_pages(extent, f, margin_mm)[0]))


def tile(guide: Guide, paper: str = "a4", *, orientation: str | None = None, overlap_mm: float = OVERLAP_MM,
         margin_mm: float = MARGIN_MM, max_sheets: int = MAX_SHEETS) -> Guide:
    """``guide`` with its :attr:`~projector.guide.Guide.pages`: the sheets of ``paper`` covering it at 1:1.

    Parameters
    ----------
    guide : Guide
        Its ``extent_mm`` is what the sheets must cover (plus ``margin_mm`` all round).
    paper : str
        ``"a4"``, ``"letter"`` or ``"a3"``.
    orientation : str or None
        ``"portrait"`` or ``"landscape"``; None picks the one needing fewer sheets.
    overlap_mm : float
        How much neighbouring sheets' drawings overlap.
    margin_mm : float
        White kept round the extent.
    max_sheets : int
        More sheets than this is refused (a :class:`ProjectorError` saying the extent and what to do).
    """
    fmt = choose_format(guide.extent_mm, paper, orientation, overlap_mm=overlap_mm, margin_mm=margin_mm)
    pages, (columns, rows) = tile_pages(guide.extent_mm, fmt, margin_mm)
    if len(pages) > max_sheets:
        u0, v0, u1, v1 = guide.extent_mm
        raise ProjectorError(
            f"guide of {guide.scenario!r}: its extent is {u1 - u0:.0f} x {v1 - v0:.0f} mm, which takes "
            f"{columns} x {rows} = {len(pages)} sheets of {fmt.paper} at 1:1 (at most {max_sheets}); print on "
            f"larger paper (--paper a3), mark the board from the SVG with a plotter or laser, or project the guide")
    return dataclasses.replace(guide, pages=pages)


def page_format(page: GuidePage, overlap_mm: float = OVERLAP_MM) -> SheetFormat:
    """The :class:`SheetFormat` a page was tiled with (its paper and orientation, the default margins)."""
    orientation = "landscape" if page.size_mm[0] > page.size_mm[1] else "portrait"
    return sheet_format(page.paper, orientation, overlap_mm=overlap_mm)


def grid_shape(pages: tuple[GuidePage, ...]) -> tuple[int, int]:
    """``(columns, rows)`` of a tiling, from its pages' labels."""
    columns = {"".join(c for c in p.label if c.isalpha()) for p in pages}
    rows = {"".join(c for c in p.label if c.isdigit()) for p in pages}
    return len(columns), len(rows)
