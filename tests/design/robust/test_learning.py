"""PSP learning on synthetic scenarios with known success regions: classifiers, calibration, factorization."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.metrics import roc_auc_score

from design.robust import CalibratedSVM, FactorizedPSP, PSPSettings, RobustError, explore, synthetic_chain
from design.robust.psp import fit_platt
from design.robust.sampling import sobol_valid, valid_in_ball

SMALL = PSPSettings(n_initial=160, n_successes=40, max_exploration_steps=20)


def disc_data(n=300, seed=0):
    rng = np.random.default_rng(seed)
    X = rng.random((n, 2))
    y = np.linalg.norm(X - [0.5, 0.5], axis=1) < 0.3
    return X, y


def test_calibrated_svm_separates_a_disc_and_ranks_probabilities():
    X, y = disc_data()
    model = CalibratedSVM(random_state=0).fit(X, y)
    assert model.cv_accuracy_ > 0.9
    assert set(model.best_params_) == {"C", "gamma"}
    points = np.array([[0.5, 0.5], [0.5, 0.75], [0.5, 0.95], [0.05, 0.05]])
    p = model.success_probability(points)
    assert np.all((p >= 0) & (p <= 1))
    assert p[0] > 0.8 and p[-1] < 0.2
    assert p[0] >= p[1] > p[2]  # deeper inside ranks higher
    proba = model.predict_proba(points)
    np.testing.assert_allclose(proba.sum(axis=1), 1.0)
    # Platt is fitted once, after the search: a < 0 means higher scores give higher probabilities.
    assert model.platt_[0] < 0


def test_classifier_with_too_few_of_one_class_predicts_a_constant():
    X, y = disc_data(40)
    y[:] = False
    y[:2] = True
    model = CalibratedSVM(cv_folds=3).fit(X, y)
    assert model.constant_ == pytest.approx(3 / 42)
    np.testing.assert_allclose(model.success_probability(X[:5]), 3 / 42)


def test_classifier_rejects_mismatched_input():
    with pytest.raises(RobustError, match="one label per row"):
        CalibratedSVM().fit(np.zeros((5, 2)), np.zeros(4, dtype=bool))


def test_platt_fit_is_monotone_and_bounded():
    rng = np.random.default_rng(1)
    scores = rng.normal(size=400)
    labels = rng.random(400) < 1 / (1 + np.exp(-3 * scores))
    a, b = fit_platt(scores, labels)
    assert a < 0
    p = 1 / (1 + np.exp(a * np.array([-2.0, 0.0, 2.0]) + b))
    assert p[0] < p[1] < p[2]


def test_exploration_finds_successes_and_respects_its_cap():
    problem = synthetic_chain()
    samples = explore(problem, problem.simulate_batch, SMALL, seed=3, max_simulations=200)
    assert len(samples.U) <= 200
    assert problem.is_valid(samples.U).all()
    assert samples.success.sum() >= 20


def test_exploration_moves_towards_partial_successes():
    # A tiny success region far from most Sobol points: adaptive steps must sample around partial successes.
    problem = synthetic_chain()
    settings = PSPSettings(n_initial=32, n_successes=200, max_exploration_steps=15)
    samples = explore(problem, problem.simulate_batch, settings, seed=0)
    later = samples.events[32:]
    first = samples.events[:32]
    assert later.sum(axis=1).mean() > first.sum(axis=1).mean()


def test_factorized_psp_learns_the_known_regions():
    problem = synthetic_chain()
    samples = explore(problem, problem.simulate_batch, SMALL, seed=0, max_simulations=200)
    psp = FactorizedPSP(SMALL, random_state=0).fit(problem, samples, problem.simulate_batch)
    by_event = {m.event: m for m in psp.models_}
    # start and last always follow their parents: no classifier (quasi-deterministic).
    assert by_event["start"].quasi_deterministic and by_event["last"].quasi_deterministic
    assert not by_event["first"].quasi_deterministic
    # "second" depends on roll only; "first" on x (and maybe z), never on roll.
    assert by_event["second"].subspace == (2,)
    assert 0 in by_event["first"].subspace and 2 not in by_event["first"].subspace
    test = sobol_valid(problem, 512, seed=99)
    truth = problem.simulate_batch(test).all(axis=1)
    p = psp.predict_proba(test)
    assert np.all((p >= 0) & (p <= 1))
    assert roc_auc_score(truth, p) > 0.9
    centre, outside = np.array([[0.35, 0.5, 0.6]]), np.array([[0.95, 0.1, 0.05]])
    assert psp.predict_proba(centre)[0] > 0.6 > 0.1 > psp.predict_proba(outside)[0]


def test_global_psp_without_factorization():
    problem = synthetic_chain()
    settings = SMALL.with_changes(factorize=False)
    samples = explore(problem, problem.simulate_batch, settings, seed=1, max_simulations=200)
    psp = FactorizedPSP(settings, random_state=1).fit(problem, samples)
    assert [m.event for m in psp.models_] == ["global success"]
    test = sobol_valid(problem, 256, seed=5)
    assert roc_auc_score(problem.simulate_batch(test).all(axis=1), psp.predict_proba(test)) > 0.85


def test_settings_validation_names_the_setting():
    with pytest.raises(RobustError, match="n_initial"):
        PSPSettings(n_initial=0)
    with pytest.raises(RobustError, match="target_accuracy"):
        PSPSettings(target_accuracy=1.5)
    with pytest.raises(RobustError, match="unknown setting"):
        PSPSettings().with_changes(sigma=3)


@pytest.mark.parametrize(("data", "message"), [
    ({"n_initial": 1.5}, "S: n_initial must be an integer, got 1.5"),
    ({"factorize": "no"}, "S: factorize must be true or false, got 'no'"),
    ({"smooth_min_alpha": None}, "S: smooth_min_alpha must be a number, got None"),
    ({"gamma_grid": 0.1}, "S: gamma_grid must be a list of numbers, got 0.1"),
    ({"cv_scoring": 3}, "S: cv_scoring must be a string, got 3"),
    ({"target_accuracy": 2}, "S: target_accuracy must be in (0, 1], got 2"),
    ({"sigma": 3}, "S: unknown setting(s) ['sigma']"),
    ([1, 2], "S: expected a table of settings, got list"),
])
def test_settings_from_a_mapping_name_the_bad_field(data, message):
    with pytest.raises(RobustError) as error:
        PSPSettings.from_mapping(data, "S")
    assert str(error.value).startswith(message)


def test_settings_round_trip_through_json():
    import json
    from dataclasses import asdict

    for settings in (PSPSettings(), PSPSettings.recommended(c_grid=(1.0, 10.0), placement_error=0.1)):
        assert PSPSettings.from_mapping(json.loads(json.dumps(asdict(settings)))) == settings
    assert PSPSettings.from_mapping({"smooth_min_alpha": 5}) == PSPSettings(smooth_min_alpha=5)  # an int is a number


def concentrated_samples(problem, n_initial=128, n_explored=2000, seed=0):
    """A uniform Sobol start, then many layouts where ``second`` always succeeds (as a mixture around successes)."""
    from design.robust.psp import Samples

    U0 = sobol_valid(problem, n_initial, seed=seed)
    rng = np.random.default_rng(seed)
    U1 = np.column_stack([
        0.35 + 0.05 * rng.standard_normal(n_explored),
        0.5 + 0.05 * rng.standard_normal(n_explored),
        rng.uniform(0.5, 0.7, n_explored),
    ])
    U = np.concatenate([U0, U1])
    return Samples(U, problem.simulate_batch(U), n_initial=n_initial)


def test_quasi_deterministic_test_on_the_uniform_start_sees_through_concentrated_exploration():
    problem = synthetic_chain()
    samples = concentrated_samples(problem)
    second = list(problem.event_names).index("second")
    first = list(problem.event_names).index("first")
    initial = samples.events[:128]
    assert 0.3 < initial[initial[:, first], second].mean() < 0.7  # half the roll interval fails...
    assert samples.events[samples.events[:, first], second].mean() > 0.95  # ...but hardly ever where explored
    thesis = FactorizedPSP(PSPSettings(), random_state=0).fit(problem, samples)
    ours = FactorizedPSP(PSPSettings(quasi_deterministic_sample="initial"), random_state=0).fit(problem, samples)
    assert {m.event: m.quasi_deterministic for m in thesis.models_}["second"]
    by_event = {m.event: m for m in ours.models_}
    assert not by_event["second"].quasi_deterministic and by_event["second"].subspace == (2,)
    assert by_event["start"].quasi_deterministic and by_event["last"].quasi_deterministic
    # Too few uniform rows whose parents succeeded: the test falls back to every explored row.
    strict = PSPSettings(quasi_deterministic_sample="initial", quasi_deterministic_min_rows=1000)
    fallback = FactorizedPSP(strict, random_state=0).fit(problem, samples)
    assert {m.event: m.quasi_deterministic for m in fallback.models_}["second"]


def test_quasi_deterministic_settings_are_checked():
    with pytest.raises(RobustError, match="quasi_deterministic_sample"):
        PSPSettings(quasi_deterministic_sample="sobol")
    with pytest.raises(RobustError, match="quasi_deterministic_min_rows"):
        PSPSettings(quasi_deterministic_min_rows=0)
    with pytest.raises(RobustError, match="optimizer_starts"):
        PSPSettings(optimizer_starts=0)


def test_roc_auc_search_ranks_a_rare_failure_region_and_still_reports_accuracy():
    # A failure region on a fifth of the range that fails 60 % of the time: about 12 % failures overall.
    rng = np.random.default_rng(2)
    X = rng.random((500, 1))
    y = ~((X[:, 0] < 0.2) & (rng.random(500) < 0.6))
    model = CalibratedSVM(random_state=0, scoring="roc_auc").fit(X, y)
    assert model.cv_score_ > 0.9  # the search's score is the AUC...
    assert 0.8 < model.cv_accuracy_ < 0.95  # ...and the accuracy of the same C, γ is kept for the stopping rule
    p = model.success_probability(np.array([[0.1], [0.6]]))
    assert p[0] < 0.6 < 0.9 < p[1]
    with pytest.raises(RobustError, match="cv_scoring"):
        PSPSettings(cv_scoring="f1")


def test_valid_in_ball_draws_in_the_ball_or_ellipsoid_and_is_empty_where_nothing_is_valid():
    problem = synthetic_chain()
    centre = np.full(problem.dim, 0.5)
    rng = np.random.default_rng(0)
    ball = valid_in_ball(problem, centre, 0.1, 50, rng)
    assert ball.shape == (50, problem.dim)
    assert np.all(np.linalg.norm(ball - centre, axis=1) <= 0.1 + 1e-12)
    assert problem.is_valid(ball).all()
    radius = np.zeros(problem.dim)
    radius[0] = 0.2
    ellipsoid = valid_in_ball(problem, centre, radius, 20, rng)
    assert np.all(np.abs(ellipsoid[:, 0] - 0.5) <= 0.2 + 1e-12)
    np.testing.assert_array_equal(ellipsoid[:, 1:], 0.5)  # a zero radius pins that parameter
    assert len(valid_in_ball(problem, centre, 0.1, 0, rng)) == 0
    # Wholly outside the design space: nothing valid, an empty result rather than an error.
    outside = valid_in_ball(problem, np.full(problem.dim, 3.0), 0.1, 5, rng)
    assert outside.shape == (0, problem.dim)


def test_valid_in_ball_lets_a_broken_validity_check_raise():
    # Only "too few valid layouts" means an empty ball; any other error is a bug and must not read as robustness 0.
    problem = synthetic_chain()

    class Broken:
        dim = problem.dim
        name = problem.name

        def is_valid(self, U):
            raise ValueError("broken constraint")

    with pytest.raises(ValueError, match="broken constraint"):
        valid_in_ball(Broken(), np.full(problem.dim, 0.5), 0.1, 5, np.random.default_rng(0))
