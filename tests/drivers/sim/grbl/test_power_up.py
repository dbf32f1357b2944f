"""A homing machine as GRBL 1.1h is switched on (``sim://grbl?...&homed=0``): locked in alarm until it homes
(HOMING_INIT_LOCK), at machine zero, with G54 at 0 as a fresh EEPROM has it. The station says, in one line, how to
home it and how to set work zero, and runs the job once that is done."""

from __future__ import annotations

from drivers.grbl import Job, JobRunner

from .test_sim import BANNER, UNLOCK, Raw

SQUARE = ["G21", "G90", "M4 S400", "G0 X10 Y10", "G1 X60 Y10 F3000", "G1 X60 Y60", "G1 X10 Y60", "G1 X10 Y10",
          "G0 X0 Y0"]


def test_grbl_with_homing_powers_up_locked_with_g54_at_zero():
    port = Raw("sim://grbl?profile=laser&homed=0&time_scale=0.01")
    try:
        assert port.read_until(UNLOCK) == BANNER + UNLOCK  # main.c: HOMING_INIT_LOCK
        assert port.status().startswith("<Alarm|MPos:0.000,0.000,0.000|")
        assert port.ask("$#").startswith(b"[G54:0.000,0.000,0.000]\r\n")
        assert port.ask("G0 X1", b"error:9\r\n") == b"error:9\r\n"
        assert port.ask("$H") == b"ok\r\n"
        assert port.status().startswith("<Idle|MPos:-1.000,-1.000,-1.000|")  # pulled off the switches ($27)
    finally:
        port.port.close()
    plain = Raw("sim://grbl?profile=laser&homing=0&homed=0&time_scale=0.01")  # no homing: no lock
    try:
        assert plain.read_until(BANNER) == BANNER and plain.status().startswith("<Idle|")
    finally:
        plain.port.close()


def test_the_refusals_say_how_to_home_and_set_work_zero_and_the_job_runs_after(make_connection):
    conn = make_connection("sim://grbl?profile=laser&homed=0&time_scale=0.01")
    square = Job("square", SQUARE, laser=True)
    locked = JobRunner(conn, square).run()
    assert locked.state == "refused" and "\n" not in locked.message
    assert "machine is locked (homing is on ($22=1) and it has not homed): home it ($H)" in locked.message
    assert "G10 L20 P1 X0 Y0" in locked.message
    conn.command("$H")
    assert conn.wait_for(lambda: conn.status.state == "Idle", 5.0)
    outside = JobRunner(conn, square).run()  # G54 at 0: the job's X 10..60 is machine 10..60, past the travel's 0
    assert outside.state == "refused" and "\n" not in outside.message
    assert "leaves the machine's travel" in outside.message
    assert outside.message.endswith("Set work zero where the job should start (jog there, then G10 L20 P1 X0 Y0), "
                                    "after homing ($H) if the machine has not homed since it was switched on")
    conn.stream(["G90 G53 G0 X-390 Y-390", "G4 P0"])  # to the front-left corner
    conn.command("G10 L20 P1 X0 Y0")
    result = JobRunner(conn, square).run()
    assert result.state == "done", result.message
    assert [b.end[:2] for b in conn.port.machine.snapshot().executed][-1] == (-390.0, -390.0)
