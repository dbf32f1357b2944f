"""The job pre-flight against the machine's travel: both ends of every axis, Z, arcs and relative moves, with homing
(machine space as GRBL's soft limits see it) and without (the job's size and the way to it must fit the travel).

Most tests call :meth:`JobRunner.preflight` only: it reads the settings, offsets and status from the simulated
machine, and nothing moves.
"""

from __future__ import annotations

import numpy as np
import pytest

from drivers.errors import JobRefused
from drivers.gcode import interpret
from drivers.grbl import Job, JobRunner
from drivers.grbl.job import commanded_extent

from ..conftest import sim_url


def preflight(conn, *lines: str) -> dict:
    return JobRunner(conn, Job("job", list(lines))).preflight()


def refusal(conn, *lines: str) -> str:
    with pytest.raises(JobRefused) as refused:
        preflight(conn, *lines)
    return str(refused.value)


# ------------------------------------------------------------------ homing on: GRBL's machine space


@pytest.fixture
def homed(make_connection):
    """The laser profile: homing on, travel 400 x 400 x 20, work zero at the front-left corner (machine -400, -400);
    the head stands at machine 0 (work X 400 Y 400)."""
    conn = make_connection(sim_url("laser"))
    assert conn.homing_enabled and conn.machine_bounds() == ((-400, -400, -20), (0, 0, 0))
    return conn


@pytest.mark.parametrize(("move", "expected"), [
    # the head stands at work X 400 Y 400, so the extent reaches from there
    ("G0 X-1 Y10", "X -1.00..400.00 (machine -401.00..0.00, travel -400.00..0.00)"),
    ("G0 X401 Y10", "X 400.00..401.00 (machine 0.00..1.00, travel -400.00..0.00)"),
    ("G0 X10 Y-1", "Y -1.00..400.00 (machine -401.00..0.00, travel -400.00..0.00)"),
    ("G0 X10 Y401", "Y 400.00..401.00 (machine 0.00..1.00, travel -400.00..0.00)"),
    ("G0 Z-21", "Z -21.00..0.00 (machine -21.00..0.00, travel -20.00..0.00)"),
    ("G0 Z1", "Z 0.00..1.00 (machine 0.00..1.00, travel -20.00..0.00)"),
])
def test_both_ends_of_every_axis_are_checked(homed, move, expected):
    message = refusal(homed, "G21 G90", move)
    assert "leaves the machine's travel" in message and expected in message
    assert message.count("(machine") == 1  # only the axis that leaves


@pytest.mark.parametrize("move", ["G0 X0 Y0", "G0 X400 Y400", "G0 X0 Y400 Z-20", "G0 X400 Y0 Z0"])
def test_the_ends_themselves_are_inside(homed, move):
    assert preflight(homed, "G21 G90", move)["homing"] is True


def test_an_arc_bulging_outside_its_end_points_is_refused(homed):
    # from (10, 200) to (10, 100) around (10, 150): counter-clockwise it passes X -40 (machine -440), clockwise X 60
    message = refusal(homed, "G21 G90", "G0 X10 Y200", "G3 X10 Y100 I0 J-50 F1000")
    assert "X -39.99..400.00 (machine -439.99..0.00" in message  # chords of at most 0.01 mm error on the arc
    preflight(homed, "G21 G90", "G0 X10 Y200", "G2 X10 Y100 I0 J-50 F1000")


def test_relative_moves_leaving_the_travel_are_refused(homed):
    assert "X 10.00..410.00" in refusal(homed, "G21 G90", "G0 X10 Y10", "G91", "G0 X200", "G0 X200")
    assert "X -10.00..400.00" in refusal(homed, "G21 G90", "G0 X10 Y10", "G91 G0 X-20")
    preflight(homed, "G21 G90", "G0 X10 Y10", "G91", "G0 X200", "G0 X-100", "G0 X150")  # peaks at 310: inside


