"""The seeded benchmark-set generator: deterministic, realistic damage, symmetric sectors, no near-circles."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from design.machines import get_machine
from design.sketch.strokes import rotation
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


def test_another_seed_gives_another_case():
    # The counterpart of the test above, which also passes if the generator ignores its random source.
    machine = get_machine("spirograph")
    a, b = (make_case(machine, {"r_f": 7, "r_r": 3}, np.random.default_rng(seed), symmetry=7) for seed in (5, 6))
    assert a is not None and b is not None
    assert a.params["d"] != b.params["d"]
    first, second = np.concatenate(a.sketch.strokes), np.concatenate(b.sketch.strokes)
    assert first.shape != second.shape or not np.allclose(first, second)


def covered(curve: np.ndarray, points: np.ndarray, tolerance: float) -> float:
    """Fraction of the points of ``curve`` within ``tolerance`` of one of ``points``."""
    return float(np.mean(cKDTree(points).query(curve)[0] < tolerance))


def test_sector_cases_carry_their_symmetry_order_and_centre():
    machine = get_machine("spirograph")
    case = make_case(machine, {"r_f": 5, "r_r": 2}, np.random.default_rng(1), symmetry=5, sector_probability=1.0)
    assert case is not None and case.sector and case.sketch.symmetry == 5
    # The sector is a fifth of the pattern: alone it draws about a fifth of the whole curve, and its five copies
    # about the sketch's centre draw all of it (but for the pen lifts). The sketch is the curve rotated, scaled and
    # moved to the centre: the scale is the ratio of the largest radii (a fifth of a 5-fold pattern reaches its
    # largest radius), the rotation is searched over a fifth of a turn (the copies are 5-fold symmetric).
    sector = np.concatenate(case.sketch.strokes) - case.sketch.center
    copies = np.concatenate([sector @ rotation(2 * np.pi * j / 5).T for j in range(5)])
    curve = machine.curve(case.params, np.linspace(0.0, machine.period(case.params), 2000))
    scale = np.hypot(*sector.T).max() / np.hypot(*curve.T).max()
    tolerance = 0.02 * scale * float(np.linalg.norm(np.ptp(curve, axis=0)))
    angles = np.radians(np.arange(0.0, 72.0, 0.5))
    best = max(angles, key=lambda a: covered(curve @ (scale * rotation(a)).T, copies, tolerance))
    placed = curve @ (scale * rotation(best)).T
    assert covered(placed, copies, tolerance) > 0.9
    assert 0.12 < covered(placed, sector, tolerance) < 0.3


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
