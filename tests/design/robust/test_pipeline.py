"""Optimization, robustness, baselines, executor backends and cache, on synthetic scenarios."""

from __future__ import annotations

import numpy as np
import pytest

from common.progress import Cancelled, Reporter
from design.robust import (
    FactorizedPSP,
    PSPSettings,
    RobustError,
    RobustnessSettings,
    SimulationCache,
    SimulationExecutor,
    baseline_b1,
    baseline_b2,
    baseline_b3,
    compare_methods,
    explore,
    optimize_layout,
    optimize_robust_layout,
    robustness_curve,
    smooth_minimum,
    synthetic_branching,
    synthetic_chain,
)
from design.robust.executor import _process_gone, cache_scope
from design.robust.optimize import energy, placement_offsets
from design.robust.pipeline import plan_budget, verify_candidates
from design.robust.problem import EllipsoidEvent, SyntheticProblem
from design.robust.robustness import (
    EvaluationSet,
    ball_means,
    densest_successes,
    epsilon_grid,
    estimated_global_robustness,
    evaluation_set,
    local_robustness_from_points,
    predicted_global_robustness,
)
from design.robust.sampling import sobol_valid

SMALL = PSPSettings(n_initial=128, n_successes=40, max_exploration_steps=20)


def test_smooth_minimum_goes_from_mean_to_minimum():
    z = np.array([0.2, 0.9, 0.7])
    assert smooth_minimum(z, 1e-9) == pytest.approx(z.mean())
    assert smooth_minimum(z, 200.0) == pytest.approx(0.2, abs=1e-3)
    assert 0.2 < smooth_minimum(z, 10.0) < z.mean()


class CornerPSP:
    """A PSP of one learned factor: 1 on the whole square x + y >= 1.2 (its corner (1, 1) included), else 0.2."""

    learned_factors = [0]

    def factor_probabilities(self, U):
        U = np.atleast_2d(U)
        return np.where(U.sum(axis=1) >= 1.2, 1.0, 0.2)[:, None]


def test_placement_error_energy_is_the_mean_over_clipped_offsets():
    offsets = placement_offsets(2, 0.1, 32, seed=3)
    assert offsets.shape == (32, 2) and np.all(np.abs(offsets) <= 0.1) and np.all(offsets[0] == 0)
    assert np.array_equal(offsets, placement_offsets(2, 0.1, 32, seed=3))
    assert placement_offsets(2, 0.0, 32) is None
    psp = CornerPSP()
    u = np.array([0.95, 0.28])
    points = np.clip(u + offsets, 0, 1)
    expected = -np.mean(np.where(points.sum(axis=1) >= 1.2, 1.0, 0.2))
    assert energy(psp, u, 10.0, offsets) == pytest.approx(expected)
    assert energy(psp, u, 10.0) == -1.0  # at the point itself the PSP cannot tell it from the interior
    # Under a placement error, the layout on the edge of the success region scores worse than one inside it.
    assert energy(psp, np.array([0.8, 0.8]), 10.0, offsets) < energy(psp, u, 10.0, offsets)
    with pytest.raises(RobustError, match="placement_error"):
        PSPSettings(placement_error=0.7)
    with pytest.raises(RobustError, match="placement_samples"):
        PSPSettings(placement_samples=0)


def test_pipeline_with_a_placement_error_returns_a_valid_success():
    problem = synthetic_chain()
    settings = PSPSettings(n_initial=128, n_successes=40, max_exploration_steps=20, placement_error=0.1,
                           placement_samples=16)
    with SimulationExecutor(problem, backend="inline") as executor:
        result = optimize_robust_layout(problem, executor, budget=250, seed=2, settings=settings)
    assert problem.is_valid(result.u[None, :])[0] and result.simulated_success
    assert np.linalg.norm((result.u[:2] - [0.35, 0.5]) / [0.25, 0.3]) < 1


