"""The optimization after learning (thesis 4.7) improves on the best sample where it can.

``test_pipeline_finds_a_robust_valid_layout_within_budget`` stays green if the SLSQP result is thrown away (the best
sample already is a valid success inside the region); these tests are not.
"""

from __future__ import annotations

import numpy as np

from design.robust import PSPSettings, SimulationExecutor, optimize_robust_layout, synthetic_chain
from design.robust.optimize import energy
from design.robust.pipeline import optimize_from_samples
from design.robust.psp import Samples

SMALL = PSPSettings(n_initial=128, n_successes=40, max_exploration_steps=20)


class BumpPSP:
    """A PSP of two learned factors whose product and smooth minimum peak exactly at ``OPTIMUM``.

    Factor 1 is a Gaussian bump in parameters 0-1 around (0.35, 0.5), factor 2 one in parameter 2 around 0.6.
    """

    OPTIMUM = np.array([0.35, 0.5, 0.6])
    learned_factors = [0, 1]

    def factor_probabilities(self, U):
        U = np.atleast_2d(U)
        first = np.exp(-np.sum((U[:, :2] - self.OPTIMUM[:2]) ** 2, axis=1) / (2 * 0.2**2))
        second = np.exp(-(U[:, 2] - self.OPTIMUM[2]) ** 2 / (2 * 0.2**2))
        return np.column_stack([first, second])

    def predict_proba(self, U):
        return np.prod(self.factor_probabilities(U), axis=1)


def test_slsqp_reaches_a_known_optimum_the_samples_miss():
    problem = synthetic_chain()  # its impossible ball around (0.8, 0.8, 0.2) is far from the optimum
    rng = np.random.default_rng(0)
    U = rng.random((60, 3))
    U = U[problem.is_valid(U) & (np.linalg.norm(U - BumpPSP.OPTIMUM, axis=1) > 0.15)]
    samples = Samples(U, problem.simulate_batch(U), n_initial=len(U))
    psp = BumpPSP()
    optimized = optimize_from_samples(problem, psp, samples, SMALL, seed=0)
    best = samples.U[optimized.best_sample]
    assert np.linalg.norm(best - BumpPSP.OPTIMUM) > 0.15
    np.testing.assert_allclose(optimized.u, BumpPSP.OPTIMUM, atol=0.01)
    assert psp.predict_proba(optimized.u)[0] > psp.predict_proba(best)[0] + 0.1
    assert optimized.info["energy"] < optimized.info["energy_start"] - 0.05


def test_the_pipeline_keeps_the_optimized_layout_not_the_best_sample():
    problem = synthetic_chain()
    with SimulationExecutor(problem, backend="inline") as executor:
        result = optimize_robust_layout(problem, executor, budget=250, seed=2, settings=SMALL)
    assert result.simulated_success and "fallback" not in result.optimizer
    # The layout kept is the model's optimum: lower in the model's own energy than the best sample (both are near
    # -1 here, where the calibrated probabilities saturate, hence no margin), and elsewhere.
    alpha = result.settings.smooth_min_alpha
    assert energy(result.model, result.u, alpha) < energy(result.model, result.u_best_sample, alpha)
    assert np.linalg.norm(result.u - result.u_best_sample) > 1e-3
    # And it is closer to the centre of the known success region than the best sample (in region-radius units).
    centre, radii = np.array([0.35, 0.5, 0.6]), np.array([0.25, 0.3, 0.25])
    assert np.linalg.norm((result.u - centre) / radii) < np.linalg.norm((result.u_best_sample - centre) / radii)
