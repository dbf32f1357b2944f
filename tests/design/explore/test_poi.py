"""PoI detection and tracking on synthetic curves (no machine model needed)."""

from __future__ import annotations

import numpy as np
import pytest

from design.errors import ParameterError
from design.explore import poi, tracking


def hypotrochoid(big_r: int, r: int, d: float, n: int, rng=None) -> tuple[np.ndarray, np.ndarray]:
    """A closed hypotrochoid (Spirograph curve) and its times; random increasing times when ``rng`` is given."""
    period = 2 * np.pi * r / np.gcd(big_r, r)
    if rng is None:
        t = np.linspace(0.0, period, n + 1)
    else:
        t = np.sort(np.concatenate([[0.0, period], rng.uniform(0, period, n - 1)]))
    k = (big_r - r) / r
    xy = np.column_stack([(big_r - r) * np.cos(t) + d * np.cos(k * t), (big_r - r) * np.sin(t) - d * np.sin(k * t)])
    xy[-1] = xy[0]
    return xy, t


def brute_force_crossings(points: np.ndarray) -> int:
    """All-pairs reference (test oracle only)."""
    p, e = points[:-1], points[1:]
    m = len(p)
    r = e - p
    i, j = np.triu_indices(m, 2)
    keep = ~((i == 0) & (j == m - 1))
    i, j = i[keep], j[keep]
    den = r[i, 0] * r[j, 1] - r[i, 1] * r[j, 0]
    qp = p[j] - p[i]
    with np.errstate(all="ignore"):
        u = (qp[:, 0] * r[j, 1] - qp[:, 1] * r[j, 0]) / den
        v = (qp[:, 0] * r[i, 1] - qp[:, 1] * r[i, 0]) / den
    return int(np.sum((np.abs(den) > 1e-12) & (u >= 0) & (u < 1) & (v >= 0) & (v < 1)))


def test_circle_has_no_curvature_maximum_even_with_uneven_sampling():
    rng = np.random.default_rng(0)
    t = np.sort(rng.uniform(0, 2 * np.pi, 3000))
    circle = np.column_stack([3 * np.cos(t), 3 * np.sin(t)])
    assert poi.detect_curvature_maxima(circle) == []
    assert poi.detect_self_intersections(circle) == []


def test_ellipse_has_two_maxima_at_the_major_axis_ends_with_the_right_curvature():
    rng = np.random.default_rng(1)
    t = np.sort(rng.uniform(0, 2 * np.pi, 4000))
    ellipse = np.column_stack([2 * np.cos(t), np.sin(t)])
    found = poi.detect_curvature_maxima(ellipse, t)
    assert len(found) == 2
    xs = sorted(p.xy[0] for p in found)
    assert xs == pytest.approx([-2, 2], abs=2e-3)
    for p in found:
        assert p.kind == poi.CURVATURE
        assert p.curvature == pytest.approx(2.0, rel=0.01)  # a / b^2
        assert np.cos(p.times[0]) == pytest.approx(np.sign(p.xy[0]), abs=1e-4)


def test_figure_eight_crossing_position_angle_and_both_arclengths():
    t = np.linspace(0, 2 * np.pi, 2001)
    gerono = np.column_stack([np.sin(t), np.sin(t) * np.cos(t)])  # crosses itself at the origin at 90 degrees
    found = poi.detect_self_intersections(gerono, t)
    assert len(found) == 1
    (x,) = found
    assert x.kind == poi.INTERSECTION
    assert x.xy == pytest.approx((0, 0), abs=1e-9)
    assert np.degrees(x.angle) == pytest.approx(90.0, abs=0.05)
    assert x.times == pytest.approx((np.pi, 2 * np.pi), abs=1e-6) or x.times == pytest.approx((0, np.pi), abs=1e-6)
    assert x.relative_arclength[1] - x.relative_arclength[0] == pytest.approx(0.5, abs=1e-6)


@pytest.mark.parametrize(("big_r", "r", "d"), [(5, 3, 2.0), (7, 3, 4.5), (9, 4, 1.0), (8, 3, 3.0)])
def test_strtree_crossings_match_the_all_pairs_oracle(big_r, r, d):
    xy, _ = hypotrochoid(big_r, r, d, 700)
    i, j, u, v = poi.segment_crossings(xy)
    assert len(i) == brute_force_crossings(xy)
    # Every crossing pair is reported once, with i < j and non-adjacent segments.
    assert np.all(j - i > 1)
    assert len(set(zip(i.tolist(), j.tolist()))) == len(i)


