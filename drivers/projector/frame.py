"""Frames for a projector: what :meth:`show` accepts, and how a frame of another size is fitted to the screen.

A frame is a numpy ``uint8`` array, ``H x W`` (grey) or ``H x W x 3`` (RGB; an ``H x W x 4`` RGBA array loses its
alpha), or a PIL image (converted to RGB). Row 0 is the top of the screen. A frame whose size is not the screen's is
scaled, keeping its aspect ratio, and letterboxed (centred on black): a frame drawn through a calibrated homography
for another size is then no longer true to scale, so :func:`fit_to_screen` says so in one line.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from drivers.errors import DriverError

__all__ = ["EXPECTED_FRAME", "as_rgb", "fit_to_screen"]

EXPECTED_FRAME = "a uint8 array H x W (grey) or H x W x 3 (RGB), or a PIL image"


def as_rgb(frame: Any, what: str = "frame") -> np.ndarray:
    """``frame`` as a C-contiguous ``H x W x 3`` uint8 RGB array (a :class:`DriverError` naming ``what`` if it is
    none of the accepted kinds)."""
    if hasattr(frame, "convert") and hasattr(frame, "size") and not isinstance(frame, np.ndarray):  # a PIL image
        frame = np.asarray(frame.convert("RGB"))
    if not isinstance(frame, np.ndarray):
        raise DriverError(f"{what}: expected {EXPECTED_FRAME}, got {type(frame).__name__}")
    if frame.dtype != np.uint8 or frame.ndim not in (2, 3) or (frame.ndim == 3 and frame.shape[2] not in (1, 3, 4)) \
            or 0 in frame.shape:
        raise DriverError(f"{what}: expected {EXPECTED_FRAME}, got a {frame.dtype} array of shape {frame.shape}")
    if frame.ndim == 2:
        frame = frame[:, :, None]
    if frame.shape[2] == 1:
        frame = np.repeat(frame, 3, axis=2)
    return np.ascontiguousarray(frame[:, :, :3])


def fit_to_screen(frame: np.ndarray, size: tuple[int, int]) -> tuple[np.ndarray, str | None]:
    """An RGB ``frame`` fitted to a screen of ``size`` (width, height).

    Returns
    -------
    image : ndarray
        ``frame`` itself when its size is the screen's, else the frame scaled by one factor (aspect kept) and
        centred on black.
    note : str or None
        None when shown pixel for pixel; else one line saying what was done (the scale is then not the frame's).
    """
    import cv2

    width, height = size
    rows, cols = frame.shape[:2]
    if (cols, rows) == (width, height):
        return frame, None
    scale = min(width / cols, height / rows)
    new_w, new_h = max(1, round(cols * scale)), max(1, round(rows * scale))
    # INTER_AREA averages when shrinking (thin lines survive); INTER_LINEAR when enlarging
    resized = cv2.resize(frame, (new_w, new_h), interpolation=cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR)
    screen = np.zeros((height, width, 3), dtype=np.uint8)
    top, left = (height - new_h) // 2, (width - new_w) // 2
    screen[top:top + new_h, left:left + new_w] = resized
    return screen, (f"frame {cols}x{rows} is not the screen's {width}x{height}: scaled by {scale:.4g} and "
                    "letterboxed (not pixel for pixel)")

