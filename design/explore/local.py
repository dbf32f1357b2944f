"""Batch tracking of Points of Interest on many neighbouring designs at once, near their known parameter times.

Building the invariant subspace evaluates the tracked PoIs on hundreds of neighbouring designs; the thesis
re-simulated and re-analysed every full curve. Here a PoI is only looked for near its parameter time(s) on the
current design (the thesis notes that candidates "need only be computed in the circle of radius sigma_PoI centered
at the reference PoI"), and every design is evaluated in the same numpy call through the machine's vectorized
kinematics:

- a curvature maximum: ``|kappa(t)|`` on a window of times around ``t0`` (analytic curve, finite differences in
  time), the local maximum nearest to ``t0`` (Eq. 3.14 in time rather than arc length: both are monotone along the
  curve), then successive parabolic refinements;
- a crossing: Newton's method on ``gamma(t1) - gamma(t2) = 0`` from the current ``(t1, t2)``.

A PoI is reported lost on a design when no maximum is inside the window, Newton does not converge or collapses onto
one time, or the PoI moved farther than ``sigma_poi`` from where it was on the current design.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from design.explore.poi import CURVATURE, INTERSECTION

#: Time step of the five-point finite differences that give the curve's derivatives (time is a gear angle in
#: radians): truncation ~ DT^4 times the 6th derivative (gear ratios up to ~30), round-off ~ 1e-16 / DT^2.
_DT = 2e-3


class BatchCurve:
    """Pen positions of many designs of one machine that differ only in their continuous parameters.

    Parameters
    ----------
    machine : DrawingMachine
        A model of :mod:`design.machines`.
    params : mapping
        A complete design; its discrete parameters are shared by every row.
    names : sequence of str
        The continuous parameters that vary (columns of the ``X`` arrays).
    """

    def __init__(self, machine, params: Mapping[str, float], names):
        self.machine = machine
        self.params = dict(params)
        self.names = tuple(names)

    def rows(self, X: np.ndarray) -> dict[str, np.ndarray]:
        """Parameter arrays of ``k`` designs (``X`` is (k, len(names)))."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        k = len(X)
        rows = {name: np.full(k, float(value)) for name, value in self.params.items()}
        for i, name in enumerate(self.names):
            rows[name] = X[:, i].copy()
        return rows

    def feasible(self, X: np.ndarray) -> np.ndarray:
        """Vectorized feasibility of the designs (the machine's constraints only)."""
        return self.machine.feasible_mask(self.rows(X))

    def positions(self, X: np.ndarray, T: np.ndarray) -> np.ndarray:
        """Complex pen positions ``(k, m)`` of design ``k`` at its times ``T[k]``."""
        rows = self.rows(X)
        k = len(next(iter(rows.values())))
        T = np.broadcast_to(np.asarray(T, dtype=float), (k,) + np.shape(T)[-1:])
        # The models' batch evaluation: every design and time in one numpy call. No feasibility check here: callers
        # filter designs with feasible() (a probe just past a constraint only yields a lost PoI, never a crash).
        with np.errstate(all="ignore"):
            xy = self.machine.curve_many(rows, T, check=False)
        return xy[..., 0] + 1j * xy[..., 1]

    def derivatives(self, X: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, first and second time derivatives at times ``T`` (five-point stencils, one batched call)."""
        T = np.asarray(T, dtype=float)
        stacked = np.concatenate([T - 2 * _DT, T - _DT, T, T + _DT, T + 2 * _DT], axis=-1)
        z = self.positions(X, stacked)
        m = T.shape[-1]
        z_mm, z_m, z_0, z_p, z_pp = (z[:, i * m : (i + 1) * m] for i in range(5))
        d1 = (z_mm - 8 * z_m + 8 * z_p - z_pp) / (12 * _DT)
        d2 = (-z_mm + 16 * z_m - 30 * z_0 + 16 * z_p - z_pp) / (12 * _DT**2)
        return z_0, d1, d2


def curvature_of(d1: np.ndarray, d2: np.ndarray) -> np.ndarray:
    """Unsigned curvature from complex first and second derivatives."""
    speed = np.abs(d1)
    with np.errstate(all="ignore"):
        kappa = np.abs((np.conj(d1) * d2).imag) / speed**3
    return np.where(np.isfinite(kappa), kappa, 0.0)


@dataclass
class LocalPoI:
    """A PoI followed by parameter time on the current design.

    Attributes
    ----------
    kind : {"curvature", "intersection"}
    times : tuple of float
        Parameter time(s) on the current design.
    xy : (float, float)
        Position on the current design (the sigma_PoI test is relative to it).
    window : float
        Half-width (in time) of the search for a curvature maximum; also the largest time shift accepted.
    period : float
        The pattern's period (times are modulo it).
    min_prominence : float
        A curvature maximum whose peak rises less than this above the lowest curvature on either side within the
        window is lost (it is fading away; the full detection would not see it either).
    """

    kind: str
    times: tuple[float, ...]
    xy: tuple[float, float]
    window: float
    period: float
    min_prominence: float = 0.0


@dataclass
class LocalFeatures:
    """Features of one tracked PoI on ``k`` designs (NaN where lost)."""

    xy: np.ndarray  # (k, 2)
    times: np.ndarray  # (k, 1) or (k, 2)
    curvature: np.ndarray  # (k,)
    angle: np.ndarray  # (k,)
    lost: np.ndarray  # (k,) bool


def track_curvature_maximum(curves: BatchCurve, X: np.ndarray, ref: LocalPoI, sigma_poi: float, coarse: int = 25):
    """Follow a curvature maximum onto designs ``X`` (see the module docstring)."""
    X = np.atleast_2d(X)
    k = len(X)
    t0 = ref.times[0]
    offsets = np.linspace(-ref.window, ref.window, coarse)
    _, d1, d2 = curves.derivatives(X, np.broadcast_to(t0 + offsets, (k, coarse)))
    kappa = curvature_of(d1, d2)
    interior = (kappa[:, 1:-1] > kappa[:, :-2]) & (kappa[:, 1:-1] >= kappa[:, 2:])
    found = interior.any(axis=1)
    # Among the local maxima, the one nearest to t0 (Eq. 3.14 in time).
    closeness = np.where(interior, -np.abs(offsets[1:-1])[None, :], -np.inf)
    index = np.argmax(closeness, axis=1) + 1
    # Prominence within the window: the peak above the higher of the lowest values on its left and on its right.
    left_low = np.minimum.accumulate(kappa, axis=1)
    right_low = np.minimum.accumulate(kappa[:, ::-1], axis=1)[:, ::-1]
    rows = np.arange(k)
    prominence = kappa[rows, index] - np.maximum(left_low[rows, index], right_low[rows, index])
    found &= prominence >= ref.min_prominence
    t = t0 + offsets[index]
    step = np.full(k, offsets[1] - offsets[0])
    for _ in range(12):
        T = t[:, None] + step[:, None] * np.array([-1.0, 0.0, 1.0])
        _, d1, d2 = curves.derivatives(X, T)
        kk = curvature_of(d1, d2)
        denom = kk[:, 0] - 2 * kk[:, 1] + kk[:, 2]
        with np.errstate(all="ignore"):
            shift = np.where(denom < 0, 0.5 * (kk[:, 0] - kk[:, 2]) / denom, 0.0)
        shift = np.clip(np.nan_to_num(shift), -1.0, 1.0)
        t = t + shift * step
        step = step * np.where(np.abs(shift) < 0.5, 0.25, 1.0)
        if np.all(step < 1e-9):
            break
    z, d1, d2 = curves.derivatives(X, t[:, None])
    z, kappa = z[:, 0], curvature_of(d1, d2)[:, 0]
    xy = np.column_stack([z.real, z.imag])
    moved = np.hypot(xy[:, 0] - ref.xy[0], xy[:, 1] - ref.xy[1])
    lost = ~found | ~np.isfinite(moved) | (moved > sigma_poi) | (np.abs(t - t0) > ref.window)
    xy[lost] = np.nan
    kappa = np.where(lost, np.nan, kappa)
    return LocalFeatures(xy, t[:, None], kappa, np.full(k, np.nan), lost)


def track_crossing(curves: BatchCurve, X: np.ndarray, ref: LocalPoI, sigma_poi: float, size: float, iterations=12):
    """Follow a self-intersection onto designs ``X`` by Newton's method on ``gamma(t1) = gamma(t2)``."""
    X = np.atleast_2d(X)
    k = len(X)
    t = np.tile(np.asarray(ref.times, dtype=float), (k, 1))
    max_step = ref.window / 2
    for _ in range(iterations):
        z, d1, _ = curves.derivatives(X, t)
        F = z[:, 0] - z[:, 1]
        # J = [z'(t1), -z'(t2)] as real 2x2; solve J dt = -F by Cramer's rule (vectorized).
        a, c = d1[:, 0].real, d1[:, 0].imag
        b, d = -d1[:, 1].real, -d1[:, 1].imag
        det = a * d - b * c
        with np.errstate(all="ignore"):
            dt1 = (-F.real * d + F.imag * b) / det
            dt2 = (-F.imag * a + F.real * c) / det
        step = np.column_stack([dt1, dt2])
        step = np.nan_to_num(step, nan=0.0, posinf=0.0, neginf=0.0)
        scale = np.maximum(np.abs(step).max(axis=1) / max_step, 1.0)
        t = t + step / scale[:, None]
    z, d1, _ = curves.derivatives(X, t)
    residual = np.abs(z[:, 0] - z[:, 1])
    xy = np.column_stack([z[:, 0].real, z[:, 0].imag])
    cos = np.abs((np.conj(d1[:, 0]) * d1[:, 1]).real) / (np.abs(d1[:, 0]) * np.abs(d1[:, 1]))
    angle = np.arccos(np.clip(np.nan_to_num(cos, nan=1.0), 0.0, 1.0))
    moved = np.hypot(xy[:, 0] - ref.xy[0], xy[:, 1] - ref.xy[1])
    shift = np.abs(t - np.asarray(ref.times)[None, :]).max(axis=1)
    separation = np.abs(t[:, 0] - t[:, 1]) % ref.period
    separation = np.minimum(separation, ref.period - separation)
    lost = (
        ~np.isfinite(residual)
        | (residual > 1e-7 * size)
        | (separation < ref.window)  # collapsed onto a single time: not a crossing
        | (moved > sigma_poi)
        | (shift > 4 * ref.window)
    )
    xy[lost] = np.nan
    return LocalFeatures(xy, t, np.full(k, np.nan), np.where(lost, np.nan, angle), lost)


def track_local(curves: BatchCurve, X: np.ndarray, ref: LocalPoI, sigma_poi: float, size: float) -> LocalFeatures:
    """Features of PoI ``ref`` on every design of ``X`` (rows of continuous parameter values)."""
    if ref.kind == CURVATURE:
        return track_curvature_maximum(curves, X, ref, sigma_poi)
    if ref.kind == INTERSECTION:
        return track_crossing(curves, X, ref, sigma_poi, size)
    raise ValueError(f"unknown PoI kind {ref.kind!r}")
