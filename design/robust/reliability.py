"""How honest a fitted success model is: Brier score and reliability curve on held-out simulations.

A success probability is *calibrated* when, of the layouts it gives probability p, a fraction p succeeds. This module
measures it on simulations the model never saw:

- :func:`held_out_layouts` draws them, seeded: a scrambled Sobol sample of the whole design space (another seed than
  the exploration's) and layouts uniform in balls of growing radius around a layout of interest (the optimum, where a
  maker will build);
- :func:`psp_reliability` scores a fitted :class:`~design.robust.psp.FactorizedPSP` on their simulated events: each
  factor on the rows where it applies (its parents happened, as it was trained) and the whole PSP against global
  success. Each score is a :class:`Reliability`: Brier score, the Brier score of the held-out base rate (a model that
  knows only how often success happens; a useful model scores below it), log loss, expected calibration error and
  the binned reliability curve.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from design.robust.problem import LayoutProblem
from design.robust.sampling import sobol_valid, valid_in_ball

#: Radii (normalized) of the balls of held-out layouts around a layout of interest.
NEAR_RADII = (0.02, 0.05, 0.1, 0.2)
#: Probabilities are clipped to [EPS, 1 - EPS] in the log loss (a model that says 1 and is wrong costs 34 nats).
EPS = 1e-15


@dataclass(frozen=True)
class Reliability:
    """Calibration of one predicted probability on held-out layouts.

    Attributes
    ----------
    name : str
        The event (a factor of the PSP) or ``"success"`` (the whole PSP against global success).
    n : int
        Held-out layouts scored (for an event: those where its parents happened).
    brier : float
        Mean squared difference between predicted probability and outcome (0 is perfect; NaN when ``n == 0``).
    reference_brier : float
        The Brier score of always predicting the held-out success rate: p (1 - p).
    log_loss : float
        Mean negative log likelihood (nats).
    ece : float
        Expected calibration error: the bins' |mean predicted - observed rate|, weighted by their counts.
    predicted, observed : ndarray
        Per bin of predicted probability: mean prediction and observed success rate (NaN in empty bins).
    counts : ndarray
        Layouts per bin.
    edges : ndarray
        Bin edges (equal widths on [0, 1]).
    """

    name: str
    n: int
    brier: float
    reference_brier: float
    log_loss: float
    ece: float
    predicted: np.ndarray
    observed: np.ndarray
    counts: np.ndarray
    edges: np.ndarray

    def to_json(self) -> dict:
        def clean(values):
            return [None if not np.isfinite(v) else round(float(v), 6) for v in values]
        return {"name": self.name, "n": self.n, "brier": _finite(self.brier),
                "reference_brier": _finite(self.reference_brier), "log_loss": _finite(self.log_loss),
                "ece": _finite(self.ece), "predicted": clean(self.predicted), "observed": clean(self.observed),
                "counts": [int(c) for c in self.counts]}


def _finite(value: float) -> float | None:
    return None if not np.isfinite(value) else round(float(value), 6)


def reliability(name: str, probability: np.ndarray, outcome: np.ndarray, bins: int = 10) -> Reliability:
    """Brier score, log loss and the reliability curve of ``probability`` against Boolean ``outcome``."""
    p = np.clip(np.asarray(probability, dtype=float).ravel(), 0.0, 1.0)
    y = np.asarray(outcome, dtype=bool).ravel()
    edges = np.linspace(0.0, 1.0, bins + 1)
    if len(p) == 0:
        nan = np.full(bins, np.nan)
        return Reliability(name, 0, np.nan, np.nan, np.nan, np.nan, nan, nan, np.zeros(bins, dtype=int), edges)
    which = np.clip(np.searchsorted(edges, p, side="right") - 1, 0, bins - 1)
    counts = np.bincount(which, minlength=bins)
    with np.errstate(invalid="ignore", divide="ignore"):
        predicted = np.bincount(which, weights=p, minlength=bins) / counts
        observed = np.bincount(which, weights=y.astype(float), minlength=bins) / counts
    filled = counts > 0
    rate = float(y.mean())
    clipped = np.clip(p, EPS, 1.0 - EPS)
    return Reliability(
        name=name,
        n=len(p),
        brier=float(np.mean((p - y) ** 2)),
        reference_brier=rate * (1.0 - rate),
        log_loss=float(-np.mean(np.where(y, np.log(clipped), np.log1p(-clipped)))),
        ece=float(np.sum(counts[filled] * np.abs(predicted[filled] - observed[filled])) / len(p)),
        predicted=predicted,
        observed=observed,
        counts=counts,
        edges=edges,
    )


def held_out_layouts(problem: LayoutProblem, n_uniform: int, seed: int, centre: np.ndarray | None = None,
                     n_near: int = 0, radii: Sequence[float] = NEAR_RADII) -> tuple[np.ndarray, np.ndarray]:
    """Seeded held-out layouts: ``n_uniform`` Sobol points and ``n_near`` spread over balls around ``centre``.

    The Sobol sample is scrambled with ``seed``, which callers keep apart from the exploration's seed (the two
    samples then share no point). Returns the layouts ``(n, d)`` and, per row, where it came from: ``"uniform"`` or
    ``"near r"`` with the ball's radius.
    """
    rng = np.random.default_rng(seed)
    parts = [sobol_valid(problem, n_uniform, seed)] if n_uniform > 0 else []
    groups = ["uniform"] * (len(parts[0]) if parts else 0)
    if centre is not None and n_near > 0:
        per_ball = np.diff(np.linspace(0, n_near, len(radii) + 1).round().astype(int))
        for radius, n in zip(radii, per_ball):
            near = valid_in_ball(problem, np.asarray(centre, dtype=float), radius, int(n), rng,
                                 "held-out layouts")
            parts.append(near)
            groups += [f"near {radius:g}"] * len(near)
    U = np.concatenate(parts) if parts else np.zeros((0, problem.dim))
    return U, np.array(groups, dtype=object)


def psp_reliability(psp, U: np.ndarray, events: np.ndarray, bins: int = 10) -> list[Reliability]:
    """Each factor of a fitted PSP, then the whole PSP, scored on held-out layouts and their simulated events.

    A factor is scored where it applies, as it was trained: on the rows whose parents happened (the global model
    of ``factorize=False`` on every row). The last entry, ``"success"``, is the PSP against global success.
    """
    U = np.atleast_2d(np.asarray(U, dtype=float))
    events = np.asarray(events, dtype=bool)
    factors = psp.factor_probabilities(U)
    scores = []
    for k, model in enumerate(psp.models_):
        condition, labels = psp.factor_rows(events, k)
        scores.append(reliability(model.event, factors[condition, k], labels[condition], bins))
    scores.append(reliability("success", psp.predict_proba(U), events.all(axis=1), bins))
    return scores
