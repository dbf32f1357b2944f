"""The Hoot-Nanny, or Magic Designer (thesis A.2.4, Figure A.4).

The paper is on a turntable gear (radius ``r_t``, center G_T at the origin) which drives two external gears of radii
``r_g1`` and ``r_g2``; G_1 is on the +x axis at ``r_t + r_g1`` and G_2 at polar angle ``theta_12`` at
``r_t + r_g2``. Each gear carries a pivot P_i at ``r_p1``/``r_p2`` from its center; two arms of lengths ``l1`` and
``l2`` hinge on the pivots and meet at the pen holder H. The drawing is H's path in the turntable's frame::

    theta_i(t) = -(r_t / r_gi) t                                   (A.70, law of gearing)
    P_i = G_i + r_pi (cos theta_i, sin theta_i)                     (A.73-A.74)
    H = P_2 + l2 R_{-alpha} (P_1 - P_2) / |P_1 - P_2|,  cos alpha = (l2^2 + |P_1P_2|^2 - l1^2) / (2 l2 |P_1P_2|)
    gamma(t) = R_{-t} H                                             (A.53)

of the two intersections of the arms' circles the pen is the one on the turntable's side of the line P_2 P_1
(rotation by ``-alpha``: with G_1 on +x and ``0 < theta_12 < pi`` the turntable's center is clockwise of P_2 -> P_1;
the thesis's ``R_alpha`` is the mirror convention). Period (lcm rule): ``T = 2 pi lcm(r_t, r_g1, r_g2) / r_t``.

Notes on the constraint system, where the station reads Appendix A carefully:

* Symmetry reduction A.62 is taken as ``gcd(r_t, r_g1, r_g2) = 1``, as section 3.4.2 states ("all three radii are
  constrained to share no common divisor, any pair of them taken separately still can") and as Figure 3.8's radii
  (4, 3, 2) require.
* The drawing-bounds vertices (A.65-A.66) are where the pen's distance to G_i is extremal, ``l_i -+ r_pi`` (the
  thesis prints ``r_gi -+ l_i``).
* A.69 keeps the arms from stretching straight; the station adds its mirror, ``|l1 - l2| + r_p1 + r_p2 <
  |G_1G_2|`` (``arms_not_folded``), without which the triangle H P_1 P_2 cannot close at some times (the arccos of
  A.72 leaves [-1, 1]) and the quadrilateral of A.65 has no vertices.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

from design.machines.base import TurntableMachine
from design.machines.constraints import Constraint, coprime_constraint, ordered
from design.machines.parameters import MAX_GEAR_RADIUS, angle, gear_period, gear_radius, length, scalar_arrays
from design.machines.shapes import Circle, Point, Segment, Shape, xy

#: Upper box bound of the arm lengths (A.60 bounds them by 2 r_t + r_gi - r_pi < 3 B_r).
MAX_ARM_LENGTH = 3.0 * MAX_GEAR_RADIUS


def gear_centers(P: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Complex centers of G_1 and G_2."""
    g1 = (P["r_t"] + P["r_g1"]) * np.ones_like(P["theta_12"]) + 0j
    g2 = (P["r_t"] + P["r_g2"]) * np.exp(1j * P["theta_12"])
    return g1, g2


def gear_distance(P: Mapping[str, np.ndarray]) -> np.ndarray:
    """|G_1 G_2| (A.61)."""
    g1, g2 = gear_centers(P)
    return np.abs(g1 - g2)


def triangle_apex(p1: np.ndarray, p2: np.ndarray, l1: np.ndarray, l2: np.ndarray) -> np.ndarray:
    """The point at ``l1`` from ``p1`` and ``l2`` from ``p2``, clockwise of ``p2 -> p1`` (law of cosines, A.71)."""
    base = p1 - p2
    length = np.abs(base)
    cos_alpha = (l2 * l2 + length * length - l1 * l1) / (2.0 * l2 * length)
    alpha = np.arccos(np.clip(cos_alpha, -1.0, 1.0))
    return p2 + l2 * np.exp(-1j * alpha) * base / length


def farthest_pen_distance(P: Mapping[str, np.ndarray]) -> np.ndarray:
    """Largest distance from G_T of the four vertices of the pen's quadrilateral (A.64-A.67, sufficient)."""
    g1, g2 = gear_centers(P)
    farthest = np.zeros(np.broadcast(g1, g2, P["l1"], P["l2"], P["r_p1"], P["r_p2"]).shape)
    for s1 in (-1.0, 1.0):
        for s2 in (-1.0, 1.0):
            vertex = triangle_apex(g1, g2, P["l1"] + s1 * P["r_p1"], P["l2"] + s2 * P["r_p2"])
            farthest = np.maximum(farthest, np.abs(vertex))
    return farthest


