"""Local and global robustness (thesis 4.8.3, Appendix C.3).

ρ_l(x, ε) is the success rate of the simulated layouts of an evaluation set within distance ε of x (normalized,
Euclidean), 0 if x is impossible; ρ_g(x) = ∫₀¹ ρ_l(x, ε) dε. As in Appendix C.3, the ball gets a thickness
η = 0.1 l_ε and ``n_local`` layouts simulated in B_η(x) are added to the evaluation set for each x.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from design.robust.problem import LayoutProblem
from design.robust.sampling import ball_draw, sample_physically_valid, sobol_valid
from design.robust.settings import RobustnessSettings

Oracle = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class EvaluationSet:
    """Simulated valid Sobol layouts: ``U`` ``(n, d)`` and their global ``success`` ``(n,)``."""

    U: np.ndarray
    success: np.ndarray


@dataclass(frozen=True)
class RobustnessCurve:
    """ρ_l(x, ε) on a grid of ε, and ρ_g."""

    epsilon: np.ndarray
    local: np.ndarray
    global_robustness: float
    valid: bool


def evaluation_set(problem: LayoutProblem, oracle: Oracle, n: int, seed: int = 12345) -> EvaluationSet:
    """``n`` valid Sobol layouts, simulated (the executor's cache makes this a one-time cost per scenario)."""
    U = sobol_valid(problem, n, seed)
    events = oracle(U)
    return EvaluationSet(U, events.all(axis=1))


def epsilon_grid(settings: RobustnessSettings) -> np.ndarray:
    """ε from 0 to 1 in steps of l_ε."""
    steps = int(round(1.0 / settings.epsilon_step))
    return np.linspace(0.0, 1.0, steps + 1)


def local_robustness_from_points(
    u: np.ndarray, U: np.ndarray, success: np.ndarray, epsilon: np.ndarray, thickness: float
) -> np.ndarray:
    """ρ_l(u, ε + η) for every ε, from simulated valid points ``U`` and their ``success`` (0 where empty)."""
    distances = np.linalg.norm(U - u, axis=1)
    order = np.argsort(distances)
    sorted_distances = distances[order]
    cumulative_success = np.concatenate([[0], np.cumsum(success[order])])
    counts = np.searchsorted(sorted_distances, epsilon + thickness, side="right")
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = np.where(counts > 0, cumulative_success[counts] / np.maximum(counts, 1), 0.0)
    return rho


def robustness_curve(
    problem: LayoutProblem,
    oracle: Oracle,
    evaluation: EvaluationSet,
    u: np.ndarray,
    settings: RobustnessSettings | None = None,
    seed: int = 0,
) -> RobustnessCurve:
    """ρ_l(u, ·) and ρ_g(u), simulating ``n_local`` layouts in B_η(u) (Appendix C.3)."""
    settings = settings or RobustnessSettings()
    u = np.asarray(u, dtype=float)
    epsilon = epsilon_grid(settings)
    if not problem.is_valid(u[None, :])[0]:
        return RobustnessCurve(epsilon, np.zeros_like(epsilon), 0.0, False)
    thickness = settings.thickness_factor * settings.epsilon_step
    U, success = evaluation.U, evaluation.success
    if thickness > 0 and settings.n_local > 0:
        rng = np.random.default_rng(seed)
        try:
            local = sample_physically_valid(problem, ball_draw(u, thickness, rng), settings.n_local, "local layouts")
        except Exception:  # noqa: BLE001 - a layout squeezed against D∅ may have too few valid neighbours
            local = np.zeros((0, problem.dim))
        if len(local):
            U = np.concatenate([U, local])
            success = np.concatenate([success, oracle(local).all(axis=1)])
    rho = local_robustness_from_points(u, U, success, epsilon, thickness)
    return RobustnessCurve(epsilon, rho, float(np.trapezoid(rho, epsilon)), True)


def estimate_local_robustness(
    problem: LayoutProblem, oracle: Oracle, u: np.ndarray, radius: float, n: int, rng: np.random.Generator
) -> tuple[float, int]:
    """The baselines' objective ρ_l(u, radius), estimated from ``n`` valid layouts simulated uniformly in the ball.

    Returns the estimate and the number of simulations used (0 if ``u`` is invalid).
    """
    if not problem.is_valid(np.asarray(u, dtype=float)[None, :])[0]:
        return 0.0, 0
    try:
        neighbours = sample_physically_valid(problem, ball_draw(u, radius, rng), n, "neighbours")
    except Exception:  # noqa: BLE001 - no valid neighbour at all
        return 0.0, 0
    return float(oracle(neighbours).all(axis=1).mean()), len(neighbours)
