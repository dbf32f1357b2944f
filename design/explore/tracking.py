"""Tracking Points of Interest between two nearby designs by arc length (thesis Eq. 3.14).

Superimposing two drawings and taking the nearest PoI is ambiguous where several PoIs overlap; comparing arc
lengths (relative to each curve's length, a pair of them for a crossing) is not, because the pen has to travel a
full turn before it comes back near the same place. A match farther than ``sigma_poi`` (in the curve's frame) or
than ``sigma_arclength`` (in fractions of the curve's length) is reported as lost, never swapped for another PoI.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from design.explore.poi import PointOfInterest


@dataclass(frozen=True)
class TrackResult:
    """Outcome of tracking one PoI onto another curve.

    Attributes
    ----------
    reference : PointOfInterest
        The PoI that was looked for.
    match : PointOfInterest or None
        Its counterpart on the new curve; None when lost.
    arclength_distance : float
        Eq. 3.14 distance to the best candidate, in fractions of the curve's length (inf without candidate).
    distance : float
        Euclidean distance between the reference and the best candidate (inf without candidate).
    reason : str
        Why it was lost ("" when matched).
    """

    reference: PointOfInterest
    match: PointOfInterest | None
    arclength_distance: float
    distance: float
    reason: str = ""

    @property
    def lost(self) -> bool:
        return self.match is None


def _periodic(delta: np.ndarray) -> np.ndarray:
    """Distance on the unit circle of relative arc lengths."""
    delta = np.abs(delta) % 1.0
    return np.minimum(delta, 1.0 - delta)


def arclength_distances(reference: PointOfInterest, candidates: Sequence[PointOfInterest]) -> np.ndarray:
    """Eq. 3.14 distances ``|Lambda(ref) - Lambda(candidate)|`` in relative arc length, inf for another type.

    Crossings are unordered pairs: both pairings are tried and the better one is kept.
    """
    ref = np.array(reference.relative_arclength)
    out = np.full(len(candidates), np.inf)
    for k, cand in enumerate(candidates):
        if cand.kind != reference.kind:
            continue
        c = np.array(cand.relative_arclength)
        if len(ref) == 1:
            out[k] = float(_periodic(ref - c)[0])
        else:
            straight = np.hypot(*_periodic(ref - c))
            crossed = np.hypot(*_periodic(ref - c[::-1]))
            out[k] = float(min(straight, crossed))
    return out


def track_poi(
    reference: PointOfInterest,
    candidates: Sequence[PointOfInterest],
    sigma_poi: float,
    sigma_arclength: float = 0.05,
) -> TrackResult:
    """Find the counterpart of ``reference`` among ``candidates`` (the PoIs of a nearby design).

    Parameters
    ----------
    reference : PointOfInterest
        PoI on the first curve.
    candidates : sequence of PointOfInterest
        PoIs of the second curve.
    sigma_poi : float
        Largest accepted displacement, in the curves' frame.
    sigma_arclength : float
        Largest accepted Eq. 3.14 distance, in fractions of the curve's length.
    """
    if sigma_poi <= 0 or sigma_arclength <= 0:
        raise ValueError("track_poi: sigma_poi and sigma_arclength must be > 0")
    dist = arclength_distances(reference, candidates)
    if not len(dist) or not np.isfinite(dist).any():
        return TrackResult(reference, None, np.inf, np.inf, f"no {reference.kind} PoI on the new curve")
    best = int(np.argmin(dist))
    cand = candidates[best]
    moved = float(np.hypot(cand.xy[0] - reference.xy[0], cand.xy[1] - reference.xy[1]))
    if dist[best] > sigma_arclength:
        return TrackResult(
            reference, None, float(dist[best]), moved,
            f"nearest {reference.kind} PoI by arc length is {dist[best]:.3g} of the curve's length away "
            f"(limit {sigma_arclength:g})",
        )
    if moved > sigma_poi:
        return TrackResult(
            reference, None, float(dist[best]), moved,
            f"matching {reference.kind} PoI moved by {moved:.3g} (limit sigma_PoI = {sigma_poi:.3g})",
        )
    return TrackResult(reference, cand, float(dist[best]), moved)


def track_pois(
    references: Sequence[PointOfInterest],
    candidates: Sequence[PointOfInterest],
    sigma_poi: float,
    sigma_arclength: float = 0.05,
) -> list[TrackResult]:
    """:func:`track_poi` for several references (each tracked independently)."""
    return [track_poi(ref, candidates, sigma_poi, sigma_arclength) for ref in references]
