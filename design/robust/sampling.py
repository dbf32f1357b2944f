"""Drawing physically valid layouts: Sobol sequences, uniform draws, Gaussian mixtures and balls (normalized space)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.stats import qmc

from design.robust.problem import LayoutProblem, RobustError

#: Candidate batches tried before giving up on finding enough valid layouts.
MAX_DRAW_ROUNDS = 200


def sample_physically_valid(
    problem: LayoutProblem, draw: Callable[[int], np.ndarray], n: int, what: str = "layouts",
    on_checked: Callable[[int, int], None] | None = None,
) -> np.ndarray:
    """``n`` valid layouts from ``draw(m) -> (m, d)`` candidates; candidates outside ``[0, 1]^d`` are rejected.

    The first ``n`` valid candidates in draw order are kept. They are checked in chunks, stopping as soon as
    there are enough: a contraption's check builds its world (tens of ms), and checking all of a batch of ``2n``
    spent half the checks in vain where almost every layout is valid. ``on_checked(checked, valid)`` is called
    after each chunk (progress of a long draw).

    Raises
    ------
    RobustError
        If ``MAX_DRAW_ROUNDS`` batches do not give ``n`` valid layouts (the distribution lies in D∅).
    """
    if n <= 0:
        return np.zeros((0, problem.dim))
    kept: list[np.ndarray] = []
    count = checked = 0
    batch = max(2 * n, 16)
    chunk = max(16, n // 16)
    for _ in range(MAX_DRAW_ROUNDS):
        candidates = np.atleast_2d(draw(batch))
        in_box = np.all((candidates >= 0.0) & (candidates <= 1.0), axis=1)
        candidates = candidates[in_box]
        for begin in range(0, len(candidates), chunk):
            part = candidates[begin:begin + chunk]
            part = part[problem.is_valid(part)]
            kept.append(part)
            count += len(part)
            checked += min(chunk, len(candidates) - begin)
            if on_checked is not None:
                on_checked(checked, min(count, n))
            if count >= n:
                return np.concatenate(kept)[:n]
    raise RobustError(
        f"{problem.name}: found only {count} physically valid {what} of {n} after {MAX_DRAW_ROUNDS} draws"
    )


def sobol_valid(problem: LayoutProblem, n: int, seed: int,
                on_checked: Callable[[int, int], None] | None = None) -> np.ndarray:
    """The first ``n`` valid points of a scrambled Sobol sequence (seeded); ``on_checked`` as in
    :func:`sample_physically_valid`."""
    engine = qmc.Sobol(d=problem.dim, scramble=True, seed=seed)

    def draw(m: int) -> np.ndarray:
        # Whole powers of two keep the sequence's balance properties (and scipy quiet).
        return engine.random_base2(int(np.ceil(np.log2(max(m, 2)))))

    return sample_physically_valid(problem, draw, n, "Sobol points", on_checked)


def uniform_valid(problem: LayoutProblem, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` valid layouts drawn uniformly in ``[0, 1]^d``."""
    return sample_physically_valid(problem, lambda m: rng.random((m, problem.dim)), n, "uniform layouts")


def gaussian_mixture_draw(
    centers: np.ndarray, weights: np.ndarray, scales: np.ndarray, rng: np.random.Generator
) -> Callable[[int], np.ndarray]:
    """A sampler of the mixture Σ wᵢ N(cᵢ, diag(sᵢ²)); ``scales`` is ``(k, d)`` standard deviations."""
    centers = np.atleast_2d(centers)
    weights = np.asarray(weights, dtype=float)
    weights = weights / weights.sum() if weights.sum() > 0 else np.full(len(centers), 1.0 / len(centers))
    scales = np.broadcast_to(np.asarray(scales, dtype=float), centers.shape)

    def draw(m: int) -> np.ndarray:
        which = rng.choice(len(centers), size=m, p=weights)
        return centers[which] + rng.standard_normal((m, centers.shape[1])) * scales[which]

    return draw


def ball_draw(center: np.ndarray, radius, rng: np.random.Generator) -> Callable[[int], np.ndarray]:
    """A uniform sampler of the ball of ``radius`` around ``center`` (an ellipsoid if ``radius`` is per axis)."""
    center = np.asarray(center, dtype=float)
    d = len(center)
    radius = np.asarray(radius, dtype=float)  # () or (d,): broadcasts either way

    def draw(m: int) -> np.ndarray:
        directions = rng.standard_normal((m, d))
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        return center + directions * (rng.random(m)[:, None] ** (1.0 / d) * radius)

    return draw


def valid_in_ball(
    problem: LayoutProblem, center: np.ndarray, radius, n: int, rng: np.random.Generator, what: str = "layouts"
) -> np.ndarray:
    """Up to ``n`` valid layouts uniform in the ball of ``radius`` (scalar or per axis) around ``center``.

    Empty when ``n`` is 0 or when the ball lies almost wholly in D∅, as it may for a layout squeezed against the
    impossible region; callers score such a layout from what they have instead of failing.
    """
    if n <= 0:
        return np.zeros((0, problem.dim))
    try:
        return sample_physically_valid(problem, ball_draw(center, radius, rng), n, what)
    except RobustError:
        return np.zeros((0, problem.dim))
