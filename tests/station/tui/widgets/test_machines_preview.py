"""The Machines screen's job preview (station.tui.widgets.machines_preview): the drawing is drivers.gcode's
drawn_polylines, each point tied to the job line that drew it; progress splits it into done and left."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.gcode import drawn_polylines
from drivers.grbl import Job
from station.services.job_preview import preview_runs, split_at_line
from station.tui.widgets.machines_preview import JobPreview

# Two squares (pen down M3 S30, pen up M3 S50), then a laser-style run with the spindle off (M5) that draws nothing.
LINES = [
    "G21", "G90", "M3 S50",                                      # 0-2
    "G0 X0 Y0", "M3 S30",                                        # 3-4
    "G1 X10 Y0 F3000", "G1 X10 Y10", "G1 X0 Y10", "G1 X0 Y0",    # 5-8
    "M3 S50", "G0 X20 Y0", "M3 S30",                             # 9-11
    "G1 X30 Y0", "G2 X30 Y10 I0 J5",                             # 12-13: an arc, split into chords
    "M5", "G1 X40 Y40",                                          # 14-15: spindle off, no drawing
    "G0 X0 Y0",                                                  # 16
]


def test_the_drawing_is_drawn_polylines_and_each_point_has_its_line():
    runs = preview_runs(Job("squares", LINES))
    expected = drawn_polylines(LINES)
    assert len(runs) == len(expected) == 2
    for (points, lines), want in zip(runs, expected):
        assert np.array_equal(points, want) and len(lines) == len(points)
    (square, square_lines), (arc, arc_lines) = runs
    assert square_lines.tolist() == [5, 5, 6, 7, 8]
    assert arc_lines[:2].tolist() == [12, 12] and set(arc_lines[2:].tolist()) == {13} and len(arc) > 4
    assert np.all(np.diff(arc_lines) >= 0)


def test_progress_splits_the_drawing_at_the_current_line():
    runs = preview_runs(Job("squares", LINES))
    polylines, colors = split_at_line(runs, None)
    assert colors == ["white", "white"]
    polylines, colors = split_at_line(runs, 6)  # the square's second side is being drawn
    assert colors == ["green", "grey50", "grey50"]
    assert polylines[0].tolist() == [[0, 0], [10, 0], [10, 10]]
    assert polylines[1].tolist() == [[10, 10], [0, 10], [0, 0]]  # the rest starts where the done part ends
    polylines, colors = split_at_line(runs, len(LINES))
    assert colors == ["green", "green"]


@pytest.mark.parametrize("lines", [["G1 X1 Y1 Q"], ["G21"]])
def test_a_job_that_cannot_be_read_or_draws_nothing_shows_nothing(lines):
    preview = JobPreview()
    preview.show_job(Job("odd", LINES))
    assert len(preview.polylines) == 2
    preview.show_job(Job("odd", lines))
    assert preview.polylines == []


def test_each_job_is_read_once():
    preview = JobPreview()
    first, second = Job("a", LINES), Job("b", LINES[:9])
    runs = preview.runs_of(first)
    preview.show_job(second, 5)
    assert preview.runs_of(first) is runs and len(preview.runs_of(second)) == 1
    for k in range(JobPreview.KEEP):
        preview.runs_of(Job(f"c{k}", LINES))
    assert preview.runs_of(first) is not runs  # the oldest drawings are let go
