"""The simulated GRBL on a virtual clock: the same simulated timing as on the wall clock, in a fraction of the wall
time, with the host-side driver (status polls, ``ok`` order, hold, resume, reset) unchanged."""

from __future__ import annotations

import io
import time

import numpy as np
import pytest
import serial

import drivers.sim  # noqa: F401 - registers sim://
from cam.plot import WriterOptions, write_plot_gcode
from drivers.errors import DriverError, SimConfigError
from drivers.gcode import clean_line
from drivers.grbl import Job, JobRunner
from drivers.sim.clock import VirtualClock, WallClock
from drivers.sim.grbl import SimConfig, SimRecord, SimulatedGrbl

from ...conftest import sim_url

BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"
UNLOCK = b"[MSG:'$H'|'$X' to unlock]\r\n"


def plot_lines(points: int = 160) -> list[str]:
    """A pen plot of two polylines (a wavy ring) as the job writer writes it: pen dwells, travels, feeds."""
    t = np.linspace(0, 2 * np.pi, points)
    radius = 40 + 10 * np.cos(5 * t)
    ring = np.column_stack([100 + radius * np.cos(t), 100 + radius * np.sin(t)])
    out = io.StringIO()
    write_plot_gcode([ring[: points // 2], ring[points // 2:]], out, WriterOptions())
    return out.getvalue().splitlines()


def motion_texts(lines: list[str]) -> list[str]:
    return [clean_line(x) for x in lines if clean_line(x).startswith(("G0", "G1"))]


def wait_until(condition, timeout: float) -> bool:
    """Poll ``condition`` every millisecond (wall clock) until it holds or ``timeout`` s have passed."""
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.001)
    return True


def job_span(record: SimRecord) -> float:
    """From the start of the first block to the end of the last (the machine's clock)."""
    start = min(s.t for s in record.samples if s.state == "Run")
    return record.executed[-1].t_end - start


def run_plot(make_connection, url: str, lines: list[str]) -> tuple[SimRecord, float]:
    conn = make_connection(url)
    started = time.monotonic()
    result = JobRunner(conn, Job("plot", lines)).run()
    wall = time.monotonic() - started
    assert result.ok, result.message
    return conn.port.machine.snapshot(), wall


def test_a_job_takes_the_same_simulated_time_on_both_clocks_and_little_wall_time_on_the_virtual_one(
        make_connection):
    lines = plot_lines()
    scale = 0.25
    wall_record, wall_seconds = run_plot(make_connection, sim_url("plotter", time_scale=scale), lines)
    virtual_record, virtual_seconds = run_plot(make_connection, sim_url("plotter", time_scale=1, clock="virtual"),
                                               lines)
    simulated = job_span(virtual_record)
    assert simulated > 3.0  # a job worth timing: dwells, travels, 160 feed moves
    assert job_span(wall_record) / scale == pytest.approx(simulated, rel=0.02)
    assert [b.text for b in virtual_record.executed] == [b.text for b in wall_record.executed] == motion_texts(lines)
    ends = np.array([b.end for b in virtual_record.executed])
    assert np.allclose(ends, [b.end for b in wall_record.executed], atol=1e-9)
    # the machine ran as fast as the host streamed: a fraction of its simulated time and of the wall clock's run
    assert virtual_seconds < 0.2 * simulated and virtual_seconds < 0.5 * wall_seconds


def test_virtual_record_timings_are_consistent(make_connection):
    lines = ["G21", "G90", "G0 X0 Y0", "G1 X10 Y0 F600", "G4 P2", "G1 X20 Y0", "G0 X0 Y0"]
    conn = make_connection(sim_url("plotter", time_scale=1, clock="virtual"))
    assert JobRunner(conn, Job("timed", lines)).run().ok
    record = conn.port.machine.snapshot()
    travel, first, second, back = record.executed
    assert [b.text for b in record.executed] == ["G0X0Y0", "G1X10Y0F600", "G1X20Y0", "G0X0Y0"]
    # 10 mm at 600 mm/min is at least 1 s (acceleration adds a little), right after the travel
    assert 1.0 - 1e-9 <= first.t_end - travel.t_end < 1.2  # (a difference of clock readings: rounding)
    # then the 2 s dwell before the next block starts
    second_start = min(s.t for s in record.samples if s.state == "Run" and s.t > first.t_end)
    assert second_start - first.t_end == pytest.approx(2.0, abs=1e-6)
    assert 1.0 - 1e-9 <= second.t_end - second_start < 1.2
    assert back.t_end > second.t_end
    times = [s.t for s in record.samples]
    assert times == sorted(times) and all(b.t_end <= times[-1] for b in record.executed)
    fills = [t for t, _, _ in record.planner_fill]
    assert fills == sorted(fills)


def test_the_same_seed_gives_the_same_record(make_connection):
    """Faults drawn from the seed (split and delayed replies) and a host that sends line by line: every run of the
    machine is the same, to the sample."""

    def run() -> SimRecord:
        port = serial.serial_for_url("sim://grbl?profile=plotter&clock=virtual&seed=5&delay=0.3&delay_max=0.01",
                                     timeout=1.0)
        try:
            assert port.read_until(BANNER).endswith(BANNER)
            for line in plot_lines(60):
                port.write(line.encode() + b"\n")
                assert port.read_until(b"ok\r\n").endswith(b"ok\r\n"), line
            return port.machine.snapshot()
        finally:
            port.close()

    first, second = run(), run()
    assert len(first.executed) >= 60
    assert first == second


def test_the_driver_runs_a_job_the_same_way_every_time(make_connection):
    """Status polls on the wall clock do not change what the machine executes, nor when (simulated)."""
    lines = plot_lines(80)
    first, _ = run_plot(make_connection, sim_url("plotter", time_scale=1, clock="virtual"), lines)
    second, _ = run_plot(make_connection, sim_url("plotter", time_scale=1, clock="virtual"), lines)
    assert first.executed == second.executed
    assert first.samples == second.samples


def test_hold_and_resume_on_the_virtual_clock(make_connection):
    square = ["G21", "G90", "M4 S400", "G0 X10 Y10", "G1 X60 Y10 F3000", "G1 X60 Y60", "G1 X10 Y60",
              "G1 X10 Y10", "G0 X0 Y0"]
    long_job = square[:3] + [f"G1 X{10 + (i % 50)} Y{10 + i // 50} F3000" for i in range(400)] + ["G0 X0 Y0"]
    conn = make_connection(sim_url("laser", time_scale=1, clock="virtual"))
    runner = JobRunner(conn, Job("long", long_job, laser=True))
    runner.start()
    assert wait_until(lambda: runner.progress.lines_acked >= 10, 10)
    runner.hold()
    assert conn.wait_for(lambda: conn.status.label == "Hold:0", 5)
    machine = conn.port.machine
    held = machine.snapshot()
    assert held.samples[-1].power == 0.0  # laser dark while held
    position = conn.status.mpos
    asked = time.monotonic()
    assert conn.wait_for(lambda: conn.status_time > asked, 2)  # a fresh report ...
    assert conn.status.label == "Hold:0" and conn.status.mpos == position  # ... still held, not moving
    assert len(machine.snapshot().executed) == len(held.executed)
    runner.resume()
    result = runner.wait(20)
    assert result.ok and runner.progress.state == "done", result.message
    assert [b.text for b in machine.snapshot().executed] == motion_texts(long_job)


def test_hold_resume_and_reset_byte_by_byte_on_the_virtual_clock():
    port = serial.serial_for_url("sim://grbl?profile=laser&clock=virtual", timeout=1.0)
    try:
        assert port.read_until(BANNER).endswith(BANNER)
        port.write(b"G1 X100 F600\n")  # 30 s of motion (machine 0 to -300) ...
        port.write(b"!")  # ... held as soon as it has started
        assert port.read_until(b"ok\r\n").endswith(b"ok\r\n")
        machine = port.machine
        assert wait_until(lambda: machine.state == "Hold:0", 5), machine.state
        time.sleep(0.1)  # the host does nothing: simulated time does not run on while held
        port.write(b"?")
        report = port.read_until(b">\r\n").decode()
        assert report.startswith("<Hold:0|")
        x = float(report.split("MPos:")[1].split(",")[0])
        assert -0.5 < x < 0.0  # stopped within the deceleration distance of machine 0, where it started
        port.write(b"~")
        assert wait_until(lambda: machine.state == "Idle", 5), machine.state
        assert [b.text for b in machine.snapshot().executed] == ["G1X100F600"]
        # a reset in motion: ALARM:3, then the banner; the position where it stopped is kept
        port.write(b"G1 X200 F600\n")
        port.write(b"\x18")
        assert port.read_until(UNLOCK).endswith(b"ALARM:3\r\n" + BANNER + UNLOCK)
        assert machine.state == "Alarm" and machine.snapshot().alarms == [3]
        assert -300.0 <= machine.mpos[0] < -200.0
    finally:
        port.close()


def test_a_paced_virtual_clock_runs_at_most_pace_simulated_seconds_per_wall_second():
    port = serial.serial_for_url("sim://grbl?profile=laser&clock=virtual&pace=20", timeout=1.0)
    try:
        assert port.read_until(BANNER).endswith(BANNER)
        machine = port.machine
        started = time.monotonic()
        port.write(b"G1 X10 F600\n")  # machine 0 to -390: 39 s of motion, about 2 s of wall time at pace 20
        assert port.read_until(b"ok\r\n").endswith(b"ok\r\n")
        assert wait_until(lambda: machine.clock.now() > 5.0, 5)
        assert machine.state == "Run"  # under way: a test can act while the job runs
        assert wait_until(lambda: machine.state == "Idle", 10)
        wall = time.monotonic() - started
        assert 39.0 / 20 - 0.05 <= wall < 39.0 / 20 + 2.0
        record = machine.snapshot()
        (block,) = record.executed
        assert block.text == "G1X10F600"
        assert block.t_end - min(s.t for s in record.samples if s.state == "Run") == pytest.approx(39.0, abs=1e-9)
    finally:
        port.close()


def test_a_virtual_clock_from_python():
    clock = VirtualClock()
    machine = SimulatedGrbl(SimConfig(profile="plotter", wire=False), clock=clock)
    try:
        assert machine.clock is clock and clock.now() == 0.0
        machine.receive(b"G4 P30\n")  # half a minute of dwell passes at once
        deadline = time.monotonic() + 5
        output = b""
        while not output.endswith(b"ok\r\n"):
            assert time.monotonic() < deadline, output
            output += machine.read_output(64, 0.5)
        assert clock.now() == pytest.approx(30.0)
        machine.greet()
        assert machine.read_output(64, 1.0).endswith(BANNER)
    finally:
        machine.stop()
    machine = SimulatedGrbl(SimConfig.from_query({"clock": "wall"}))
    try:
        assert isinstance(machine.clock, WallClock) and not machine.clock.virtual
    finally:
        machine.stop()


def test_clock_option_and_bad_options_name_what_they_take():
    assert SimConfig.from_query({"clock": "virtual"}).clock == "virtual"
    assert SimConfig.from_query({}).clock == "wall"
    with pytest.raises(SimConfigError, match="sim option clock: expected wall or virtual, got 'fast'"):
        SimConfig.from_query({"clock": "fast"})
    with pytest.raises(SimConfigError, match="sim option time_scale: expected a number, got 'quick'"):
        SimConfig.from_query({"time_scale": "quick"})
    with pytest.raises(SimConfigError, match="sim option seed: expected a whole number, got '1.5'"):
        SimConfig.from_query({"seed": "1.5"})
    with pytest.raises(SimConfigError, match="unknown sim option 'bogus'; known: clock, corrupt"):
        SimConfig.from_query({"bogus": "1"})
    error = pytest.raises(ValueError, SimConfig.from_query, {"s20": "x"}).value  # callers catching ValueError
    assert isinstance(error, DriverError) and "sim option s20: expected a number" in str(error)
    with pytest.raises(SimConfigError, match="sim option pace: expected a positive number with clock=virtual"):
        SimConfig.from_query({"pace": "3"})
    with pytest.raises(serial.SerialException, match="sim option clock: expected wall or virtual"):
        serial.serial_for_url("sim://grbl?clock=slow")
