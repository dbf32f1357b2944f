"""WPCA, the invariant-subspace update and slider bounds on synthetic residual functions."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.decomposition import PCA

from design.explore import WPCA, OverConstrainedError, compute_subspace
from design.explore.subspace import align_basis, grid_samples, line_interval


def test_wpca_with_equal_weights_is_pca():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(300, 4)) @ rng.normal(size=(4, 4))
    ours = WPCA().fit(X)
    ref = PCA().fit(X)
    for a, b in zip(ours.components_, ref.components_):
        assert abs(a @ b) == pytest.approx(1.0, abs=1e-8)
    assert ours.explained_variance_ratio_ == pytest.approx(ref.explained_variance_ratio_, rel=1e-8)
    Y = ours.transform(X[:5])
    assert ours.inverse_transform(Y) == pytest.approx(X[:5], abs=1e-9)


def test_wpca_zero_weights_silence_outliers():
    rng = np.random.default_rng(1)
    line = np.outer(rng.normal(size=200), [1.0, 0.0])
    outliers = np.outer(rng.normal(size=20) * 10, [0.0, 1.0])
    X = np.vstack([line, outliers])
    w = np.concatenate([np.ones(200), np.zeros(20)])
    fitted = WPCA(center=np.zeros(2)).fit(X, w)
    assert abs(fitted.components_[0] @ [1.0, 0.0]) == pytest.approx(1.0, abs=1e-12)
    assert fitted.explained_variance_ratio_[1] == pytest.approx(0.0, abs=1e-12)
    assert abs(PCA().fit(X).components_[0] @ [0.0, 1.0]) > 0.9  # unweighted PCA is fooled


def test_grid_adapts_resolution_to_each_feasible_range():
    U = grid_samples(np.array([-1.0, -0.25, -1.0]), np.array([1.0, 0.25, 0.0]), 512)
    counts = [len(np.unique(U[:, k])) for k in range(3)]
    assert counts[0] > counts[2] > counts[1] >= 2
    assert U.min(axis=0) == pytest.approx([-1, -0.25, -1]) and U.max(axis=0) == pytest.approx([1, 0.25, 0])


def _always(U):
    return np.ones(len(U), dtype=bool)


@pytest.mark.parametrize("pull", [True, False])
def test_one_linear_invariant_in_three_dimensions_leaves_its_plane(pull):
    normal = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)

    def residual(U):
        return (U @ normal)[:, None] * 20.0

    sub = compute_subspace(residual, _always, -np.ones(3), np.ones(3), ["demo"], budget=2000, pull=pull)
    assert not sub.redundant
    assert sub.basis.shape == (2, 3)
    assert np.abs(sub.basis @ normal).max() < 0.05
    assert sub.n_good >= 2


def test_curved_invariant_set_is_followed_by_the_scores():
    # Residual zero on the circle |u - c| = |c| through the origin: the tangent at 0 is the y axis.
    c = np.array([2.0, 0.0])

    def residual(U):
        return (np.linalg.norm(U - c, axis=1) - 2.0)[:, None] * 10

    sub = compute_subspace(residual, _always, -np.ones(2), np.ones(2), ["circle"], budget=900)
    assert sub.basis.shape == (1, 2)
    assert abs(sub.basis[0] @ [0.0, 1.0]) > 0.98


def test_as_many_independent_invariants_as_parameters_is_over_constrained():
    def residual(U):
        return U * 10.0

    with pytest.raises(OverConstrainedError, match=r"position:3.*angle:7") as info:
        compute_subspace(residual, _always, -np.ones(2), np.ones(2), ["position:3", "angle:7"])
    assert info.value.invariants == ("position:3", "angle:7")


def test_redundant_invariants_keep_the_base_parameters():
    def residual(U):
        return np.zeros((len(U), 1))

    sub = compute_subspace(residual, _always, -np.ones(3), np.ones(3), ["radial:0"])
    assert sub.redundant
    assert sub.basis == pytest.approx(np.eye(3))


def test_lost_pois_score_zero_and_do_not_shape_the_basis():
    def residual(U):
        r = (U[:, 0] * 10.0)[:, None]
        r[U[:, 1] > 0.5] = np.nan  # PoI lost there
        return r

    sub = compute_subspace(residual, _always, -np.ones(2), np.ones(2), ["x"], budget=400)
    assert sub.basis.shape == (1, 2)
    assert abs(sub.basis[0, 1]) > 0.99


def test_temporal_consistency_flips_and_rotates_back_towards_the_previous_basis():
    old = np.eye(3)[:2]
    flipped = np.array([[-1.0, 0, 0], [0, 1.0, 0]])
    assert align_basis(flipped, old) == pytest.approx(old)
    angle = 0.7
    rotated = np.array([[np.cos(angle), np.sin(angle), 0], [-np.sin(angle), np.cos(angle), 0]])
    assert align_basis(rotated, old) == pytest.approx(old, abs=1e-12)
    # A different dimension: only signs are fixed, pairwise.
    new = np.array([[0.0, -1.0, 0.0]])
    assert align_basis(new, np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])) == pytest.approx(np.array([[0.0, 1.0, 0.0]]))


def test_slider_bounds_are_the_feasible_run_within_plus_minus_two():
    def inside_disc(U):
        return np.linalg.norm(U - [0.3, 0.0], axis=1) < 1.0

    lo, hi = line_interval(inside_disc, np.zeros(2), np.array([1.0, 0.0]), 0.0)
    assert lo == pytest.approx(-0.7, abs=1e-3) and hi == pytest.approx(1.3, abs=1e-3)
    assert inside_disc(np.array([[lo, 0.0], [hi, 0.0]])).all()
    lo, hi = line_interval(_always, np.zeros(2), np.array([0.0, 1.0]), 0.5)
    assert (lo, hi) == (-2.0, 2.0)
