"""Contact sheet: the sketch and its ranked candidates side by side, each candidate aligned onto the sketch."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from design.sketch.distance import as_complex


def align_to(query: np.ndarray, curve: np.ndarray) -> np.ndarray:
    """``curve`` moved by the Procrustes similarity (and start point / direction) that best fits it onto ``query``.

    Both are ``(N, 2)`` closed curves sampled uniformly in arc length with the same ``N``; returns ``(N, 2)``.
    """
    a = as_complex(query)
    b = as_complex(curve)
    a_mean, b_mean = a.mean(), b.mean()
    a0, b0 = a - a_mean, b - b_mean
    fa = np.fft.fft(a0)
    best = (-1.0, b0)
    for candidate in (b0, b0[::-1]):
        fb = np.fft.fft(candidate)
        correlation = np.fft.fft(fa * fb.conj())  # [s] = sum_n a_n conj(b_{n+s}) * N
        s = int(np.argmax(np.abs(correlation)))
        if abs(correlation[s]) > best[0]:
            best = (abs(correlation[s]), np.roll(candidate, -s))
    shifted = best[1]
    scale = np.vdot(shifted, a0) / max(np.vdot(shifted, shifted).real, 1e-300)  # optimal complex factor
    z = scale * shifted + a_mean
    return np.column_stack([z.real, z.imag])


def _fit(points: Sequence[np.ndarray], box: tuple[int, int, int, int], margin: int = 8):
    allpts = np.concatenate([np.asarray(p) for p in points if len(p)])
    lo, hi = allpts.min(axis=0), allpts.max(axis=0)
    x0, y0, x1, y1 = box
    span = max(float((hi - lo).max()), 1e-12)
    scale = min(x1 - x0 - 2 * margin, y1 - y0 - 2 * margin) / span
    centre = (lo + hi) / 2
    mid = np.array([(x0 + x1) / 2, (y0 + y1) / 2])

    def transform(p: np.ndarray) -> list[tuple[float, float]]:
        q = (np.asarray(p) - centre) * scale
        q[:, 1] = -q[:, 1]  # y up on paper, down in images
        q = q + mid
        return [tuple(v) for v in q]

    return transform


def render_contact_sheet(
    path: str | Path,
    strokes: Sequence[np.ndarray],
    sketch_curve: np.ndarray,
    candidates: Sequence[tuple[str, np.ndarray]],
    cell: int = 260,
    columns: int = 4,
) -> Path:
    """Write a PNG: the sketch (strokes grey, fitted spline blue), then each candidate (black) with the sketch's
    spline overlaid (light red) after aligning the candidate onto it.

    Parameters
    ----------
    path : path
        Output ``.png``.
    strokes : list of ndarray
        The sketch strokes with symmetry copies.
    sketch_curve : ndarray
        ``(N, 2)`` fitted closed curve, uniform in arc length.
    candidates : list of (label, curve)
        Labels and closed curves (``(M, 2)``, any sampling) of the ranked candidates.
    """
    path = Path(path)
    count = 1 + len(candidates)
    columns = max(1, min(columns, count))
    rows = (count + columns - 1) // columns
    label_height = 34
    image = Image.new("RGB", (columns * cell, rows * (cell + label_height)), "white")
    draw = ImageDraw.Draw(image)
    font = ImageFont.load_default()
    closed = np.vstack([sketch_curve, sketch_curve[:1]])

    def box(i: int) -> tuple[int, int, int, int]:
        r, c = divmod(i, columns)
        return (c * cell, r * (cell + label_height), (c + 1) * cell, r * (cell + label_height) + cell)

    transform = _fit(list(strokes) + [closed], box(0))
    for stroke in strokes:
        if len(stroke) > 1:
            draw.line(transform(stroke), fill=(150, 150, 150), width=3)
    draw.line(transform(closed), fill=(40, 90, 220), width=1)
    x0, _, _, y1 = box(0)
    draw.text((x0 + 6, y1 + 2), "sketch (grey) and spline (blue)", fill="black", font=font)
    n = len(sketch_curve)
    for i, (label, curve) in enumerate(candidates, start=1):
        curve = np.asarray(curve, dtype=float)
        if len(curve) > 1 and np.allclose(curve[0], curve[-1]):
            curve = curve[:-1]
        from design.sketch.spline import resample_closed

        aligned = align_to(sketch_curve, resample_closed(curve, n))
        aligned_closed = np.vstack([aligned, aligned[:1]])
        transform = _fit([aligned_closed, closed], box(i))
        draw.line(transform(closed), fill=(240, 160, 160), width=3)
        draw.line(transform(aligned_closed), fill=(0, 0, 0), width=1)
        x0, _, x1, y1 = box(i)
        for j, line in enumerate(label.split("\n")[:2]):
            draw.text((x0 + 6, y1 + 2 + 14 * j), line, fill="black", font=font)
        draw.rectangle(box(i), outline=(220, 220, 220))
    path.parent.mkdir(parents=True, exist_ok=True)
    image.save(path)
    return path
