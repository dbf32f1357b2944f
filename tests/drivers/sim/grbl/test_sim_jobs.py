"""The job writers' output run through the simulated GRBL end to end (virtual clock): what the machine executed is
what the G-code reader says the program draws or burns."""

from __future__ import annotations

import io

import numpy as np
import pytest

from cam.laser import OperationSettings, plan_laser_job, write_laser_gcode
from cam.plot import WriterOptions, write_plot_gcode
from drivers.gcode import clean_line, drawn_polylines, interpret
from drivers.grbl import Job, JobRunner

from ...conftest import sim_url


def _square(x: float, y: float, size: float) -> np.ndarray:
    return np.array([[x, y], [x + size, y], [x + size, y + size], [x, y + size], [x, y]], dtype=float)


def _motion(lines: list[str]) -> list[str]:
    return [clean_line(x) for x in lines if clean_line(x).startswith(("G0", "G1"))]


def test_a_plot_job_from_the_writer_runs_on_the_twin_as_the_reader_reads_it(make_connection):
    t = np.linspace(0, 2 * np.pi, 120)
    radius = 30 + 12 * np.cos(6 * t)
    star = np.column_stack([150 + radius * np.cos(t), 120 + radius * np.sin(t)])
    options = WriterOptions(draw_feed=2400.0, pen_up=("M3 S50", "G4 P0.15"), pen_down=("M3 S30", "G4 P0.15"))
    out = io.StringIO()
    write_plot_gcode([star, _square(20, 20, 40)], out, options)
    lines = out.getvalue().splitlines()
    conn = make_connection(sim_url("plotter", time_scale=1, clock="virtual"))
    result = JobRunner(conn, Job("plot", lines, pen_up=options.pen_up)).run()
    assert result.ok, result.message
    record = conn.port.machine.snapshot()
    wco = np.array(conn.work_offset())
    assert [b.text for b in record.executed] == _motion(lines)
    # every block ends where the reader's toolpath says its line ends (work mm)
    toolpath = interpret(lines)
    ends = np.array([b.end for b in record.executed]) - wco
    assert np.allclose(ends, toolpath.end, atol=1e-9)
    # the pen is down (S30) exactly on the drawn polylines, up (S50) on every travel
    drawn = [np.array(b.end)[:2] - wco[:2] for b in record.executed if b.power == 30.0]
    expected = drawn_polylines(lines, options.pen_down, options.pen_up)
    assert len(expected) == 2
    assert np.allclose(np.array(drawn), np.concatenate([p[1:] for p in expected]), atol=1e-9)
    assert all(b.power == 50.0 for b in record.executed if b.rapid)


def test_a_laser_job_runs_on_the_twin_dark_on_travels_at_power_on_cuts(make_connection):
    engrave = OperationSettings(power=0.3, feed=3000.0, passes=1)
    cut = OperationSettings(power=1.0, feed=600.0, passes=2)
    strokes = [np.array([[30.0, 30.0], [60.0, 30.0]])]
    groups = [([_square(110, 110, 10)], _square(100, 100, 30)), ([], _square(20, 60, 20))]
    job = plan_laser_job(strokes, groups, engrave, cut, 1000.0)
    out = io.StringIO()
    write_laser_gcode(job, out, (0.0, 0.0, 400.0, 400.0))
    lines = out.getvalue().splitlines()
    conn = make_connection(sim_url("laser", time_scale=1, clock="virtual"))
    result = JobRunner(conn, Job("laser", lines, laser=True)).run()
    assert result.ok and result.laser_off, result.message
    record = conn.port.machine.snapshot()
    assert [b.text for b in record.executed] == _motion(lines)
    rapids = [b for b in record.executed if b.rapid]
    burns = [b for b in record.executed if not b.rapid]
    assert len(rapids) >= len(job.paths) and all(b.power == 0.0 for b in rapids)
    assert sorted({b.power for b in burns}) == [pytest.approx(300.0), pytest.approx(1000.0)]
    # the engraving (S300) comes before every cut (S1000), and the hole before its part's outline
    powers = [b.power for b in burns]
    assert powers.index(1000.0) > len(powers) - 1 - powers[::-1].index(300.0)
    wco = np.array(conn.work_offset())
    cut_ends = np.array([b.end for b in burns if b.power == 1000.0])[:, :2] - wco[:2]
    in_hole = np.all((cut_ends >= 110 - 1e-6) & (cut_ends <= 120 + 1e-6), axis=1)
    on_outline = np.all((cut_ends >= 100 - 1e-6) & (cut_ends <= 130 + 1e-6), axis=1) & ~in_hole
    assert in_hole.sum() == 8 and on_outline.sum() == 8  # two passes of four sides each
    assert np.flatnonzero(in_hole)[-1] < np.flatnonzero(on_outline)[0]
    assert record.samples[-1].power == 0.0