def test_more_optimizer_starts_never_end_at_a_higher_energy():
    problem = synthetic_branching()
    single = SMALL.with_changes(placement_error=0.1, placement_samples=16)
    results = {}
    for starts in (1, 4):
        with SimulationExecutor(problem, backend="inline") as executor:
            results[starts] = optimize_robust_layout(problem, executor, budget=250, seed=1,
                                                     settings=single.with_changes(optimizer_starts=starts))
    assert results[4].optimizer["energy"] <= results[1].optimizer["energy"] + 1e-12
    assert results[1].optimizer["start_sample"] == int(np.flatnonzero(
        (results[1].model.samples_.U == results[1].u_best_sample).all(axis=1))[0])
    for result in results.values():
        assert problem.is_valid(result.u[None, :])[0]


def test_predicted_global_robustness_is_the_evaluation_formula_with_probabilities():
    rng = np.random.default_rng(0)
    reference = rng.random((500, 3))
    success = rng.random(500) < 0.4
    candidates = rng.random((6, 3))
    candidate_success = np.array([1, 0, 1, 0, 1, 1], dtype=bool)
    settings = RobustnessSettings(n_local=1)
    predicted = predicted_global_robustness(candidates, candidate_success.astype(float), reference,
                                            success.astype(float), settings)
    epsilon = epsilon_grid(settings)
    for i, u in enumerate(candidates):
        # One local layout in B_η(u): u itself with its own outcome.
        rho = local_robustness_from_points(u, np.vstack([reference, u]), np.r_[success, candidate_success[i]],
                                           epsilon, settings.thickness_factor * settings.epsilon_step)
        assert predicted[i] == pytest.approx(np.trapezoid(rho, epsilon))


def test_global_robustness_objective_finds_the_centre_of_the_success_region():
    problem = synthetic_chain()
    settings = SMALL.with_changes(objective="global_robustness", reference_layouts=512, candidate_layouts=512)
    with SimulationExecutor(problem, backend="inline") as executor:
        result = optimize_robust_layout(problem, executor, budget=250, seed=0, settings=settings)
        point = optimize_robust_layout(problem, executor, budget=250, seed=0, settings=SMALL)
    assert problem.is_valid(result.u[None, :])[0] and result.simulated_success
    assert result.optimizer["predicted_rho_g"] >= result.optimizer["predicted_rho_g_best_sample"]
    # Parameters outside every event's subspace keep the best sample's values; the others move inside the region.
    free = [problem.parameter_names.index(name) for name in result.optimizer["free_parameters"]]
    fixed = [i for i in range(problem.dim) if i not in free]
    np.testing.assert_array_equal(result.u[fixed], result.u_best_sample[fixed])
    centre, radii = np.array([0.35, 0.5, 0.6]), np.array([0.25, 0.3, 0.25])
    assert {0, 2} <= set(free) and np.linalg.norm(((result.u - centre) / radii)[free]) < 0.7
    robustness = RobustnessSettings(n_evaluation=512, n_local=10)
    with SimulationExecutor(problem, backend="inline") as executor:
        evaluation = evaluation_set(problem, executor.run, robustness.n_evaluation)
        ours = robustness_curve(problem, executor.run, evaluation, result.u, robustness).global_robustness
        thesis = robustness_curve(problem, executor.run, evaluation, point.u, robustness).global_robustness
    assert ours >= thesis - 0.02
    with pytest.raises(RobustError, match="objective"):
        PSPSettings(objective="robust")


def test_verification_keeps_the_candidate_that_does_best_in_simulation():
    problem = synthetic_chain()
    centre = np.array([0.35, 0.5, 0.6])
    edge = np.array([0.35, 0.5, 0.6 + 0.245])  # succeeds itself, but about half its ball leaves the roll interval
    outside = np.array([0.35, 0.5, 0.95])
    settings = PSPSettings(verification_candidates=3, verification_samples=20, verification_radius=0.05)
    u, events, report = verify_candidates(problem, problem.simulate_batch, [edge, outside, edge + 0.01, centre],
                                          settings, seed=0)
    np.testing.assert_array_equal(u, centre)
    assert events.all()
    # edge + 0.01 is closer than the radius to edge: not a distinct candidate, so centre is the third.
    assert [r["u"] for r in report] == [list(edge), list(outside), list(centre)]
    assert [r["success"] for r in report] == [True, False, True]
    assert report[2]["local_success_rate"] == 1.0 > report[0]["local_success_rate"] > 0.2
    assert report[1]["simulations"] == 20
    # One candidate and one sample: the thesis's single re-simulation.
    u, events, report = verify_candidates(problem, problem.simulate_batch, [outside, centre], PSPSettings(), seed=0)
    np.testing.assert_array_equal(u, outside)
    assert not events.all() and len(report) == 1


