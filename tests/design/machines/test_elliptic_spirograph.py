"""Elliptic Spirograph (A.2.2): the arc-length change of variable, e = 0 is the Spirograph, each constraint."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from design.errors import ConstraintViolation
from design.machines import Ellipse, get_machine
from design.machines.elliptic_spirograph import semi_axes

elliptic = get_machine("elliptic_spirograph")
spirograph = get_machine("spirograph")


@pytest.mark.parametrize("r_f, r_r, d", [(5, 3, 2.0), (7, 4, 3.5), (11, 2, 1.0), (13, 8, 8.0)])
@pytest.mark.parametrize("spacing", ["time", "arclength"])
def test_zero_eccentricity_is_the_spirograph(r_f, r_r, d, spacing):
    ellipse = elliptic.sample({"r_f": r_f, "r_r": r_r, "e": 0.0, "d": d}, 1500, spacing)
    circle = spirograph.sample({"r_f": r_f, "r_r": r_r, "d": d}, 1500, spacing)
    np.testing.assert_allclose(ellipse, circle, atol=1e-9)


@pytest.mark.parametrize("r_r, e", [(3, 0.0), (3, 0.5), (7, 0.8), (1, 0.3)])
def test_equivalent_radius_keeps_the_perimeter(r_r, e):
    a, b = semi_axes(r_r, e)
    perimeter, _ = quad(lambda u: np.hypot(a * np.sin(u), b * np.cos(u)), 0, 2 * np.pi)
    assert perimeter == pytest.approx(2 * np.pi * r_r, rel=1e-10)
    assert b == pytest.approx(a * np.sqrt(1 - e * e))


@pytest.mark.parametrize("design", [{"r_f": 5, "r_r": 3, "e": 0.4, "d": 1.5}, {"r_f": 9, "r_r": 4, "e": 0.6, "d": 3.0}])
def test_rolls_inside_the_ring_without_slipping(design):
    P = {k: np.float64(v) for k, v in elliptic.validate(design).items()}
    for t0 in np.linspace(0.1, elliptic.period(design), 9):
        contact, psi, on_ellipse, a, b = elliptic._state(P, np.float64(t0))
        # The ellipse touches the ring at the contact point and stays inside it.
        shape = next(s for s in elliptic.mechanism(design, t0) if isinstance(s, Ellipse))
        outline = shape.polyline(2000)
        assert np.hypot(*outline.T).max() <= design["r_f"] * (1 + 1e-6)
        assert abs(abs(contact) - design["r_f"]) < 1e-12
        # Rolling without slipping: the ellipse's material point at the contact has zero velocity.
        h = 1e-6
        positions = []
        for t in (t0 - h, t0 + h):
            c, p, on, _, _ = elliptic._state(P, np.float64(t))
            positions.append(c + np.exp(1j * p) * (on_ellipse - on))
        velocity = abs(positions[1] - positions[0]) / (2 * h)
        assert velocity < 1e-6 * design["r_f"]


CONSTRAINT_CASES = [
    ("rolling_gear_inside", {"r_f": 4, "r_r": 5, "e": 0.1, "d": 1.0}, "r_r must be smaller than r_f = 4, got 5"),
    ("eccentricity_below_one", {"e": 1.0}, "e must be smaller than 1"),
    ("compatible_curvatures", {"r_f": 5, "r_r": 3, "e": 0.9, "d": 1.0}, "a must be below sqrt(b r_f) = 2.96"),
    ("pen_inside_gear", {"r_f": 5, "r_r": 3, "e": 0.4, "d": 3.2}, "d must be at most the semi-major axis a = 3.1"),
    ("coprime_radii", {"r_f": 9, "r_r": 6, "e": 0.1, "d": 1.0}, "gcd(9, 6) = 3"),
    ("pen_offset_positive", {"d": 0.0}, "d must be greater than 0"),
]


def test_constraint_cases_cover_every_named_constraint():
    box = {c.name for c in elliptic._box_constraints()}
    assert {case[0] for case in CONSTRAINT_CASES} == {c.name for c in elliptic.all_constraints()} - box


@pytest.mark.parametrize("constraint, params, message", CONSTRAINT_CASES)
def test_each_constraint_raises(constraint, params, message):
    with pytest.raises(ConstraintViolation) as info:
        elliptic.validate(params)
    assert info.value.constraint == constraint
    assert message in str(info.value)


def test_eccentricity_slider_stops_at_the_curvature_limit():
    design = {"r_f": 5, "r_r": 3, "e": 0.4, "d": 1.5}
    lo, hi = elliptic.feasible_interval(design, "e")
    assert lo == 0.0
    a, b = semi_axes(3, hi)
    assert np.sqrt(b * 5) - a == pytest.approx(0, abs=1e-9)
    lo_d, hi_d = elliptic.feasible_interval(design, "d")
    assert hi_d == pytest.approx(semi_axes(3, 0.4)[0], abs=1e-9)
