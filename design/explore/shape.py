"""How different two drawings look: a symmetric mean closest-point (chamfer) distance between the inked curves."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


def resample_by_length(points: np.ndarray, n: int = 2048) -> np.ndarray:
    """``n`` points equidistant along a polyline (so fast and slow parts of a curve weigh the same)."""
    points = np.asarray(points, dtype=float)
    seg = np.hypot(*np.diff(points, axis=0).T)
    arc = np.concatenate(([0.0], np.cumsum(seg)))
    if arc[-1] <= 0:
        return np.repeat(points[:1], n, axis=0)
    s = np.linspace(0.0, arc[-1], n)
    return np.column_stack([np.interp(s, arc, points[:, 0]), np.interp(s, arc, points[:, 1])])


def bbox_diagonal(points: np.ndarray) -> float:
    """The size of a drawing: the diagonal of its bounding box."""
    return float(np.hypot(*np.ptp(np.asarray(points, dtype=float), axis=0)))


def shape_distance(a: np.ndarray, b: np.ndarray, size: float | None = None, n: int = 2048) -> float:
    """Mean distance from each curve's ink to the other's, both ways, divided by ``size`` (default: a's size).

    0 for the same drawing whatever the parametrization; it sees what the eye sees on paper (position, size,
    rotation all count), which is what "the drawing changed visibly" means.
    """
    pa, pb = resample_by_length(a, n), resample_by_length(b, n)
    da = cKDTree(pb).query(pa)[0]
    db = cKDTree(pa).query(pb)[0]
    size = bbox_diagonal(a) if size is None else size
    return float((da.mean() + db.mean()) / 2 / max(size, 1e-300))
