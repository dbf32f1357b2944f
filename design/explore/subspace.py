"""The invariant subspace (thesis 3.5.2): local sampling, invariance scores, weighted PCA, sliders.

Coordinates: the continuous parameters ``x`` of the current design ``x0`` are normalized per dimension,
``u = (x - x0) / h``, where ``h`` is a fixed fraction of each parameter's feasible range (so every parameter gets
the same say, and a slider step of 1 is a step of ``h`` along a unit direction of ``u``).

Steps of one subspace update (:func:`compute_subspace`):

1. a grid in the box ``[-1, 1]^n`` cut to each parameter's feasible interval, its resolution per dimension
   proportional to the length of that feasible range, within a total sample budget; infeasible samples dropped;
2. (``pull=True``, default) each sample is moved onto the invariants' linearization at ``x0``: a finite-difference
   Jacobian ``J`` (n + 1 designs) gives the projection ``u - J^+ J u``. On a coarse grid in 5 dimensions almost no
   sample would otherwise fall close enough to a 1- or 3-dimensional invariant set to score above 0.9; the scores
   still judge every pulled sample on the true, non-linear invariants. ``pull=False`` is the thesis's plain grid;
3. invariance scores ``S = exp(-d)`` (Eq. 3.16) from batch tracking of the PoIs on every sample;
4. fewer than two samples (``x0`` included) with ``S > sigma_inv = 0.9`` -> :class:`OverConstrainedError`;
5. the best fraction of the samples feeds a WPCA centred on ``x0`` with the scores as weights (Delchambre);
   components explaining more than ``sigma_var = 0.1 v1_rel`` are kept; if none is dropped every invariant was
   redundant and the base parameters are kept;
6. temporal consistency: the new basis is turned towards the previous one (projection of the old vectors, then
   Gram-Schmidt; or sign flips when the dimension changed), Figure 3.14.

Slider bounds (:func:`line_interval`) are the feasible run of ``[-2, 2]`` along one slider's line, the other sliders
held, found on a vectorized grid and refined by bracketing; only the machine's constraints are used, no PoI.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from design.explore.errors import OverConstrainedError
from design.explore.wpca import WPCA

SIGMA_INV = 0.9
SIGMA_VAR_FACTOR = 0.1
SLIDER_BOUND = 2.0


@dataclass(frozen=True)
class Subspace:
    """A local linear approximation of the invariant space.

    Attributes
    ----------
    basis : (m, n) array
        Orthonormal directions in normalized coordinates, one per slider.
    redundant : bool
        True when the invariants constrain nothing (or there are none): the basis is the identity.
    explained_variance_ratio : (n,) array
        WPCA relative variances (empty without invariants).
    n_samples : int
        Feasible samples scored.
    n_good : int
        Samples (x0 included) with a score above ``sigma_inv``.
    """

    basis: np.ndarray
    redundant: bool
    explained_variance_ratio: np.ndarray
    n_samples: int
    n_good: int


def grid_samples(lower: np.ndarray, upper: np.ndarray, budget: int) -> np.ndarray:
    """A grid in the box ``[lower, upper]`` (normalized units) with about ``budget`` points.

    The number of points of each dimension is proportional to its length (a dimension squeezed by the constraints
    gets fewer points), at least 2.
    """
    lower = np.asarray(lower, dtype=float)
    upper = np.asarray(upper, dtype=float)
    n = len(lower)
    widths = np.maximum(upper - lower, 0.0)
    if n == 0:
        return np.zeros((1, 0))
    # Points per dimension ~ c * width with prod = budget.
    positive = widths > 0
    geometric = np.exp(np.mean(np.log(widths[positive]))) if positive.any() else 1.0
    base = budget ** (1.0 / max(int(positive.sum()), 1))
    counts = np.where(positive, np.maximum(np.rint(base * widths / geometric), 2), 1).astype(int)
    while np.prod(counts) > 2 * budget and counts.max() > 2:
        counts[np.argmax(counts)] -= 1
    axes = []
    for lo, hi, c in zip(lower, upper, counts):
        axes.append(np.linspace(lo, hi, c) if c > 1 else np.array([0.0]))
    mesh = np.meshgrid(*axes, indexing="ij")
    return np.column_stack([m.ravel() for m in mesh])


def jacobian(residual_fn: Callable[[np.ndarray], np.ndarray], u: np.ndarray, step: float = 0.02):
    """Forward-difference Jacobian of ``residual_fn`` at ``u`` (one batched call of n + 1 designs).

    The step is large on purpose (in normalized units, 0.02 is 0.2 % of a feasible range): the position of a
    curvature maximum is only known to ~1e-5 (the peak is flat), and a tiny step would turn that into noise.
    """
    n = len(u)
    U = np.vstack([u, u + step * np.eye(n)])
    R = residual_fn(U)
    return R[0], (R[1:] - R[0]).T / step


def null_projector(J: np.ndarray, absolute: float = 1e-2, relative: float = 1e-3) -> np.ndarray:
    """Projector onto the null space of ``J``; singular values below the thresholds count as zero.

    ``absolute`` is in normalized residual per normalized parameter step: an invariant that moves less than that is
    redundant (it does not constrain the design).
    """
    n = J.shape[1]
    if J.size == 0 or not np.all(np.isfinite(J)):
        return np.eye(n)
    _, s, vt = np.linalg.svd(J, full_matrices=True)
    threshold = max(absolute, relative * (s[0] if len(s) else 0.0))
    rank = int(np.sum(s > threshold))
    rows = vt[:rank]
    return np.eye(n) - rows.T @ rows


def align_basis(new: np.ndarray, previous: np.ndarray | None) -> np.ndarray:
    """Turn a new basis towards the previous one (Figure 3.14): rotate within the subspace, or flip signs."""
    if previous is None or len(previous) == 0 or len(new) == 0 or previous.shape[1] != new.shape[1]:
        return new
    if len(previous) == len(new):
        projected = previous @ new.T @ new
        if np.all(np.linalg.norm(projected, axis=1) > 0.3):
            out = []
            for v in projected:
                for w in out:
                    v = v - (v @ w) * w
                norm = np.linalg.norm(v)
                if norm < 1e-6:
                    break
                out.append(v / norm)
            else:
                return np.array(out)
    aligned = new.copy()
    for i in range(min(len(new), len(previous))):
        if aligned[i] @ previous[i] < 0:
            aligned[i] = -aligned[i]
    return aligned


def compute_subspace(
    residual_fn: Callable[[np.ndarray], np.ndarray],
    feasible_fn: Callable[[np.ndarray], np.ndarray],
    lower: np.ndarray,
    upper: np.ndarray,
    labels: Sequence[str],
    *,
    budget: int = 1024,
    keep_fraction: float = 0.25,
    pull: bool = True,
    previous: np.ndarray | None = None,
) -> Subspace:
    """One update of the invariant subspace around ``u = 0`` (see the module docstring).

    Parameters
    ----------
    residual_fn : callable
        ``(k, n) -> (k, r)`` normalized invariant residuals of designs (NaN where a PoI is lost).
    feasible_fn : callable
        ``(k, n) -> (k,)`` bool, the machine's constraints.
    lower, upper : (n,) arrays
        Sampling box in normalized units (``[-1, 1]`` cut to the feasible intervals).
    labels : sequence of str
        The invariants' labels, for the over-constrained message.
    budget : int
        About how many grid samples.
    keep_fraction : float
        Fraction of the best-scored samples the WPCA sees.
    pull : bool
        Pull samples onto the linearized invariants first (see the module docstring).
    previous : (m, n) array, optional
        The previous basis, for temporal consistency.
    """
    n = len(lower)
    U = grid_samples(lower, upper, budget)
    U = U[feasible_fn(U)] if len(U) else U
    if pull:
        _, J = jacobian(residual_fn, np.zeros(n))
        U = U @ null_projector(J)  # the projector is symmetric
        U = U[feasible_fn(U)] if len(U) else U
    R = residual_fn(U) if len(U) else np.zeros((0, 1))
    d = np.linalg.norm(R, axis=1)
    scores = np.where(np.isfinite(d), np.exp(-np.nan_to_num(d, nan=np.inf)), 0.0)
    distinct = np.linalg.norm(U, axis=1) > 1e-9
    n_good = 1 + int(np.sum((scores > SIGMA_INV) & distinct))
    if n_good < 2:
        raise OverConstrainedError(
            "over-constrained: no design near the current one keeps all the invariants "
            f"({', '.join(labels)}) within the tolerance; remove one of them",
            tuple(labels),
        )
    order = np.argsort(-scores, kind="stable")
    keep = max(int(np.ceil(keep_fraction * len(U))), min(len(U), 2 * n + 2))
    chosen = order[:keep]
    chosen = chosen[scores[chosen] > 0]
    wpca = WPCA(center=np.zeros(n)).fit(U[chosen], scores[chosen])
    ratios = wpca.explained_variance_ratio_
    significant = ratios > SIGMA_VAR_FACTOR * ratios[0] if ratios[0] > 0 else np.zeros(n, dtype=bool)
    m = int(significant.sum())
    if m == n or m == 0:
        basis = np.eye(n)
        redundant = True
    else:
        basis = align_basis(wpca.components_[:m], previous)
        redundant = False
    return Subspace(basis, redundant, ratios, len(U), n_good)


def line_interval(
    feasible_fn: Callable[[np.ndarray], np.ndarray],
    origin: np.ndarray,
    direction: np.ndarray,
    current: float,
    bound: float = SLIDER_BOUND,
    grid: int = 81,
    rounds: int = 3,
) -> tuple[float, float]:
    """Feasible run of slider values in ``[-bound, bound]`` containing ``current``.

    The design at slider value ``v`` is ``origin + (v - current) * direction``; ``origin`` is the current design.
    """
    values = np.sort(np.append(np.linspace(-bound, bound, grid), current))
    ok = feasible_fn(origin[None, :] + (values - current)[:, None] * direction[None, :])
    position = int(np.searchsorted(values, current))
    position = min(position, len(values) - 1)
    if not ok[position]:
        return current, current

    def refine(bad: float, good: float) -> float:
        for _ in range(rounds):
            probes = np.linspace(good, bad, 18)
            fine = feasible_fn(origin[None, :] + (probes - current)[:, None] * direction[None, :])
            last = int(np.argmin(fine)) - 1 if not fine.all() else len(probes) - 1
            good, bad = probes[max(last, 0)], probes[min(last + 1, len(probes) - 1)]
        return float(good)

    lo = position
    while lo > 0 and ok[lo - 1]:
        lo -= 1
    hi = position
    while hi < len(values) - 1 and ok[hi + 1]:
        hi += 1
    lower = values[lo] if lo == 0 else refine(values[lo - 1], values[lo])
    upper = values[hi] if hi == len(values) - 1 else refine(values[hi + 1], values[hi])
    return float(lower), float(upper)
