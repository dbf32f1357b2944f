"""The printed guide: a PDF at exactly 1:1, tiled over sheets of A4 / Letter / A3, and a last page of lists.

Each sheet shows its part of the guide plane (1 mm on the plane is 1 mm on paper: reportlab's ``mm`` unit), clipped to
its drawing area: a light grey 10 mm grid labelled every 50 mm in guide millimetres (the lines to join sheets by), the
footprints of the laser-cut jigs the steps use, the parts (placed ones solid, static ones hatched grey), their numbered
labels, heading arrows, tolerance zones and arcs coloured by care, where each part's tag goes, the four reference tags
at their exact size, join marks in the overlaps, and in the footer the page map and a 100 mm scale bar to check the
print. The last page(s) (:mod:`projector.pdf_lists`) list the parts, the steps and the tolerances.
"""

from __future__ import annotations

from os import PathLike
from typing import BinaryIO

import numpy as np
import shapely

from projector.drawing import (
    CARE_COLORS,
    DETAIL_MM,
    NAME_MM,
    Label,
    arc_points,
    arrow,
    care_color,
    hatch_segments,
    heading_length,
    place_labels,
    placement_deltas,
    polygons,
    tag_box,
    tolerance_zone,
)
from projector.guide import Guide, GuidePage, PartDrawing, PartKind
from projector.pdf_lists import draw_lists
from projector.pdf_marks import BOLD, FONT, INK, SCALE_BAR_MM, draw_scale_bar, draw_tag
from projector.tiling import OVERLAP_MM, SheetFormat, grid_shape, page_format, tile
from vision.tags import tag_cells

__all__ = ["write_pdf"]

GRID_LIGHT, GRID_DARK = 0.86, 0.68  # grey levels of the 10 mm and 50 mm lines
ARROW_COLOR = (0.1, 0.25, 0.65)
STATIC_FILL = 0.86
JIG_FILL, JIG_EDGE = (0.96, 0.91, 0.82), (0.55, 0.35, 0.15)  # a laser-cut jig's footprint: light wood, brown edge


def write_pdf(guide: Guide, stream_or_path: BinaryIO | str | PathLike, *, paper: str = "a4",
              orientation: str | None = None, steps=(), title: str | None = None,
              overlap_mm: float = OVERLAP_MM) -> Guide:
    """Write the guide as a PDF: the 1:1 sheets, then the parts, steps and tolerances.

    Parameters
    ----------
    guide : Guide
        What to draw (its pages are recomputed for ``paper``).
    stream_or_path : binary stream or path
        Where the PDF goes.
    paper : str
        ``"a4"``, ``"letter"`` or ``"a3"``.
    orientation : str or None
        ``"portrait"``, ``"landscape"``, or None for whichever needs fewer sheets.
    steps : sequence of str
        The assembly steps, one line each (listed on the last page).
    title : str or None
        The title on every page (default: the scenario and its view).
    overlap_mm : float
        How much neighbouring sheets overlap.

    Returns
    -------
    Guide
        ``guide`` with its ``pages`` (the sheets, in the PDF's order; the lists follow them).
    """
    from reportlab.pdfgen import canvas as pdfcanvas

    guide = tile(guide, paper, orientation=orientation, overlap_mm=overlap_mm)
    title = title if title is not None else f"{guide.scenario} \u2013 {guide.view} view"
    target = stream_or_path if hasattr(stream_or_path, "write") else str(stream_or_path)
    canvas = pdfcanvas.Canvas(target, invariant=1, pageCompression=1)
    canvas.setTitle(title)
    canvas.setAuthor("chaos-station")
    canvas.setSubject("assembly guide, print at 100 % (actual size)")
    labels = place_labels(guide, avoid=_sheet_edges(guide, overlap_mm))
    for page in guide.pages:
        draw_sheet(canvas, guide, page, labels, title, overlap_mm)
        canvas.showPage()
    draw_lists(canvas, guide, [str(s) for s in steps], title)
    canvas.save()
    return guide


