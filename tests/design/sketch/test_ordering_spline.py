"""Stroke ordering (exact MILP vs brute force, heuristic), closed spline fit and arc-length resampling."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from design.sketch.errors import SketchError
from design.sketch.ordering import connection_costs, order_strokes, tour_cost, tour_gap_length
from design.sketch.spline import fit_closed_spline, resample_closed


def brute_force(costs, n):
    best = np.inf
    for perm in itertools.permutations(range(1, n)):
        order = (0,) + perm
        for flips in itertools.product([False, True], repeat=n - 1):
            best = min(best, tour_cost(costs, order, (False,) + flips))
    return best


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("continuity", [0.0, 1.0])
def test_exact_order_is_optimal(seed, continuity):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 6))
    strokes = [rng.random((int(rng.integers(1, 5)), 2)) for _ in range(n)]
    exact = order_strokes(strokes, method="exact", continuity=continuity)
    assert exact.method == "exact"
    assert sorted(exact.order) == list(range(n))
    costs = connection_costs(strokes, continuity)
    assert exact.cost == pytest.approx(brute_force(costs, n), abs=1e-9)
    if continuity == 0:
        assert exact.gap_length == pytest.approx(exact.cost)
    assert exact.gap_length == pytest.approx(tour_gap_length(strokes, exact.order, exact.reversed))


def test_continuity_follows_the_branch_at_a_crossing():
    # an X crossing cut into four strokes with gaps at the centre: distance alone pairs the ends arbitrarily,
    # continuity pairs each arm with the arm on its own straight line
    arms = [np.array([[-1.0, -1.0], [-0.1, -0.1]]), np.array([[0.12, 0.12], [1.0, 1.0]])]
    arms += [np.array([[-1.0, 1.0], [-0.1, 0.1]]), np.array([[0.11, -0.11], [1.0, -1.0]])]
    tour = order_strokes(arms, method="exact", continuity=1.0)
    position = {stroke: k for k, stroke in enumerate(tour.order)}
    assert abs(position[0] - position[1]) in (1, 3)  # consecutive (cyclically): the diagonal is continued
    assert abs(position[2] - position[3]) in (1, 3)


def test_heuristic_recovers_a_cut_curve_and_is_never_better_than_exact():
    rng = np.random.default_rng(3)
    t = np.linspace(0, 2 * np.pi, 600, endpoint=False)
    curve = np.column_stack([np.cos(t) + 0.3 * np.cos(4 * t), np.sin(t) - 0.3 * np.sin(4 * t)])
    pieces = [curve[i : i + 25] for i in range(0, 600, 30)]  # 20 strokes with gaps
    order = rng.permutation(len(pieces))
    strokes = [pieces[i][::-1] if rng.random() < 0.5 else pieces[i] for i in order]
    exact = order_strokes(strokes, method="exact")
    heuristic = order_strokes(strokes, method="heuristic")
    assert heuristic.cost >= exact.cost - 1e-9
    # the true tour: consecutive pieces, gaps of 5 samples each
    true_gap = sum(np.linalg.norm(curve[(i + 30) % 600] - curve[i + 24]) for i in range(0, 600, 30))
    assert exact.gap_length == pytest.approx(true_gap, rel=0.05)
    assert heuristic.gap_length == pytest.approx(true_gap, rel=0.05)


def test_ordering_errors():
    with pytest.raises(SketchError, match="no strokes"):
        order_strokes([])
    with pytest.raises(SketchError, match="method"):
        order_strokes([np.zeros((2, 2))], method="fast")


def test_spline_fits_closed_noisy_curve():
    rng = np.random.default_rng(0)
    t = np.linspace(0, 2 * np.pi, 300, endpoint=False)
    truth = np.column_stack([np.cos(t), np.sin(t)])
    spline = fit_closed_spline(truth + rng.normal(0, 0.01, truth.shape), smoothing=0.01)
    points = spline.resample(256)
    radius = np.linalg.norm(points, axis=1)
    assert np.abs(radius - 1).max() < 0.04
    steps = np.linalg.norm(np.diff(np.vstack([points, points[:1]]), axis=0), axis=1)
    assert steps.std() / steps.mean() < 0.02  # uniform in arc length, closed


def test_spline_errors():
    with pytest.raises(SketchError, match="at least 4"):
        fit_closed_spline(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 0.0]]))
    with pytest.raises(SketchError, match="smoothing"):
        fit_closed_spline(np.random.default_rng(0).random((20, 2)), smoothing=float("nan"))


def test_resample_closed_spacing():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    points = resample_closed(square, 8)
    assert np.allclose(points[:3], [[0, 0], [0.5, 0], [1, 0]])
