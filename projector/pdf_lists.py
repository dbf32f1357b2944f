"""The PDF guide's last page(s): the parts list, every parameter in the maker's words, the side views of the parts
lifted or tilted off the sheet, the assembly steps and the tolerance table (reportlab platypus).

Every text from the guide (part names, parameters, steps) is escaped before it reaches a Paragraph, so any name
prints as written.
"""

from __future__ import annotations

from xml.sax.saxutils import escape

from projector.drawing import CARE_COLORS, tolerance_axes
from projector.guide import Guide, where_text
from projector.pdf_marks import draw_scale_bar
from projector.tiling import FOOTER_MM, PRINTABLE_MM, grid_shape, sheet_format

__all__ = ["SOURCE_TEXT", "draw_lists", "tolerance_source_text"]

#: What the last page says about where the tolerances come from (Guide.tolerance_source).
SOURCE_TEXT = {
    "model": "Tolerances from the layout's success model: \u00b1delta is the largest error of that parameter alone "
             "that keeps the predicted success at 90 % or more of the layout's; predicted is the success there as a "
             "fraction of the layout's.",
    "simulation": "Tolerances by simulation: \u00b1delta was checked by "
                  "simulating layouts with that parameter off by \u00b1delta; measured is their success rate.",
    "none": "No tolerances: the layout carries no fitted success model and none were simulated, so every part "
            "should be placed as precisely as you can (add --verify N to measure them by simulation).",
}


def tolerance_source_text(guide: Guide) -> str:
    """The sentence saying where the guide's tolerances come from."""
    text = SOURCE_TEXT.get(guide.tolerance_source, f"Tolerances: {guide.tolerance_source}.")
    if guide.tolerance_note:
        text = f"{guide.tolerance_note[0].upper()}{guide.tolerance_note[1:]}. " + text
    if guide.tolerance_source != "none" and any(t.measured is not None for p in guide.parts for t in p.tolerances):
        text += " Measured: the success rate of simulated layouts at \u00b1delta (--verify)."
    return text


def _f(value, digits: int = 1) -> str:
    return "\u2013" if value is None else f"{value:.{digits}f}"


def _hex(rgb) -> str:
    return "#" + "".join(f"{round(255 * c):02x}" for c in rgb)


