"""G-code writer (a table of input, options, exact output, vpype style), parser, fitting and simplification."""

from __future__ import annotations

import io

import numpy as np
import pytest
from shapely import LineString, Point

from cam.plot import WriterOptions, fit_polylines, simplify_polylines, write_plot_gcode
from drivers.gcode import GcodeError, clean_line, drawn_polylines, interpret, tokenize
from drivers.profiles import builtin_profile

SQUARE = np.array([[0, 0], [10, 0], [10, 10], [0, 10], [0, 0]], dtype=float)
BARE = WriterOptions(pen_up=("PU",), pen_down=("PD",), header=(), home_at_end=False)

WRITER_CASES = [
    (
        "one segment, bare",
        [np.array([[1, 2], [3, 4]])],
        BARE,
        "PU\nG0 X1 Y2\nPD\nG1 X3 Y4 F3000\nPU\n",
    ),
    (
        "feed only on the first draw move; precision trims zeros",
        [np.array([[0.5, 0.25], [1.1234, 2], [3, 4.0006]])],
        BARE,
        "PU\nG0 X0.5 Y0.25\nPD\nG1 X1.123 Y2 F3000\nG1 X3 Y4.001\nPU\n",
    ),
    (
        "two polylines, custom feeds, home at end",
        [np.array([[0, 0], [1, 0]]), np.array([[5, 5], [6, 6]])],
        WriterOptions(draw_feed=1200, pen_up=("PU",), pen_down=("PD",), header=("G21",), home_at_end=True),
        "G21\nPU\nG0 X0 Y0\nPD\nG1 X1 Y0 F1200\nPU\nG0 X5 Y5\nPD\nG1 X6 Y6 F1200\nPU\nG0 X0 Y0\n",
    ),
    (
        "single points are skipped",
        [np.array([[1, 1]]), np.array([[2, 2], [3, 3]])],
        BARE,
        "PU\nG0 X2 Y2\nPD\nG1 X3 Y3 F3000\nPU\n",
    ),
    (
        "travels as G1 at travel feed, comment and footer",
        [np.array([[0, 0], [0, 1]])],
        WriterOptions(pen_up=(), pen_down=(), header=(), footer=("M5 S0",), travel_with_g1=True,
                      travel_feed=5000, comment="t", home_at_end=False),
        "(t)\nG1 X0 Y0 F5000\nG1 X0 Y1 F3000\nM5 S0\n",
    ),
    (
        "negative zero is written as 0",
        [np.array([[-0.0001, 0], [-2, -3]])],
        BARE,
        "PU\nG0 X0 Y0\nPD\nG1 X-2 Y-3 F3000\nPU\n",
    ),
]


@pytest.mark.parametrize(("label", "polylines", "options", "expected"), WRITER_CASES, ids=[c[0] for c in WRITER_CASES])
def test_writer_table(label, polylines, options, expected):
    stream = io.StringIO()
    count = write_plot_gcode(polylines, stream, options)
    assert stream.getvalue() == expected
    assert count == expected.count("\n")


def test_writer_options_from_profiles():
    plotter = WriterOptions.from_profile(builtin_profile("plotter"))
    assert plotter.pen_up == ("M3 S50", "G4 P0.15") and plotter.pen_down == ("M3 S30", "G4 P0.15")
    laser = WriterOptions.from_profile(builtin_profile("laser"), power=0.5)
    assert laser.header[-1] == "M4 S500" and laser.footer == ("M5 S0",) and laser.pen_up == ()


def test_writer_rejects_bad_polylines():
    with pytest.raises(GcodeError, match="shape"):
        write_plot_gcode([np.zeros((3, 3))], io.StringIO())
    with pytest.raises(GcodeError, match="non-finite"):
        write_plot_gcode([np.array([[0, 0], [np.nan, 1]])], io.StringIO())


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


def test_fit_centres_and_scales():
    fitted = fit_polylines([SQUARE], (0, 0, 100, 50))
    stacked = np.concatenate(fitted)
    assert stacked.min(axis=0).tolist() == pytest.approx([25, 0])
    assert stacked.max(axis=0).tolist() == pytest.approx([75, 50])
    sized = np.concatenate(fit_polylines([SQUARE], (0, 0, 100, 50), size=20))
    assert (sized.max(axis=0) - sized.min(axis=0)).tolist() == pytest.approx([20, 20])
    with pytest.raises(GcodeError, match="does not fit"):
        fit_polylines([SQUARE], (0, 0, 100, 50), size=60)
    with pytest.raises(GcodeError, match="no extent"):
        fit_polylines([np.zeros((3, 2))], (0, 0, 1, 1))


def test_simplify_stays_within_tolerance_and_keeps_closed():
    t = np.linspace(0, 2 * np.pi, 2000)
    circle = np.column_stack([50 * np.cos(t), 50 * np.sin(t)])
    circle[-1] = circle[0]
    (simple,) = simplify_polylines([circle], 0.05)
    assert len(simple) < 200
    assert np.array_equal(simple[0], simple[-1])
    line = LineString(simple)
    assert max(line.distance(Point(p)) for p in circle[::7]) <= 0.05 + 1e-9


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
