"""What every printed sheet of the station carries, whatever it shows: the fonts and ink, the 100 mm scale bar to
check the print's scale, and a tag drawn at its exact size. The guide's sheets (:mod:`projector.pdf`), its lists
(:mod:`projector.pdf_lists`) and the side board (:mod:`projector.board`) draw them alike.

Everything here draws on a reportlab canvas in millimetres (the caller scales it by ``mm``).
"""

from __future__ import annotations

from projector.drawing import tag_black_rects

__all__ = ["BOLD", "FONT", "INK", "SCALE_BAR_MM", "draw_scale_bar", "draw_tag"]

#: The length of the scale bar (mm): a printer that scales the page shows it here.
SCALE_BAR_MM = 100.0
FONT, BOLD = "Helvetica", "Helvetica-Bold"
INK = (0.0, 0.0, 0.0)


def draw_scale_bar(canvas, x: float, y: float) -> None:
    """The 100 mm bar (solid black, 2.5 mm tall) from ``(x, y)``, ticks every 10 mm, and what to check."""
    canvas.setFillColorRGB(*INK)
    canvas.rect(x, y, SCALE_BAR_MM, 2.5, stroke=0, fill=1)
    for k in range(11):  # ticks inside the bar's length, so they never lengthen it
        tx = min(max(x + 10.0 * k - 0.15, x), x + SCALE_BAR_MM - 0.3)
        canvas.rect(tx, y + 2.5, 0.3, 1.8 if k % 5 == 0 else 1.0, stroke=0, fill=1)
    canvas.setFont(FONT, 2.2)
    canvas.drawString(x, y - 2.6, "0")
    canvas.drawCentredString(x + 50.0, y - 2.6, "50")
    canvas.drawRightString(x + SCALE_BAR_MM, y - 2.6, "100 mm")
    canvas.setFont(BOLD, 2.8)
    canvas.drawString(x, y + 6.0, "check: this bar must measure 100 mm")


def draw_tag(canvas, tag_id: int, center, size_mm: float) -> None:
    """A decodable tag from :func:`~vision.tags.tag_cells`: black square ``size_mm`` on a white border."""
    half = size_mm * 10 / 8 / 2
    canvas.setFillColorRGB(1.0, 1.0, 1.0)
    canvas.rect(center[0] - half, center[1] - half, 2 * half, 2 * half, stroke=0, fill=1)
    canvas.setFillColorRGB(*INK)
    for u0, v0, u1, v1 in tag_black_rects(tag_id, center, size_mm):
        canvas.rect(u0, v0, u1 - u0, v1 - v0, stroke=0, fill=1)
