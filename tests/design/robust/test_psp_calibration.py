"""Honest success probabilities: calibration measured on held-out simulations, and what makes it.

The fast version of bench/bench_psp_calibration.py: the tilted plank (tests/data/robust/tilted_plank.toml, a scenario
nobody tuned on, quick to simulate) at a budget where the settings without the probability calibration say "PSP 0.5"
at the steep end of the range, where the block always slides.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from bench.bench_psp_calibration import UNCALIBRATED as UNCALIBRATED_CHANGES
from design.robust import CalibratedSVM, PSPSettings, SimulationExecutor, optimize_robust_layout
from design.robust.contraption import load_problem
from design.robust.plot import plot_reliability
from design.robust.reliability import held_out_layouts, psp_reliability, reliability

TILTED_PLANK = Path(__file__).resolve().parents[2] / "data" / "robust" / "tilted_plank.toml"


def test_reliability_scores_are_the_textbook_ones():
    p = np.array([0.0, 0.1, 0.15, 0.9, 0.95, 1.0])
    y = np.array([False, False, True, True, True, False])
    score = reliability("e", p, y, bins=10)
    assert score.n == 6
    assert score.brier == pytest.approx(np.mean((p - y) ** 2))
    assert score.reference_brier == pytest.approx(0.5 * 0.5)
    # bins [0, 0.1): 0.0; [0.1, 0.2): 0.1, 0.15; [0.9, 1.0]: 0.9, 0.95, 1.0 (the last bin is closed)
    assert score.counts.tolist() == [1, 2, 0, 0, 0, 0, 0, 0, 0, 3]
    assert score.observed[1] == pytest.approx(0.5) and score.observed[9] == pytest.approx(2 / 3)
    assert score.predicted[9] == pytest.approx(0.95)
    expected_ece = (1 * 0.0 + 2 * abs(0.125 - 0.5) + 3 * abs(0.95 - 2 / 3)) / 6
    assert score.ece == pytest.approx(expected_ece)
    # A model that says 1 and is wrong pays a large but finite log loss.
    assert np.isfinite(score.log_loss) and score.log_loss > 5
    empty = reliability("e", [], [])
    assert empty.n == 0 and np.isnan(empty.brier)


def test_calibrated_search_does_not_pick_a_flat_setting_that_ranks_each_fold():
    """One parameter, success above a threshold, as the tilted plank: the per-fold ROC AUC of the most regularized
    setting (C 0.1, γ 0.01) is 1, yet its pooled out-of-fold values carry nothing and Platt says ~0.5 everywhere."""
    rng = np.random.default_rng(3)
    X = np.concatenate([rng.random((40, 1)), 0.47 + 0.05 * rng.standard_normal((40, 1))])
    y = X[:, 0] > 0.47
    ends = np.array([[0.0], [1.0]])
    auc = CalibratedSVM(random_state=0, scoring="roc_auc").fit(X, y)
    ours = CalibratedSVM(random_state=0, scoring="calibrated_log_loss").fit(X, y)
    assert ours.best_params_ != {"C": 0.1, "gamma": 0.01}
    p = ours.success_probability(ends)
    assert p[0] < 0.1 and p[1] > 0.9
    assert ours.cv_score_ > -0.3  # the pooled log loss of the chosen setting, in nats
    # The ROC AUC search keeps the first of its tied settings: what made the PSP dishonest.
    assert auc.best_params_ == {"C": 0.1, "gamma": 0.01}


@pytest.fixture(scope="module")
def plank():
    problem = load_problem(TILTED_PLANK)
    executor = SimulationExecutor(problem, backend="inline", cache_path=None)
    yield problem, executor
    executor.close()


def test_tilted_plank_success_region_is_the_steep_end(plank):
    problem, executor = plank
    angles = np.array([[5.0], [15.0], [30.0], [44.0]])
    success = executor.run(problem.to_normalized(angles)).all(axis=1)
    assert success.tolist() == [False, False, True, True]


#: The recommended settings without their probability calibration (the bench's "uncalibrated").
UNCALIBRATED = PSPSettings.recommended(**UNCALIBRATED_CHANGES)


def test_tilted_plank_psp_is_calibrated_on_held_out_simulations(plank, tmp_path):
    problem, executor = plank
    layout = optimize_robust_layout(problem, executor, budget=100, seed=0, settings=PSPSettings.recommended())
    U, groups = held_out_layouts(problem, 96, seed=2020, centre=layout.u, n_near=32)
    assert len(U) == 128 and (groups == "uniform").sum() == 96
    events = executor.run(U)
    scores = psp_reliability(layout.model, U, events)
    whole = scores[-1]
    assert whole.name == "success" and whole.n == len(U)
    assert [s.name for s in scores[:-1]] == list(problem.event_names)
    assert layout.simulated_success and layout.psp > 0.9
    assert whole.brier < 0.05 < whole.reference_brier
    assert whole.ece < 0.1
    near = np.array([g != "uniform" for g in groups])
    assert events[near].all(axis=1).mean() > 0.95  # the layout's neighbourhood succeeds...
    assert layout.model.predict_proba(U[near]).mean() > 0.9  # ...and the model says so

    # The same run without the calibration: a coin toss where the block always slides.
    uncalibrated = optimize_robust_layout(problem, executor, budget=100, seed=0, settings=UNCALIBRATED)
    assert uncalibrated.simulated_success and uncalibrated.psp < 0.6
    old = psp_reliability(uncalibrated.model, U, events)[-1]
    assert old.brier > old.reference_brier > whole.brier
    picture = plot_reliability({problem.name: {"uncalibrated": old, "recommended": whole}}, tmp_path / "r.png",
                               columns=2)
    with Image.open(picture) as image:
        assert image.size == (500, 36 + 250 + 26)
        assert len(image.getcolors(1 << 16)) > 10  # curves and text were drawn, not a blank canvas


class Agree:
    """Three parameters; the event happens when the first two are on the same side of 0.5 and the third is above
    0.3: each of the first two alone says nothing about it (mutual information 0), only together."""

    name = "AGREE"
    parameter_names = ("a", "b", "c")
    lower, upper = np.zeros(3), np.ones(3)
    dim = 3
    event_names = ("matches",)
    event_parents = {"matches": ()}

    @staticmethod
    def simulate_batch(U):
        return (((U[:, 0] > 0.5) == (U[:, 1] > 0.5)) & (U[:, 2] > 0.3))[:, None]

    @staticmethod
    def is_valid(U):
        return np.ones(len(np.atleast_2d(U)), dtype=bool)


def test_subspace_check_keeps_the_parameters_an_event_needs_together():
    from design.robust.psp import FactorizedPSP, Samples
    from design.robust.sampling import sobol_valid

    problem = Agree()
    U = sobol_valid(problem, 256, seed=4)
    samples = Samples(U, problem.simulate_batch(U), n_initial=len(U))
    held_out = np.random.default_rng(5).random((400, 3))
    truth = problem.simulate_batch(held_out)
    briers, subspaces = {}, {}
    for check in (False, True):
        settings = PSPSettings.recommended(subspace_check=check, mutual_information_threshold=0.2)
        psp = FactorizedPSP(settings, random_state=0).fit(problem, samples)
        briers[check] = psp_reliability(psp, held_out, truth)[-1].brier
        subspaces[check] = psp.models_[0].subspace
    assert subspaces == {False: (2,), True: (0, 1, 2)}  # mutual information kept the third parameter only
    assert briers[True] < 0.5 * briers[False]
