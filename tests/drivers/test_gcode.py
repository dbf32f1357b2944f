"""The G-code reader (clean lines, words, the modal state machine), and a plot job read back through it."""

from __future__ import annotations

import numpy as np
import pytest
from shapely import LineString, Point

from drivers.gcode import GcodeError, clean_line, drawn_polylines, interpret, tokenize
from drivers.profiles import builtin_profile


@pytest.mark.parametrize(
    ("line", "expected"),
    [("G1 X10 (comment) Y2 ; tail", "G1X10Y2"), ("  g0x1  ", "G0X1"), ("(only a comment)", ""), ("$$", "$$")],
)
def test_clean_line(line, expected):
    assert clean_line(line) == expected


def test_tokenize_and_errors():
    assert tokenize("G1X-1.5Y.25F3000") == [("G", 1.0), ("X", -1.5), ("Y", 0.25), ("F", 3000.0)]
    with pytest.raises(GcodeError, match="column 3"):
        tokenize("G1?X1")


def test_interpret_modal_state_units_relative_and_arcs():
    program = ["G21 G90", "G0 X10 Y0", "G1 X20 F600", "G91", "G1 Y5", "G20 G90", "G1 X1", "G21",
               "G2 X25.4 Y-5 I0 J-5 F300", "M3 S200", "G4 P0.5"]
    path = interpret(program)
    assert path.end[0].tolist() == [10, 0, 0]  # the first move from an unknown position is just its end point
    assert path.end[1].tolist() == [20, 0, 0] and path.feed[1] == 600
    assert path.end[2].tolist() == [20, 5, 0]
    assert path.end[3].tolist() == pytest.approx([25.4, 5, 0])
    arc_points = path.end[path.line == 8]
    assert len(arc_points) > 4
    assert arc_points[-1].tolist() == pytest.approx([25.4, -5, 0])
    radii = np.linalg.norm(arc_points[:, :2] - np.array([25.4, 0.0]), axis=1)
    assert np.allclose(radii, 5.0) and arc_points[:, 0].max() == pytest.approx(30.4, abs=0.011)  # clockwise: through +X
    assert path.dwell[10] == 0.5
    state = path.states[-1]
    assert state.spindle == 3 and state.power == 200 and state.units_mm
    lo, hi = path.extent()
    assert lo[0] == pytest.approx(10) and hi[0] == pytest.approx(30.4, abs=0.011)


def test_preamble_rebuilds_modal_state():
    path = interpret(["G21 G90", "G0 X5 Y6", "M4 S300", "G1 X7 Y8 F1500", "G1 X9 Y9"])
    state = path.states[4]
    assert state.preamble(("M5",)) == ["G21 G90 G94 G54 G17", "M5", "G0 X7 Y8", "M4 S300", "F1500"]


def test_plot_job_read_back_matches_pattern_within_tolerance():
    """A pattern written through the plot path and read back from the G-code lies within the tolerance."""
    from station.commands.machines_io import plot_job

    rng = np.random.default_rng(4)
    t = np.linspace(0, 2 * np.pi, 3000)
    noise = 0.2 * rng.normal(0, 0.001, t.size)
    pattern = np.column_stack([np.cos(3 * t) + 0.3 * np.cos(11 * t), np.sin(2 * t) + noise])
    profile = builtin_profile("plotter")
    tolerance = 0.05
    text, fitted, simplified, options = plot_job([pattern], profile, 120.0, tolerance)
    drawn = drawn_polylines(text.splitlines(), options.pen_down, options.pen_up)
    assert len(drawn) == 1
    path = LineString(drawn[0])
    distances = np.array([path.distance(Point(p)) for p in fitted[0]])
    assert distances.max() <= tolerance + 1e-3  # + the 3-decimal rounding of coordinates
    back = LineString(fitted[0])
    assert max(back.distance(Point(p)) for p in drawn[0]) <= 1e-3
    paper = profile.paper
    lo, hi = drawn[0].min(axis=0), drawn[0].max(axis=0)
    assert np.all(lo >= paper.margin - 1e-6) and hi[0] <= paper.width - paper.margin + 1e-6
    assert (hi - lo).max() == pytest.approx(120.0, abs=2 * tolerance)  # simplification may cut extremes