def _sheet_edges(guide: Guide, overlap_mm: float):
    """The edges of every sheet's drawing area on the guide plane, 3 mm wide (where a label would be cut)."""
    from shapely.geometry import box

    edges = []
    for page in guide.pages:
        x0, y0, x1, y1 = page_format(page, overlap_mm).drawing_box
        u, v = page.origin_mm
        edges.append(box(u + x0, v + y0, u + x1, v + y1).exterior.buffer(1.5))
    return shapely.union_all(edges) if edges else None


def draw_sheet(canvas, guide: Guide, page: GuidePage, labels: dict[str, Label], title: str,
               overlap_mm: float = OVERLAP_MM) -> None:
    """Draw one sheet of the tiled guide on ``canvas`` (a reportlab canvas, at a new page)."""
    from reportlab.lib.units import mm

    fmt = page_format(page, overlap_mm)
    canvas.setPageSize((page.size_mm[0] * mm, page.size_mm[1] * mm))
    canvas.saveState()
    canvas.scale(mm, mm)  # from here on, one unit is one millimetre of paper
    x0, y0, x1, y1 = fmt.drawing_box
    canvas.saveState()
    clip = canvas.beginPath()
    clip.rect(x0, y0, x1 - x0, y1 - y0)
    canvas.clipPath(clip, stroke=0, fill=0)
    canvas.translate(-page.origin_mm[0], -page.origin_mm[1])  # guide-plane mm from here on
    area = (page.origin_mm[0] + x0, page.origin_mm[1] + y0, page.origin_mm[0] + x1, page.origin_mm[1] + y1)
    _grid(canvas, area)
    _drawing(canvas, guide, labels)
    _reminders(canvas, guide, labels, area, fmt.overlap_mm)
    _join_marks(canvas, guide, fmt)
    canvas.restoreState()
    _crop_marks(canvas, guide, page, fmt)
    _footer(canvas, guide, page, fmt, title)
    canvas.restoreState()


def _ring_path(canvas, rings):
    path = canvas.beginPath()
    for ring in rings:
        ring = np.asarray(ring, dtype=float)
        path.moveTo(*ring[0])
        for point in ring[1:]:
            path.lineTo(*point)
        path.close()
    return path


def _fill_geometry(canvas, geometry, stroke: int, fill: int) -> None:
    from reportlab.pdfgen.canvas import FILL_EVEN_ODD

    for polygon in polygons(geometry):
        rings = [polygon.exterior.coords, *(hole.coords for hole in polygon.interiors)]
        canvas.drawPath(_ring_path(canvas, rings), stroke=stroke, fill=fill, fillMode=FILL_EVEN_ODD)


def _polyline(canvas, points) -> None:
    points = np.asarray(points, dtype=float)
    path = canvas.beginPath()
    path.moveTo(*points[0])
    for point in points[1:]:
        path.lineTo(*point)
    canvas.drawPath(path, stroke=1, fill=0)


def _grid(canvas, area) -> None:
    """The 10 mm background grid in guide mm, darker and labelled every 50 mm (the same lines on every sheet)."""
    u0, v0, u1, v1 = area
    for step, grey, width in ((10, GRID_LIGHT, 0.15), (50, GRID_DARK, 0.3)):
        canvas.setStrokeGray(grey)
        canvas.setLineWidth(width)
        for u in np.arange(np.ceil(u0 / step) * step, u1 + 1e-9, step):
            canvas.line(u, v0, u, v1)
        for v in np.arange(np.ceil(v0 / step) * step, v1 + 1e-9, step):
            canvas.line(u0, v, u1, v)
    canvas.setFillGray(0.45)
    canvas.setFont(FONT, 2.2)
    for u in np.arange(np.ceil(u0 / 50) * 50, u1 + 1e-9, 50):
        canvas.drawString(u + 0.6, v1 - 2.8, f"u {u:.0f}")
    for v in np.arange(np.ceil(v0 / 50) * 50, v1 + 1e-9, 50):
        canvas.drawString(u0 + 0.8, v + 0.6, f"v {v:.0f}")


