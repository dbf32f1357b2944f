"""Invariants: what the user freezes in the drawing (thesis 3.5.1, Figure 3.11, 3.6.2).

An invariant compares the features of one or two tracked PoIs on a new design with their values on the design where
the invariant was set:

========== ======= ================================================ =================================
type       PoIs    residual (normalized so that 1 is a clear change)  error reported
========== ======= ================================================ =================================
position   1 any   (p - p0) / (0.05 size)                             |p - p0| / size
curvature  1 max   ln(kappa / kappa0) / 0.1                           |kappa / kappa0 - 1|
angle      1 cross (theta - theta0) / 10 deg                          |theta - theta0| in degrees
radial     1 any   distance of p to the line (O, p0) / (0.05 size)    that distance / size
distance   2 any   (|pa - pb| - D0) / (0.05 size)                     |D - D0| / size
========== ======= ================================================ =================================

``size`` is the diagonal of the bounding box of the curve the invariants were set on; ``O`` is the origin of the
drawing frame (the fixed gear's or the turntable's centre). The invariance score of a design is
``S = exp(-d)`` (Eq. 3.16) where ``d`` is the Euclidean norm of all residuals together, so ``S > 0.9`` means
roughly an error below 0.5 % of the size, 1 % of curvature or 1 degree.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from design.explore.errors import InvariantSpecError
from design.explore.poi import CURVATURE, INTERSECTION, PointOfInterest

#: Residual scale per invariant type (a residual of 1 is a clear change); lengths are fractions of the size.
RESIDUAL_SCALE = {"position": 0.05, "distance": 0.05, "radial": 0.05, "curvature": 0.1, "angle": np.radians(10.0)}
#: Number of PoIs each type takes, and the PoI kinds it accepts.
ARITY = {"position": 1, "curvature": 1, "angle": 1, "radial": 1, "distance": 2}
ACCEPTS = {
    "position": (CURVATURE, INTERSECTION),
    "curvature": (CURVATURE,),
    "angle": (INTERSECTION,),
    "radial": (CURVATURE, INTERSECTION),
    "distance": (CURVATURE, INTERSECTION),
}
INVARIANT_TYPES = tuple(ARITY)
#: Unit of each type's reported error.
ERROR_UNIT = {"position": "size", "distance": "size", "radial": "size", "curvature": "relative", "angle": "deg"}


@dataclass(frozen=True)
class Invariant:
    """A frozen feature of one or two PoIs.

    Attributes
    ----------
    kind : str
        One of :data:`INVARIANT_TYPES`.
    pois : tuple of int
        Ids of the PoIs (in the PoI list of the design the invariant was set on).
    target : tuple of float
        The feature's value on that design: ``(x, y)`` for position and radial, ``(kappa,)``, ``(theta,)``,
        ``(D,)``.
    size : float
        The curve's size (bounding-box diagonal) on that design.
    keys : tuple of int
        Keys of the PoIs in the ``features`` mappings given to :meth:`residuals` (the ids by default; the explorer
        uses its own keys, since ids change from one design to the next).
    """

    kind: str
    pois: tuple[int, ...]
    target: tuple[float, ...]
    size: float
    keys: tuple[int, ...] = ()

    @property
    def feature_keys(self) -> tuple[int, ...]:
        return self.keys or self.pois

    @property
    def label(self) -> str:
        return f"{self.kind}:{','.join(str(p) for p in self.pois)}"

    @property
    def n_residuals(self) -> int:
        return 2 if self.kind == "position" else 1

    def residuals(self, features: Mapping[int, Mapping[str, np.ndarray]]) -> np.ndarray:
        """Normalized residuals ``(k, n_residuals)`` on ``k`` designs (NaN where a PoI is lost).

        ``features[poi_id]`` holds arrays ``xy`` (k, 2), ``curvature`` (k,) and ``angle`` (k,).
        """
        f = features[self.feature_keys[0]]
        scale = RESIDUAL_SCALE[self.kind]
        if self.kind == "position":
            return (f["xy"] - np.asarray(self.target)) / (scale * self.size)
        if self.kind == "curvature":
            with np.errstate(all="ignore"):
                return (np.log(f["curvature"] / self.target[0]) / scale)[:, None]
        if self.kind == "angle":
            return ((f["angle"] - self.target[0]) / scale)[:, None]
        if self.kind == "radial":
            u = np.asarray(self.target) / np.hypot(*self.target)
            off_line = f["xy"][:, 0] * u[1] - f["xy"][:, 1] * u[0]
            return (off_line / (scale * self.size))[:, None]
        if self.kind == "distance":
            g = features[self.feature_keys[1]]
            dist = np.hypot(*(f["xy"] - g["xy"]).T)
            return ((dist - self.target[0]) / (scale * self.size))[:, None]
        raise AssertionError(self.kind)  # pragma: no cover

    def errors(self, features: Mapping[int, Mapping[str, np.ndarray]]) -> np.ndarray:
        """Error on ``k`` designs in the type's unit (:data:`ERROR_UNIT`): NaN where a PoI is lost."""
        r = self.residuals(features)
        scale = RESIDUAL_SCALE[self.kind]
        if self.kind in ("position", "radial", "distance"):
            return np.hypot.reduce(r, axis=1) * scale if r.shape[1] > 1 else np.abs(r[:, 0]) * scale
        if self.kind == "curvature":
            return np.abs(np.expm1(r[:, 0] * scale))
        return np.degrees(np.abs(r[:, 0]) * scale)


