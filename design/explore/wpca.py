"""Weighted Principal Component Analysis, after Delchambre (2015, MNRAS 446, 3545).

Principal vectors come from a direct eigen-decomposition of the weighted covariance matrix
``C = (W * X)^T (W * X) / (W^T W)`` (element-wise weights), and the coordinates of a sample on them from a weighted
least-squares fit. The thesis (3.5.2) used the ``wpca`` package for this; it is small enough to keep here, in the
scikit-learn estimator shape.
"""

from __future__ import annotations

import numpy as np

from design.errors import ParameterError


class WPCA:
    """Weighted PCA.

    Parameters
    ----------
    n_components : int or None
        Number of components to keep (all by default).
    center : array-like or None
        Point the data are centered on; the weighted mean when None. The invariant subspace centers on the current
        design, so its principal directions pass through it.

    Attributes
    ----------
    center_ : (d,) array
    components_ : (n_components, d) array
        Unit principal vectors, by decreasing explained variance.
    explained_variance_ : (n_components,) array
    explained_variance_ratio_ : (n_components,) array
        Relative variances (sum to 1 over all d components).
    """

    def __init__(self, n_components: int | None = None, center=None):
        self.n_components = n_components
        self.center = center

    def fit(self, X, weights=None) -> WPCA:
        X = np.asarray(X, dtype=float)
        if X.ndim != 2 or len(X) < 1:
            raise ParameterError(f"WPCA: X must be a non-empty (n_samples, n_features) array, got shape {X.shape}")
        W = self._weights(X, weights)
        if self.center is None:
            with np.errstate(invalid="ignore", divide="ignore"):
                center = np.nan_to_num(np.sum(W * X, axis=0) / np.sum(W, axis=0))
        else:
            center = np.asarray(self.center, dtype=float).reshape(-1)
            if center.shape != (X.shape[1],):
                raise ParameterError(f"WPCA: center must have {X.shape[1]} values, got {center.shape}")
        Xc = X - center
        Xw = Xc * W
        with np.errstate(invalid="ignore", divide="ignore"):
            covar = (Xw.T @ Xw) / (W.T @ W)
        covar = np.nan_to_num(covar)
        evals, evecs = np.linalg.eigh(covar)
        order = np.argsort(evals)[::-1]
        evals = np.clip(evals[order], 0.0, None)
        evecs = evecs[:, order].T
        k = X.shape[1] if self.n_components is None else int(self.n_components)
        total = float(np.sum(evals))
        self.center_ = center
        self.components_ = evecs[:k]
        self.explained_variance_ = evals[:k]
        self.explained_variance_ratio_ = evals[:k] / total if total > 0 else np.zeros(k)
        return self

    def transform(self, X, weights=None) -> np.ndarray:
        """Coordinates on the principal vectors, by weighted least squares per sample."""
        X = np.asarray(X, dtype=float)
        W = self._weights(X, weights)
        Xc = X - self.center_
        V = self.components_
        out = np.empty((len(X), len(V)))
        for k in range(len(X)):
            A = V.T * W[k][:, None]
            out[k] = np.linalg.lstsq(A, Xc[k] * W[k], rcond=None)[0]
        return out

    def inverse_transform(self, Y) -> np.ndarray:
        return self.center_ + np.asarray(Y, dtype=float) @ self.components_

    @staticmethod
    def _weights(X: np.ndarray, weights) -> np.ndarray:
        if weights is None:
            return np.ones_like(X)
        W = np.asarray(weights, dtype=float)
        if W.ndim == 1:
            W = W[:, None]
        W = np.broadcast_to(W, X.shape).astype(float)
        if np.any(W < 0) or not np.all(np.isfinite(W)):
            raise ParameterError("WPCA: weights must be finite and >= 0")
        return W