def _drawing(canvas, guide: Guide, labels: dict[str, Label]) -> None:
    """Everything on the guide plane, back to front: the jigs' footprints, tolerance zones, parts, where their tags
    go, heading arrows, reference tags, labels."""
    for jig in guide.jigs:
        _jig(canvas, guide, jig)
    for part in guide.parts:
        du, dv, _ = placement_deltas(part, guide.plane)
        zone = tolerance_zone(part.outline, du, dv)
        if zone is not None:
            color = care_color(part.care)
            canvas.setFillColorRGB(*color, alpha=0.16)
            canvas.setStrokeColorRGB(*color)
            canvas.setLineWidth(0.35)
            canvas.setDash(1.5, 1.0)
            _fill_geometry(canvas, zone, stroke=1, fill=1)
            canvas.setDash()
            canvas.setFillAlpha(1.0)  # alpha stays set in reportlab until changed
    for part in guide.parts:
        _part(canvas, part)
    for part in guide.parts:
        for tagged in part.tag_views():
            _part_tag(canvas, tagged)
        if part.tag_views():
            if part.kind != PartKind.STATIC:  # the tag sits on the part: keep the part's outline visible over it
                canvas.setStrokeColorRGB(*INK)
                canvas.setLineWidth(0.5)
                _fill_geometry(canvas, part.outline, stroke=1, fill=0)
    for part in guide.parts:
        _heading(canvas, guide, part)
    for tag in guide.reference_tags:
        draw_tag(canvas, tag.id, tag.center_mm, tag.size_mm)
        canvas.setFillGray(0.3)
        canvas.setFont(FONT, 2.5)
        canvas.drawCentredString(tag.center_mm[0], tag.center_mm[1] - tag.size_mm * 0.625 - 3.0,
                                 f"reference tag {tag.id}")
    for part in guide.parts:
        _label(canvas, labels[part.name], part)


def _jig(canvas, guide: Guide, jig) -> None:
    """A laser-cut jig's footprint, where the maker lays it: wood-coloured, a dashed brown edge and its name where
    the part does not cover it."""
    canvas.setFillColorRGB(*JIG_FILL)
    canvas.setStrokeColorRGB(*JIG_EDGE)
    canvas.setLineWidth(0.4)
    canvas.setDash(2.0, 1.0)
    _fill_geometry(canvas, jig.footprint, stroke=1, fill=1)
    canvas.setDash()
    try:
        covered = guide.part(jig.part).outline
    except KeyError:
        covered = None
    free = jig.footprint if covered is None else jig.footprint.difference(covered.buffer(1.0))
    where = (free if not free.is_empty and free.area > 4.0 else jig.footprint).representative_point()
    canvas.setFillColorRGB(*JIG_EDGE)
    canvas.setFont(BOLD, 3.0)
    canvas.drawCentredString(where.x, where.y - 1.0, f"jig {jig.id}")


def _reminders(canvas, guide: Guide, labels: dict[str, Label], area, overlap_mm: float) -> None:
    """A part's number again on a sheet that shows some of the part but not its label (a long part, a run).

    Kept out of the overlaps, so two sheets still show the same drawing where they are laid over each other.
    """
    from shapely.geometry import LineString, Point, box

    sheet = box(*area)
    marks = shapely.union_all(
        [LineString(arrow(p.center_mm, p.heading_deg, heading_length(p))[0]).buffer(3.5) for p in guide.parts]
        + [tag_box(t.tag_center_mm, t.tag_size_mm, t.tag_heading_deg).buffer(3.0) for p in guide.parts
           for t in p.tag_views()])
    inner = box(area[0] + overlap_mm + 3, area[1] + overlap_mm + 3, area[2] - overlap_mm - 3,
                area[3] - overlap_mm - 3)
    for part in guide.parts:
        label = labels[part.name]
        if inner.is_empty or sheet.contains(Point(label.circle).buffer(label.radius)):
            continue
        visible = part.outline.intersection(inner)
        if visible.is_empty or visible.area < 1.0:
            continue
        free = visible.difference(marks)  # off the arrows and tags, when the part leaves room
        point = (free if free.area >= 1.0 else visible).representative_point()
        _number(canvas, (point.x, point.y), 2.8, part.step, part.kind != PartKind.STATIC)