def make_invariant(kind: str, poi_ids: Sequence[int], pois: Sequence[PointOfInterest], size: float) -> Invariant:
    """Build an invariant from the PoIs of the current design, checking type, arity and PoI kinds.

    Raises
    ------
    InvariantSpecError
        Unknown type, wrong number of PoIs, unknown PoI id, a PoI of a kind the type does not accept, a radial
        invariant on a PoI at the origin, or a distance between a PoI and itself.
    """
    if kind not in ARITY:
        raise InvariantSpecError(f"invariant type must be one of {', '.join(INVARIANT_TYPES)}, got {kind!r}")
    ids = tuple(int(i) for i in poi_ids)
    if len(ids) != ARITY[kind]:
        raise InvariantSpecError(f"invariant {kind!r} takes {ARITY[kind]} PoI id(s), got {len(ids)} ({list(ids)})")
    by_id = {p.id: p for p in pois}
    for i in ids:
        if i not in by_id:
            raise InvariantSpecError(
                f"invariant {kind!r}: PoI id must be one of 0..{len(pois) - 1} on this design, got {i}"
            )
        if by_id[i].kind not in ACCEPTS[kind]:
            raise InvariantSpecError(
                f"invariant {kind!r}: PoI {i} must be {_a(' or '.join(ACCEPTS[kind]))} PoI, "
                f"got {_a(by_id[i].kind)} PoI"
            )
    first = by_id[ids[0]]
    if kind in ("position", "radial"):
        target = tuple(float(v) for v in first.xy)
        if kind == "radial" and np.hypot(*target) < 1e-6 * size:
            raise InvariantSpecError(f"invariant 'radial': PoI {ids[0]} is at the origin, its radial line is undefined")
    elif kind == "curvature":
        target = (float(first.curvature),)
    elif kind == "angle":
        target = (float(first.angle),)
    else:
        if ids[0] == ids[1]:
            raise InvariantSpecError("invariant 'distance' needs two different PoIs, got the same id twice")
        second = by_id[ids[1]]
        target = (float(np.hypot(first.xy[0] - second.xy[0], first.xy[1] - second.xy[1])),)
    return Invariant(kind, ids, target, float(size))


def parse_keep(spec: str) -> tuple[str, tuple[int, ...]]:
    """Parse ``TYPE:POI[,POI]`` (the CLI's ``--keep``), e.g. ``"distance:2,5"`` -> ``("distance", (2, 5))``."""
    kind, sep, ids = spec.partition(":")
    kind = kind.strip()
    if not sep or not ids.strip():
        raise InvariantSpecError(f"--keep {spec!r}: expected TYPE:POI[,POI], e.g. position:3 or distance:2,5")
    if kind not in ARITY:
        raise InvariantSpecError(f"--keep {spec!r}: type must be one of {', '.join(INVARIANT_TYPES)}, got {kind!r}")
    try:
        parsed = tuple(int(i) for i in ids.split(","))
    except ValueError:
        raise InvariantSpecError(f"--keep {spec!r}: PoI ids must be integers, got {ids!r}") from None
    return kind, parsed


def _a(phrase: str) -> str:
    """``phrase`` with its indefinite article: "an intersection", "a curvature" (every PoI kind starts with a
    letter whose sound matches its spelling, so the first letter decides)."""
    return f"{'an' if phrase[:1].lower() in 'aeiou' else 'a'} {phrase}"
