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

from design.machines.base import (
    MAX_GEAR_RADIUS,
    Circle,
    Constraint,
    DrawingMachine,
    Parameter,
    Point,
    Segment,
    Shape,
    _xy,
    coprime_constraint,
    gear_period,
)


class Spirograph(DrawingMachine):
    """Basic Spirograph: 2 discrete + 1 continuous parameters (Table 3.2)."""

    name = "spirograph"
    title = "Spirograph"
    description = "A gear rolling inside a fixed ring; the pen in a hole of the rolling gear draws a hypotrochoid."
    symmetry_gear = "r_f"
    parameters = (
        Parameter(
            "r_f", "discrete", 5, 2, MAX_GEAR_RADIUS - 1, "radius of the fixed ring (teeth count scale)",
            category="finite pattern", equation="A.7",
        ),
        Parameter(
            "r_r", "discrete", 3, 1, MAX_GEAR_RADIUS - 2, "radius of the rolling gear",
            category="valid layout", equation="A.8",
        ),
        Parameter(
            "d", "continuous", 2.0, 0.0, MAX_GEAR_RADIUS - 2, "distance from the rolling gear's center to the pen hole",
            category="valid layout", equation="A.9",
        ),
    )  # fmt: skip

    def constraints(self) -> Iterable[Constraint]:
        yield Constraint(
            "rolling_gear_inside",
            "valid layout",
            "A.8",
            lambda P: P["r_f"] - P["r_r"],
            lambda p: f"r_r must be smaller than r_f = {p['r_f']:g}, got {p['r_r']:g}",
            depends=("r_f", "r_r"),
        )
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
        yield Constraint(
            "pen_offset_positive",
            "symmetry reduction",
            "A.11",
            lambda P: P["d"],
            lambda p: f"d must be greater than 0 (d < 0 draws a rotated copy, d = 0 a circle), got {p['d']:g}",
            depends=("d",),
        )

    def _period(self, P: Mapping[str, np.ndarray]) -> np.ndarray:
        # Time is the angle of the rolling gear's center: one turn per r_f teeth; lcm rule over (r_f, r_r).
        return gear_period(P["r_f"], P["r_r"])

    def _positions(self, P: Mapping[str, np.ndarray], t: np.ndarray) -> np.ndarray:
        r_f, r_r, d = P["r_f"], P["r_r"], P["d"]
        q = r_f / r_r
        return (r_f - r_r) * np.exp(1j * t) + d * np.exp(-1j * (q - 1.0) * t)

    def mechanism(self, params: Mapping[str, float], t: float, frame: str = "drawing") -> list[Shape]:
        self._check_frame(frame)
        p = self.validate(params)
        r_f, r_r, d = p["r_f"], p["r_r"], p["d"]
        center = (r_f - r_r) * np.exp(1j * t)
        spin = -(r_f / r_r - 1.0) * t  # rotation of the rolling gear (rolling without slipping)
        pen = center + d * np.exp(1j * spin)
        contact = r_f * np.exp(1j * t)
        return [
            Circle("fixed ring", (0.0, 0.0), float(r_f)),
            Circle("rolling gear", _xy(center), float(r_r)),
            Segment("pen arm", _xy(center), _xy(pen)),
            Point("contact", _xy(contact)),
            Point("rolling gear center", _xy(center)),
            Point("pen", _xy(pen)),
        ]
