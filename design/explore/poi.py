"""Points of Interest (PoI) of a sampled closed curve: curvature maxima and self-intersections (thesis 3.5.1).

Both detectors work on any polyline (the drawing machines' curves, or synthetic ones in tests):

- curvature maxima: discrete (Menger) curvature at every vertex, peaks of ``|kappa|`` found with
  :func:`scipy.signal.find_peaks` and a prominence threshold relative to the curve's typical curvature, so that the
  tiny ripples of a discretization make no PoI; the peak is refined by a parabola through its three samples;
- self-intersections: candidate segment pairs come from a GEOS STRtree (shapely) bulk query, i.e. a spatial index
  rather than the n^2 test of every pair (O((n + k) log n) for n segments and k crossings); the exact crossing of
  each candidate pair is then computed in one vectorized pass.

Every PoI carries its position, its arc length from the curve's start (two for a crossing), the curve's total length
(to compare arc lengths across designs, Eq. 3.14), the parameter times when the caller gave them, and its type's
feature: the curvature at a maximum, the angle between the tangents at a crossing.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import shapely
from scipy.signal import find_peaks
from scipy.spatial import cKDTree

from design.errors import ParameterError

CURVATURE = "curvature"
INTERSECTION = "intersection"
POI_KINDS = (CURVATURE, INTERSECTION)


@dataclass(frozen=True)
class PointOfInterest:
    """One Point of Interest of a curve.

    Parameters
    ----------
    id : int
        Index in the list it was detected in (stable for one design only; use tracking across designs).
    kind : {"curvature", "intersection"}
        A curvature maximum or a self-intersection.
    xy : (float, float)
        Position, in the curve's frame.
    arclength : tuple of float
        Arc length(s) from the curve's start: one for a curvature maximum, two (sorted) for a crossing.
    length : float
        Total length of the curve the PoI was found on.
    times : tuple of float or None
        Curve parameter time(s) matching ``arclength``, when the curve's sample times were given.
    curvature : float or None
        ``|kappa|`` at a curvature maximum.
    angle : float or None
        Angle between the two tangent lines at a crossing, radians in [0, pi/2] (0 = tangency).
    """

    id: int
    kind: str
    xy: tuple[float, float]
    arclength: tuple[float, ...]
    length: float
    times: tuple[float, ...] | None = None
    curvature: float | None = None
    angle: float | None = None

    @property
    def relative_arclength(self) -> tuple[float, ...]:
        """Arc length(s) as fractions of the curve's length, in [0, 1)."""
        return tuple(s / self.length for s in self.arclength)

    def as_dict(self) -> dict:
        """Plain values for JSON output."""
        out = {
            "id": self.id,
            "type": self.kind,
            "xy": [float(self.xy[0]), float(self.xy[1])],
            "arclength": [float(s) for s in self.arclength],
        }
        if self.times is not None:
            out["times"] = [float(t) for t in self.times]
        if self.curvature is not None:
            out["curvature"] = float(self.curvature)
        if self.angle is not None:
            out["angle_deg"] = float(np.degrees(self.angle))
        return out


def _as_closed(points: np.ndarray, times: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
    """The polyline with its closing vertex (last == first), and its times extended the same way."""
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 2 or len(points) < 4:
        raise ParameterError(f"PoI detection: curve must be an (n, 2) array with n >= 4, got shape {points.shape}")
    if not np.all(np.isfinite(points)):
        raise ParameterError("PoI detection: curve has non-finite points")
    if times is not None:
        times = np.asarray(times, dtype=float)
        if times.shape != (len(points),):
            raise ParameterError(
                f"PoI detection: times must have one value per point ({len(points)}), got shape {times.shape}"
            )
    scale = max(float(np.ptp(points, axis=0).max()), 1e-300)
    if np.hypot(*(points[-1] - points[0])) > 1e-9 * scale:
        points = np.vstack([points, points[:1]])
        if times is not None:
            times = np.append(times, times[-1] + (times[-1] - times[-2]))
    return points, times


def cumulative_arclength(points: np.ndarray) -> np.ndarray:
    """Arc length at every vertex of a polyline (0 at the first)."""
    seg = np.hypot(*np.diff(points, axis=0).T)
    return np.concatenate(([0.0], np.cumsum(seg)))


def menger_curvature(points: np.ndarray) -> np.ndarray:
    """Signed discrete curvature at the vertices of a closed polyline (last == first), one value per vertex.

    The curvature at a vertex is the inverse radius of the circle through it and its two neighbours,
    ``2 cross(b - a, c - a) / (|b - a| |c - b| |c - a|)``: exact on circles whatever the spacing.
    """
    ring = points[:-1]
    a = np.roll(ring, 1, axis=0)
    c = np.roll(ring, -1, axis=0)
    ab = ring - a
    ac = c - a
    cross = ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0]
    denom = np.hypot(*ab.T) * np.hypot(*(c - ring).T) * np.hypot(*ac.T)
    with np.errstate(divide="ignore", invalid="ignore"):
        kappa = np.where(denom > 0, 2.0 * cross / denom, 0.0)
    return kappa


