"""Local and global robustness (thesis 4.8.3, Appendix C.3).

ρ_l(x, ε) is the success rate of the simulated layouts of an evaluation set within distance ε of x (normalized,
Euclidean), 0 if x is impossible; ρ_g(x) = ∫₀¹ ρ_l(x, ε) dε. As in Appendix C.3, the ball gets a thickness
η = 0.1 l_ε and ``n_local`` layouts simulated in B_η(x) are added to the evaluation set for each x.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial.distance import cdist

from design.robust.problem import LayoutProblem, check_seed
from design.robust.sampling import sobol_valid, valid_in_ball
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


#: Seed of the Sobol evaluation set: the same set in every command and run, so its simulations are cached once.
EVALUATION_SEED = 12345


def evaluation_layouts(problem: LayoutProblem, n: int, seed: int = EVALUATION_SEED,
                       on_checked: Callable[[int, int], None] | None = None) -> np.ndarray:
    """The ``n`` valid Sobol layouts of the evaluation set, not simulated (``on_checked(checked, valid)`` reports
    the validity checks, a long step for a contraption: each builds its world)."""
    return sobol_valid(problem, n, seed, on_checked)


def evaluation_set(problem: LayoutProblem, oracle: Oracle, n: int, seed: int = EVALUATION_SEED,
                   layouts: np.ndarray | None = None) -> EvaluationSet:
    """``n`` valid Sobol layouts, simulated (the executor's cache makes this a one-time cost per scenario).

    ``layouts`` are :func:`evaluation_layouts` already drawn (e.g. to count the cached ones first).
    """
    U = evaluation_layouts(problem, n, seed) if layouts is None else np.asarray(layouts, dtype=float)
    events = oracle(U)
    return EvaluationSet(U, events.all(axis=1))


def epsilon_grid(settings: RobustnessSettings) -> np.ndarray:
    """ε from 0 to 1 in steps of l_ε."""
    steps = int(round(1.0 / settings.epsilon_step))
    return np.linspace(0.0, 1.0, steps + 1)


def ball_means(
    centres: np.ndarray,
    points: np.ndarray,
    values: np.ndarray,
    radii: np.ndarray,
    own_weight: float = 0.0,
    own_values: np.ndarray | None = None,
    max_pairs: int = 1 << 20,
) -> np.ndarray:
    """Mean of ``values`` over the ``points`` within each radius of each centre, ``(m, len(radii))``.

    Each centre may count its own value ``own_weight`` times (the evaluation's local layouts in B_η(x)); an empty
    ball scores 0. This is ρ_l when the values are simulated successes, and its expectation when they are
    probabilities. Centres go in blocks of at most ``max_pairs`` centre-point distances.
    """
    centres = np.atleast_2d(np.asarray(centres, dtype=float))
    points = np.asarray(points, dtype=float)
    values = np.asarray(values, dtype=float)
    radii = np.asarray(radii, dtype=float)
    own = np.zeros(len(centres)) if own_values is None else np.asarray(own_values, dtype=float)
    order = np.argsort(radii, kind="stable")
    sorted_radii = radii[order]
    n_radii = len(radii)
    result = np.empty((len(centres), n_radii))
    block = max(1, max_pairs // max(1, len(points)))
    for begin in range(0, len(centres), block):
        distances = cdist(centres[begin:begin + block], points)
        rows = len(distances)
        # Each point falls in every ball from the smallest radius that holds it on: count it there once, then a
        # running sum over the radii (memory per pair, not per pair and radius).
        first = np.searchsorted(sorted_radii, distances, side="left")
        bins = (first + (n_radii + 1) * np.arange(rows)[:, None]).ravel()
        size = rows * (n_radii + 1)
        counts = np.bincount(bins, minlength=size).reshape(rows, n_radii + 1)[:, :n_radii].cumsum(axis=1)
        mass = np.bincount(bins, weights=np.broadcast_to(values, distances.shape).ravel(), minlength=size)
        mass = mass.reshape(rows, n_radii + 1)[:, :n_radii].cumsum(axis=1)
        counts = counts + own_weight
        mass = mass + own_weight * own[begin:begin + block, None]
        means = np.divide(mass, counts, out=np.zeros_like(mass), where=counts > 0)
        result[begin:begin + block, order] = means
    return result


def local_robustness_from_points(
    u: np.ndarray, U: np.ndarray, success: np.ndarray, epsilon: np.ndarray, thickness: float
) -> np.ndarray:
    """ρ_l(u, ε + η) for every ε, from simulated valid points ``U`` and their ``success`` (0 where empty)."""
    return ball_means(u, U, success, np.asarray(epsilon) + thickness)[0]


def estimated_global_robustness(
    u: np.ndarray, U: np.ndarray, success: np.ndarray, settings: RobustnessSettings | None = None
) -> float:
    """ρ_g(u) computed from the simulated layouts ``U`` at hand (their ``success``), without new simulations."""
    return float(_global_from_points(u, U, success, settings or RobustnessSettings())[0])


def densest_successes(
    U: np.ndarray, success: np.ndarray, n: int, settings: RobustnessSettings | None = None
) -> np.ndarray:
    """The ``n`` successful layouts of a uniform sample ``U`` with the highest ρ_g estimated from the sample alone.

    Each success is scored by ρ_g's formula with the sample as evaluation set (no local layouts: the layout itself
    is the centre of its balls), so the ones surrounded by the most success at every scale come first. Ties keep
    the sample's order. Returns ``(min(n, successes), d)``.
    """
    U = np.asarray(U, dtype=float)
    success = np.asarray(success, dtype=bool)
    successes = U[success]
    if n < 1 or not len(successes):
        return successes[:0]
    scores = _global_from_points(successes, U, success.astype(float), settings or RobustnessSettings())
    return successes[np.argsort(-scores, kind="stable")[:n]]


def _ball_radii(settings: RobustnessSettings) -> tuple[np.ndarray, np.ndarray]:
    """The ε grid and the radii ε + η of ρ_l's balls."""
    epsilon = epsilon_grid(settings)
    return epsilon, epsilon + settings.thickness_factor * settings.epsilon_step


def _curve_from_points(u, U, success, settings: RobustnessSettings) -> tuple[np.ndarray, np.ndarray]:
    """The ε grid and ρ_l(u, ε + η) on it, from simulated layouts."""
    epsilon, radii = _ball_radii(settings)
    return epsilon, ball_means(u, U, success, radii)[0]


def _global_from_points(centres, points, values, settings: RobustnessSettings, own_weight: float = 0.0,
                        own_values=None) -> np.ndarray:
    """ρ_g's formula for each centre, with ``values`` of ``points`` in place of simulated successes (see ball_means)."""
    epsilon, radii = _ball_radii(settings)
    return np.trapezoid(ball_means(centres, points, values, radii, own_weight, own_values), epsilon, axis=1)


def local_layouts(problem: LayoutProblem, u: np.ndarray, settings: RobustnessSettings | None = None,
                  seed: int = 0) -> np.ndarray:
    """The ``n_local`` valid layouts in B_η(u) that :func:`robustness_curve` simulates (none if ``u`` is invalid)."""
    settings = settings or RobustnessSettings()
    seed = check_seed(seed)
    u = np.asarray(u, dtype=float)
    thickness = settings.thickness_factor * settings.epsilon_step
    if thickness <= 0 or settings.n_local <= 0 or not problem.is_valid(u[None, :])[0]:
        return np.zeros((0, problem.dim))
    return valid_in_ball(problem, u, thickness, settings.n_local, np.random.default_rng(seed), "local layouts")


def robustness_curve(
    problem: LayoutProblem,
    oracle: Oracle,
    evaluation: EvaluationSet,
    u: np.ndarray,
    settings: RobustnessSettings | None = None,
    seed: int = 0,
    local: np.ndarray | None = None,
) -> RobustnessCurve:
    """ρ_l(u, ·) and ρ_g(u), simulating ``n_local`` layouts in B_η(u) (Appendix C.3).

    ``local`` are :func:`local_layouts` already drawn with the same settings and seed (e.g. to count the cached
    ones first).
    """
    settings = settings or RobustnessSettings()
    seed = check_seed(seed)
    u = np.asarray(u, dtype=float)
    epsilon = epsilon_grid(settings)
    if not problem.is_valid(u[None, :])[0]:
        return RobustnessCurve(epsilon, np.zeros_like(epsilon), 0.0, False)
    U, success = evaluation.U, evaluation.success
    if local is None:
        local = local_layouts(problem, u, settings, seed)
    if len(local):
        U = np.concatenate([U, local])
        success = np.concatenate([success, oracle(local).all(axis=1)])
    epsilon, rho = _curve_from_points(u, U, success, settings)
    return RobustnessCurve(epsilon, rho, float(np.trapezoid(rho, epsilon)), True)


def estimate_local_robustness(
    problem: LayoutProblem, oracle: Oracle, u: np.ndarray, radius: float, n: int, rng: np.random.Generator
) -> tuple[float, int]:
    """The baselines' objective ρ_l(u, radius), estimated from ``n`` valid layouts simulated uniformly in the ball.

    Returns the estimate and the number of simulations used (0 if ``u`` is invalid).
    """
    if not problem.is_valid(np.asarray(u, dtype=float)[None, :])[0]:
        return 0.0, 0
    neighbours = valid_in_ball(problem, u, radius, n, rng, "neighbours")
    if not len(neighbours):
        return 0.0, 0
    return float(oracle(neighbours).all(axis=1).mean()), len(neighbours)


def predicted_global_robustness(
    candidates: np.ndarray,
    candidate_probability: np.ndarray,
    reference: np.ndarray,
    reference_probability: np.ndarray,
    settings: RobustnessSettings | None = None,
) -> np.ndarray:
    """ρ_g's formula with predicted success probabilities in place of simulated successes.

    For each candidate ``x``, ρ̂_l(x, ε) is the mean probability of the ``reference`` layouts within ε + η of x, the
    candidate's own probability counted ``n_local`` times (the evaluation's local layouts in B_η(x)); ρ̂_g is its
    integral over ε. With a calibrated PSP this is the expected ρ_g of the candidate under the model, so maximizing
    it aims at what :func:`robustness_curve` measures rather than at the probability at a single point.

    Parameters
    ----------
    candidates : ndarray, shape (m, d)
    candidate_probability : ndarray, shape (m,)
    reference : ndarray, shape (n, d)
        Valid layouts spread over the design space (a Sobol sample).
    reference_probability : ndarray, shape (n,)

    Returns
    -------
    ndarray, shape (m,)
    """
    settings = settings or RobustnessSettings()
    return _global_from_points(candidates, reference, reference_probability, settings, float(settings.n_local),
                               candidate_probability)
