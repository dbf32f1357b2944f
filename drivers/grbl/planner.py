"""How long GRBL 1.1 takes to run a job: its planner (``planner.c``) and trapezoids, the one time estimate of the
station (the streamer's ETA, the plot preview, the job queue, ``--verify``).

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

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from drivers.gcode import Toolpath, clean_line

__all__ = ["MotionBlock", "PlanTimes", "line_seconds", "plan_segments", "plan_times", "sync_lines"]

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


#: GRBL 1.1's defaults (``defaults.h``) for a setting a machine did not report: max rate (mm/min), acceleration
#: (mm/s^2), junction deviation (mm).
DEFAULT_RATE, DEFAULT_ACCELERATION, DEFAULT_DEVIATION = 500.0, 10.0, 0.01

#: Blocks after which GRBL's planner is empty when the next block is planned (``protocol_buffer_synchronize``):
#: program pauses and ends, coordinate-system writes (EEPROM), stored positions; spindle changes and dwells are read
#: from the modal state instead.
_SYNC_WORDS = re.compile(r"(?<![A-Z])(?:M0*(?:0|2|30)(?![\d.])|G10(?![\d.])|G[23]8\.1)")


def _limit_by_axes(values: np.ndarray, units: np.ndarray) -> np.ndarray:
    """``limit_value_by_axis_maximum`` per row of ``units``: the largest value along it that keeps every axis
    within its own."""
    magnitude = np.abs(units)
    moving = magnitude > 1e-12
    with np.errstate(divide="ignore"):
        ratio = np.where(moving, values / np.where(moving, magnitude, 1.0), np.inf)
    limited = ratio.min(axis=1)
    return np.where(moving.any(axis=1), limited, values.min())


def _setting(settings: Mapping[int, float], key: int, default: float) -> float:
    value = settings.get(key)
    return float(value) if value is not None and float(value) > 0 else default


def plan_times(blocks: Sequence[MotionBlock], settings: Mapping[int, float],
               window: int = PLANNER_WINDOW) -> PlanTimes:
    """The time of each block as GRBL plans and runs it (module docstring); ``settings`` maps ``$N`` to values
    (``$11``, ``$110``-``$112`` mm/min, ``$120``-``$122`` mm/s^2; GRBL's defaults for those missing)."""
    n = len(blocks)
    if n == 0:
        empty = np.zeros(0)
        return PlanTimes(empty, empty, empty)
    return plan_segments(np.array([b.start for b in blocks], dtype=float), np.array([b.end for b in blocks],
                         dtype=float), np.array([b.rapid for b in blocks], dtype=bool),
                         np.array([b.feed for b in blocks], dtype=float),
                         np.array([b.from_rest for b in blocks], dtype=bool), settings, window)


def plan_segments(start: np.ndarray, end: np.ndarray, rapid: np.ndarray, feed: np.ndarray, from_rest: np.ndarray,
                  settings: Mapping[int, float], window: int = PLANNER_WINDOW) -> PlanTimes:
    """:func:`plan_times` on arrays: ``start``/``end`` (n, 3) mm, ``rapid`` and ``from_rest`` (n,) bool, ``feed``
    (n,) mm/min (ignored for rapids). A zero-length block is not planned (GRBL drops it): it takes no time, and a
    sync before it carries to the next block."""
    n = len(start)
    seconds, entry_out, exit_out = np.zeros(n), np.zeros(n), np.zeros(n)
    if n == 0:
        return PlanTimes(seconds, entry_out, exit_out)
    max_rate = np.array([_setting(settings, 110 + axis, DEFAULT_RATE) for axis in range(3)])
    accel_axes = np.array([_setting(settings, 120 + axis, DEFAULT_ACCELERATION) for axis in range(3)]) * 3600.0
    deviation = _setting(settings, 11, DEFAULT_DEVIATION)
    delta = np.asarray(end, dtype=float) - np.asarray(start, dtype=float)
    size = np.linalg.norm(delta, axis=1)
    planned = size >= 1e-9
    index = np.flatnonzero(planned)
    if len(index) == 0:
        return PlanTimes(seconds, entry_out, exit_out)
    # a sync before a dropped block still empties the planner before the next planned one
    synced = np.cumsum(np.asarray(from_rest, dtype=bool))
    before = np.concatenate([[0], synced[index[:-1]]])
    rest = (synced[index] - before) > 0
    rest[0] = True
    length = size[index]
    unit = delta[index] / length[:, None]
    accel = _limit_by_axes(accel_axes, unit)
    rapid_rate = _limit_by_axes(max_rate, unit)
    feeds = np.asarray(feed, dtype=float)[index]
    speed = np.where(np.asarray(rapid, dtype=bool)[index] | ~np.isfinite(feeds), rapid_rate,
                     np.minimum(np.nan_to_num(feeds, nan=np.inf), rapid_rate))
    nominal = np.maximum(speed, 1.0)  # MINIMUM_FEED_RATE
    m = len(index)
    junction = np.zeros(m)
    if m > 1:
        previous = unit[:-1]
        cos_theta = -np.einsum("ij,ij->i", previous, unit[1:])
        turn = unit[1:] - previous
        norm = np.linalg.norm(turn, axis=1)
        turn = turn / np.where(norm > 0, norm, 1.0)[:, None]
        sin_half = np.sqrt(np.clip(0.5 * (1.0 - cos_theta), 0.0, 1.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            corner = _limit_by_axes(accel_axes, turn) * deviation * sin_half / (1.0 - sin_half)
        corner = np.where(cos_theta > 0.999999, 0.0, np.where(cos_theta < -0.999999, _LARGE, corner))
        junction[1:] = corner
    junction[rest] = 0.0
    previous_nominal = np.concatenate([[0.0], nominal[:-1]])
    max_entry = np.minimum(np.minimum(nominal, previous_nominal) ** 2, junction)
    # the look-ahead: when block i runs, the planner holds it and the next window-1 blocks, the last of which
    # ends at rest; so block i's exit (the next block's entry) is capped by stopping within those
    entry = max_entry.copy()
    reach = 2.0 * accel * length
    if m > 1:
        v = np.zeros(m - 1)
        origin = np.arange(m - 1)
        for k in range(window - 1, 0, -1):
            j = origin + k
            inside = j <= m - 1
            v[inside] = np.minimum(max_entry[j[inside]], v[inside] + reach[j[inside]])
        entry[1:] = np.minimum(entry[1:], v)
    # the whole plan: backward from rest at the end, then forward from each entry (one block depends on the next)
    entries, reaches = entry.tolist(), reach.tolist()
    following = 0.0
    for i in range(m - 1, -1, -1):
        entries[i] = min(entries[i], following + reaches[i])
        following = entries[i]
    for i in range(m - 1):
        if entries[i + 1] > entries[i] + reaches[i]:
            entries[i + 1] = entries[i] + reaches[i]
    entry = np.array(entries)
    exit_sqr = np.append(entry[1:], 0.0)
    seconds[index] = _trapezoid(length, entry, exit_sqr, nominal ** 2, accel) * 60.0
    entry_out[index], exit_out[index] = np.sqrt(entry) / 60.0, np.sqrt(exit_sqr) / 60.0
    return PlanTimes(seconds, entry_out, exit_out)


def sync_lines(toolpath: Toolpath, lines: Sequence[str], laser_mode: bool) -> np.ndarray:
    """Per line of ``lines``: whether GRBL empties its planner there (a dwell, a spindle change, a pause...), so
    that the next motion starts from rest."""
    states = toolpath.states
    sync = np.asarray(toolpath.dwell, dtype=float) > 0
    for i, line in enumerate(lines):
        if sync[i]:
            continue
        before, after = states[i], states[i + 1]
        if after.spindle != before.spindle or (
                not laser_mode and after.spindle in (3, 4) and after.power != before.power):
            sync[i] = True
        elif _SYNC_WORDS.search(clean_line(line)):
            sync[i] = True
    return sync


def line_seconds(toolpath: Toolpath, lines: Sequence[str], settings: Mapping[int, float], *,
                 laser_mode: bool = False) -> np.ndarray:
    """Seconds per line of ``lines`` (read as ``toolpath``) as GRBL's planner runs them on a machine with
    ``settings`` (``$N``), dwells included: what every job-time estimate of the station uses."""
    per_line = np.zeros(len(lines))
    if len(toolpath.start):
        sync = np.cumsum(sync_lines(toolpath, lines, laser_mode))
        segment_line = np.asarray(toolpath.line, dtype=int)
        # a segment starts from rest when a line from the previous segment's (exclusive) to its own synced
        from_rest = np.empty(len(segment_line), dtype=bool)
        from_rest[0] = True
        from_rest[1:] = sync[segment_line[1:]] - sync[segment_line[:-1]] > 0
        planned = plan_segments(toolpath.start, toolpath.end, toolpath.rapid, toolpath.feed, from_rest, settings)
        np.add.at(per_line, segment_line, planned.seconds)
    return per_line + np.asarray(toolpath.dwell, dtype=float)


def _trapezoid(size: np.ndarray, v0_sqr: np.ndarray, v1_sqr: np.ndarray, vn_sqr: np.ndarray,
               accel: np.ndarray) -> np.ndarray:
    """Minutes to run ``size`` mm entering at ``v0``, leaving at ``v1``, cruising at most at ``vn`` (all squared,
    mm/min) with ``accel`` mm/min^2 (arrays, one value per block)."""
    v0_sqr, v1_sqr = np.minimum(v0_sqr, vn_sqr), np.minimum(v1_sqr, vn_sqr)
    up = (vn_sqr - v0_sqr) / (2.0 * accel)
    down = (vn_sqr - v1_sqr) / (2.0 * accel)
    v0, v1, vn = np.sqrt(v0_sqr), np.sqrt(v1_sqr), np.sqrt(vn_sqr)
    cruise = (vn - v0) / accel + (vn - v1) / accel + (size - up - down) / vn
    peak = np.sqrt(np.maximum(np.maximum(v0_sqr, v1_sqr), (2.0 * accel * size + v0_sqr + v1_sqr) / 2.0))
    triangle = (peak - v0) / accel + (peak - v1) / accel
    return np.where(up + down <= size, cruise, triangle)