def detect_curvature_maxima(
    points: np.ndarray,
    times: np.ndarray | None = None,
    rel_prominence: float = 0.05,
) -> list[PointOfInterest]:
    """Maxima of ``|kappa|`` along a closed polyline.

    Parameters
    ----------
    points : (n, 2) array
        The curve; closed (the closing segment is added when last != first).
    times : (n,) array, optional
        Parameter time of each point, to report the PoI's time.
    rel_prominence : float
        A peak must rise above its surroundings by this fraction of the median ``|kappa|`` (the median, not the
        mean, so that a few very sharp loops do not hide the gentle maxima): discretization ripples stay far below.

    Returns
    -------
    list of PointOfInterest
        Sorted by arc length; ``id`` is the index in this list.
    """
    closed, times_c = _as_closed(points, times)
    kappa = np.abs(menger_curvature(closed))
    n = len(kappa)
    finite = np.isfinite(kappa)
    if not finite.any():
        return []
    typical = max(float(np.median(kappa[finite])), 1e-300)
    # The curve is closed: look for peaks on three copies so that peaks near the seam have their full context.
    tiled = np.tile(np.nan_to_num(kappa, posinf=np.finfo(float).max / 4), 3)
    peaks, _ = find_peaks(tiled, prominence=rel_prominence * typical)
    peaks = peaks[(peaks >= n) & (peaks < 2 * n)] - n
    arc = cumulative_arclength(closed)
    length = float(arc[-1])
    out = []
    for i in np.sort(peaks):
        k_prev, k_mid, k_next = tiled[n + i - 1], tiled[n + i], tiled[n + i + 1]
        curvature_ = (k_prev - 2 * k_mid + k_next)
        offset = 0.0 if curvature_ >= 0 else float(np.clip(0.5 * (k_prev - k_next) / curvature_, -0.5, 0.5))
        peak_value = k_mid - 0.25 * (k_prev - k_next) * offset
        # Interpolate position, arc length and time along the polyline by the fractional offset.
        j = i + 1 if offset >= 0 else (i - 1) % n
        w = abs(offset)
        xy = (1 - w) * closed[i] + w * closed[j]
        s_j = arc[j] if offset >= 0 else (arc[j] if j < i else arc[j] - length)
        s = ((1 - w) * arc[i] + w * s_j) % length
        t = None
        if times_c is not None:
            t_j = times_c[j] if offset >= 0 else (times_c[j] if j < i else times_c[j] - (times_c[-1] - times_c[0]))
            t = ((1 - w) * times_c[i] + w * t_j,)
        out.append(
            PointOfInterest(
                id=0, kind=CURVATURE, xy=(float(xy[0]), float(xy[1])), arclength=(float(s),), length=length,
                times=t, curvature=float(peak_value),
            )
        )
    out.sort(key=lambda p: p.arclength)
    return [replace(p, id=k) for k, p in enumerate(out)]