def _story(guide: Guide, steps: list[str], title: str, frame_mm: tuple[float, float] = (190.0, 253.0)) -> list:
    from reportlab.lib import colors
    from reportlab.lib.styles import ParagraphStyle, getSampleStyleSheet
    from reportlab.lib.units import mm
    from reportlab.platypus import Paragraph, Spacer, Table, TableStyle

    styles = getSampleStyleSheet()
    body = ParagraphStyle("guide-body", parent=styles["BodyText"], fontSize=9, leading=11.5)
    cell = ParagraphStyle("guide-cell", parent=body, fontSize=8, leading=9.5)
    h1, h2 = styles["Heading1"], styles["Heading2"]

    def p(text: str, style=body) -> Paragraph:
        return Paragraph(text, style)

    def table(rows: list[list], widths: list[float]) -> Table:
        t = Table(rows, colWidths=[w * mm for w in widths], repeatRows=1, hAlign="LEFT")
        t.setStyle(TableStyle([
            ("FONT", (0, 0), (-1, 0), "Helvetica-Bold", 8),
            ("FONT", (0, 1), (-1, -1), "Helvetica", 8),
            ("LINEBELOW", (0, 0), (-1, 0), 0.6, colors.black),
            ("ROWBACKGROUNDS", (0, 1), (-1, -1), [colors.white, colors.Color(0.94, 0.94, 0.94)]),
            ("VALIGN", (0, 0), (-1, -1), "TOP"),
            ("TOPPADDING", (0, 0), (-1, -1), 1.5),
            ("BOTTOMPADDING", (0, 0), (-1, -1), 1.5),
        ]))
        return t

    columns, rows = grid_shape(guide.pages)
    paper = guide.pages[0].paper.upper() if guide.pages else "\u2013"
    axes = "u to your right, v away from you" if guide.view == "top" else "u to your right, v up"
    story = [
        p(escape(title), h1),
        p(f"Assembly guide for <b>{escape(guide.scenario)}</b>, {escape(guide.view)} view, at 1:1 in millimetres "
          f"({axes}, as you face the {'table' if guide.view == 'top' else 'board'}). {len(guide.pages)} "
          f"sheet{'s' if len(guide.pages) != 1 else ''} "
          f"of {paper} ({columns} x {rows}): print at actual size, check each scale bar measures 100 mm, trim the "
          f"marked margins and lay each sheet over its neighbour matching the grid and the join marks. Place the "
          f"parts in the order of their numbers; coloured zones show how far each may be off (red tight, orange "
          f"normal, green loose)."),
        *([p(f"<b>Chance it works:</b> {escape(guide.headline)}.")] if guide.headline else []),
        p("<b>On the sheets:</b> a black outline is a part you place, a grey hatched one is fixed (a support, the "
          "floor); the number in a circle is its step; + is its centre, the point the steps give; the blue arrow "
          "its heading; the dashed coloured zone is where its outline may lie and the coloured arc how far its "
          "heading may turn; a grey square with a dark corner is where its tag goes (the dark corner is the tag's "
          "lower-left corner, the tag's id above it); the black squares are the reference tags the camera finds "
          "the board by (leave them uncovered); the purple targets are the join marks of two sheets."
          + (" A light brown zone with a dashed edge is where a laser-cut jig lies (its name in it): lay the jig on "
             "it before the part, as its step says." if guide.jigs else "")),
        Spacer(1, 3 * mm),
        p("Parts", h2),
    ]
    rows_ = [["#", "part", "kind", "where (u, v) mm", "heading", "tag", "care"]]
    for part in guide.parts:
        care = part.care or "\u2013"
        if part.care in CARE_COLORS:
            care = f'<font color="{_hex(CARE_COLORS[part.care])}"><b>{part.care}</b></font>'
        rows_.append([str(part.step), p(escape(part.name), cell), str(part.kind),
                      where_text(part).removesuffix(" mm"),
                      f"{part.heading_deg:.1f}\u00b0",
                      "\u2013" if part.tag_id is None else str(part.tag_id), p(care, cell)])
    story += [table(rows_, [9, 50, 15, 40, 17, 11, 16]), Spacer(1, 3 * mm)]
    story += _parameters(guide, p, cell, table, h2, *frame_mm)
    story += [Spacer(1, 3 * mm), p("Steps", h2)]
    if steps:
        story += [p(escape(step)) for step in steps]
    else:
        story.append(p("No steps were given: place the parts in the order of their numbers (the parts list)."))
    story += [Spacer(1, 3 * mm), p("Tolerances", h2), p(escape(tolerance_source_text(guide)))]
    rows_ = [["#", "part", "parameter", "\u00b1delta", "unit", "predicted", "measured", "on the sheet"]]
    for part in guide.parts:
        for t in part.tolerances:
            rows_.append([str(part.step), p(escape(part.name), cell), p(escape(t.parameter), cell),
                          _f(t.delta, 1), t.unit, _f(t.predicted, 2), _f(t.measured, 2),
                          _where(t, guide.plane)])
    if len(rows_) > 1:
        story += [Spacer(1, 2 * mm), table(rows_, [9, 40, 40, 15, 10, 17, 17, 22])]
    return story


#: How the parameters table says each is set.
SET_WITH_TEXT = {"sheet": "on the sheet", "ruler": "ruler", "jig": "jig", "check": "sheet, camera check"}


