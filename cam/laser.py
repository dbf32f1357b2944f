"""Laser jobs for GRBL 1.1 from plain polylines grouped by operation.

A job engraves first (labels: the sheet has not moved yet), then cuts each part: its inner contours (holes) before
its outer contour, so that a part never drops or shifts before its holes are cut; parts that sit inside another
part's hole (a gear nested in a ring) are cut before that part. Travel between paths is ordered by nearest neighbour
then improved by 2-opt (all candidate reversals scored at once with numpy); closed contours start at their vertex
nearest to the laser, open strokes may be run backwards.

G-code: ``M4`` (dynamic power: power scales with speed, so corners do not burn) with the operation's ``S`` on the
first cutting move of every path; every travel is a ``G0`` that also says ``S0``, so the beam is dark on travels
whether or not GRBL's laser mode (``$32=1``) blanks rapids; ``M5 S0`` ends the program. Passes and feeds come from
the profile's material table. A job is checked against the work area before it can be written or sent.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TextIO

import numpy as np

from drivers.errors import JobRefused
from drivers.gcode import format_number
from drivers.grbl.planner import plan_segments

__all__ = [
    "LaserPath",
    "LaserJob",
    "OperationSettings",
    "plan_laser_job",
    "plan_operations",
    "order_paths",
    "write_laser_gcode",
    "check_work_area",
    "path_travel",
    "travel_moves",
    "material_settings",
    "DEFAULT_MATERIAL",
]

#: The material used when none is named and the profile has it.
DEFAULT_MATERIAL = "plywood_3mm"


@dataclass(frozen=True)
class OperationSettings:
    """Power (fraction of max), feed (mm/min) and passes of one operation (duck-compatible with a profile's)."""

    power: float
    feed: float
    passes: int = 1

    @classmethod
    def checked(cls, name: str, settings) -> OperationSettings:
        """Operation ``name``'s settings from an object with ``power``, ``feed`` and ``passes`` (or such a tuple).

        Raises
        ------
        JobRefused
            A power outside [0, 1], a feed not positive or fewer than one pass.
        """
        power, feed, passes = settings if isinstance(settings, tuple) else (settings.power, settings.feed,
                                                                            settings.passes)
        power, feed, passes = float(power), float(feed), int(passes)
        if not 0.0 <= power <= 1.0:
            raise JobRefused(f"{name}: power must be a fraction of max power in [0, 1], got {power}")
        if not feed > 0 or passes < 1:
            raise JobRefused(f"{name}: feed must be positive and passes at least 1, got feed {feed}, passes {passes}")
        return cls(power, feed, passes)


@dataclass(frozen=True)
class LaserPath:
    """One path to burn: ``operation`` (``"engrave"`` or ``"cut"``), ``points`` ``(n, 2)`` mm, ``closed``."""

    operation: str
    points: np.ndarray
    closed: bool
    part: int = -1


@dataclass(frozen=True)
class LaserJob:
    """An ordered laser job.

    Attributes
    ----------
    paths : tuple of LaserPath
        In burning order, in work coordinates (mm).
    operations : mapping
        Settings per operation name (power fraction, feed mm/min, passes).
    max_power : float
        GRBL ``$30``: the ``S`` of full power.
    travel_feed : float
        Rapid rate (mm/min) for the estimate of a machine whose settings do not say it.
    travel_unordered : float
        Travel (mm) had the paths been run in the order given, each from its first point.
    machine_settings : mapping
        The machine's GRBL settings (``$N`` -> value: rates, accelerations, junction deviation) the run-time
        estimate plans with; GRBL's defaults for those missing.
    """

    paths: tuple[LaserPath, ...]
    operations: Mapping[str, OperationSettings]
    max_power: float = 1000.0
    travel_feed: float = 6000.0
    travel_unordered: float = 0.0
    start: tuple[float, float] = (0.0, 0.0)
    metadata: Mapping[str, str] = field(default_factory=dict)
    machine_settings: Mapping[int, float] = field(default_factory=dict)

    @property
    def travel(self) -> float:
        """Travel (mm) of the ordered job, from ``start`` and back to it, passes included."""
        return path_travel(self._burn_sequence(), self.start)

    def _burn_sequence(self) -> list[np.ndarray]:
        """Every burned polyline in order, passes expanded (open strokes alternate direction)."""
        sequence = []
        for path in self.paths:
            passes = int(self.operations[path.operation].passes)
            for index in range(passes):
                points = path.points
                if not path.closed and index % 2 == 1:
                    points = points[::-1]
                sequence.append(points)
        return sequence

    def burn_length(self, operation: str) -> float:
        """Length (mm) burned by ``operation``, passes included."""
        total = 0.0
        for path in self.paths:
            if path.operation == operation:
                total += float(np.linalg.norm(np.diff(path.points, axis=0), axis=1).sum())
        return total * int(self.operations[operation].passes) if operation in self.operations else 0.0

    def estimate_seconds(self) -> dict[str, float]:
        """Run-time estimate per operation and for travel, as GRBL's planner runs the job written from it
        (:mod:`drivers.grbl.planner`: acceleration, corner speeds, look-ahead) on the machine of
        :attr:`machine_settings`."""
        starts, ends, rapid, feed, owner = [], [], [], [], []

        def move(start, end, operation: str | None = None) -> None:
            starts.append(start)
            ends.append(end)
            rapid.append(operation is None)
            feed.append(np.nan if operation is None else self.operations[operation].feed)
            owner.append(operation or "travel")

        position = np.asarray(self.start, dtype=float)
        for path in self.paths:
            for index in range(int(self.operations[path.operation].passes)):
                points = path.points[::-1] if (not path.closed and index % 2 == 1) else path.points
                if not np.allclose(position, points[0], atol=5e-4):
                    move(position, points[0])
                for a, b in zip(points[:-1], points[1:]):
                    move(a, b, path.operation)
                position = points[-1]
        move(position, np.asarray(self.start, dtype=float))

        def xyz(points) -> np.ndarray:
            flat = np.asarray(points, dtype=float).reshape(-1, 2)
            return np.column_stack([flat, np.zeros(len(flat))])

        machine = {110: self.travel_feed, 111: self.travel_feed, **dict(self.machine_settings)}
        from_rest = np.zeros(len(starts), dtype=bool)
        from_rest[0] = True  # the job's start: the laser switched on (M4) empties the planner
        seconds = plan_segments(xyz(starts), xyz(ends), np.array(rapid), np.array(feed, dtype=float), from_rest,
                                machine).seconds
        owner = np.array(owner)
        estimate = {name: float(seconds[owner == name].sum()) for name in self.operations}
        estimate["travel"] = float(seconds[owner == "travel"].sum())
        estimate["total"] = sum(estimate.values())
        return estimate

    def extent(self) -> tuple[np.ndarray, np.ndarray]:
        """``(lo, hi)`` over every point visited, travel included (the start point too)."""
        points = np.concatenate([np.asarray([self.start], dtype=float)] + [p.points for p in self.paths])
        return points.min(axis=0), points.max(axis=0)


def path_travel(paths: Sequence[np.ndarray], start=(0.0, 0.0)) -> float:
    """Travel length (mm) to run ``paths`` in order, each from its first to its last point, from and back to
    ``start``."""
    if not paths:
        return 0.0
    starts = np.array([p[0] for p in paths])
    ends = np.array([p[-1] for p in paths])
    previous = np.vstack([np.asarray(start, dtype=float), ends])
    following = np.vstack([starts, np.asarray(start, dtype=float)])
    return float(np.linalg.norm(following - previous, axis=1).sum())


# ---------------------------------------------------------------------------------------------------------------
# Ordering.


def _two_opt(entry: np.ndarray, exit_: np.ndarray, start: np.ndarray, max_rounds: int = 2000) -> np.ndarray:
    """2-opt on an open tour from ``start``; path ``i`` is entered at ``entry[i]`` and left at ``exit_[i]``.

    Reversing the run ``i..j`` swaps each path's entry and exit (an open stroke runs backwards, a closed contour is
    unaffected because its entry equals its exit). All ``(i, j)`` gains are scored at once; the best improving
    reversal is applied until none improves. Returns the order and, per position, whether the path is reversed.
    """
    n = len(entry)
    order = np.arange(n)
    flipped = np.zeros(n, dtype=bool)
    if n < 3:
        return np.stack([order, flipped.astype(int)])
    for _ in range(max_rounds):
        e = np.where(flipped[:, None], exit_[order], entry[order])
        x = np.where(flipped[:, None], entry[order], exit_[order])
        previous_exit = np.vstack([start, x[:-1]])  # where the laser is before position i
        next_entry = np.vstack([e[1:], [np.nan, np.nan]])  # entry of position j+1 (none after the last)
        # gain(i, j) = |prev_i - e_i| + |x_j - next_j| - |prev_i - x_j| - |e_i - next_j|
        d_prev_e = np.linalg.norm(previous_exit - e, axis=1)[:, None]
        d_x_next = np.nan_to_num(np.linalg.norm(x - next_entry, axis=1), nan=0.0)[None, :]
        d_prev_x = np.linalg.norm(previous_exit[:, None, :] - x[None, :, :], axis=2)
        d_e_next = np.nan_to_num(np.linalg.norm(e[:, None, :] - next_entry[None, :, :], axis=2), nan=0.0)
        gain = d_prev_e + d_x_next - d_prev_x - d_e_next
        gain = np.triu(gain, k=1)
        candidates = np.flatnonzero(gain > 1e-9)
        if candidates.size == 0:
            break
        # Apply the best reversal and every other improving one that does not touch it: reversals of runs at
        # least one path apart change disjoint travel moves, so their gains add up. Rounds then scale with the
        # number of independent improvements, not with their total.
        if candidates.size > 4 * n:
            candidates = candidates[np.argpartition(gain.ravel()[candidates], -4 * n)[-4 * n:]]
        candidates = candidates[np.argsort(-gain.ravel()[candidates], kind="stable")]
        taken = np.zeros(n + 2, dtype=bool)
        for flat in candidates:
            i, j = divmod(int(flat), n)
            if taken[i:j + 3].any():  # the run, its neighbours' moves included
                continue
            taken[i:j + 3] = True
            order[i:j + 1] = order[i:j + 1][::-1].copy()
            flipped[i:j + 1] = ~flipped[i:j + 1][::-1]
    return np.stack([order, flipped.astype(int)])


def order_paths(paths: Sequence[np.ndarray], closed: Sequence[bool], start=(0.0, 0.0),
                ) -> tuple[list[np.ndarray], np.ndarray]:
    """Order paths to shorten travel: nearest neighbour, then 2-opt; closed contours re-started at their vertex
    nearest to the laser.

    Returns
    -------
    ordered : list of (n, 2) arrays
        The paths, in order and direction, closed ones rotated to their best start.
    order : (k,) int array
        Index of each ordered path in ``paths``.
    """
    count = len(paths)
    if count == 0:
        return [], np.zeros(0, dtype=int)
    position = np.asarray(start, dtype=float)
    starts = np.array([p[0] for p in paths], dtype=float)
    ends = np.array([p[-1] for p in paths], dtype=float)
    # Closed contours are represented by their vertex nearest to the centre of their box for the tour.
    anchors = []
    for path, is_closed in zip(paths, closed):
        if is_closed:
            centre = (path.min(axis=0) + path.max(axis=0)) / 2.0
            anchors.append(path[int(np.argmin(np.linalg.norm(path - centre, axis=1)))])
        else:
            anchors.append(path[0])
    anchors = np.array(anchors)
    entry = np.where(np.asarray(closed)[:, None], anchors, starts)
    exit_ = np.where(np.asarray(closed)[:, None], anchors, ends)
    # Nearest neighbour (either end of an open stroke).
    remaining = np.ones(count, dtype=bool)
    nn_order, nn_flip = [], []
    for _ in range(count):
        d_entry = np.where(remaining, np.linalg.norm(entry - position, axis=1), np.inf)
        d_exit = np.where(remaining & ~np.asarray(closed), np.linalg.norm(exit_ - position, axis=1), np.inf)
        i_entry, i_exit = int(np.argmin(d_entry)), int(np.argmin(d_exit))
        if d_exit[i_exit] < d_entry[i_entry]:
            nn_order.append(i_exit)
            nn_flip.append(True)
            position = entry[i_exit]
        else:
            nn_order.append(i_entry)
            nn_flip.append(False)
            position = exit_[i_entry]
        remaining[nn_order[-1]] = False
    nn_order = np.array(nn_order)
    nn_flip = np.array(nn_flip)
    e = np.where(nn_flip[:, None], exit_[nn_order], entry[nn_order])
    x = np.where(nn_flip[:, None], entry[nn_order], exit_[nn_order])
    improved = _two_opt(e, x, np.asarray(start, dtype=float))
    order = nn_order[improved[0]]
    flip = nn_flip[improved[0]] ^ improved[1].astype(bool)
    # Realize directions and the best start vertex of closed contours, following the laser.
    ordered = []
    position = np.asarray(start, dtype=float)
    for index, reverse in zip(order, flip):
        path = np.asarray(paths[index], dtype=float)
        if closed[index]:
            ring = path[:-1] if np.allclose(path[0], path[-1]) else path
            k = int(np.argmin(np.linalg.norm(ring - position, axis=1)))
            path = np.vstack([ring[k:], ring[:k], ring[k:k + 1]])
        elif reverse:
            path = path[::-1]
        ordered.append(path)
        position = path[-1]
    return ordered, order


def _inside(point: np.ndarray, polygon: np.ndarray) -> bool:
    """Even-odd point-in-polygon test (vectorized over the polygon's edges)."""
    x, y = point
    xa, ya = polygon[:-1, 0], polygon[:-1, 1]
    xb, yb = polygon[1:, 0], polygon[1:, 1]
    crosses = (ya > y) != (yb > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xs = xa + (y - ya) * (xb - xa) / (yb - ya)
    return bool(np.count_nonzero(crosses & (x < xs)) % 2)


def plan_laser_job(engrave: Sequence[np.ndarray], cut: Sequence[tuple[Sequence[np.ndarray], np.ndarray]],
                   engrave_settings, cut_settings, max_power: float = 1000.0, travel_feed: float = 6000.0,
                   offset=(0.0, 0.0), start=(0.0, 0.0), optimize: bool = True,
                   metadata: Mapping[str, str] | None = None,
                   machine_settings: Mapping[int, float] | None = None) -> LaserJob:
    """Order the engraving strokes and the parts' contours into a :class:`LaserJob`.

    Parameters
    ----------
    engrave : list of (n, 2) arrays
        Open strokes to engrave (labels).
    cut : list of (inner contours, outer contour)
        One entry per part: closed ``(n, 2)`` contours (first point repeated last).
    engrave_settings, cut_settings : objects with ``power``, ``feed``, ``passes``
        E.g. a profile material's ``engrave`` and ``cut`` (:class:`drivers.profiles.LaserOperation`).
    max_power : float
        GRBL ``$30``.
    travel_feed : float
        Rapid rate for estimates (mm/min) when ``machine_settings`` do not say it.
    offset : (float, float)
        Added to every point: where the sheet's front-left corner sits in work coordinates.
    start : (float, float)
        Where the laser head starts and returns (work coordinates).
    optimize : bool
        False keeps the given order (for comparisons).
    machine_settings : mapping, optional
        The machine's GRBL settings (a profile's ``grbl_settings``) the run-time estimate plans with.
    """
    offset = np.asarray(offset, dtype=float)
    start_xy = np.asarray(start, dtype=float)
    operations = {}
    for name, settings in (("engrave", engrave_settings), ("cut", cut_settings)):
        operations[name] = OperationSettings.checked(name, settings)
    strokes = [np.asarray(s, dtype=float) + offset for s in engrave if len(s) >= 2]
    groups = [([np.asarray(h, dtype=float) + offset for h in inner], np.asarray(outer, dtype=float) + offset)
              for inner, outer in cut]
    unordered = strokes + [c for inner, outer in groups for c in [*inner, outer]]
    travel_unordered = path_travel(unordered, start_xy)

    paths: list[LaserPath] = []
    if not optimize:
        paths += [LaserPath("engrave", s, False) for s in strokes]
        for index, (inner, outer) in enumerate(groups):
            paths += [LaserPath("cut", h, True, index) for h in inner] + [LaserPath("cut", outer, True, index)]
        return LaserJob(tuple(paths), operations, max_power, travel_feed, travel_unordered, tuple(start_xy),
                        dict(metadata or {}), dict(machine_settings or {}))

    ordered, _ = order_paths(strokes, [False] * len(strokes), start_xy)
    paths += [LaserPath("engrave", s, False) for s in ordered]
    position = ordered[-1][-1] if ordered else start_xy
    # Depth of each part: how many other parts' outlines enclose it. Deeper parts are cut first.
    depth = np.array([sum(_inside(outer[0], other) for j, (_, other) in enumerate(groups) if j != i)
                      for i, (_, outer) in enumerate(groups)], dtype=int)
    for level in sorted(set(depth.tolist()), reverse=True):
        members = [i for i in range(len(groups)) if depth[i] == level]
        # Order the parts by a representative contour each, then each part's holes, then its outline.
        _, part_order = order_paths([groups[i][1] for i in members], [True] * len(members), position)
        for k in part_order:
            index = members[int(k)]
            inner, outer = groups[index]
            holes, _ = order_paths(inner, [True] * len(inner), position)
            for hole in holes:
                paths.append(LaserPath("cut", hole, True, index))
                position = hole[-1]
            outline, _ = order_paths([outer], [True], position)
            paths.append(LaserPath("cut", outline[0], True, index))
            position = outline[0][-1]
    return LaserJob(tuple(paths), operations, max_power, travel_feed, travel_unordered, tuple(start_xy),
                    dict(metadata or {}), dict(machine_settings or {}))


def plan_operations(groups: Sequence[tuple[str, object, Sequence[np.ndarray], bool]], max_power: float = 1000.0,
                    travel_feed: float = 6000.0, offset=(0.0, 0.0), start=(0.0, 0.0),
                    metadata: Mapping[str, str] | None = None,
                   machine_settings: Mapping[int, float] | None = None) -> LaserJob:
    """A job of named operations burned one after the other, each with its own settings (a test card's cells).

    ``groups`` holds ``(name, settings, paths, closed)``: ``settings`` has ``power``, ``feed`` and ``passes`` (or is
    a ``(power, feed, passes)`` tuple); the paths of one group are ordered for travel from where the laser stands.
    A name may come back in a later group with the same settings (one tag's fill, then the next one's).
    ``machine_settings`` are the machine's GRBL settings the run-time estimate plans with (as
    :func:`plan_laser_job`'s).
    """
    offset = np.asarray(offset, dtype=float)
    position = np.asarray(start, dtype=float)
    operations: dict[str, OperationSettings] = {}
    paths: list[LaserPath] = []
    unordered: list[np.ndarray] = []
    for name, settings, group, closed in groups:
        checked = OperationSettings.checked(name, settings)
        if name in operations and operations[name] != checked:
            raise JobRefused(f"operation {name!r} is given two different settings")
        operations[name] = checked
        shifted = [np.asarray(p, dtype=float) + offset for p in group if len(p) >= 2]
        unordered += shifted
        ordered, _ = order_paths(shifted, [closed] * len(shifted), position)
        paths += [LaserPath(name, p, closed) for p in ordered]
        if ordered:
            position = ordered[-1][-1]
    return LaserJob(tuple(paths), operations, max_power, travel_feed,
                    path_travel(unordered, np.asarray(start, dtype=float)), tuple(np.asarray(start, dtype=float)),
                    dict(metadata or {}), dict(machine_settings or {}))


# ---------------------------------------------------------------------------------------------------------------
# Checks and writing.


def check_work_area(job: LaserJob, bounds: tuple[float, float, float, float], machine: str = "the laser") -> None:
    """Refuse a job that leaves the work area ``(xmin, ymin, xmax, ymax)``.

    Raises
    ------
    JobRefused
        Naming the job's extent and the work area.
    """
    lo, hi = job.extent()
    xmin, ymin, xmax, ymax = bounds
    tolerance = 1e-6
    if lo[0] < xmin - tolerance or lo[1] < ymin - tolerance or hi[0] > xmax + tolerance or hi[1] > ymax + tolerance:
        raise JobRefused(
            f"job extent X {lo[0]:.2f}..{hi[0]:.2f} mm, Y {lo[1]:.2f}..{hi[1]:.2f} mm leaves the work area of "
            f"{machine} (X {xmin:g}..{xmax:g} mm, Y {ymin:g}..{ymax:g} mm); use a smaller sheet or scale")


def write_laser_gcode(job: LaserJob, stream: TextIO, bounds: tuple[float, float, float, float] | None = None,
                      laser_mode: bool = True, machine: str = "the laser") -> int:
    """Write the job as GRBL 1.1 G-code; returns the number of lines.

    ``bounds`` (the profile's work area) is checked first; a profile whose laser mode is off is refused, because
    ``M4`` dynamic power needs ``$32=1``.
    """
    if not laser_mode:
        raise JobRefused(f"{machine}: laser mode ($32) is off in the profile; M4 dynamic power needs $32=1")
    if bounds is not None:
        check_work_area(job, bounds, machine)
    lines = [f"; chaos-station laser job: {k}: {v}" for k, v in job.metadata.items()]
    estimate = job.estimate_seconds()
    for name, settings in job.operations.items():
        lines.append(f"; {name}: S{format_number(settings.power * job.max_power)} (power {settings.power:g}) "
                     f"F{format_number(settings.feed)} passes {settings.passes}")
    lines.append(f"; estimated run time {estimate['total'] / 60.0:.1f} min, travel {job.travel:.0f} mm")
    lines += ["G21 G90 G94 G17", "M5 S0", "M4 S0"]
    x, y = job.start
    lines.append(f"G0 X{format_number(x)} Y{format_number(y)} S0")
    # Where the head is after the last burn: a path that starts there continues without a travel.
    lines_at = None
    for path in job.paths:
        settings = job.operations[path.operation]
        s_word = format_number(settings.power * job.max_power)
        points = path.points
        for index in range(int(settings.passes)):
            run = points[::-1] if (not path.closed and index % 2 == 1) else points
            if not (lines_at is not None and np.allclose(lines_at, run[0], atol=5e-4)):
                lines.append(f"G0 X{format_number(run[0, 0])} Y{format_number(run[0, 1])} S0")
            lines_at = run[-1]
            lines.append(f"G1 X{format_number(run[1, 0])} Y{format_number(run[1, 1])} S{s_word} "
                         f"F{format_number(settings.feed)}")
            lines.extend(f"G1 X{format_number(px)} Y{format_number(py)}" for px, py in run[2:])
    lines.append(f"G0 X{format_number(x)} Y{format_number(y)} S0")
    lines.append("M5 S0")
    stream.write("\n".join(lines) + "\n")
    return len(lines)


def travel_moves(job: LaserJob) -> list[np.ndarray]:
    """The travel moves of a job as two-point polylines (for previews)."""
    moves = []
    position = np.asarray(job.start, dtype=float)
    for points in job._burn_sequence():
        moves.append(np.vstack([position, points[0]]))
        position = points[-1]
    moves.append(np.vstack([position, np.asarray(job.start, dtype=float)]))
    return moves


def material_settings(profile, material: str | None) -> tuple[object, object, str]:
    """``(engrave, cut, material name)`` from a laser profile's material table.

    Without a name: :data:`DEFAULT_MATERIAL` when the profile has it, else its first material by name.
    """
    if not getattr(profile, "is_laser", False) or profile.laser is None:
        raise JobRefused(f"profile {profile.name!r} is a {profile.kind}, not a laser")
    if not profile.materials:
        raise JobRefused(f"profile {profile.name!r} has no [materials.NAME] table")
    if material is None:
        material = DEFAULT_MATERIAL if DEFAULT_MATERIAL in profile.materials else sorted(profile.materials)[0]
    name = material
    chosen = profile.material(name)
    return chosen.engrave, chosen.cut, name
