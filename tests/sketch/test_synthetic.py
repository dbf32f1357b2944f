"""The seeded benchmark-set generator: deterministic, realistic damage, symmetric sectors, no near-circles."""

from __future__ import annotations

import numpy as np

from design.machines import get_machine
from design.sketch.synthetic import make_case, pattern_detail


def test_cases_are_seeded_and_damaged_as_described():
    machine = get_machine("spirograph")
    a = make_case(machine, {"r_f": 7, "r_r": 3}, np.random.default_rng(5), symmetry=7, sector_probability=0.0)
    b = make_case(machine, {"r_f": 7, "r_r": 3}, np.random.default_rng(5), symmetry=7, sector_probability=0.0)
    assert a is not None and b is not None
    assert a.params == b.params
    assert all(np.array_equal(x, y) for x, y in zip(a.sketch.strokes, b.sketch.strokes))
    assert 1 <= len(a.sketch.strokes) <= 4 and a.sketch.symmetry == 1 and not a.sector
    assert machine.is_feasible(a.params) and (a.params["r_f"], a.params["r_r"]) == (7, 3)


def test_sector_cases_carry_their_symmetry_order_and_centre():
    machine = get_machine("spirograph")
    case = make_case(machine, {"r_f": 5, "r_r": 2}, np.random.default_rng(1), symmetry=5, sector_probability=1.0)
    assert case is not None and case.sector and case.sketch.symmetry == 5
    # the sector spans a fifth of the pattern: its copies around the centre cover about the whole curve
    points = np.concatenate(case.sketch.strokes)
    angles = np.arctan2(*(points - case.sketch.center).T[::-1])
    assert np.ptp(np.unwrap(np.sort(angles))) < 2 * np.pi


def test_near_circles_are_measured_and_redrawn():
    t = np.linspace(0, 2 * np.pi, 512, endpoint=False)
    circle = np.column_stack([np.cos(t), np.sin(t)])
    wobbly = circle * (1 + 0.3 * np.cos(5 * t))[:, None]
    assert pattern_detail(circle) < 1e-6 < 0.02 < pattern_detail(wobbly)
    machine = get_machine("spirograph")
    # r_f = 5, r_r = 1: the pen offset d <= 1 against a ring of radius 4; small offsets are near-circles
    case = make_case(machine, {"r_f": 5, "r_r": 1}, np.random.default_rng(0), symmetry=5)
    assert case is not None
    assert pattern_detail(machine.sample(case.params, n=2048, spacing="arclength")[:-1]) >= 0.02
    # r_f = 12, r_r = 1 can only draw near-circles (d <= 1 against a ring of radius 11): no case
    assert make_case(machine, {"r_f": 12, "r_r": 1}, np.random.default_rng(0), symmetry=12, tries=5) is None
