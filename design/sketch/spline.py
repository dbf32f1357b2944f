"""A closed smoothing cubic B-spline through ordered strokes, and uniform arc-length resampling.

The ordered strokes (see :mod:`design.sketch.ordering`) are concatenated and a periodic cubic smoothing spline is
fitted with :func:`scipy.interpolate.splprep` (thesis, end of section 3.4.1). Curves are then compared after
resampling uniformly in arc length (section 3.4.3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import splev, splprep

from design.sketch.errors import SketchError

#: Most points handed to the spline fit; longer paths are first resampled in arc length (the fit is O(n)).
MAX_FIT_POINTS = 4000


@dataclass(frozen=True)
class ClosedSpline:
    """A fitted closed cubic B-spline.

    Attributes
    ----------
    tck : tuple
        Knots, coefficients and degree as returned by :func:`scipy.interpolate.splprep`.
    smoothing : float
        The relative smoothing factor used for the fit.
    """

    tck: tuple
    smoothing: float

    def __call__(self, u: np.ndarray) -> np.ndarray:
        """Points at spline parameters ``u`` (period 1), ``(len(u), 2)``."""
        x, y = splev(np.mod(np.asarray(u, dtype=float), 1.0), self.tck)
        return np.column_stack([x, y])

    def resample(self, n: int = 1024, spacing: str = "arclength") -> np.ndarray:
        """``n`` points of the closed curve, the first not repeated at the end.

        Parameters
        ----------
        n : int
            Number of points.
        spacing : {"arclength", "parameter"}
            Uniform in arc length, or uniform in the spline parameter.
        """
        if spacing == "parameter":
            return self(np.arange(n) / n)
        dense = self(np.arange(8 * n) / (8 * n))
        return resample_closed(dense, n)


def resample_closed(points: np.ndarray, n: int) -> np.ndarray:
    """Resample a closed polyline to ``n`` points uniformly spaced in arc length (start kept, end not repeated).

    Parameters
    ----------
    points : ndarray
        ``(m, 2)`` vertices; the closing segment from the last vertex back to the first is implied (a repeated first
        vertex at the end is harmless).
    n : int
        Number of output points.
    """
    points = np.asarray(points, dtype=float)
    closed = np.vstack([points, points[:1]])
    seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    total = cum[-1]
    if total <= 0:
        raise SketchError("curve resampling: the curve has zero length")
    s = np.arange(n) * (total / n)
    return np.column_stack([np.interp(s, cum, closed[:, 0]), np.interp(s, cum, closed[:, 1])])


def resample_open(points: np.ndarray, n: int) -> np.ndarray:
    """Resample an open polyline to ``n`` points uniformly in arc length (both ends kept)."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    s = np.linspace(0.0, cum[-1], n)
    return np.column_stack([np.interp(s, cum, points[:, 0]), np.interp(s, cum, points[:, 1])])


def fit_closed_spline(path: np.ndarray, smoothing: float = 0.01) -> ClosedSpline:
    """Fit a closed (periodic) cubic smoothing B-spline to an ordered path.

    Parameters
    ----------
    path : ndarray
        ``(n, 2)`` ordered points; the closing gap from the last to the first point is bridged by the spline.
    smoothing : float
        Relative smoothing factor: the expected deviation of the sketch from the intended curve, as a fraction of
        the sketch's size (bounding-box diagonal). 0 interpolates. The spline's residual bound is
        ``s = n * (smoothing * diagonal) ** 2`` (scipy's ``s``).

    Raises
    ------
    SketchError
        Fewer than 4 distinct points, a non-finite or negative smoothing factor, or a failed fit.
    """
    if not np.isfinite(smoothing) or smoothing < 0:
        raise SketchError(f"spline fit: smoothing must be a finite number >= 0, got {smoothing!r}")
    path = np.asarray(path, dtype=float)
    keep = np.ones(len(path), dtype=bool)
    keep[1:] = np.linalg.norm(np.diff(path, axis=0), axis=1) > 0
    path = path[keep]
    if len(path) > 1 and np.array_equal(path[0], path[-1]):
        path = path[:-1]
    diagonal = float(np.linalg.norm(np.ptp(path, axis=0))) if len(path) else 0.0
    if len(path) < 4 or diagonal == 0:
        raise SketchError(
            f"spline fit: the sketch has {len(path)} distinct point(s); expected at least 4 to fit a closed curve"
        )
    if len(path) > MAX_FIT_POINTS:
        path = resample_closed(path, MAX_FIT_POINTS)
    if len(path) < 12:
        # A few clicks: densify along the polygon so that a cubic periodic spline is well posed.
        path = resample_closed(path, 12 * len(path))
    closed = np.vstack([path, path[:1]])
    chord = np.linalg.norm(np.diff(closed, axis=0), axis=1)
    u = np.concatenate([[0.0], np.cumsum(chord)])
    u /= u[-1]
    s = len(closed) * (smoothing * diagonal) ** 2
    try:
        tck, _ = splprep([closed[:, 0], closed[:, 1]], u=u, s=s, k=3, per=1, quiet=1)
    except (ValueError, TypeError) as error:
        raise SketchError(f"spline fit failed on {len(closed)} points: {error}") from None
    spline = ClosedSpline(tuple(tck), float(smoothing))
    sample = spline(np.linspace(0, 1, 64, endpoint=False))
    if not np.all(np.isfinite(sample)):
        raise SketchError("spline fit produced non-finite points; try a larger smoothing factor")
    return spline
