"""Curve sampling shared by every machine: times uniform in arc length, vectorized over many designs.

A machine's kinematics is a vectorized function ``positions(P, t) -> complex`` of parameter arrays ``P`` (one row
per design, shape ``(k, 1)``) and times ``t`` (shape ``(k, n)``); :func:`arclength_times` inverts the arc length
of such curves so that samples are equidistant along them, which plotters and curve distances want.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

Positions = Callable[[Mapping[str, np.ndarray], np.ndarray], np.ndarray]


def arclength_times(positions: Positions, P: Mapping[str, np.ndarray], period: np.ndarray, n: int, dense: int):
    """Times at which the curves are equidistant in arc length (vectorized over designs).

    1. Evaluate each curve densely (``dense`` points per period) and accumulate its length, each chord corrected to
       its arc by the turning angle ``theta`` at its ends (``arc = chord (1 + theta^2 / 24)`` on a circle through
       three points).
    2. Invert the cumulative length by linear interpolation (one ``searchsorted`` for every design).
    3. One Newton step inside each dense interval, measuring the length reached with the chord to the
       interpolated point, which removes the error of assuming a constant speed within the interval.
    Relative spacing errors are ~1e-4 at 256 points (larger across cusps, where chords cannot follow arcs).

    Parameters
    ----------
    positions : callable
        The machine's vectorized kinematics, ``positions(P, t)`` -> complex array.
    P : mapping of str to ndarray
        Parameter columns, shape ``(k, 1)`` each.
    period : ndarray, shape (k, 1)
        Each design's period.
    n : int
        Samples per design; the first is at time 0, the last at the period.
    dense : int
        Dense evaluations per design used to measure the length.

    Returns
    -------
    ndarray, shape (k, n)
        The sampling times.
    """
    k = period.shape[0]
    h = period / (dense - 1)  # (k, 1) dense time step
    z = positions(P, h * np.arange(dense)[None, :])
    dz = np.diff(z, axis=1)
    chord = np.abs(dz)
    safe = np.where(dz == 0, 1.0, dz)
    turn = np.abs(np.angle(safe[:, 1:] / safe[:, :-1]))
    theta = np.empty_like(chord)
    theta[:, 1:-1] = 0.5 * (turn[:, 1:] + turn[:, :-1])
    theta[:, 0], theta[:, -1] = turn[:, 0], turn[:, -1]
    arc = chord * (1.0 + theta * theta / 24.0)
    length = np.concatenate([np.zeros((k, 1)), np.cumsum(arc, axis=1)], axis=1)
    total = np.where(length[:, -1:] > 0, length[:, -1:], 1.0)
    target = np.linspace(0.0, 1.0, n)[None, :] * total
    # One searchsorted for all rows: offset each row's (non-decreasing) normalized lengths by 2 x its index.
    offset = 2.0 * np.arange(k)[:, None]
    flat = (length / total + offset).ravel()
    goal = (target / total + offset).ravel()
    index = np.searchsorted(flat, goal, side="right").reshape(k, n) - 1 - dense * np.arange(k)[:, None]
    index = np.clip(index, 0, dense - 2)
    rows = np.arange(k)[:, None]
    start, step, step_chord = length[rows, index], arc[rows, index], chord[rows, index]
    moving = step > 0
    weight = np.clip(np.where(moving, (target - start) / np.where(moving, step, 1.0), 0.0), 0.0, 1.0)
    t = (index + weight) * h
    # Newton step: the length reached at t is the interval's arc times the chord fraction to z(t).
    reached = start + step * np.abs(positions(P, t) - z[rows, index]) / np.where(moving, step_chord, 1.0)
    speed = np.where(moving, step / h, 1.0)
    t = np.clip(t + np.where(moving, (target - reached) / speed, 0.0), index * h, (index + 1) * h)
    t[:, 0], t[:, -1] = 0.0, period[:, 0]
    return t
