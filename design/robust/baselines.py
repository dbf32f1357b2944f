"""Baselines of thesis 4.8.3, each with a simulation budget B.

- B1: uniform sampling until the first global success.
- B2: ⌊B/d²⌋ uniform layouts, each scored by ρ_l(x, 0.1) estimated from d² simulations in its ball; the best wins.
- B3: Bayesian optimization of the same objective with a Gaussian process (scikit-learn), initialized by uniform
  sampling, expected improvement maximized over random valid candidates; ⌊B/d²⌋ evaluations.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.stats import norm
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel

from design.robust.problem import LayoutProblem, RobustError, check_seed
from design.robust.robustness import estimate_local_robustness
from design.robust.sampling import uniform_valid
from design.robust.settings import RobustnessSettings

Oracle = Callable[[np.ndarray], np.ndarray]

#: Uniform evaluations that start B3's Gaussian process (ours: the thesis does not say how many).
B3_INITIAL_FRACTION = 0.3
#: Random valid candidates over which B3 maximizes expected improvement.
B3_CANDIDATES = 2000


@dataclass(frozen=True)
class BaselineResult:
    """A baseline's layout ``u`` (normalized), its score and the simulations it used."""

    method: str
    u: np.ndarray
    score: float
    n_simulations: int


def _check_budget(problem: LayoutProblem, budget: int, seed: int) -> None:
    if isinstance(budget, bool) or int(budget) != budget or budget < 1:
        raise RobustError(f"{problem.name}: the simulation budget must be a positive integer, got {budget!r}")
    check_seed(seed)


def baseline_b1(problem: LayoutProblem, oracle: Oracle, budget: int, seed: int, batch: int = 2) -> BaselineResult:
    """B1: uniform layouts simulated (``batch`` at a time, for parallel workers) until the first success.

    If the budget runs out first, the layout with the most successful events is returned.
    """
    _check_budget(problem, budget, seed)
    rng = np.random.default_rng([seed, 1])
    best_u, best_count, used = None, -1, 0
    while used < budget:
        U = uniform_valid(problem, min(batch, budget - used), rng)
        events = oracle(U)
        used += len(U)
        success = np.flatnonzero(events.all(axis=1))
        if len(success):
            return BaselineResult("b1", U[success[0]], 1.0, used)
        counts = events.sum(axis=1)
        if counts.max() > best_count:
            best_count, best_u = int(counts.max()), U[int(np.argmax(counts))]
    return BaselineResult("b1", best_u, 0.0, used)


def _evaluations(problem: LayoutProblem, budget: int) -> int:
    return max(1, budget // problem.dim**2)


def baseline_b2(problem: LayoutProblem, oracle: Oracle, budget: int, seed: int,
                settings: RobustnessSettings | None = None) -> BaselineResult:
    """B2: ⌊B/d²⌋ uniform layouts scored by ρ_l(x, 0.1) from d² simulations each; the best."""
    _check_budget(problem, budget, seed)
    settings = settings or RobustnessSettings()
    rng = np.random.default_rng([seed, 2])
    centers = uniform_valid(problem, _evaluations(problem, budget), rng)
    scores, used = [], 0
    for u in centers:
        score, n = estimate_local_robustness(problem, oracle, u, settings.baseline_radius, problem.dim**2, rng)
        scores.append(score)
        used += n
    best = int(np.argmax(scores))
    return BaselineResult("b2", centers[best], float(scores[best]), used)


def baseline_b3(problem: LayoutProblem, oracle: Oracle, budget: int, seed: int,
                settings: RobustnessSettings | None = None) -> BaselineResult:
    """B3: Gaussian-process Bayesian optimization of ρ_l(x, 0.1), ⌊B/d²⌋ evaluations."""
    _check_budget(problem, budget, seed)
    settings = settings or RobustnessSettings()
    rng = np.random.default_rng([seed, 3])
    n_evaluations = _evaluations(problem, budget)
    n_initial = max(2, min(n_evaluations, int(round(B3_INITIAL_FRACTION * n_evaluations))))
    X = list(uniform_valid(problem, n_initial, rng))
    y, used = [], 0
    for u in X:
        score, n = estimate_local_robustness(problem, oracle, u, settings.baseline_radius, problem.dim**2, rng)
        y.append(score)
        used += n
    kernel = ConstantKernel(1.0, (1e-3, 1e2)) * Matern(length_scale=np.full(problem.dim, 0.3),
                                                       length_scale_bounds=(1e-2, 10.0), nu=2.5) + \
        WhiteKernel(1e-2, (1e-6, 1e-1))
    while len(X) < n_evaluations:
        gp = GaussianProcessRegressor(kernel=kernel, normalize_y=True, random_state=seed, n_restarts_optimizer=1)
        with warnings.catch_warnings():
            # Hyper-parameters at their bounds are expected on a flat, noisy objective; not worth a warning.
            warnings.simplefilter("ignore", ConvergenceWarning)
            gp.fit(np.asarray(X), np.asarray(y))
        # Expected improvement on raw uniform candidates; validity (which may cost a physics query each) is
        # checked lazily, best candidate first.
        candidates = rng.random((B3_CANDIDATES, problem.dim))
        mean, std = gp.predict(candidates, return_std=True)
        best = max(y)
        std = np.maximum(std, 1e-12)
        z = (mean - best) / std
        improvement = (mean - best) * norm.cdf(z) + std * norm.pdf(z)
        u = next((candidates[i] for i in np.argsort(-improvement) if problem.is_valid(candidates[i][None, :])[0]),
                 None)
        if u is None:
            u = uniform_valid(problem, 1, rng)[0]
        score, n = estimate_local_robustness(problem, oracle, u, settings.baseline_radius, problem.dim**2, rng)
        X.append(u)
        y.append(score)
        used += n
    best = int(np.argmax(y))
    return BaselineResult("b3", np.asarray(X[best]), float(y[best]), used)
