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
