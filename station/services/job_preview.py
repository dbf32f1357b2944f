"""What a G-code job draws, for a preview: its drawing tied to the job's lines, so that progress (the line the machine
is executing) splits it into what is done and what is left; a multi-pen plot's pens and pen-up travel.

The drawing is :func:`drivers.gcode.drawn_polylines` of the job (feed moves with the spindle on: the laser burning,
the servo pen of a plotter); each point is then tied to the job line that drew it, so that progress splits the
drawing without reading the G-code again. Used by the Machines screen's preview.
"""

from __future__ import annotations

import numpy as np

from drivers.gcode import GcodeError, Toolpath, drawn_polylines
from drivers.gcode_layers import layer_at, layer_marks
from drivers.grbl import Job
from station.errors import station_errors

__all__ = ["PreviewRun", "preview_runs", "run_pens", "split_at_line", "travel_segments"]

#: A drawn polyline ((n, 2) points) and, for each point, the 0-based job line that drew it.
PreviewRun = tuple[np.ndarray, np.ndarray]


@station_errors
def preview_runs(job: Job) -> list[PreviewRun]:
    """The polylines ``job`` draws, each point with its 0-based line.

    Raises
    ------
    drivers.gcode.GcodeError
        If a line of the job cannot be read.
    """
    polylines = drawn_polylines(job.lines)
    return list(zip(polylines, _lines_of_points(polylines, job.toolpath)))


def _lines_of_points(polylines: list[np.ndarray], toolpath: Toolpath) -> list[np.ndarray]:
    # drawn_polylines keeps the toolpath's feed segments in order (a polyline's step i is one segment, its point
    # values copied exactly), so one forward scan over the feed segments finds the line of every step.
    feed = np.flatnonzero(~toolpath.rapid)
    segments = list(zip(map(tuple, toolpath.start[feed, :2].tolist()), map(tuple, toolpath.end[feed, :2].tolist())))
    seg_lines = toolpath.line[feed].tolist()
    k = 0
    result = []
    for points in polylines:
        xy = list(map(tuple, points.tolist()))
        lines = np.zeros(len(xy), dtype=int)
        for i in range(1, len(xy)):
            while k < len(segments) and segments[k] != (xy[i - 1], xy[i]):
                k += 1
            lines[i] = seg_lines[min(k, len(segments) - 1)]
            k += 1
        lines[0] = lines[1] if len(xy) > 1 else 0
        result.append(lines)
    return result


@station_errors
def split_at_line(runs: list[PreviewRun], current_line: int | None,
                  pens: list[str] | None = None) -> tuple[list[np.ndarray], list[str]]:
    """Polylines and colours to show: all white without ``current_line``; else green up to and including that
    0-based line, grey50 after it (the two parts share the point where the line is cut). ``pens`` (a colour per
    run: a multi-pen plot's) replaces white and green."""
    polylines, colors = [], []
    for k, (points, lines) in enumerate(runs):
        pen = pens[k] if pens is not None else None
        if current_line is None:
            polylines.append(points)
            colors.append(pen or "white")
            continue
        cut = int(np.searchsorted(lines, current_line, side="right"))
        if cut >= 2:
            polylines.append(points[:cut])
            colors.append(pen or "green")
        if len(points) - max(cut - 1, 0) >= 2:
            polylines.append(points[max(cut - 1, 0):])
            colors.append("grey50")
    return polylines, colors


@station_errors
def travel_segments(job: Job) -> list[np.ndarray]:
    """The pen-up travel of a job: its rapid moves, each a two-point polyline (empty for a job that cannot be read)."""
    try:
        toolpath = job.toolpath
    except GcodeError:
        return []
    rapid = np.flatnonzero(toolpath.rapid)
    return [np.array([toolpath.start[k, :2], toolpath.end[k, :2]]) for k in rapid]


@station_errors
def run_pens(job: Job, runs: list[PreviewRun]) -> list[str] | None:
    """The pen colour of each run of a multi-pen plot (its layer marks), None for a job written without them."""
    marks = layer_marks(job.lines)
    if not marks:
        return None
    return [(layer_at(marks, int(lines[0])) or marks[0]).color for _, lines in runs]
