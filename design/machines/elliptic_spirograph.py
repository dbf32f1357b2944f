"""The elliptic Spirograph (thesis A.2.2): an elliptic gear rolling without slipping inside a fixed ring.

Parameters: ``r_f`` (ring radius) and ``r_r`` (the rolling ellipse's *equivalent radius*: the radius of the circle
with the same perimeter, so the finite-pattern condition A.13 is again an integer condition), integers; ``e`` (the
ellipse's eccentricity) and ``d`` (pen distance from the ellipse's center, on its major axis).

The semi-axes follow from A.16-A.17: ``2 pi r_r = 4 a E(e)`` and ``b = a sqrt(1 - e^2)`` (E the complete
elliptic integral of the second kind).

Kinematics (A.31-A.39). Time ``t`` is the ellipse's own parameter, ``gamma_R(t) = (a cos t, b sin t)``: instead of
inverting the ellipse's arc-length function (an incomplete elliptic integral, A.38), the *circle* is
re-parameterized by the ellipse's arc length ``s(t) = a (E(t + pi/2, e) - E(e))`` (the change of variable of
A.39), which only needs E evaluated forwards. The contact point is ``C = r_f (cos(s / r_f), sin(s / r_f))``; the
ellipse's frame is turned by ``psi = phi_F - phi_R`` so the tangents stay aligned (A.29), and the pen is

    gamma(t) = C + R_psi (H_R - gamma_R(t)),   H_R = (d, 0)

With ``e = 0`` the ellipse is the circle of radius ``r_r``, ``s = r_r t`` and this is exactly the Spirograph's
hypotrochoid with its time rescaled by ``r_r / r_f``; uniform samples of one period coincide point for point.

Period: the ellipse's parameter runs ``2 pi`` per perimeter (``r_r`` teeth); the pattern closes when the contact
point has covered a whole number of both perimeters (A.13): ``T = 2 pi lcm(r_f, r_r) / r_r = 2 pi r_f / gcd``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np
from scipy.special import ellipe, ellipeinc

from design.machines.base import DrawingMachine
from design.machines.constraints import Constraint, coprime_constraint, ordered, positive
from design.machines.parameters import MAX_GEAR_RADIUS, Parameter, gear_period, gear_radius, length, scalar_arrays
from design.machines.shapes import Circle, Ellipse, Point, Segment, Shape, xy


def semi_axes(r_r, e):
    """Semi-major and semi-minor axes ``(a, b)`` of the ellipse of equivalent radius ``r_r`` and eccentricity ``e``.

    From A.16 (``2 pi r_r = 4 a E(e)``; scipy's ``ellipe`` takes the parameter ``m = e^2``) and A.17.
    """
    r_r = np.asarray(r_r, dtype=float)
    e = np.asarray(e, dtype=float)
    a = np.pi * r_r / (2.0 * ellipe(e * e))
    b = a * np.sqrt(np.clip(1.0 - e * e, 0.0, None))
    return a, b


class EllipticSpirograph(DrawingMachine):
    """Elliptic Spirograph: 2 discrete + 2 continuous parameters (Table 3.2)."""

    name = "elliptic_spirograph"
    title = "Elliptic Spirograph"
    description = (
        "An elliptic gear rolling inside a fixed ring; the pen on the ellipse's major axis draws a roulette curve."
    )
    symmetry_gear = "r_f"
    parameters = (
        gear_radius("r_f", 5, "radius of the fixed ring", "A.19", lower=2),
        gear_radius(
            "r_r", 3, "equivalent radius of the rolling ellipse (radius of the circle with the same perimeter)", "A.21",
            upper=MAX_GEAR_RADIUS - 2, category="valid layout",
        ),
        Parameter(
            "e", "continuous", 0.4, 0.0, 1.0, "eccentricity of the rolling ellipse",
            unit="", category="valid layout", equation="A.22",
        ),
        length(
            "d", 1.5, MAX_GEAR_RADIUS - 2, "distance from the ellipse's center to the pen hole, along the major axis",
            "A.23",
        ),
    )  # fmt: skip

    def constraints(self) -> Iterable[Constraint]:
        def a_of(P):
            return semi_axes(P["r_r"], P["e"])[0]

        def curvature_margin(P):
            a, b = semi_axes(P["r_r"], P["e"])
            return np.sqrt(b * P["r_f"]) - a

        def curvature_message(p):
            a, b = semi_axes(p["r_r"], p["e"])
            return (
                f"the ellipse's flattest point must still fit the ring's curvature: a must be below "
                f"sqrt(b r_f) = {float(np.sqrt(b * p['r_f'])):.6g}, got a = {float(a):.6g} "
                f"(r_r = {p['r_r']:g}, e = {p['e']:g}; lower e or use a larger ring)"
            )

        yield ordered("rolling_gear_inside", "r_r", "<", "r_f", "A.21")
        yield Constraint(
            "eccentricity_below_one",
            "valid layout",
            "A.22",
            lambda P: 1.0 - P["e"],
            lambda p: f"e must be smaller than 1 (e = 1 flattens the ellipse to a segment), got {p['e']:g}",
            depends=("e",),
        )
        yield Constraint(
            "compatible_curvatures",
            "compatible curvatures",
            "A.20",
            curvature_margin,
            curvature_message,
            depends=("r_f", "r_r", "e"),
        )
        yield Constraint(
            "pen_inside_gear",
            "valid layout",
            "A.23",
            lambda P: a_of(P) - np.abs(P["d"]),
            lambda p: f"d must be at most the semi-major axis a = {float(a_of(p)):.6g}, got {p['d']:g}",
            strict=False,
            depends=("r_r", "e", "d"),
        )
        yield coprime_constraint("A.24", "r_f", "r_r")
        yield positive("pen_offset_positive", "d", "A.25", "symmetry reduction", " (d < 0 draws a rotated copy)")

    def _period(self, P: Mapping[str, np.ndarray]) -> np.ndarray:
        return gear_period(P["r_r"], P["r_f"])

    @staticmethod
    def _state(P: Mapping[str, np.ndarray], t: np.ndarray):
        """Contact point, frame rotation psi, ellipse point gamma_R(t) and semi-axes at times t (vectorized)."""
        r_f, e = P["r_f"], P["e"]
        a, b = semi_axes(P["r_r"], e)
        m = e * e
        # Common arc length (A.38): the circle is re-parameterized by it (A.39), never inverted.
        s = a * (ellipeinc(t + np.pi / 2.0, m) - ellipe(m))
        sin_t, cos_t = np.sin(t), np.cos(t)
        # Tangential angle of the ellipse minus t, continuous (the denominator is positive): phi_R = pi/2 + t + delta.
        delta = np.arctan((a - b) * sin_t * cos_t / (b * cos_t * cos_t + a * sin_t * sin_t))
        # phi_F = pi/2 + s / r_f for the circle; psi = phi_F - phi_R keeps the tangents aligned (A.29).
        psi = s / r_f - t - delta
        contact = r_f * np.exp(1j * s / r_f)
        on_ellipse = a * cos_t + 1j * b * sin_t
        return contact, psi, on_ellipse, a, b

    def _positions(self, P: Mapping[str, np.ndarray], t: np.ndarray) -> np.ndarray:
        contact, psi, on_ellipse, _, _ = self._state(P, t)
        return contact + np.exp(1j * psi) * (P["d"] - on_ellipse)

    def mechanism(self, params: Mapping[str, float], t: float, frame: str = "drawing") -> list[Shape]:
        p = self._preview_design(params, frame)
        contact, psi, on_ellipse, a, b = self._state(scalar_arrays(p), np.float64(t))
        rotation = np.exp(1j * psi)
        center = contact - rotation * on_ellipse
        pen = center + rotation * p["d"]
        return [
            Circle("fixed ring", (0.0, 0.0), float(p["r_f"])),
            Ellipse("rolling ellipse", xy(center), float(a), float(b), float(psi)),
            Segment("pen arm", xy(center), xy(pen)),
            Point("contact", xy(contact)),
            Point("ellipse center", xy(center)),
            Point("pen", xy(pen)),
        ]