def test_verification_by_estimated_rho_g_prefers_the_middle_of_the_success_region():
    # Both candidates succeed throughout their small ball; only ρ_g's larger balls tell the middle from the side.
    problem = synthetic_chain()
    centre = np.array([0.35, 0.5, 0.6])
    side = centre + [0.17, 0.0, 0.0]
    reference = sobol_valid(problem, 256, seed=3)
    reference = (reference, problem.simulate_batch(reference).all(axis=1))
    by_rate = PSPSettings(verification_candidates=2, verification_samples=12)
    u, _, report = verify_candidates(problem, problem.simulate_batch, [side, centre], by_rate, 0, reference)
    assert [r["local_success_rate"] for r in report] == [1.0, 1.0]
    np.testing.assert_array_equal(u, side)  # a tie: the model's order decides
    by_rho = by_rate.with_changes(verification_score="rho_g")
    u, _, report = verify_candidates(problem, problem.simulate_batch, [side, centre], by_rho, 0, reference)
    np.testing.assert_array_equal(u, centre)
    assert report[1]["score"] > report[0]["score"]
    # The estimate is ρ_g's formula on the layouts at hand: with the same points it is what the evaluation measures.
    no_local = RobustnessSettings(thickness_factor=0.0)
    evaluation = EvaluationSet(*reference)
    measured = robustness_curve(problem, problem.simulate_batch, evaluation, centre, no_local).global_robustness
    assert estimated_global_robustness(centre, *reference, no_local) == pytest.approx(measured)
    with pytest.raises(RobustError, match="verification_score"):
        PSPSettings(verification_score="best")


@pytest.mark.parametrize("max_pairs", [1, 37, 1 << 22])
def test_ball_means_is_the_mean_over_each_ball_by_its_definition(max_pairs):
    rng = np.random.default_rng(4)
    centres, points = rng.uniform(size=(9, 3)), rng.uniform(size=(200, 3))
    values, own = rng.uniform(size=200), rng.uniform(size=9)
    points[0] = centres[0] + [0.25, 0, 0]  # exactly on a radius: inside (<=)
    radii = np.array([0.5, 0.0, 0.25, 1e-3, 2.0])  # unsorted, one empty for every centre
    expected = np.zeros((9, 5))
    for i, c in enumerate(centres):
        distance = np.linalg.norm(points - c, axis=1)
        for k, r in enumerate(radii):
            inside = distance <= r
            count = inside.sum() + 2.5
            expected[i, k] = (values[inside].sum() + 2.5 * own[i]) / count
    got = ball_means(centres, points, values, radii, 2.5, own, max_pairs=max_pairs)
    np.testing.assert_allclose(got, expected, rtol=1e-12)
    bare = ball_means(centres, points, values, radii, max_pairs=max_pairs)
    assert np.all(bare[:, 1] == 0)  # an empty ball scores 0
    np.testing.assert_allclose(bare[0, 2], values[np.linalg.norm(points - centres[0], axis=1) <= 0.25].mean())


def test_densest_successes_come_from_the_middle_of_the_largest_success_region():
    # Successes on a large disc and a small one; failures elsewhere.
    U = np.random.default_rng(0).random((600, 2))
    big = np.linalg.norm(U - [0.3, 0.3], axis=1) < 0.25
    small = np.linalg.norm(U - [0.85, 0.85], axis=1) < 0.08
    success = big | small
    densest = densest_successes(U, success, 5)
    assert densest.shape == (5, 2)
    assert (np.linalg.norm(densest - [0.3, 0.3], axis=1) < 0.25).all()  # all on the large disc
    # Ranked by ρ_g's formula on the sample: the first is the success it scores highest.
    scores = [estimated_global_robustness(u, U, success) for u in U[success]]
    assert estimated_global_robustness(densest[0], U, success) == pytest.approx(max(scores))
    # Every success when n is large; none without successes or with n = 0; always successes of the sample.
    assert len(densest_successes(U, success, 10_000)) == success.sum()
    assert densest_successes(U, np.zeros(len(U), bool), 3).shape == (0, 2)
    assert densest_successes(U, success, 0).shape == (0, 2)
    assert {tuple(u) for u in densest_successes(U, success, 50)} <= {tuple(u) for u in U[success]}