def _parameters(guide: Guide, p, cell, table, h2, width_mm: float, height_mm: float) -> list:
    """The parameters table (every design parameter: value, tolerance, how it is set, in the maker's words) and the
    dimensioned side view of each part lifted or tilted off the sheet."""
    from reportlab.lib.units import mm
    from reportlab.platypus import CondPageBreak, Spacer

    from projector.pdf_elevation import ElevationDrawing

    settings = [(part, s) for part in guide.parts for s in part.settings]
    if not settings:
        return []
    story = [p("Parameters", h2),
             p("Every design parameter of the layout, as you set it: on the sheet (the outline), with a ruler (a "
               "height above the table or a tilt, not on the sheet), with a jig, or on the sheet and then measured "
               "by the camera check (a part with a tag).")]
    rows = [["#", "part", "parameter", "value", "±", "set with", "in your words"]]
    for part, setting in settings:
        t = setting.tolerance
        tolerance = "\u2013" if t is None or t.delta is None else \
            f"{'>= ' if t.bound_limited else ''}{abs(t.delta):.1f} {setting.unit}"
        rows.append([str(part.step), p(escape(part.name), cell), p(escape(setting.name), cell),
                     f"{setting.value:.1f} {setting.unit}", p(escape(tolerance), cell),
                     p(SET_WITH_TEXT.get(setting.set_with, setting.set_with), cell), p(escape(setting.meaning), cell)])
    story += [Spacer(1, 1.5 * mm), table(rows, [8, 26, 28, 19, 17, 18, 74])]
    lifted = [part for part in guide.parts if part.elevation is not None]
    if lifted:
        off = "above the table" if guide.view == "top" else "in front of the board"
        story += [Spacer(1, 3 * mm), p("Heights and tilts", h2),
                  p("Each part a parameter lifts or tilts off the sheet, alone and seen from the side: its "
                    f"underside's height {off} at each end and at the middle (mm), and its tilt. Drawn at 1:1 where "
                    "it fits (hold the part against the drawing); the 20 mm bar checks the print.")]
        for part in lifted:
            drawing = ElevationDrawing(part.elevation, guide.view)
            words = "; ".join(escape(f"{s.meaning}, {SET_WITH_TEXT.get(s.set_with, s.set_with)}")
                              for s in part.settings if not s.in_plane)
            _, tall = drawing.wrap(width_mm * mm, height_mm * mm)
            # the part's name, its drawing and its words on one page (a bare frame cannot keep them together)
            story += [CondPageBreak(tall + 24 * mm),
                      p(f"<b>{part.step}. {escape(part.name)}</b>, {escape(part.elevation.seen_from)}, "
                        f"{drawing.scale_text}"),
                      drawing, p(words, cell), Spacer(1, 2 * mm)]
    return story


def _where(tolerance, plane) -> str:
    """Which mark on the sheet shows this tolerance: the zone along u or v, the arc, or none (listed only; a delta
    bound only by the range's end is a lower bound, not drawn)."""
    if tolerance.bound_limited:
        return "range end (>=)"
    axes = tolerance_axes(tolerance, plane) if tolerance.placement_delta is not None else ()
    if not axes:
        return "side view (heights and tilts)"
    return "arc" if axes == ("arc",) else "zone along " + "/".join(axes)


def draw_lists(canvas, guide: Guide, steps: list[str], title: str) -> int:
    """Draw the parts list, the steps and the tolerances on as many portrait pages as they take; their count."""
    from reportlab.lib.units import mm
    from reportlab.platypus import Frame

    fmt = sheet_format(guide.pages[0].paper if guide.pages else "a4", "portrait")
    width, height = fmt.size_mm
    story = _story(guide, steps, title, (width - 2 * PRINTABLE_MM, height - 2 * PRINTABLE_MM - FOOTER_MM))
    count = 0
    while story:
        canvas.setPageSize((width * mm, height * mm))
        frame = Frame(PRINTABLE_MM * mm, (PRINTABLE_MM + FOOTER_MM) * mm, (width - 2 * PRINTABLE_MM) * mm,
                      (height - 2 * PRINTABLE_MM - FOOTER_MM) * mm, leftPadding=0, rightPadding=0, topPadding=0,
                      bottomPadding=0)
        before = len(story)
        frame.addFromList(story, canvas)
        if len(story) == before and story:
            story.pop(0)  # a flowable taller than a page that cannot split: leave it out rather than loop
        count += 1
        canvas.saveState()
        canvas.scale(mm, mm)
        canvas.setFont("Helvetica-Bold", 3.4)
        canvas.drawString(PRINTABLE_MM, PRINTABLE_MM + FOOTER_MM - 6.0, f"{title} \u2013 parts, steps, "
                                                                         f"tolerances ({count})")
        draw_scale_bar(canvas, width - PRINTABLE_MM - 100.0, PRINTABLE_MM + 3.0)
        canvas.restoreState()
        canvas.showPage()
    return count
