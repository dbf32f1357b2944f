"""Platt's sigmoid and the combination of a PSP's factors: the arithmetic the fitted model and its JSON share.

Light on purpose (numpy only): :mod:`design.robust.model_io` predicts from a LAYOUT.json with it, without importing
scikit-learn.
"""

from __future__ import annotations

import numpy as np

#: Platt parameters that leave a probability as it is when applied to its logit.
IDENTITY_PLATT = (-1.0, 0.0)
#: Logits are clipped to this magnitude (a factor of exactly 0 or 1 would give an infinite one).
LOGIT_LIMIT = 30.0


def platt_probability(scores: np.ndarray, platt: tuple[float, float]) -> np.ndarray:
    """Platt's sigmoid ``1 / (1 + exp(a f + b))`` of decision values, the exponent clipped to [-500, 500]."""
    return 1.0 / (1.0 + np.exp(np.clip(platt[0] * np.asarray(scores, dtype=float) + platt[1], -500, 500)))


def logit(p: np.ndarray) -> np.ndarray:
    """``log(p / (1 - p))``, clipped to ±:data:`LOGIT_LIMIT`."""
    p = np.clip(np.asarray(p, dtype=float), 1e-300, 1.0 - 1e-16)
    return np.clip(np.log(p) - np.log1p(-p), -LOGIT_LIMIT, LOGIT_LIMIT)


def combine_factors(factors: np.ndarray, platt: tuple[float, float] = IDENTITY_PLATT) -> np.ndarray:
    """The PSP from factor probabilities ``(n, n_factors)``: their product, mapped by Platt's sigmoid of its logit
    (the identity with :data:`IDENTITY_PLATT`, the thesis's Equation 4.8)."""
    product = np.prod(np.atleast_2d(factors), axis=1)
    if tuple(float(v) for v in platt) == IDENTITY_PLATT:
        return product
    return platt_probability(logit(product), platt)