def test_start_candidates_are_verified_after_the_model_candidates_and_can_win():
    problem = synthetic_chain()
    centre = np.array([0.35, 0.5, 0.6])
    edge = np.array([0.35, 0.5, 0.6 + 0.245])
    outside = np.array([0.35, 0.5, 0.95])
    settings = PSPSettings(verification_candidates=2, verification_samples=20, verification_start_candidates=2)
    # The model offers a failure and an edge; the start offers the centre and (a duplicate of) the edge.
    u, events, report = verify_candidates(problem, problem.simulate_batch, [outside, edge, centre], settings,
                                          seed=0, additional=[centre, edge + 0.01])
    np.testing.assert_array_equal(u, centre)
    assert events.all()
    assert [r["source"] for r in report] == ["model", "model", "start"]
    assert [r["u"] for r in report] == [list(outside), list(edge), list(centre)]
    # The budget plan reserves simulations for the start candidates too.
    plan = plan_budget(settings, 614)
    assert plan.reserve == 4 * 20
    with pytest.raises(RobustError, match="verification_start_candidates"):
        PSPSettings(verification_start_candidates=-1)


def test_recommended_settings_fit_a_small_budget_and_return_a_verified_success():
    problem = synthetic_branching()
    settings = PSPSettings.recommended(n_initial=128, n_successes=40, max_exploration_steps=20)
    with SimulationExecutor(problem, backend="inline") as executor:
        result = optimize_robust_layout(problem, executor, budget=120, seed=0, settings=settings)
    assert result.n_simulations <= 120
    assert result.simulated_success and problem.is_valid(result.u[None, :])[0]
    verified = result.optimizer["verification"]
    assert len(verified) == 6 and sum(r["simulations"] for r in verified) <= 120 // 4
    assert [r["source"] for r in verified] == ["model"] * 3 + ["start"] * 3
    kept = next(r for r in verified if r["kept"])
    source = "an optimum of the model" if kept["source"] == "model" else "a success of the uniform start"
    assert result.kept_candidate().startswith(f"{source} (of 6 checked; local success")
    # The recommended C, gamma search minimizes the calibrated log loss (ROC AUC, fold by fold, ranks but never
    # checks a probability).
    assert PSPSettings().cv_scoring == "accuracy" and settings.cv_scoring == "calibrated_log_loss"
    assert settings.calibrate_product and not PSPSettings().calibrate_product


