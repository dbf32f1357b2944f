"""The basic Spirograph (thesis A.2.1, Figure 3.1): a gear rolling without slipping inside a fixed ring.

Parameters: ``r_f`` (fixed ring radius) and ``r_r`` (rolling gear radius), integers; ``d`` (pen hole distance from
the rolling gear's center). Time ``t`` is the polar angle of the rolling gear's center; the pen draws the
hypotrochoid (A.12, upper signs)::

    gamma(t) = r_r (q - 1) [cos t, sin t] + d [cos((q - 1) t), -sin((q - 1) t)],   q = r_f / r_r

and the pattern closes after ``T = 2 pi r_r / gcd(r_f, r_r)`` (A.1.1: the rolling gear's center goes round the
ring once per ``r_f`` teeth; both gears are back after lcm(r_f, r_r) teeth).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

from design.machines.base import DrawingMachine
from design.machines.constraints import Constraint, coprime_constraint, ordered, positive
from design.machines.parameters import MAX_GEAR_RADIUS, gear_period, gear_radius, length
from design.machines.shapes import Circle, Point, Segment, Shape, xy


class Spirograph(DrawingMachine):
    """Basic Spirograph: 2 discrete + 1 continuous parameters (Table 3.2)."""

    name = "spirograph"
    title = "Spirograph"
    description = "A gear rolling inside a fixed ring; the pen in a hole of the rolling gear draws a hypotrochoid."
    symmetry_gear = "r_f"
    parameters = (
        gear_radius("r_f", 5, "radius of the fixed ring (teeth count scale)", "A.7", lower=2),
        gear_radius("r_r", 3, "radius of the rolling gear", "A.8", upper=MAX_GEAR_RADIUS - 2, category="valid layout"),
        length("d", 2.0, MAX_GEAR_RADIUS - 2, "distance from the rolling gear's center to the pen hole", "A.9"),
    )

    def constraints(self) -> Iterable[Constraint]:
        yield ordered("rolling_gear_inside", "r_r", "<", "r_f", "A.8")
        yield Constraint(
            "pen_inside_gear",
            "valid layout",
            "A.9",
            lambda P: P["r_r"] - np.abs(P["d"]),
            lambda p: f"d must be at most r_r = {p['r_r']:g}, got {p['d']:g}",
            strict=False,
            depends=("r_r", "d"),
        )
        yield coprime_constraint("A.10", "r_f", "r_r")
        mirrored = " (d < 0 draws a rotated copy, d = 0 a circle)"
        yield positive("pen_offset_positive", "d", "A.11", "symmetry reduction", mirrored)

    def _period(self, P: Mapping[str, np.ndarray]) -> np.ndarray:
        # Time is the angle of the rolling gear's center: one turn per r_f teeth; lcm rule over (r_f, r_r).
        return gear_period(P["r_f"], P["r_r"])

    def _positions(self, P: Mapping[str, np.ndarray], t: np.ndarray) -> np.ndarray:
        r_f, r_r, d = P["r_f"], P["r_r"], P["d"]
        q = r_f / r_r
        return (r_f - r_r) * np.exp(1j * t) + d * np.exp(-1j * (q - 1.0) * t)

    def mechanism(self, params: Mapping[str, float], t: float, frame: str = "drawing") -> list[Shape]:
        p = self._preview_design(params, frame)
        r_f, r_r, d = p["r_f"], p["r_r"], p["d"]
        center = (r_f - r_r) * np.exp(1j * t)
        spin = -(r_f / r_r - 1.0) * t  # rotation of the rolling gear (rolling without slipping)
        pen = center + d * np.exp(1j * spin)
        contact = r_f * np.exp(1j * t)
        return [
            Circle("fixed ring", (0.0, 0.0), float(r_f)),
            Circle("rolling gear", xy(center), float(r_r)),
            Segment("pen arm", xy(center), xy(pen)),
            Point("contact", xy(contact)),
            Point("rolling gear center", xy(center)),
            Point("pen", xy(pen)),
        ]