def test_hypotrochoid_pois_follow_its_rotational_symmetry():
    rng = np.random.default_rng(2)
    xy, t = hypotrochoid(7, 3, 2.0, 6000, rng)
    pois = poi.detect_pois(xy, t)
    maxima = [p for p in pois if p.kind == poi.CURVATURE]
    crossings = [p for p in pois if p.kind == poi.INTERSECTION]
    assert len(maxima) % 7 == 0 and maxima
    assert len(crossings) % 7 == 0 and crossings
    assert [p.id for p in pois] == list(range(len(pois)))
    # Rotating every maximum by 2 pi / 7 lands on another maximum.
    pts = np.array([p.xy for p in maxima])
    c, s = np.cos(2 * np.pi / 7), np.sin(2 * np.pi / 7)
    rotated = pts @ np.array([[c, s], [-s, c]])
    nearest = np.min(np.hypot(*(rotated[:, None, :] - pts[None, :, :]).transpose(2, 0, 1)), axis=1)
    assert nearest.max() < 0.02
    # The curvature at every maximum is the same (symmetry), to the discretization's precision.
    kappas = np.array([p.curvature for p in maxima])
    assert np.ptp(kappas) / kappas.mean() < 0.01


def test_bad_curves_are_refused_with_the_shape_named():
    with pytest.raises(ParameterError, match=r"\(n, 2\)"):
        poi.detect_pois(np.zeros((10, 3)))
    with pytest.raises(ParameterError, match="non-finite"):
        poi.detect_pois(np.array([[0, 0], [1, 0], [np.nan, 1], [0, 1], [0, 0]], dtype=float))
    with pytest.raises(ParameterError, match="times"):
        poi.detect_pois(np.random.default_rng(0).normal(size=(10, 2)), times=np.arange(4))
    with pytest.raises(ParameterError, match="kinds"):
        poi.detect_pois(np.random.default_rng(0).normal(size=(10, 2)), kinds=("cusp",))


def test_tracking_by_arclength_follows_each_poi_to_a_nearby_design():
    a, ta = hypotrochoid(7, 3, 2.0, 5000)
    b, tb = hypotrochoid(7, 3, 2.1, 5000)
    pois_a, pois_b = poi.detect_pois(a, ta), poi.detect_pois(b, tb)
    for ref in pois_a:
        result = tracking.track_poi(ref, pois_b, sigma_poi=0.5)
        assert not result.lost, result.reason
        assert result.match.kind == ref.kind
        # Same PoI: same parameter time(s), up to the small shift a 5 % change of d makes.
        assert np.abs(np.subtract(sorted(result.match.times), sorted(ref.times))).max() < 0.1


def test_tracking_prefers_arclength_over_a_closer_overlapping_poi():
    # Two crossings at almost the same place but at different arc lengths: position alone would pick the wrong one.
    ref = poi.PointOfInterest(0, poi.INTERSECTION, (0.0, 0.0), (10.0, 60.0), 100.0, angle=0.5)
    impostor = poi.PointOfInterest(0, poi.INTERSECTION, (0.001, 0.0), (30.0, 80.0), 100.0, angle=0.5)
    right = poi.PointOfInterest(1, poi.INTERSECTION, (0.05, 0.0), (10.5, 60.2), 100.0, angle=0.5)
    result = tracking.track_poi(ref, [impostor, right], sigma_poi=0.2)
    assert result.match is right


def test_a_poi_that_disappears_is_reported_lost_not_swapped():
    ref = poi.PointOfInterest(0, poi.CURVATURE, (1.0, 0.0), (10.0,), 100.0, curvature=3.0)
    far = poi.PointOfInterest(0, poi.CURVATURE, (1.0, 0.1), (40.0,), 100.0, curvature=3.0)
    result = tracking.track_poi(ref, [far], sigma_poi=0.5)
    assert result.lost and "arc length" in result.reason
    moved = poi.PointOfInterest(0, poi.CURVATURE, (3.0, 0.0), (10.2,), 100.0, curvature=3.0)
    result = tracking.track_poi(ref, [moved], sigma_poi=0.5)
    assert result.lost and "sigma_PoI" in result.reason
    assert tracking.track_poi(ref, [], sigma_poi=0.5).lost
    crossing = poi.PointOfInterest(0, poi.INTERSECTION, (1.0, 0.0), (10.0, 50.0), 100.0, angle=1.0)
    assert tracking.track_poi(ref, [crossing], sigma_poi=0.5).lost  # another type never matches


def test_seam_is_handled_arclengths_wrap_around():
    ref = poi.PointOfInterest(0, poi.CURVATURE, (1.0, 0.0), (99.8,), 100.0, curvature=3.0)
    across = poi.PointOfInterest(0, poi.CURVATURE, (1.0, 0.01), (0.1,), 100.0, curvature=3.0)
    assert tracking.track_poi(ref, [across], sigma_poi=0.5).match is across
