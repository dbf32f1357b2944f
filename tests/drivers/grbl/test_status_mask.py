"""Status reports in every form a machine's ``$10`` asks for: the driver reads them as they come and never changes
the setting (GRBL keeps it in EEPROM: a lasting change to the user's machine)."""

from __future__ import annotations

import pytest

from drivers.gcode import clean_line
from drivers.grbl import Job, JobRunner
from station.devices import DeviceEntry
from station.tui.widgets.machines_status import status_lines

from ..conftest import sim_url

SQUARE = ["G21", "G90", "M4 S400", "G0 X10 Y10", "G1 X60 Y10 F3000", "G1 X60 Y60", "G1 X10 Y60", "G1 X10 Y10",
          "G0 X0 Y0"]


def _mask(conn) -> int:
    return next(int(reply.value) for reply in conn.command("$$") if getattr(reply, "key", None) == 10)


@pytest.mark.parametrize("mask", [0, 1, 2, 3])
def test_a_job_streams_under_any_status_mask_and_the_mask_stays(make_connection, mask):
    # $10 bit 0: MPos (1) or WPos (0) in reports; bit 1: the buffer state Bf. GRBL 1.1's default is 1.
    conn = make_connection(sim_url("laser", s10=mask))
    machine = conn.port.machine
    assert int(conn.settings[10]) == mask and _mask(conn) == mask
    assert not any(direction == "out" and text.startswith("$10=") for _, direction, text in conn.log)
    # both positions, whatever the report carried: WPos = MPos - WCO, with GRBL's work offset (G54 at -400, -400)
    status = conn.fresh_status()
    assert (status.mpos, status.wpos) == ((0.0, 0.0, 0.0), (400.0, 400.0, 0.0))
    result = JobRunner(conn, Job("square", SQUARE, laser=True)).run()
    assert result.state == "done" and result.laser_off, result.message
    executed = [b.text for b in machine.snapshot().executed]
    assert executed == [clean_line(x) for x in SQUARE if x.startswith(("G0", "G1"))]
    status = conn.fresh_status()
    assert status.wpos == pytest.approx((0.0, 0.0, 0.0)) and status.mpos == pytest.approx((-400.0, -400.0, 0.0))
    assert _mask(conn) == mask and int(machine.settings[10]) == mask


@pytest.mark.parametrize("mask", [0, 1])
def test_a_lost_ok_is_found_without_the_buffer_state(make_connection, mask):
    # without Bf the watchdog judges by the state alone: Idle with lines pending, for its timeout, is a lost reply
    lines = ["G21", "G90", "M4 S300", "F2000"] + [f"G1 X{10 + i} Y{10 + 2 * i}" for i in range(12)] + ["G0 X0 Y0"]
    conn = make_connection(sim_url("laser", s10=mask, drop_reply_at=9))
    result = JobRunner(conn, Job("walk", lines, laser=True)).run()
    assert result.ok and "lost ok" in result.message
    assert [b.text for b in conn.port.machine.snapshot().executed] == [clean_line(x) for x in lines if "X" in x]
    assert _mask(conn) == mask


def test_a_work_offset_set_in_wpos_mode_moves_both_positions(make_connection):
    # with WPos reports the machine position is WPos + WCO, and GRBL sends the new WCO in the next report
    conn = make_connection(sim_url("laser", s10=2))
    conn.stream(["G90 G0 X100 Y50", "G4 P0"])
    conn.command("G10 L20 P1 X0 Y0")  # work zero here: machine (-300, -350)
    assert conn.wait_for(lambda: conn.status.wpos == (0.0, 0.0, 0.0), 5.0)
    assert conn.status.mpos == (-300.0, -350.0, 0.0) and conn.work_offset() == (-300.0, -350.0, 0.0)


def test_the_machines_panel_shows_both_positions_and_says_when_buffers_are_not_reported(make_connection):
    url = sim_url("laser", s10=0)  # WPos only
    conn = make_connection(url)
    conn.fresh_status()
    lines = status_lines(DeviceEntry("laser", "laser", url, True), conn, 1.0)
    assert "WPos X  400.000  Y  400.000  Z    0.000" in lines and "MPos X    0.000  Y    0.000  Z    0.000" in lines
    assert any(line.startswith("planner and RX not reported ($10=0)   feed 0 mm/min") for line in lines)
