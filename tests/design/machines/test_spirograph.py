"""Spirograph (A.2.1): the hypotrochoid, its period and each constraint."""

from __future__ import annotations

import numpy as np
import pytest

from design.errors import ConstraintViolation, ParameterError
from design.machines import get_machine

spirograph = get_machine("spirograph")


@pytest.mark.parametrize("r_f, r_r, d", [(5, 3, 2.0), (7, 2, 0.5), (11, 4, 4.0), (29, 17, 9.3)])
def test_hypotrochoid_formula(r_f, r_r, d):
    t = np.linspace(0, spirograph.period({"r_f": r_f, "r_r": r_r, "d": d}), 777)
    q = r_f / r_r
    expected = np.column_stack(
        [r_r * (q - 1) * np.cos(t) + d * np.cos((q - 1) * t), r_r * (q - 1) * np.sin(t) - d * np.sin((q - 1) * t)]
    )
    np.testing.assert_allclose(spirograph.curve({"r_f": r_f, "r_r": r_r, "d": d}, t), expected, atol=1e-12)


@pytest.mark.parametrize("r_f, r_r", [(5, 3), (7, 2), (12, 5), (29, 28)])
def test_period_is_the_lcm_rule(r_f, r_r):
    assert spirograph.period({"r_f": r_f, "r_r": r_r, "d": 0.5}) == pytest.approx(2 * np.pi * r_r)
    assert spirograph.turns({"r_f": r_f, "r_r": r_r, "d": 0.5}) == r_r


CONSTRAINT_CASES = [
    ("rolling_gear_inside", {"r_f": 5, "r_r": 7, "d": 1.0}, "r_r must be smaller than r_f = 5, got 7"),
    ("rolling_gear_inside", {"r_f": 5, "r_r": 5, "d": 1.0}, "r_r must be smaller than r_f = 5, got 5"),
    ("pen_inside_gear", {"r_f": 5, "r_r": 3, "d": 3.5}, "d must be at most r_r = 3, got 3.5"),
    ("coprime_radii", {"r_f": 6, "r_r": 4, "d": 1.0}, "gcd(6, 4) = 2"),
    ("pen_offset_positive", {"r_f": 5, "r_r": 3, "d": 0.0}, "d must be greater than 0"),
]


def test_constraint_cases_cover_every_named_constraint():
    box = {c.name for c in spirograph._box_constraints()}
    assert {case[0] for case in CONSTRAINT_CASES} == {c.name for c in spirograph.all_constraints()} - box


@pytest.mark.parametrize("constraint, params, message", CONSTRAINT_CASES)
def test_each_constraint_raises(constraint, params, message):
    with pytest.raises(ConstraintViolation) as info:
        spirograph.validate(params)
    assert info.value.constraint == constraint
    assert message in str(info.value)
    assert constraint in [v.constraint for v in spirograph.violations(params)]


@pytest.mark.parametrize(
    "params, constraint",
    [
        ({"r_f": 30}, "r_f_max"),
        ({"r_f": 1, "r_r": 1}, "r_f_min"),
        ({"r_r": 0}, "r_r_min"),
        ({"r_f": 5.5}, "r_f_integer"),
        ({"d": -1.0}, "d_min"),
        ({"d": 40.0}, "d_max"),
    ],
)
def test_box_and_integrality_are_parameter_errors_and_violations(params, constraint):
    with pytest.raises(ParameterError, match=f"parameter '{constraint.split('_')[0]}"):
        spirograph.validate(params)
    assert constraint in [v.constraint for v in spirograph.violations(params)]


def test_feasible_interval_of_d_is_exact():
    lo, hi = spirograph.feasible_interval({"r_f": 7, "r_r": 3, "d": 1.0}, "d")
    assert hi == 3.0
    assert 0 < lo < 1e-9


def test_feasible_interval_without_feasible_value_raises():
    with pytest.raises(ConstraintViolation, match="coprime"):
        spirograph.feasible_interval({"r_f": 6, "r_r": 4, "d": 1.0}, "d")


def test_arclength_spacing_follows_the_curve():
    points = spirograph.sample({"r_f": 5, "r_r": 3, "d": 3.0}, 4096, "arclength")  # hypocycloid: cusps
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    assert steps.max() / steps.min() < 1.05
