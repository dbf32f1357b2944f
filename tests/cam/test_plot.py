"""Plot jobs written from polylines (a table of input, options, exact output, vpype style), fitted to the paper and
simplified within a tolerance."""

from __future__ import annotations

import io

import numpy as np
import pytest
from shapely import LineString, Point

from cam.plot import WriterOptions, fit_polylines, simplify_polylines, write_plot_gcode
from drivers.gcode import GcodeError
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