def segment_crossings(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Proper crossings between non-adjacent segments of a closed polyline (last == first).

    Candidate pairs come from a bulk STRtree query (GEOS), never from all pairs.

    Returns
    -------
    i, j : int arrays
        Indices of the two crossing segments (``i < j``), segment k going from vertex k to k + 1.
    u, v : float arrays
        Position of the crossing along each segment, in [0, 1).
    """
    starts, ends = points[:-1], points[1:]
    m = len(starts)
    lines = shapely.linestrings(np.stack([starts, ends], axis=1))
    tree = shapely.STRtree(lines)
    i, j = tree.query(lines)  # bounding-box candidates only: the exact test below is vectorized
    keep = (i < j) & (j - i > 1) & ~((i == 0) & (j == m - 1))
    i, j = i[keep], j[keep]
    p, r = starts[i], ends[i] - starts[i]
    q, s = starts[j], ends[j] - starts[j]
    den = r[:, 0] * s[:, 1] - r[:, 1] * s[:, 0]
    qp = q - p
    norm = np.hypot(*r.T) * np.hypot(*s.T)
    proper = np.abs(den) > 1e-12 * np.maximum(norm, 1e-300)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = (qp[:, 0] * s[:, 1] - qp[:, 1] * s[:, 0]) / den
        v = (qp[:, 0] * r[:, 1] - qp[:, 1] * r[:, 0]) / den
    # Slightly widened half-open ranges, so that a crossing exactly at a vertex is never lost to rounding; the
    # duplicates this can make (the same crossing seen from both segments at the vertex) are merged below.
    eps = 1e-9
    hit = proper & (u >= -eps) & (u < 1 - eps) & (v >= -eps) & (v < 1 - eps)
    i, j, u, v = i[hit], j[hit], np.clip(u[hit], 0, 1), np.clip(v[hit], 0, 1)
    if len(i) > 1:
        position = np.column_stack([i + u, j + v])
        duplicates = cKDTree(position).query_pairs(r=1e-6, output_type="ndarray")
        if len(duplicates):
            keep = np.ones(len(i), dtype=bool)
            keep[np.max(duplicates, axis=1)] = False
            i, j, u, v = i[keep], j[keep], u[keep], v[keep]
    return i, j, u, v


def detect_self_intersections(points: np.ndarray, times: np.ndarray | None = None) -> list[PointOfInterest]:
    """Self-intersections of a closed polyline, with both arc lengths and the angle between the tangents.

    Parameters
    ----------
    points : (n, 2) array
        The curve; closed (the closing segment is added when last != first).
    times : (n,) array, optional
        Parameter time of each point, to report the crossing's two times.

    Returns
    -------
    list of PointOfInterest
        Sorted by first arc length; ``id`` is the index in this list.
    """
    closed, times_c = _as_closed(points, times)
    i, j, u, v = segment_crossings(closed)
    u = np.minimum(u, 1.0)
    arc = cumulative_arclength(closed)
    length = float(arc[-1])
    seg_len = np.diff(arc)
    s1 = arc[i] + u * seg_len[i]
    s2 = arc[j] + v * seg_len[j]
    xy = closed[i] + u[:, None] * (closed[i + 1] - closed[i])
    r = closed[i + 1] - closed[i]
    s = closed[j + 1] - closed[j]
    cos = np.abs(np.sum(r * s, axis=1)) / (np.hypot(*r.T) * np.hypot(*s.T))
    angle = np.arccos(np.clip(cos, 0.0, 1.0))
    if times_c is not None:
        t1 = times_c[i] + u * (times_c[i + 1] - times_c[i])
        t2 = times_c[j] + v * (times_c[j + 1] - times_c[j])
    order = np.argsort(s1, kind="stable")
    out = []
    for k, idx in enumerate(order):
        out.append(
            PointOfInterest(
                id=k, kind=INTERSECTION, xy=(float(xy[idx, 0]), float(xy[idx, 1])),
                arclength=(float(s1[idx]), float(s2[idx])), length=length,
                times=(float(t1[idx]), float(t2[idx])) if times_c is not None else None,
                angle=float(angle[idx]),
            )
        )
    return out


def detect_pois(
    points: np.ndarray,
    times: np.ndarray | None = None,
    rel_prominence: float = 0.05,
    kinds: tuple[str, ...] = POI_KINDS,
) -> list[PointOfInterest]:
    """Every Point of Interest of a closed curve: curvature maxima first, then self-intersections.

    Ids are the index in the returned list. See :func:`detect_curvature_maxima` and
    :func:`detect_self_intersections`.
    """
    unknown = set(kinds) - set(POI_KINDS)
    if unknown:
        raise ParameterError(f"PoI detection: kinds must be among {POI_KINDS}, got {sorted(unknown)}")
    found: list[PointOfInterest] = []
    if CURVATURE in kinds:
        found += detect_curvature_maxima(points, times, rel_prominence)
    if INTERSECTION in kinds:
        found += detect_self_intersections(points, times)
    return [replace(p, id=k) for k, p in enumerate(found)]
