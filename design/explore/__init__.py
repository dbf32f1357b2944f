"""Guided exploration under visual constraints (thesis 3.5): Points of Interest, invariants, invariant subspace.

>>> from design.explore import Explorer, detect_pois
"""

from design.explore.errors import ExploreError, InvariantSpecError, OverConstrainedError
from design.explore.explorer import Explorer, MoveResult, ReleaseResult, Slider
from design.explore.invariants import ERROR_UNIT, INVARIANT_TYPES, Invariant, make_invariant, parse_keep
from design.explore.poi import (
    CURVATURE,
    INTERSECTION,
    PointOfInterest,
    detect_curvature_maxima,
    detect_pois,
    detect_self_intersections,
)
from design.explore.shape import bbox_diagonal, shape_distance
from design.explore.subspace import SIGMA_INV, SIGMA_VAR_FACTOR, SLIDER_BOUND, Subspace, compute_subspace
from design.explore.tracking import TrackResult, track_poi, track_pois
from design.explore.wpca import WPCA

__all__ = [
    "CURVATURE",
    "ERROR_UNIT",
    "INTERSECTION",
    "INVARIANT_TYPES",
    "SIGMA_INV",
    "SIGMA_VAR_FACTOR",
    "SLIDER_BOUND",
    "WPCA",
    "ExploreError",
    "Explorer",
    "Invariant",
    "InvariantSpecError",
    "MoveResult",
    "OverConstrainedError",
    "PointOfInterest",
    "ReleaseResult",
    "Slider",
    "Subspace",
    "TrackResult",
    "bbox_diagonal",
    "compute_subspace",
    "detect_curvature_maxima",
    "detect_pois",
    "detect_self_intersections",
    "make_invariant",
    "parse_keep",
    "shape_distance",
    "track_poi",
    "track_pois",
]