def _number(canvas, centre, radius: float, number: int, placed: bool) -> None:
    """A part's assembly number in a circle: white on black for a placed part, grey on white for a fixed one."""
    cu, cv = centre
    if placed:
        canvas.setFillColorRGB(*INK)
        canvas.circle(cu, cv, radius, stroke=0, fill=1)
        canvas.setFillColorRGB(1.0, 1.0, 1.0)
    else:
        canvas.setStrokeGray(0.35)
        canvas.setLineWidth(0.4)
        canvas.setFillColorRGB(1.0, 1.0, 1.0)
        canvas.circle(cu, cv, radius, stroke=1, fill=1)
        canvas.setFillGray(0.3)
    text = str(number)
    size = radius * (1.2 if len(text) < 3 else 0.9)
    canvas.setFont(BOLD, size)
    canvas.drawCentredString(cu, cv - size * 0.36, text)


def _part(canvas, part: PartDrawing) -> None:
    if part.kind == PartKind.STATIC:
        canvas.setFillGray(STATIC_FILL)
        canvas.setStrokeGray(0.35)
        canvas.setLineWidth(0.3)
        _fill_geometry(canvas, part.outline, stroke=0, fill=1)
        canvas.setLineWidth(0.15)
        canvas.setStrokeGray(0.55)
        for segment in hatch_segments(part.outline):
            canvas.line(*segment[0], *segment[1])
        canvas.setStrokeGray(0.35)
        canvas.setLineWidth(0.3)
        _fill_geometry(canvas, part.outline, stroke=1, fill=0)
    else:
        canvas.setFillColorRGB(1.0, 1.0, 1.0)
        canvas.setStrokeColorRGB(*INK)
        canvas.setLineWidth(0.5)
        _fill_geometry(canvas, part.outline, stroke=1, fill=1)
    # The part's origin, the point the steps give: a small cross.
    canvas.setStrokeColorRGB(*INK)
    canvas.setLineWidth(0.2)
    u, v = part.center_mm
    canvas.line(u - 1.5, v, u + 1.5, v)
    canvas.line(u, v - 1.5, u, v + 1.5)


def _heading(canvas, guide: Guide, part: PartDrawing) -> None:
    if part.kind == PartKind.STATIC:
        return
    length = heading_length(part)
    shaft, head = arrow(part.center_mm, part.heading_deg, length)
    canvas.setStrokeColorRGB(*ARROW_COLOR)
    canvas.setFillColorRGB(*ARROW_COLOR)
    canvas.setLineWidth(0.4)
    _polyline(canvas, shaft)
    canvas.drawPath(_ring_path(canvas, [head]), stroke=0, fill=1)
    _, _, dtheta = placement_deltas(part, guide.plane)
    if dtheta is not None:
        color = care_color(part.care)
        canvas.setStrokeColorRGB(*color)
        canvas.setLineWidth(0.6)
        arc = arc_points(part.center_mm, length, part.heading_deg, max(dtheta, 0.5))
        _polyline(canvas, arc)
        canvas.setLineWidth(0.3)
        centre = np.asarray(part.center_mm)
        for end in (arc[0], arc[-1]):
            _polyline(canvas, [centre + (end - centre) * 0.85, end + (end - centre) * 0.08])


def _part_tag(canvas, part: PartDrawing) -> None:
    """Where the part's tag goes: its square's outline, its data cells in light grey, its id and first corner.

    Not a decodable tag on purpose: a camera must find the tag on the part, never on the sheet under it.
    """
    cells = tag_cells(part.tag_id)
    size = part.tag_size_mm
    cell = size / 8
    half = size / 2
    canvas.saveState()
    canvas.translate(*part.tag_center_mm)
    canvas.rotate(part.tag_heading_deg)
    canvas.setFillColorRGB(1.0, 1.0, 1.0)
    canvas.rect(-half, -half, size, size, stroke=0, fill=1)
    canvas.setFillGray(0.72)
    for row in range(2, 8):
        for col in range(2, 8):
            if not cells[row, col]:
                canvas.rect(-half + (col - 1) * cell, half - row * cell, cell, cell, stroke=0, fill=1)
    canvas.setStrokeGray(0.25)
    canvas.setLineWidth(0.25)
    canvas.rect(-half, -half, size, size, stroke=1, fill=0)
    canvas.setFillGray(0.25)
    corner = canvas.beginPath()  # the tag's first corner (lower-left as printed on the part)
    corner.moveTo(-half, -half)
    corner.lineTo(-half + 0.3 * size, -half)
    corner.lineTo(-half, -half + 0.3 * size)
    corner.close()
    canvas.drawPath(corner, stroke=0, fill=1)
    canvas.setFont(BOLD, min(3.0, 0.3 * size))
    canvas.drawCentredString(0, half + 0.8, f"tag {part.tag_id}")
    canvas.restoreState()