class HootNanny(TurntableMachine):
    """Hoot-Nanny: 3 discrete + 5 continuous parameters (Table 3.2)."""

    name = "hoot_nanny"
    title = "Hoot-Nanny"
    description = (
        "A turntable drives two gears; an arm hinged on a pivot of each gear holds the pen where the arms meet "
        "(the Magic Designer)."
    )
    parameters = (
        gear_radius("r_t", 10, "radius of the turntable gear", "A.57"),
        gear_radius("r_g1", 3, "radius of external gear 1", "A.57"),
        gear_radius("r_g2", 2, "radius of external gear 2", "A.57"),
        angle("theta_12", 1.2, "angle G_1 G_T G_2 between the gears' centers", "A.63"),
        length("r_p1", 2.8, MAX_GEAR_RADIUS - 1, "distance from gear 1's center to pivot 1", "A.58"),
        length("r_p2", 1.8, MAX_GEAR_RADIUS - 1, "distance from gear 2's center to pivot 2", "A.58"),
        length("l1", 13.5, MAX_ARM_LENGTH, "length of arm 1 (pivot 1 to pen)", "A.60"),
        length("l2", 7.2, MAX_ARM_LENGTH, "length of arm 2 (pivot 2 to pen)", "A.60"),
    )

    def constraints(self) -> Iterable[Constraint]:
        def span(p: Mapping[str, float]) -> float:
            return float(gear_distance(scalar_arrays(p)))  # |G1G2| of one design, for the messages

        for i in ("1", "2"):
            yield ordered(f"pivot{i}_inside_gear", f"r_p{i}", "<", f"r_g{i}", "A.58")
        yield Constraint(
            "gears_apart",
            "valid layout",
            "A.59",
            lambda P: gear_distance(P) - P["r_g1"] - P["r_g2"],
            lambda p: (
                f"the gears overlap: |G1G2| = {span(p):.6g} must exceed "
                f"r_g1 + r_g2 = {p['r_g1'] + p['r_g2']:g} (increase theta_12 = {p['theta_12']:g})"
            ),
            depends=("r_t", "r_g1", "r_g2", "theta_12"),
        )
        for i in ("1", "2"):
            r_p, r_g, l = f"r_p{i}", f"r_g{i}", f"l{i}"
            yield Constraint(
                f"arm{i}_long_enough",
                "valid layout",
                "A.60",
                lambda P, r_p=r_p, r_g=r_g, l=l: P[l] - P[r_g] - P[r_p],
                lambda p, r_p=r_p, r_g=r_g, l=l: f"{l} must exceed {r_g} + {r_p} = {p[r_g] + p[r_p]:.6g}, got {p[l]:g}",
                depends=(r_p, r_g, l),
            )
            yield Constraint(
                f"arm{i}_short_enough",
                "valid layout",
                "A.60",
                lambda P, r_p=r_p, r_g=r_g, l=l: 2.0 * P["r_t"] + P[r_g] - P[r_p] - P[l],
                lambda p, r_p=r_p, r_g=r_g, l=l: (
                    f"{l} must be below 2 r_t + {r_g} - {r_p} = {2 * p['r_t'] + p[r_g] - p[r_p]:.6g}, got {p[l]:g}"
                ),
                depends=("r_t", r_p, r_g, l),
            )
        yield coprime_constraint("A.62", "r_t", "r_g1", "r_g2")
        # The singularities and the drawing bounds depend on every parameter: ``depends`` is left empty.
        yield Constraint(
            "arms_reach",
            "singularity avoidance",
            "A.69",
            lambda P: P["l1"] + P["l2"] - gear_distance(P) - P["r_p1"] - P["r_p2"],
            lambda p: (
                f"the arms must not stretch straight: l1 + l2 must exceed |G1G2| + r_p1 + r_p2 = "
                f"{span(p) + p['r_p1'] + p['r_p2']:.6g}, got {p['l1'] + p['l2']:.6g}"
            ),
        )
        yield Constraint(
            "arms_not_folded",
            "singularity avoidance",
            "",
            lambda P: gear_distance(P) - P["r_p1"] - P["r_p2"] - np.abs(P["l1"] - P["l2"]),
            lambda p: (
                f"the arms must not fold onto each other: |l1 - l2| must be below |G1G2| - r_p1 - r_p2 = "
                f"{span(p) - p['r_p1'] - p['r_p2']:.6g}, got {abs(p['l1'] - p['l2']):.6g}"
            ),
        )
        reach = "the farthest corner of its reach must be within"
        yield self._pen_on_turntable("A.67", farthest_pen_distance, reach, " of the turntable's center")

    def sampling_box(self, radii: Mapping[str, np.ndarray]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Pivots inside their gears (A.58) and arms between ``r_gi`` and ``2 r_t + r_gi`` (A.60)."""
        box = super().sampling_box(radii)
        for i in ("1", "2"):
            r_g = np.asarray(radii[f"r_g{i}"], dtype=float)
            box[f"r_p{i}"] = (np.zeros_like(r_g), np.minimum(r_g, box[f"r_p{i}"][1]))
            box[f"l{i}"] = (r_g, np.minimum(2.0 * np.asarray(radii["r_t"], dtype=float) + r_g, box[f"l{i}"][1]))
        return box

    def _period(self, P: Mapping[str, np.ndarray]) -> np.ndarray:
        return gear_period(P["r_t"], P["r_g1"], P["r_g2"])

    def _fixed_frame(self, P: Mapping[str, np.ndarray], t: np.ndarray) -> tuple[np.ndarray, ...]:
        """Gear centers, pivots and pen in the machine's fixed frame at times t."""
        g1, g2 = gear_centers(P)
        p1 = g1 + P["r_p1"] * np.exp(-1j * (P["r_t"] / P["r_g1"]) * t)
        p2 = g2 + P["r_p2"] * np.exp(-1j * (P["r_t"] / P["r_g2"]) * t)
        pen = triangle_apex(p1, p2, P["l1"], P["l2"])
        return g1, g2, p1, p2, pen

    def mechanism(self, params: Mapping[str, float], t: float, frame: str = "drawing") -> list[Shape]:
        p, (g1, g2, p1, p2, pen), turntable = self._turntable_preview(params, t, frame)
        return turntable + [
            Circle("gear 1", xy(g1), float(p["r_g1"])),
            Circle("gear 2", xy(g2), float(p["r_g2"])),
            Segment("crank 1", xy(g1), xy(p1)),
            Segment("crank 2", xy(g2), xy(p2)),
            Segment("arm 1", xy(p1), xy(pen)),
            Segment("arm 2", xy(p2), xy(pen)),
            Point("pivot 1", xy(p1)),
            Point("pivot 2", xy(p2)),
            Point("pen", xy(pen)),
        ]