def test_force_origin_puts_only_the_axes_with_a_homing_dir_bit_in_positive_space(make_connection):
    # HOMING_FORCE_SET_ORIGIN ('Z' in [OPT]) with $23=1: X in 0..400, Y (bit clear) still in -400..0
    conn = make_connection(sim_url("laser", force_origin=1, s23=1))
    assert conn.force_origin and conn.machine_bounds() == ((0, -400, -20), (400, 0, 0))
    preflight(conn, "G21 G90", "G0 X390 Y10")  # machine X 390, Y -390
    assert "X -5.00..0.00 (machine -5.00..0.00, travel 0.00..400.00)" in refusal(conn, "G21 G90", "G0 X-5 Y10")
    assert "Y 10.00..400.00 (machine -390.00..0.00" not in refusal(conn, "G21 G90", "G0 X10 Y401")
    assert "Y 400.00..401.00 (machine 0.00..1.00, travel -400.00..0.00)" in refusal(conn, "G21 G90", "G0 X10 Y401")


# ------------------------------------------------------------------ homing off: size and reach


@pytest.fixture
def unhomed(make_connection):
    """A machine with GRBL's defaults ($22=0, $20=0) and 200 x 200 x 20 mm of travel; the head stood at work zero
    when it was switched on."""
    conn = make_connection(sim_url("laser", homing=0, travel="200x200x20"))
    assert not conn.homing_enabled and not conn.soft_limits
    return conn


def test_without_homing_a_job_in_positive_coordinates_is_accepted(unhomed):
    # machine space -200..0 means nothing without homing: this job was refused before
    checked = preflight(unhomed, "G21 G90", "G0 X20 Y20", "G1 X180 Y20 F3000", "G1 X180 Y180", "G0 X0 Y0")
    assert checked["homing"] is False and checked["extent_hi"][:2] == [180.0, 180.0]


@pytest.mark.parametrize(("lines", "expected"), [
    (("G0 X0 Y0", "G1 X300 Y100 F3000"), "this job is 300.0 mm wide; your machine travels 200.0 mm in X ($130)"),
    (("G0 X10 Y10", "G1 X100 Y260 F3000"), "this job is 250.0 mm deep; your machine travels 200.0 mm in Y ($131)"),
    (("G0 X10 Y10 Z0", "G1 Z-30 F300"), "this job is 30.0 mm tall; your machine travels 20.0 mm in Z ($132)"),
    (("G0 X-150 Y10", "G1 X100 F3000"), "this job is 250.0 mm wide"),  # negative work coordinates count too
])
def test_without_homing_a_job_larger_than_the_travel_is_refused_with_its_size(unhomed, lines, expected):
    message = refusal(unhomed, "G21 G90", *lines)
    assert "does not fit the machine" in message and expected in message
    assert "Scale the job down" in message and "check $130-$132" in message


def test_without_homing_the_size_counts_arcs_and_relative_moves(unhomed):
    # a full circle of radius 110 is 220 mm wide though it starts and ends at one point
    assert "this job is 220.0 mm wide" in refusal(unhomed, "G21 G90", "G0 X10 Y100", "G2 X10 Y100 I110 J0 F3000")
    # relative moves from wherever the head is: 120 + 120 mm
    assert "this job is 240.0 mm wide" in refusal(unhomed, "G21 G91", "G1 X120 F3000", "G1 X120")
    assert "this job is 210.0 mm deep" in refusal(unhomed, "G21 G91", "G1 Y-210 F3000")
    preflight(unhomed, "G21 G91", "G1 X120 F3000", "G1 X-100", "G1 X170")  # 190 mm of X at most


def test_without_homing_the_way_from_the_head_to_the_job_must_fit_too(unhomed):
    unhomed.command("G0 X150 Y0")
    assert unhomed.wait_for(lambda: unhomed.status.state == "Idle" and unhomed.status.mpos[0] == 150.0, 5.0)
    message = refusal(unhomed, "G21 G90", "G0 X-60 Y0", "G1 X0 F3000")  # 60 mm wide, 210 mm from the head
    assert "cannot run from where the head stands" in message
    assert "the head stands at X 150.0 and the job goes to X -60.0..0.0: 210.0 mm of travel" in message
    preflight(unhomed, "G21 G90", "G0 X-40 Y0", "G1 X0 F3000")  # 190 mm