def _label(canvas, label: Label, part: PartDrawing) -> None:
    placed = part.kind != PartKind.STATIC
    if label.leader is not None:
        canvas.setStrokeColorRGB(*INK)
        canvas.setLineWidth(0.25)
        _polyline(canvas, label.leader)
        canvas.setFillColorRGB(*INK)
        canvas.circle(*label.leader[1], 0.6, stroke=0, fill=1)
    x0, y0, x1, y1 = label.box.bounds
    canvas.setFillColorRGB(1.0, 1.0, 1.0, alpha=0.85)
    canvas.roundRect(x0, y0, x1 - x0, y1 - y0, 1.2, stroke=0, fill=1)
    canvas.setFillAlpha(1.0)
    _number(canvas, label.circle, label.radius, label.number, placed)
    tu, tv = label.text
    canvas.setFillColorRGB(*INK) if placed else canvas.setFillGray(0.3)
    canvas.setFont(BOLD, NAME_MM)
    if label.detail or label.off_plane:
        canvas.drawString(tu, tv + 0.5, label.name + ("  (fixed)" if not placed and not label.detail else ""))
        below = tv - DETAIL_MM - 0.2
        if label.detail:
            canvas.setFillColorRGB(*CARE_COLORS.get(part.care or "", care_color(None)))
            canvas.setFont(FONT, DETAIL_MM)
            canvas.drawString(tu, below, label.detail)
            below -= DETAIL_MM + 0.6
        if label.off_plane:  # the height and tilt the sheet cannot show
            canvas.setFillColorRGB(*INK)
            canvas.setFont(FONT, DETAIL_MM)
            canvas.drawString(tu, below, label.off_plane)
    else:
        canvas.drawString(tu, tv - NAME_MM * 0.36, label.name + ("  (fixed)" if not placed else ""))


def _seams(guide: Guide, fmt: SheetFormat):
    """Each overlap between neighbouring sheets: ``(labels, u0, v0, u1, v1)`` of the band on the guide plane."""
    pages = guide.pages
    columns, rows = grid_shape(pages)
    bands = []
    for page in pages:
        row, column = divmod(page.index, columns)
        x0, y0, x1, y1 = fmt.drawing_box
        a = (page.origin_mm[0] + x0, page.origin_mm[1] + y0, page.origin_mm[0] + x1, page.origin_mm[1] + y1)
        if column + 1 < columns:
            other = pages[page.index + 1]
            bands.append((f"{page.label}|{other.label}", a[2] - fmt.overlap_mm, a[1], a[2], a[3]))
        if row + 1 < rows:
            other = pages[page.index + columns]
            bands.append((f"{page.label}/{other.label}", a[0], a[1], a[2], a[1] + fmt.overlap_mm))
    return bands


def _join_marks(canvas, guide: Guide, fmt: SheetFormat) -> None:
    """Targets in the middle of each overlap: the same marks on both sheets, to lay one exactly over the other."""
    canvas.setStrokeColorRGB(0.55, 0.0, 0.55)
    canvas.setFillColorRGB(0.55, 0.0, 0.55)
    canvas.setLineWidth(0.25)
    canvas.setFont(FONT, 2.0)
    for text, u0, v0, u1, v1 in _seams(guide, fmt):
        vertical = (u1 - u0) < (v1 - v0)
        for f in (0.25, 0.75):
            u, v = ((u0 + u1) / 2, v0 + f * (v1 - v0)) if vertical else (u0 + f * (u1 - u0), (v0 + v1) / 2)
            canvas.circle(u, v, 2.5, stroke=1, fill=0)
            canvas.line(u - 5, v, u + 5, v)
            canvas.line(u, v - 5, u, v + 5)
            canvas.drawString(u + 1.0, v + 1.0, text)


