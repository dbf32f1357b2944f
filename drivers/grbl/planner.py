"""How long GRBL 1.1 takes to run a list of planner blocks: its planner (``planner.c``) and trapezoids.

The simulated GRBL's own clock runs each block at one speed (enough for a streamer's tests); a job's time estimate
needs what the firmware does: each block's nominal speed (its feed, or the rapid rate, limited per axis by
``$110``-``$112``), the acceleration along it (``$120``-``$122`` limited per axis), the speed it may pass a corner at
(the junction deviation ``$11``: ``plan_buffer_line``'s ``max_junction_speed_sqr``), a block that starts with the
planner empty (after a sync: a dwell, a spindle change, the job's start) starting from rest, and the look-ahead of
the planner's 15 blocks: the machine must always be able to stop at the end of what it holds, so a block's exit
speed is capped by the blocks that follow within that window. Each block then runs as a trapezoid (accelerate,
cruise, decelerate) between its entry and exit speeds.

What it leaves out: the stepper's 10 ms acceleration segments and step rounding (well under a per cent on the jobs
measured in ``bench/bench_job_estimate.py``), and overrides (the station's jobs run at 100 %).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["MotionBlock", "PlanTimes", "plan_times"]

#: Blocks GRBL 1.1's planner holds on an ATmega328p (BLOCK_BUFFER_SIZE 16, one slot always free).
PLANNER_WINDOW = 15
_LARGE = 1e38


@dataclass(frozen=True)
class MotionBlock:
    """One planner block: from ``start`` to ``end`` (machine mm, 3-vectors), a rapid or a feed move at ``feed``
    mm/min, ``from_rest`` when the planner was empty as it was planned (GRBL then enters it at speed 0)."""

    start: tuple[float, float, float]
    end: tuple[float, float, float]
    rapid: bool
    feed: float
    from_rest: bool = False


@dataclass(frozen=True)
class PlanTimes:
    """The planned motion: ``seconds`` per block, its ``entry`` and ``exit`` speeds (mm/s) and the total."""

    seconds: np.ndarray
    entry: np.ndarray
    exit: np.ndarray

    @property
    def total(self) -> float:
        return float(self.seconds.sum())


def _limit_by_axes(values: np.ndarray, unit: np.ndarray) -> float:
    """``limit_value_by_axis_maximum``: the largest value along ``unit`` that keeps every axis within its own."""
    moving = np.abs(unit) > 1e-12
    if not moving.any():
        return float(values.min())
    return float(np.min(values[moving] / np.abs(unit[moving])))


def plan_times(blocks: Sequence[MotionBlock], settings: Mapping[int, float],
               window: int = PLANNER_WINDOW) -> PlanTimes:
    """The time of each block as GRBL plans and runs it (module docstring); ``settings`` maps ``$N`` to values
    (``$11``, ``$110``-``$112`` mm/min, ``$120``-``$122`` mm/s^2)."""
    n = len(blocks)
    if n == 0:
        empty = np.zeros(0)
        return PlanTimes(empty, empty, empty)
    max_rate = np.array([float(settings[110]), float(settings[111]), float(settings[112])])
    accel_axes = np.array([float(settings[120]), float(settings[121]), float(settings[122])]) * 3600.0  # mm/min^2
    deviation = float(settings.get(11, 0.01))
    length = np.zeros(n)
    accel = np.zeros(n)
    nominal = np.zeros(n)
    max_entry = np.zeros(n)
    previous_unit = None
    previous_nominal = 0.0
    for i, block in enumerate(blocks):
        delta = np.asarray(block.end, dtype=float) - np.asarray(block.start, dtype=float)
        size = float(np.linalg.norm(delta))
        if size < 1e-9:
            continue  # GRBL plans no zero-length block
        unit = delta / size
        length[i] = size
        accel[i] = _limit_by_axes(accel_axes, unit)
        rapid_rate = _limit_by_axes(max_rate, unit)
        speed = rapid_rate if block.rapid else min(float(block.feed), rapid_rate)
        nominal[i] = max(speed, 1.0)  # MINIMUM_FEED_RATE
        if block.from_rest or previous_unit is None:
            junction = 0.0
        else:
            cos_theta = -float(np.dot(previous_unit, unit))
            if cos_theta > 0.999999:
                junction = 0.0  # a reversal: MINIMUM_JUNCTION_SPEED
            elif cos_theta < -0.999999:
                junction = _LARGE  # straight on
            else:
                turn = unit - previous_unit
                turn /= np.linalg.norm(turn)
                sin_half = math.sqrt(0.5 * (1.0 - cos_theta))
                junction = _limit_by_axes(accel_axes, turn) * deviation * sin_half / (1.0 - sin_half)
        max_entry[i] = min(min(nominal[i], previous_nominal) ** 2, junction)
        previous_unit, previous_nominal = unit, nominal[i]
    # the look-ahead: when block i runs, the planner holds it and the next window-1 blocks, the last of which
    # ends at rest; so block i's exit (the next block's entry) is capped by stopping within those
    entry = max_entry.copy()
    reach = 2.0 * accel * length
    for i in range(n - 1):
        last = min(i + window - 1, n - 1)
        v = 0.0
        for j in range(last, i, -1):
            v = min(max_entry[j], v + reach[j])
        entry[i + 1] = min(entry[i + 1], v)
    # the whole plan: backward from rest at the end, then forward from each entry
    exit_sqr = np.zeros(n)
    for i in range(n - 1, -1, -1):
        following = entry[i + 1] if i + 1 < n else 0.0
        exit_sqr[i] = following
        entry[i] = min(entry[i], following + reach[i])
    for i in range(n - 1):
        if entry[i + 1] > entry[i] + reach[i]:
            entry[i + 1] = entry[i] + reach[i]
        exit_sqr[i] = entry[i + 1]
    exit_sqr[n - 1] = 0.0
    seconds = np.zeros(n)
    for i in range(n):
        if length[i] <= 0:
            continue
        seconds[i] = _trapezoid(length[i], entry[i], exit_sqr[i], nominal[i] ** 2, accel[i]) * 60.0
    return PlanTimes(seconds, np.sqrt(entry) / 60.0, np.sqrt(exit_sqr) / 60.0)


def _trapezoid(size: float, v0_sqr: float, v1_sqr: float, vn_sqr: float, accel: float) -> float:
    """Minutes to run ``size`` mm entering at ``v0``, leaving at ``v1``, cruising at most at ``vn`` (all squared,
    mm/min) with ``accel`` mm/min^2."""
    v0_sqr, v1_sqr = min(v0_sqr, vn_sqr), min(v1_sqr, vn_sqr)
    up = (vn_sqr - v0_sqr) / (2.0 * accel)
    down = (vn_sqr - v1_sqr) / (2.0 * accel)
    v0, v1 = math.sqrt(v0_sqr), math.sqrt(v1_sqr)
    if up + down <= size:
        vn = math.sqrt(vn_sqr)
        return (vn - v0) / accel + (vn - v1) / accel + (size - up - down) / vn
    peak = math.sqrt(max(v0_sqr, v1_sqr, (2.0 * accel * size + v0_sqr + v1_sqr) / 2.0))
    return (peak - v0) / accel + (peak - v1) / accel