def test_commanded_extent_ignores_where_the_head_stood_before_the_job_named_an_axis():
    path = interpret(["G21 G90", "G0 Z5", "G0 X100 Y50", "G1 X300 F1000", "G0 X0"], start=(500.0, 500.0, 0.0))
    lo, hi = commanded_extent(path)
    assert lo.tolist() == [0.0, 50.0, 5.0] and hi.tolist() == [300.0, 50.0, 5.0]
    lo, hi = commanded_extent(interpret(["G91 G0 X-20"], start=(500.0, 0.0, 0.0)))
    assert (lo[0], hi[0]) == (480.0, 500.0) and np.isnan(lo[1]) and np.isnan(hi[2])


def test_a_laser_job_streams_end_to_end_on_a_machine_without_homing(make_connection):
    conn = make_connection(sim_url("laser", homing=0, travel="200x200", time_scale=0.002))
    lines = ["G21 G90", "G0 X10 Y10", "M4 S600", "G1 X190 Y10 F6000", "G1 X190 Y190", "G1 X10 Y190", "G1 X10 Y10",
             "M5", "G0 X0 Y0"]
    result = JobRunner(conn, Job("square", lines, laser=True)).run()
    assert result.ok and result.laser_off, result.message
    record = conn.port.machine.snapshot()
    assert record.alarms == []
    assert [b.end[:2] for b in record.executed] == [(10, 10), (190, 10), (190, 190), (10, 190), (10, 10), (0, 0)]
    assert [b.power for b in record.executed] == [0, 600, 600, 600, 600, 0]
    assert record.samples[-1].power == 0.0


# ------------------------------------------------------------------ jobs that move their own work coordinates
# The homed laser: work zero (G54) at machine -400, -400; the head at machine 0. ``G0 X300 Y300`` puts it at
# machine -100, -100, and ``G0 X100 Y100`` at -300, -300.


@pytest.mark.parametrize(("lines", "leaves"), [
    # G92 sets work zero where the head stands: X200 is then machine +100, outside; X-50 from -300 is -350, inside
    (("G0 X300 Y300", "G92 X0 Y0", "G1 X200 Y50 F1000"), "X"),
    (("G0 X100 Y100", "G92 X0 Y0", "G1 X-50 Y-50 F1000"), ""),
    # G92 with one axis shifts that axis alone
    (("G0 X300 Y300", "G92 Y0", "G1 X350 Y200 F1000"), "Y"),
    # G10 L20 P1 (G54 itself) and P0 (the active system) move work zero as G92 does, but in the machine's EEPROM
    (("G0 X300 Y300", "G10 L20 P1 X0 Y0", "G1 X200 Y50 F1000"), "X"),
    (("G0 X100 Y100", "G10 L20 P0 X0 Y0", "G1 X-50 Y-50 F1000"), ""),
    # G10 L2 sets the offset itself (machine mm): G54 at -300 puts X350 at machine +50
    (("G10 L2 P1 X-300 Y-300", "G0 X350 Y100"), "X"),
    (("G10 L2 P1 X-300 Y-300", "G0 X250 Y250"), ""),
    # G92.1 clears G92: the job is back in G54's coordinates
    (("G0 X300 Y300", "G92 X0 Y0", "G92.1", "G1 X200 Y50 F1000"), ""),
    # an offset set for another system matters only once the job selects it
    (("G10 L2 P2 X-200 Y-200", "G0 X250 Y100"), ""),
    (("G10 L2 P2 X-200 Y-200", "G55", "G0 X250 Y100"), "X"),
])
def test_a_job_is_checked_where_its_own_work_offsets_put_it(homed, lines, leaves):
    if not leaves:
        preflight(homed, "G21 G90", *lines)
        return
    message = refusal(homed, "G21 G90", *lines)
    assert "leaves the machine's travel" in message and f"{leaves} " in message.split("): ", 1)[1]
    moved = next(i for i, line in enumerate(lines) if line.startswith(("G92", "G10 L20", "G10 L2 P1", "G55")))
    assert f"; line {moved + 2} ({lines[moved].replace(' ', '')}) moves the job's work coordinates): " in message


