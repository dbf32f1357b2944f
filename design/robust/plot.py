"""Local-robustness plots (like thesis Figure 4.18) drawn with Pillow: mean ρ_l(x*, ε) per method with a ±SEM band."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

#: Colours per method (ours first, as in Figure 4.18's legend).
COLOURS = {
    "ours": (214, 39, 40),
    "b1": (31, 119, 180),
    "b2": (44, 160, 44),
    "b3": (148, 103, 189),
}
FALLBACK = [(255, 127, 14), (140, 86, 75), (23, 190, 207)]


def plot_robustness(
    curves: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]],
    path: str | Path,
    title: str = "",
    size: tuple[int, int] = (900, 560),
) -> Path:
    """Draw ρ_l against ε for each named curve ``(epsilon, mean, sem)`` and save a PNG.

    Parameters
    ----------
    curves : dict
        Method name to ``(epsilon, mean, standard error)``; a single layout's curve has ``sem`` zeros.
    path : path
        Output ``.png``.
    title : str
        Drawn at the top.
    """
    width, height = size
    left, right, top, bottom = 80, 190, 50, 70
    image = Image.new("RGB", size, "white")
    draw = ImageDraw.Draw(image, "RGBA")
    try:
        font = ImageFont.truetype("DejaVuSans.ttf", 13)
    except OSError:  # no DejaVu on this system: Pillow's own font (labels are ASCII for that reason)
        font = ImageFont.load_default()
    plot_w, plot_h = width - left - right, height - top - bottom

    def to_pixels(x, y):
        return left + np.asarray(x) * plot_w, top + (1.0 - np.asarray(y)) * plot_h

    # Grid and axes.
    for tick in np.linspace(0, 1, 6):
        px, _ = to_pixels(tick, 0)
        _, py = to_pixels(0, tick)
        draw.line([(left, py), (left + plot_w, py)], fill=(225, 225, 225))
        draw.line([(px, top), (px, top + plot_h)], fill=(225, 225, 225))
        draw.text((px - 10, top + plot_h + 8), f"{tick:.1f}", fill="black", font=font)
        draw.text((left - 34, py - 6), f"{tick:.1f}", fill="black", font=font)
    draw.rectangle([left, top, left + plot_w, top + plot_h], outline="black")
    draw.text((left + plot_w / 2 - 100, height - 30), "error eps on the normalized layout parameters",
              fill="black", font=font)
    draw.text((8, top - 24), "local robustness rho_l(x*, eps)", fill="black", font=font)
    if title:
        title_width = draw.textlength(title, font=font)
        draw.text((left + plot_w - title_width, 14), title, fill="black", font=font)

    for index, (name, (epsilon, mean, sem)) in enumerate(curves.items()):
        colour = COLOURS.get(name, FALLBACK[index % len(FALLBACK)])
        x, y = to_pixels(epsilon, np.clip(mean, 0, 1))
        _, y_low = to_pixels(epsilon, np.clip(mean - sem, 0, 1))
        _, y_high = to_pixels(epsilon, np.clip(mean + sem, 0, 1))
        if np.any(sem > 0):
            band = list(zip(x, y_high)) + list(zip(x[::-1], y_low[::-1]))
            draw.polygon(band, fill=(*colour, 50))
        draw.line(list(zip(x, y)), fill=colour, width=3)
        # Legend outside the axes, on the right, so it never hides a curve.
        legend_x, legend_y = left + plot_w + 14, top + 8 + 20 * index
        draw.line([(legend_x, legend_y + 6), (legend_x + 28, legend_y + 6)], fill=colour, width=3)
        rho_g = float(np.trapezoid(mean, epsilon))
        draw.text((legend_x + 36, legend_y), f"{name}  rho_g={rho_g:.3f}", fill="black", font=font)
    path = Path(path)
    image.save(path)
    return path


#: Bins of fewer layouts are drawn hollow and left off the reliability curve's line.
MIN_BIN_COUNT = 5
#: Colours of the compared settings in reliability plots.
VARIANT_COLOURS = {"uncalibrated": (150, 150, 150), "recommended": (214, 39, 40)}


def plot_reliability(panels: dict, path: str | Path, title: str = "", columns: int = 4,
                     panel_size: tuple[int, int] = (250, 250)) -> Path:
    """Reliability curves, one panel per scenario: observed success rate against predicted probability.

    Parameters
    ----------
    panels : dict
        Panel title to ``{variant: Reliability}`` (:class:`design.robust.reliability.Reliability`); each bin is a dot
        whose area grows with its count, joined by a line; the diagonal is a calibrated model.
    path : path
        Output ``.png``.
    """
    names = list(panels)
    rows = max(1, -(-len(names) // columns))
    pw, ph = panel_size
    margin_top, legend_h = 36, 26
    image = Image.new("RGB", (columns * pw, margin_top + rows * ph + legend_h), "white")
    draw = ImageDraw.Draw(image, "RGBA")
    try:
        font = ImageFont.truetype("DejaVuSans.ttf", 11)
    except OSError:
        font = ImageFont.load_default()
    if title:
        draw.text((10, 10), title, fill="black", font=font)
    left, right, top, bottom = 38, 10, 22, 32
    for index, name in enumerate(names):
        x0, y0 = (index % columns) * pw, margin_top + (index // columns) * ph
        w, h = pw - left - right, ph - top - bottom

        def to_pixels(x, y, x0=x0, y0=y0, w=w, h=h):
            return x0 + left + np.asarray(x) * w, y0 + top + (1.0 - np.asarray(y)) * h

        for tick in (0.0, 0.5, 1.0):
            px, _ = to_pixels(tick, 0)
            _, py = to_pixels(0, tick)
            draw.line([(x0 + left, py), (x0 + left + w, py)], fill=(230, 230, 230))
            draw.line([(px, y0 + top), (px, y0 + top + h)], fill=(230, 230, 230))
            draw.text((px - 8, y0 + top + h + 4), f"{tick:.1f}", fill="black", font=font)
            draw.text((x0 + 8, py - 6), f"{tick:.1f}", fill="black", font=font)
        draw.rectangle([x0 + left, y0 + top, x0 + left + w, y0 + top + h], outline="black")
        draw.line([to_pixels(0, 0), to_pixels(1, 1)], fill=(120, 120, 120), width=1)
        draw.text((x0 + left, y0 + 4), str(name), fill="black", font=font)
        draw.text((x0 + left + w / 2 - 40, y0 + top + h + 16), "predicted PSP", fill="black", font=font)
        for k, (variant, score) in enumerate(panels[name].items()):
            colour = VARIANT_COLOURS.get(variant, FALLBACK[k % len(FALLBACK)])
            filled = score.counts > 0
            if not filled.any():
                continue
            x, y = to_pixels(score.predicted[filled], score.observed[filled])
            # The line joins the bins with enough layouts to say something; the others are hollow dots.
            solid = score.counts[filled] >= MIN_BIN_COUNT
            if solid.sum() > 1:
                draw.line(list(zip(x[solid], y[solid])), fill=(*colour, 200), width=2)
            for px, py, count, full in zip(x, y, score.counts[filled], solid):
                r = 2.0 + 2.0 * np.sqrt(count / max(score.n, 1) * 10)
                draw.ellipse([px - r, py - r, px + r, py + r], fill=(*colour, 160) if full else None,
                             outline=colour)
            # Bottom right: a calibrated or underconfident curve stays above the diagonal's right end.
            label = f"{variant} Brier {score.brier:.3f}"
            draw.text((x0 + left + w - draw.textlength(label, font=font) - 4, y0 + top + h - 30 + 13 * k), label,
                      fill=colour, font=font)
    legend_y = margin_top + rows * ph + 6
    draw.text((10, legend_y), "y: observed success rate of the held-out layouts in each bin of predicted PSP "
              f"(dot area ~ layouts; hollow: fewer than {MIN_BIN_COUNT}); diagonal = calibrated", fill="black",
              font=font)
    path = Path(path)
    image.save(path)
    return path