@pytest.mark.parametrize(
    ("budget", "candidates", "samples", "expected"),
    [
        # (budget, verified candidates, samples each) -> (samples each, reserve, exploration cap, Sobol cap)
        (None, 3, 15, (15, 45, None, None)),
        (614, 1, 1, (1, 1, 459, 306)),  # the thesis's single check
        (614, 3, 15, (15, 45, 426, 284)),
        (120, 3, 15, (10, 30, 67, 45)),  # at most a quarter of the budget
        (20, 3, 15, (1, 3, 12, 10)),  # never less than one simulation per candidate, nor caps below 10
    ],
)
def test_budget_plan_shares_out_the_budget(budget, candidates, samples, expected):
    settings = PSPSettings(verification_candidates=candidates, verification_samples=samples)
    plan = plan_budget(settings, budget)
    assert (plan.settings.verification_samples, plan.reserve, plan.exploration_cap, plan.initial_cap) == expected
    assert budget is None or plan.reserve <= max(budget // 4, candidates)


def squeezed_problem():
    # The success region's centre lies inside the impossible ball: the optimizer is pulled towards D∅.
    return SyntheticProblem(
        name="SQUEEZED",
        parameter_names=("a", "b"),
        lower_bounds=(0.0, 0.0),
        upper_bounds=(1.0, 1.0),
        events=(EllipsoidEvent("go"), EllipsoidEvent("hit", ("go",), (0, 1), (0.5, 0.5), (0.35, 0.35))),
        forbidden_center=(0.55, 0.5),
        forbidden_radius=0.15,
    )


class BooleanOnly(SyntheticProblem):
    """The same scenario, but it only answers valid/invalid (no margins for SLSQP)."""

    def validity_margins(self, u):
        return None


@pytest.mark.parametrize("margins", [True, False])
def test_optimization_never_returns_an_invalid_layout(margins):
    base = squeezed_problem()
    problem = base if margins else BooleanOnly(**{k: getattr(base, k) for k in (
        "name", "parameter_names", "lower_bounds", "upper_bounds", "events", "forbidden_center", "forbidden_radius")})
    samples = explore(problem, problem.simulate_batch, SMALL, seed=0, max_simulations=150)
    psp = FactorizedPSP(SMALL, random_state=0).fit(problem, samples)
    rng = np.random.default_rng(0)
    starts = samples.U[samples.success][:6]
    for start in starts:
        u, info = optimize_layout(problem, psp, start, alpha=10.0)
        assert problem.is_valid(u[None, :])[0], (start, u)
        assert np.all((u >= 0) & (u <= 1))
        assert info["energy"] <= info["energy_start"] + 1e-12
    with pytest.raises(RobustError, match="valid layout"):
        optimize_layout(problem, psp, np.array([0.55, 0.5]))
    del rng


def test_pipeline_finds_a_robust_valid_layout_within_budget():
    problem = synthetic_chain()
    progress = []
    with SimulationExecutor(problem, backend="inline") as executor:
        result = optimize_robust_layout(problem, executor, budget=250, seed=2, settings=SMALL,
                                        report=Reporter(progress.append))
    assert result.n_simulations <= 250
    assert problem.is_valid(result.u[None, :])[0]
    assert result.simulated_success
    # The optimized layout is inside the known success region (the disc and the roll interval), and the
    # optimization did not lower the predicted probability of the best sample.
    assert np.linalg.norm((result.u[:2] - [0.35, 0.5]) / [0.25, 0.3]) < 1
    assert abs(result.u[2] - 0.6) < 0.25
    assert result.optimizer["energy"] <= result.optimizer["energy_start"]
    assert 0 <= result.psp <= 1
    phases = [p.phase for p in progress]
    assert phases[0] == "exploration" and phases[-1] == "done"
    assert {"active learning", "optimization"} <= set(phases)
    assert all(p.simulations <= p.budget for p in progress)
    payload = result.to_json(problem)
    assert payload["content_hash"] == problem.content_hash
    assert [p["name"] for p in payload["parameters"]] == ["x", "z", "roll"]
    roll = payload["parameters"][2]
    assert roll["value"] == pytest.approx(15 + 60 * roll["normalized"])
    assert set(payload["event_probabilities"]) == {"start", "first", "second", "last"}


def test_pipeline_is_reproducible_and_the_cache_avoids_resimulation(tmp_path):
    problem = synthetic_chain()
    cache = tmp_path / "sims.sqlite3"
    with SimulationExecutor(problem, backend="inline", cache_path=cache) as executor:
        first = optimize_robust_layout(problem, executor, budget=200, seed=4, settings=SMALL)
    assert first.n_new_simulations > 0
    with SimulationExecutor(problem, backend="inline", cache_path=cache) as executor:
        second = optimize_robust_layout(problem, executor, budget=200, seed=4, settings=SMALL)
        assert executor.n_simulated == 0
    np.testing.assert_array_equal(first.u, second.u)
    assert second.n_simulations == first.n_simulations


class CountingProblem(SyntheticProblem):
    def simulate(self, u):
        CountingProblem.calls += 1
        return super().simulate(u)


def counting_chain():
    base = synthetic_chain("COUNTING")
    return CountingProblem(**{k: getattr(base, k) for k in (
        "name", "parameter_names", "lower_bounds", "upper_bounds", "events", "forbidden_center", "forbidden_radius")})


def test_an_interrupted_run_keeps_its_simulations(tmp_path):
    problem = counting_chain()
    cache = tmp_path / "sims.sqlite3"
    CountingProblem.calls = 0
    with pytest.raises(Cancelled):
        with SimulationExecutor(problem, backend="inline", cache_path=cache) as executor:
            optimize_robust_layout(problem, executor, budget=200, seed=7, settings=SMALL,
                                   report=Reporter(stop=lambda: CountingProblem.calls >= 60))
    assert SimulationCache(cache).count(cache_scope(problem)) == 60
    CountingProblem.calls = 0
    with SimulationExecutor(problem, backend="inline", cache_path=cache) as executor:
        result = optimize_robust_layout(problem, executor, budget=200, seed=7, settings=SMALL)
        assert executor.n_cache_hits >= 60
    assert CountingProblem.calls == result.n_new_simulations == result.n_simulations - 60


def test_outcomes_of_another_simulator_revision_are_not_read_back(tmp_path):
    problem = counting_chain()
    cache = tmp_path / "sims.sqlite3"
    U = np.full((3, len(problem.parameter_names)), 0.5) + np.arange(3)[:, None] * 0.01
    problem.cache_revision = "simulator-1"
    CountingProblem.calls = 0
    with SimulationExecutor(problem, backend="inline", cache_path=cache) as executor:
        executor.run(U)
    problem.cache_revision = "simulator-2"  # the simulating code changed: its old outcomes may be stale
    with SimulationExecutor(problem, backend="inline", cache_path=cache) as executor:
        assert executor.count_new(U) == 3
        executor.run(U)
        assert executor.n_cache_hits == 0 and executor.n_simulated == 3
    assert SimulationCache(cache).count() == 6


def test_process_and_dask_backends_give_the_local_result():
    distributed = pytest.importorskip("distributed")
    problem = synthetic_chain()
    settings = PSPSettings(n_initial=64, n_successes=20, max_exploration_steps=4, max_active_steps=1)
    with SimulationExecutor(problem, backend="inline") as executor:
        inline = optimize_robust_layout(problem, executor, budget=90, seed=5, settings=settings)
    with SimulationExecutor(problem, workers=2, chunk_size=16) as executor:
        assert executor.backend == "processes"
        local = optimize_robust_layout(problem, executor, budget=90, seed=5, settings=settings)
    cluster_options = {"n_workers": 1, "threads_per_worker": 2, "processes": False, "dashboard_address": None}
    with distributed.LocalCluster(**cluster_options) as cluster:
        with distributed.Client(cluster) as client:
            with SimulationExecutor(problem, scheduler=client, chunk_size=16) as executor:
                assert executor.backend == "dask"
                remote = optimize_robust_layout(problem, executor, budget=90, seed=5, settings=settings)
    np.testing.assert_array_equal(inline.u, local.u)
    np.testing.assert_array_equal(inline.u, remote.u)
    assert inline.n_simulations == local.n_simulations == remote.n_simulations


def test_executor_rejects_bad_settings_and_layouts():
    problem = synthetic_chain()
    with pytest.raises(RobustError, match="backend"):
        SimulationExecutor(problem, backend="gpu")
    with pytest.raises(RobustError, match="workers"):
        SimulationExecutor(problem, workers=0)
    with pytest.raises(RobustError, match="scheduler"):
        SimulationExecutor(problem, backend="dask")
    with SimulationExecutor(problem, backend="inline") as executor:
        with pytest.raises(RobustError, match="3 columns"):
            executor.run(np.zeros((2, 2)))
        with pytest.raises(RobustError, match=r"\[0, 1\]"):
            executor.run(np.full((1, 3), 1.5))
    with SimulationExecutor(problem, backend="inline") as executor:
        with pytest.raises(RobustError, match="budget"):
            optimize_robust_layout(problem, executor, budget=5)


def test_local_robustness_counts_successes_in_balls():
    U = np.array([[0.5, 0.5], [0.55, 0.5], [0.7, 0.5], [0.9, 0.5]])
    success = np.array([True, True, False, True])
    rho = local_robustness_from_points(np.array([0.5, 0.5]), U, success, np.array([0.0, 0.1, 0.25, 0.5]), 0.0)
    np.testing.assert_allclose(rho, [1.0, 1.0, 2 / 3, 3 / 4])
    empty = local_robustness_from_points(np.array([0.0, 0.0]), U, success, np.array([0.0]), 0.0)
    assert empty[0] == 0.0


def test_robustness_curve_prefers_the_centre_of_the_success_region():
    problem = synthetic_chain()
    settings = RobustnessSettings(n_evaluation=512, n_local=30)
    evaluation = evaluation_set(problem, problem.simulate_batch, settings.n_evaluation)
    centre = robustness_curve(problem, problem.simulate_batch, evaluation, np.array([0.35, 0.5, 0.6]), settings)
    edge = robustness_curve(problem, problem.simulate_batch, evaluation, np.array([0.35, 0.5, 0.38]), settings)
    invalid = robustness_curve(problem, problem.simulate_batch, evaluation, np.array([0.8, 0.8, 0.2]), settings)
    assert centre.local[0] == pytest.approx(1.0)
    assert 0 <= edge.global_robustness < centre.global_robustness <= 1
    assert centre.local[0] > centre.local[-1]
    assert invalid.global_robustness == 0 and not invalid.valid
    assert len(centre.epsilon) == 31


def test_baselines_respect_their_budget():
    problem = synthetic_branching(dim=4)
    b1 = baseline_b1(problem, problem.simulate_batch, 200, seed=0)
    assert b1.n_simulations <= 200 and problem.simulate_batch(b1.u[None, :]).all()
    b2 = baseline_b2(problem, problem.simulate_batch, 200, seed=0)
    b3 = baseline_b3(problem, problem.simulate_batch, 200, seed=0)
    for result in (b2, b3):
        assert result.n_simulations <= 200
        assert problem.is_valid(result.u[None, :])[0]
        assert 0 <= result.score <= 1
    with pytest.raises(RobustError, match="budget"):
        baseline_b2(problem, problem.simulate_batch, 0, seed=0)


def test_comparison_gives_the_baselines_our_budget():
    problem = synthetic_branching(dim=4)
    with SimulationExecutor(problem, backend="inline") as executor:
        comparison = compare_methods(problem, executor, ["ours", "b1", "b2"], runs=2, budget=200, settings=SMALL,
                                     robustness=RobustnessSettings(n_evaluation=512, n_local=20))
    rows = {r["method"]: r for r in comparison.table()}
    assert set(rows) == {"ours", "b1", "b2"}
    assert comparison.budget == round(rows["ours"]["simulations_mean"])
    assert rows["b2"]["simulations_mean"] <= comparison.budget
    assert all(0 <= r["rho_g_mean"] <= 1 for r in rows.values())
    eps, mean, sem = comparison.mean_curves()["ours"]
    assert len(eps) == len(mean) == len(sem) == 31
    with pytest.raises(RobustError, match="methods"):
        compare_methods(problem, executor, ["b4"])


ORPHANING_SCRIPT = """
import os

import numpy as np

from design.robust import SimulationExecutor, synthetic_chain

if __name__ == "__main__":
    problem = synthetic_chain()
    executor = SimulationExecutor(problem, workers=2)
    executor.run(np.full((4, problem.dim), 0.5))
    print(" ".join(str(pid) for pid in executor._pool._processes), flush=True)
    os._exit(0)  # dies without any clean-up, like kill -9
"""


@pytest.mark.skipif(not __import__("os").path.exists("/proc/self/stat"), reason="reads process states from /proc")
def test_worker_processes_end_when_their_parent_dies_without_clean_up(tmp_path):
    import os
    import subprocess
    import sys
    import time

    script = tmp_path / "orphaning.py"
    script.write_text(ORPHANING_SCRIPT)
    out = tmp_path / "pids.txt"
    with out.open("w") as stdout:  # a file, not a pipe: surviving workers would hold a pipe open
        done = subprocess.run([sys.executable, str(script)], stdout=stdout, stderr=subprocess.PIPE, text=True,
                              timeout=120)
    assert done.returncode == 0, done.stderr
    workers = [int(pid) for pid in out.read_text().split()]
    assert workers  # the pool starts workers on demand: at least one ran a simulation

    def alive(pid: int) -> bool:
        return not _process_gone(pid)

    deadline = time.monotonic() + 20
    while any(alive(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.2)
    left = [pid for pid in workers if alive(pid)]
    for pid in left:  # do not leave them behind even when the test fails
        os.kill(pid, 9)
    assert not left, f"worker processes {left} outlived their parent"