def test_the_g92_a_job_starts_with_is_the_machines_own(homed):
    # the maker set work zero at the head (machine 0) by hand: a job clearing it runs in G54's coordinates
    homed.command("G92 X0 Y0")
    try:
        assert "X 0.00..300.00 (machine 0.00..300.00" in refusal(homed, "G21 G90", "G0 X300 Y300")
        preflight(homed, "G21 G90", "G92.1", "G0 X300 Y300")
    finally:
        homed.command("G92.1")


def test_a_g92_jobs_size_counts_without_homing(unhomed):
    # two 150 mm strokes, work zero moved to the end of the first: 300 mm of X on a 200 mm machine
    message = refusal(unhomed, "G21 G90", "G0 X0 Y0", "G1 X150 F3000", "G92 X0", "G1 X150")
    assert "(line 4 (G92X0) moves the job's work coordinates): this job is 300.0 mm wide" in message
    preflight(unhomed, "G21 G90", "G0 X0 Y0", "G1 X150 F3000", "G92 X150", "G1 X0")


def test_an_offset_set_where_the_head_cannot_be_known_is_refused(homed):
    # the probe stops wherever it touches: G92 there puts the rest of the job nobody can say where
    message = refusal(homed, "G21 G90", "G0 X100 Y100", "G38.2 Z-10 F100", "G92 Z0", "G1 X120 F1000")
    assert "line 4 sets a work offset where the head's position is not known" in message
    preflight(homed, "G21 G90", "G0 X100 Y100", "G38.2 Z-10 F100", "G0 Z0", "G1 X120 F1000")  # no offset: fine


def test_resuming_a_g92_job_rebuilds_its_work_offset(make_connection):
    conn = make_connection(sim_url("laser", time_scale=0.002))
    lines = ["G21 G90", "G0 X300 Y300", "G92 X0 Y0", "G1 X50 Y0 F3000", "G1 X50 Y50", "G1 X0 Y50"]
    job = Job("g92", lines)
    preamble = job.toolpath.states[4].preamble()
    assert preamble[2:5] == ["G92.1", "G0 X350 Y300", "G92 X50 Y0"]
    result = JobRunner(conn, job, from_line=5).run()
    assert result.ok, result.message
    ends = [block.end[:2] for block in conn.port.machine.snapshot().executed]
    assert ends[-2:] == [(-50.0, -50.0), (-100.0, -50.0)]  # where the whole job would have drawn them


def test_resuming_past_a_g92_set_where_the_job_started_is_refused(make_connection):
    conn = make_connection(sim_url("laser"))
    job = Job("here", ["G21 G90", "G92 X0 Y0", "G1 X-50 Y0 F3000", "G1 X-50 Y-50"])
    with pytest.raises(JobRefused, match="cannot resume from line 4: the job sets a work offset"):
        JobRunner(conn, job, from_line=4).preflight()
    JobRunner(conn, job).preflight()  # from line 1 it runs where the head stands


@pytest.mark.parametrize("lines", [
    ("G0 X100 Y100", "G92 X0 Y0", "G1 X-50 Y-50 F3000", "G92 Y20", "G1 X-60 Y0"),
    ("G0 X100 Y100", "G10 L20 P0 X0 Y0", "G1 X-50 Y-50 F3000"),
    ("G10 L2 P1 X-300 Y-300", "G0 X250 Y250", "G10 L2 P2 X-200 Y-100", "G55 G0 X10 Y-20", "G54 G1 X5 Y5 F3000"),
    ("G0 X300 Y300", "G92 X0 Y0", "G92.1", "G1 X200 Y50 F3000"),
])
def test_the_machine_runs_an_offset_job_where_the_pre_flight_placed_it(make_connection, lines):
    conn = make_connection(sim_url("laser", time_scale=0.002))
    job = Job("offsets", ["G21 G90", *lines])
    runner = JobRunner(conn, job)
    result = runner.run()
    assert result.ok, result.message
    toolpath, wco = runner._toolpath, runner._wco
    planned = [tuple(np.round(end + wco, 3)[:2]) for end in toolpath.end]
    executed = [tuple(np.round(block.end[:2], 3)) for block in conn.port.machine.snapshot().executed]
    assert executed == planned
