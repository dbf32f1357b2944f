"""Layout optimization (thesis 4.7): smooth-minimum energy of the per-event probabilities under SLSQP."""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize
from scipy.stats import qmc

from design.robust.problem import LayoutProblem, RobustError


def smooth_minimum(z: np.ndarray, alpha: float) -> np.ndarray:
    """S_α(z) = Σ zᵢ e^(-α zᵢ) / Σ e^(-α zⱼ) along the last axis (tends to min(z) as α grows)."""
    z = np.asarray(z, dtype=float)
    shifted = -alpha * (z - z.min(axis=-1, keepdims=True))  # shift for stability; cancels in the ratio
    weights = np.exp(shifted)
    return np.sum(z * weights, axis=-1) / np.sum(weights, axis=-1)


def energy(psp, u: np.ndarray, alpha: float, offsets: np.ndarray | None = None) -> float:
    """E(x) = -S_α(r(x)) over the PSP's learned factors (quasi-deterministic ones are constant).

    With ``offsets`` (an ``(m, d)`` array), the mean of -S_α(r(x + δ)) over them, each point clipped to the design
    space: the expected energy under a placement error.
    """
    factors = psp.learned_factors
    if not factors:
        return -1.0
    u = np.atleast_2d(u)
    if offsets is not None and len(offsets):
        u = np.clip(u + offsets, 0.0, 1.0)
    r = psp.factor_probabilities(u)[:, factors]
    return -float(np.mean(smooth_minimum(r, alpha)))


def placement_offsets(dim: int, error: float, n: int, seed: int = 0) -> np.ndarray | None:
    """``n`` fixed offsets in ``[-error, error]^dim`` (scrambled Sobol, the origin first), or None for no error."""
    if error <= 0:
        return None
    points = qmc.Sobol(dim, scramble=True, seed=seed).random(n)
    offsets = error * (2.0 * points - 1.0)
    offsets[0] = 0.0
    return offsets


def _last_valid_on_segment(problem: LayoutProblem, start: np.ndarray, end: np.ndarray, steps: int = 30) -> np.ndarray:
    """The valid point closest to ``end`` on [start, end], by bisection from a valid ``start``."""
    if problem.is_valid(end[None, :])[0]:
        return end
    low, high = 0.0, 1.0
    for _ in range(steps):
        middle = 0.5 * (low + high)
        if problem.is_valid((start + middle * (end - start))[None, :])[0]:
            low = middle
        else:
            high = middle
    return start + low * (end - start)


def optimize_layout(problem: LayoutProblem, psp, start: np.ndarray, alpha: float = 10.0,
                    max_iterations: int = 100, offsets: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    """Minimize the smooth-minimum energy from a valid ``start`` under bounds and validity constraints.

    SLSQP gets the problem's validity margins as inequality constraints when it has them; whatever SLSQP returns,
    the result is pulled back along the segment from ``start`` until it is physically valid, and it is never worse
    in energy than ``start``. So the returned layout is always valid. ``offsets`` (see :func:`placement_offsets`)
    make the energy the mean over a placement error.

    Returns
    -------
    u : ndarray
        The optimized normalized layout.
    info : dict
        ``energy_start``, ``energy``, ``iterations``, ``message``.
    """
    start = np.asarray(start, dtype=float)
    if start.shape != (problem.dim,) or not problem.is_valid(start[None, :])[0]:
        raise RobustError(f"{problem.name}: the optimization must start from a valid layout of {problem.dim} values")
    e0 = energy(psp, start, alpha, offsets)
    if not psp.learned_factors:
        return start, {"energy_start": e0, "energy": e0, "iterations": 0, "message": "no learned factor"}
    constraints = []
    if problem.validity_margins(start) is not None:
        constraint = {"type": "ineq", "fun": lambda u: np.atleast_1d(problem.validity_margins(u)).ravel()}
        if hasattr(problem, "validity_jacobian"):
            constraint["jac"] = lambda u: np.atleast_2d(problem.validity_jacobian(u))
        constraints.append(constraint)
    result = minimize(
        lambda u: energy(psp, np.clip(u, 0.0, 1.0), alpha, offsets), start, method="SLSQP",
        bounds=[(0.0, 1.0)] * problem.dim, constraints=constraints, options={"maxiter": max_iterations, "ftol": 1e-10},
    )
    u = _last_valid_on_segment(problem, start, np.clip(result.x, 0.0, 1.0))
    e = energy(psp, u, alpha, offsets)
    if not e <= e0:
        u, e = start, e0
    return u, {"energy_start": e0, "energy": e, "iterations": int(result.nit), "message": str(result.message)}