def _crop_marks(canvas, guide: Guide, page: GuidePage, fmt: SheetFormat) -> None:
    """Corner marks round the drawing area, and on the sides that overlap a neighbour a dashed trim line."""
    columns, rows = grid_shape(guide.pages)
    row, column = divmod(page.index, columns)
    x0, y0, x1, y1 = fmt.drawing_box
    canvas.setStrokeColorRGB(*INK)
    canvas.setLineWidth(0.2)
    for x, y, sx, sy in ((x0, y0, -1, -1), (x1, y0, 1, -1), (x1, y1, 1, 1), (x0, y1, -1, 1)):
        canvas.line(x + sx * 1.0, y, x + sx * 6.0, y)
        canvas.line(x, y + sy * 1.0, x, y + sy * 6.0)
    canvas.setFont(FONT, 2.2)
    canvas.setFillColorRGB(*INK)
    canvas.setDash(2.0, 1.5)
    # Trim the left margin of every sheet with a neighbour on its left and the top margin of every sheet with one
    # above it, then lay it over that neighbour: its grid on the neighbour's.
    if column > 0:
        canvas.line(x0, y0, x0, y1)
        canvas.saveState()
        canvas.translate(x0 - 1.5, (y0 + y1) / 2)
        canvas.rotate(90)
        canvas.drawCentredString(0, 0, f"trim here, lay over sheet {guide.pages[page.index - 1].label}")
        canvas.restoreState()
    if row > 0:
        canvas.line(x0, y1, x1, y1)
        canvas.drawCentredString((x0 + x1) / 2, y1 + 1.5, f"trim here, lay over sheet "
                                                          f"{guide.pages[page.index - columns].label}")
    canvas.setDash()
    canvas.setStrokeGray(0.5)
    canvas.rect(x0, y0, x1 - x0, y1 - y0, stroke=1, fill=0)


def _footer(canvas, guide: Guide, page: GuidePage, fmt: SheetFormat, title: str) -> None:
    columns, rows = grid_shape(guide.pages)
    fx0, fy0, fx1, fy1 = fmt.footer_box
    canvas.setFillColorRGB(*INK)
    canvas.setFont(BOLD, 3.4)
    canvas.drawString(fx0, fy1 - 3.0, title)
    _page_map(canvas, guide, page, (fx0, fy0, fx0 + 30.0, fy1 - 5.0), columns, rows)
    canvas.setFillColorRGB(*INK)
    canvas.setFont(BOLD, 3.0)
    canvas.drawString(fx0 + 33.0, fy1 - 8.5, f"sheet {page.label} of {columns} x {rows}")
    canvas.setFont(FONT, 2.4)
    canvas.drawString(fx0 + 33.0, fy1 - 12.5, "print at actual size (100 %),")
    canvas.drawString(fx0 + 33.0, fy1 - 15.5, "not \u201cfit to page\u201d; units: mm")
    draw_scale_bar(canvas, fx1 - SCALE_BAR_MM, fy0 + 3.0)


def _page_map(canvas, guide: Guide, page: GuidePage, area, columns: int, rows: int) -> None:
    """A small map of the sheets, this one filled."""
    x0, y0, x1, y1 = area
    cell = min((x1 - x0) / columns, (y1 - y0) / rows, 8.0)
    ratio = page.size_mm[1] / page.size_mm[0]
    cw, ch = (cell, cell * ratio) if ratio <= 1 else (cell / ratio, cell)
    canvas.setLineWidth(0.2)
    for other in guide.pages:
        row, column = divmod(other.index, columns)
        x, y = x0 + column * cw, y0 + (rows - 1 - row) * ch
        canvas.setStrokeGray(0.3)
        if other.index == page.index:
            canvas.setFillGray(0.2)
            canvas.rect(x, y, cw, ch, stroke=1, fill=1)
            canvas.setFillColorRGB(1.0, 1.0, 1.0)
        else:
            canvas.setFillColorRGB(1.0, 1.0, 1.0)
            canvas.rect(x, y, cw, ch, stroke=1, fill=1)
            canvas.setFillGray(0.3)
        if cw >= 4.0:
            canvas.setFont(FONT, min(2.2, cw / 2.5))
            canvas.drawCentredString(x + cw / 2, y + ch / 2 - 0.7, other.label)
