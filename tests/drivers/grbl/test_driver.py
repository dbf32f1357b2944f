"""The GRBL driver against the simulated machine and, with CHAOS_STATION_GRBL_PORT set, a real controller.

Tests that move the machine, reset it in motion or need the simulator's record run on the simulator only."""

from __future__ import annotations

import time

import pytest

from drivers.errors import PortError, ProtocolError
from drivers.gcode import clean_line
from drivers.grbl import GrblConnection, Job, JobRunner, StreamStopped, frame_lines, list_ports, probe

from ..conftest import sim_url, start_until_acked


def _sim_only(url: str) -> None:
    if not url.startswith("sim://"):
        pytest.skip("moves the machine or needs the simulator's record")


def _motion(lines):
    return [clean_line(x) for x in lines if clean_line(x).startswith(("G0", "G1"))]


SQUARE = ["G21", "G90", "M4 S400", "G0 X10 Y10", "G1 X60 Y10 F3000", "G1 X60 Y60", "G1 X10 Y60", "G1 X10 Y10",
          "G0 X0 Y0"]


# ------------------------------------------------------------------ both sim and real


def test_connect_reads_buffer_size_settings_and_status(machine_url, make_connection):
    conn = make_connection(machine_url)
    assert conn.rx_size >= 128 and conn.planner_size >= 15
    assert {10, 30, 32, 130, 131, 132} <= set(conn.settings)
    mask = int(conn.settings[10])
    conn.refresh()
    assert int(conn.settings[10]) == mask  # the machine's status report mask is left as it was
    assert conn.status is not None and conn.status.mpos is not None and conn.status.wpos is not None
    assert conn.version.startswith("1.1") and ":" not in conn.version and conn.firmware.version == conn.version
    assert any(direction == "in" for _, direction, _ in conn.log)


def test_firmware_version_build_date_and_build_info_from_the_sim(make_connection):
    conn = make_connection(sim_url("laser"))
    assert (conn.version, conn.firmware.build, conn.firmware.info) == ("1.1h", "20190830", "")
    assert str(conn.firmware) == "GRBL 1.1h (build 20190830)"
    conn.command("$I=bench laser")
    conn.refresh()
    assert str(conn.firmware) == "GRBL 1.1h (build 20190830, info 'BENCHLASER')" and conn.version == "1.1h"


def test_command_errors_carry_their_meaning(machine_url, make_connection):
    conn = make_connection(machine_url)
    with pytest.raises(ProtocolError, match=r"error:20 \(Unsupported or invalid g-code"):
        conn.command("G41")
    assert conn.command("$G")[0].kind == "GC"


def test_dry_run_in_check_mode_reports_bad_lines_and_moves_nothing(machine_url, make_connection):
    conn = make_connection(machine_url)
    job = Job("check", ["G91", "G1 X-0.1 F100", "G41", "G1 X0.1", "G90"])
    result = JobRunner(conn, job, dry_run=True).run()
    assert result.state == "stopped"
    assert [line for line, _ in result.errors] == [3]
    assert "error:20" in result.errors[0][1] and "Unsupported" in result.errors[0][1]
    assert conn.status.state == "Idle"  # leaving check mode reset the controller
    if machine_url.startswith("sim://"):
        assert conn.port.machine.snapshot().executed == []


def test_job_outside_the_travel_is_refused_before_any_motion(machine_url, make_connection):
    conn = make_connection(machine_url)
    received_before = len(conn.port.machine.snapshot().received) if machine_url.startswith("sim://") else 0
    result = JobRunner(conn, Job("huge", ["G90", "G0 X5000 Y5000"])).run()
    assert result.state == "refused" and "leaves the machine's travel" in result.message
    if machine_url.startswith("sim://"):
        new = conn.port.machine.snapshot().received[received_before:]
        assert all(line.startswith("$") for line in new), new  # only the pre-flight's queries


# ------------------------------------------------------------------ simulator only


def test_job_runs_to_100_percent_and_ends_with_laser_off(make_connection):
    conn = make_connection(sim_url("laser"))
    updates = []
    result = JobRunner(conn, Job("square", SQUARE, laser=True), on_progress=updates.append).run()
    assert result.ok and result.laser_off
    assert updates[-1].fraction == 1.0 and updates[-1].eta == 0.0 and updates[-1].state == "done"
    record = conn.port.machine.snapshot()
    assert [b.text for b in record.executed] == _motion(SQUARE)
    assert [b.power for b in record.executed] == [0, 400, 400, 400, 400, 0]
    gcode = [line for line in record.received if not line.startswith("$")]
    assert gcode[-2:] == ["M5S0", "G4P0"]  # every laser job ends with M5 S0, then waits for the motion
    assert record.samples[-1].power == 0.0
    assert record.overflow_bytes == 0 and conn.max_pending_bytes <= conn.rx_size - 1


def test_character_counting_keeps_the_buffer_full_but_never_overfull(make_connection):
    conn = make_connection(sim_url("laser", time_scale=0.05))
    lines = ["G21 G90 F3000"] + [f"G1 X{10 + (i % 40) * 0.5:.1f} Y{10 + (i // 40) * 0.5:.1f}" for i in range(400)]
    results = conn.stream(lines)
    assert all(r.status == "ok" for r in results)
    assert conn.rx_size - 20 < conn.max_pending_bytes <= conn.rx_size - 1  # the ring buffer holds size - 1
    assert conn.port.machine.snapshot().overflow_bytes == 0


def test_laser_job_refused_unless_laser_mode(make_connection):
    conn = make_connection(sim_url("laser", s32=0))
    result = JobRunner(conn, Job("burn", SQUARE, laser=True)).run()
    assert result.state == "refused" and "$32=0" in result.message
    assert all(line.startswith("$") for line in conn.port.machine.snapshot().received)


def test_work_offset_moves_the_allowed_area(make_connection):
    conn = make_connection(sim_url("laser"))
    assert JobRunner(conn, Job("ok", ["G90", "G0 X300 Y300"])).run().ok
    conn.command("G10 L20 P1 X0 Y0")  # work zero where the head now stands (machine -100, -100)
    result = JobRunner(conn, Job("shifted", ["G90", "G0 X10 Y150"])).run()
    assert result.state == "refused" and "Y 0.00..150.00 (machine -100.00..50.00" in result.message


def test_soft_limit_alarm_clears_counter_and_the_late_ok_is_ignored(make_connection):
    conn = make_connection(sim_url("laser"))
    with pytest.raises(StreamStopped) as stopped:
        conn.stream(["G90", "G0 X10 Y10", "G0 X900", "G0 X20", "G0 X30"])  # straight to the controller
    assert stopped.value.reason == "alarm" and conn.alarm.code == 2
    assert conn.pending_count == 0
    assert conn.soft_reset()
    assert any("ignored 'ok'" in text for _, kind, text in conn.log if kind == "info")
    assert conn.status is None or conn.pending_count == 0
    assert any(getattr(r, "text", "") == "Caution: Unlocked" for r in conn.command("$X"))
    results = conn.stream(["G0 X20 Y20", "G0 X30 Y30", "G4 P0"])  # G4 P0 is answered once motion is done
    assert [r.status for r in results] == ["ok", "ok", "ok"]
    record = conn.port.machine.snapshot()
    # GRBL stops the move in progress (feed hold, reset): the first block never completes
    assert [b.text for b in record.executed] == ["G0X20Y20", "G0X30Y30"]


def test_abort_resets_at_once_laser_off_and_alarm_recovery(make_connection):
    conn = make_connection(sim_url("laser", time_scale=0.5))
    runner = JobRunner(conn, Job("square", SQUARE, laser=True))
    start_until_acked(runner, 5)
    aborted = time.monotonic()
    runner.abort()
    result = runner.wait(10)
    assert result.state == "aborted" and result.laser_off and "ALARM:3" in result.message
    record = conn.port.machine.snapshot()
    reset = next(t for t in record.resets if t >= aborted)
    assert all(s.power == 0.0 for s in record.samples if s.t >= reset)
    assert JobRunner(conn, Job("again", SQUARE, laser=True)).run().state == "refused"  # locked: home first
    conn.command("$H")
    conn.wait_for(lambda: conn.status.state == "Idle" and conn.alarm is None, 5)
    assert conn.alarm is None
    assert JobRunner(conn, Job("again", SQUARE, laser=True)).run().ok


def test_lost_ok_at_the_end_is_reported_without_inventing_it(make_connection):
    lines = ["G21", "G90", "M4 S300", "F2000"] + [f"G1 X{10 + i} Y{10 + 2 * i}" for i in range(12)] + ["G0 X0 Y0"]
    conn = make_connection(sim_url("laser", drop_reply_at=9))
    result = JobRunner(conn, Job("walk", lines, laser=True)).run()
    # counting goes on past one lost ok; at the end the machine is idle, empty, at the last line's end point
    assert result.ok and "lost ok" in result.message
    assert [b.text for b in conn.port.machine.snapshot().executed] == _motion(lines)


def test_lost_ok_stops_the_job_and_resume_runs_every_line_once(make_connection):
    walk = [f"G1 X{10 + i} Y{10 + 2 * i}" for i in range(12)]
    # G28.1 goes by send-response: its lost reply stalls the stream mid-job
    lines = ["G21", "G90", "M4 S300", "F2000", *walk[:6], "G28.1", *walk[6:], "G0 X0 Y0"]
    conn = make_connection(sim_url("laser", drop_reply_at=11))
    job = Job("walk", lines, laser=True)
    first = JobRunner(conn, job).run()
    assert first.state == "stopped" and "lost ok" in first.message and "no ok was assumed" in first.message
    assert first.resume_line == 12
    record = conn.port.machine.snapshot()
    assert record.samples[-1].power == 0.0
    second = JobRunner(conn, job, from_line=first.resume_line).run()
    assert second.ok, second.message
    executed = [b.text for b in conn.port.machine.snapshot().executed]
    assert executed == _motion(lines)
    assert conn.replies_accepted <= conn.port.machine.snapshot().replies_delivered


def test_vanished_port_means_position_lost_and_no_resume(make_connection):
    conn = make_connection(sim_url("plotter"))
    conn.port.machine.unplug()
    assert conn.wait_for(lambda: conn.position_lost, 5.0)
    assert "position lost" in conn.fault
    result = JobRunner(conn, Job("square", SQUARE)).run()
    assert result.state == "position_lost"


def test_resume_from_line_rebuilds_the_modal_state(make_connection):
    conn = make_connection(sim_url("laser"))
    lines = ["G21", "G90", "M4 S300", "G0 X10 Y10", "G1 X20 Y10 F1200", "G1 X20 Y20", "G1 X10 Y20"]
    assert JobRunner(conn, Job("part", lines[:5], laser=True)).run().ok
    result = JobRunner(conn, Job("rest", lines, laser=True), from_line=6).run()
    assert result.ok
    record = conn.port.machine.snapshot()
    tail = [b for b in record.executed][-2:]
    assert [b.text for b in tail] == ["G1X20Y20", "G1X10Y20"]
    assert [b.power for b in tail] == [300, 300] and [b.feed for b in tail] == [1200, 1200]
    received = record.received
    index = received.index("G1X20Y20")
    assert received[index - 4: index] == ["M5", "G0X20Y10", "M4S300", "F1200"]


def test_hold_and_resume(make_connection):
    conn = make_connection(sim_url("laser", time_scale=0.5))
    runner = JobRunner(conn, Job("square", SQUARE, laser=True))
    start_until_acked(runner, 5)
    runner.hold()
    assert conn.wait_for(lambda: conn.status.label == "Hold:0", 3)
    assert conn.port.machine.snapshot().samples[-1].power == 0.0
    runner.resume()
    result = runner.wait(20)
    assert result.ok and runner.progress.state == "done"


def test_frame_traces_the_bounding_box(make_connection):
    conn = make_connection(sim_url("laser"))
    job = Job("square", SQUARE, laser=True)
    lo, hi = job.toolpath.extent(include_rapids=False)
    frame = Job("frame", frame_lines(lo, hi, laser_power=10, feed=3000), laser=True)
    assert JobRunner(conn, frame).run().ok
    blocks = conn.port.machine.snapshot().executed
    wco = conn.work_offset()
    corners = [(round(b.end[0] - wco[0], 3), round(b.end[1] - wco[1], 3)) for b in blocks]
    assert corners == [(10, 10), (60, 10), (60, 60), (10, 60), (10, 10)]
    assert [b.power for b in blocks] == [0, 10, 10, 10, 10]


def test_open_errors_and_discovery():
    with pytest.raises(PortError, match="sim://mill"):
        GrblConnection("sim://mill").open()
    with pytest.raises(PortError, match="no GRBL banner"):
        GrblConnection("loop://", banner_timeout=0.3).open()
    assert probe("sim://grbl?profile=laser") == "1.1h"
    assert probe("loop://", timeout=0.3) == ""
    urls = [p.url for p in list_ports(probe_ports=False)]
    assert "sim://grbl?profile=plotter" in urls and "sim://grbl?profile=laser" in urls


def test_error_mid_job_stops_it_with_the_laser_off(make_connection):
    conn = make_connection(sim_url("laser", time_scale=0.2))
    lines = SQUARE[:6] + ["G41"] + SQUARE[6:]
    result = JobRunner(conn, Job("bad", lines, laser=True)).run()
    assert result.state == "stopped" and "error:20" in result.message and result.laser_off
    record = conn.port.machine.snapshot()
    reset = record.resets[-1]
    assert all(s.power == 0.0 for s in record.samples if s.t >= reset)
    # idle at the reset: M5 S0 follows; reset in motion: GRBL is locked (ALARM:3) and its reset killed the laser
    assert "M5S0" in record.received[record.received.index("G41"):] or 3 in record.alarms


def test_silent_port_counts_as_vanished(make_connection):
    conn = make_connection(sim_url("plotter"))
    conn.port.machine.mute()  # no error, just silence
    assert conn.wait_for(lambda: conn.position_lost, 5.0)
    assert "no byte from the controller" in conn.fault


def test_feed_override_reaches_the_controller(make_connection):
    conn = make_connection(sim_url("laser"))
    conn.override("feed", "+10")
    conn.override("rapid", "25")
    conn.wait_for(lambda: conn.port.machine.overrides[:2] == [110, 25], 2.0)
    assert conn.port.machine.overrides[:2] == [110, 25]
    with pytest.raises(ValueError, match="unknown override"):
        conn.override("feed", "+50")


def test_plot_job_executed_by_the_machine_matches_the_pattern(make_connection):
    """The plot path, read back from what the simulator executed, follows the pattern within the tolerance."""
    import numpy as np
    from shapely import LineString, Point

    from drivers.profiles import builtin_profile
    from station.commands.machines_io import plot_job

    t = np.linspace(0, 2 * np.pi, 1500)
    pattern = np.column_stack([np.cos(2 * t) + 0.5 * np.cos(7 * t), np.sin(3 * t)])
    profile = builtin_profile("plotter")
    text, fitted, _, options = plot_job([pattern], profile, 100.0, 0.05)
    conn = make_connection(sim_url("plotter", time_scale=0.005))
    result = JobRunner(conn, Job("plot", text.splitlines(), pen_up=options.pen_up)).run()
    assert result.ok, result.message
    wco = np.array(conn.work_offset())
    blocks = conn.port.machine.snapshot().executed
    first = next(i for i, b in enumerate(blocks) if not b.rapid and b.power == profile.pen.down)
    drawing = [blocks[first - 1]] + [b for b in blocks[first:] if not b.rapid and b.power == profile.pen.down]
    drawn = np.array([np.array(b.end) - wco for b in drawing])[:, :2]  # from where the pen went down
    path = LineString(fitted[0])
    assert max(path.distance(Point(p)) for p in drawn) <= 1e-3  # executed vertices lie on the pattern
    executed_path = LineString(drawn)
    assert max(executed_path.distance(Point(p)) for p in fitted[0][1:]) <= 0.05 + 1e-3


def test_lines_longer_than_grbl_takes_are_refused(make_connection):
    conn = make_connection(sim_url("laser"))
    long_line = "G1 X10 Y10 F1000 " + " ".join(["G1 X10.000000"] * 6)
    result = JobRunner(conn, Job("long", ["G90", long_line])).run()
    assert result.state == "refused" and "line 2 has" in result.message and "error:11" in result.message


def test_lost_ok_in_check_mode_stops_the_dry_run(make_connection):
    conn = make_connection(sim_url("laser", drop_reply_at=3))
    result = JobRunner(conn, Job("check", ["G90", "G0 X10 Y10", "G1 X20 F500", "G1 Y20"]), dry_run=True).run()
    assert result.state == "stopped" and "lost ok" in result.message
    assert conn.wait_for(lambda: conn.status.state == "Idle", 3.0)  # the reset left check mode


def test_one_stale_reply_after_an_alarm_is_ignored_even_without_a_reset():
    """A probe-fail alarm is followed by the probe line's ok with no reset: that one ok is stale, the next is not."""
    from drivers.grbl.connection import LineResult, _Pending

    conn = GrblConnection("loop://")  # never opened: lines are fed to the parser directly
    conn._pending.append(_Pending(LineResult(0, "G38.2Z-10F100"), 14, 0.0))
    conn._handle("ALARM:4")
    assert conn.pending_count == 0 and conn.alarm.code == 4
    conn._handle("ok")  # the probe line's late reply
    assert conn.replies_accepted == 0
    unlock = LineResult(1, "$X")
    conn._pending.append(_Pending(unlock, 3, 0.0))
    conn._handle("[MSG:Caution: Unlocked]")
    conn._handle("ok")
    assert unlock.status == "ok" and conn.replies_accepted == 1


def test_eta_is_corrected_by_the_observed_rate(make_connection):
    import dataclasses

    conn = make_connection(sim_url("laser", time_scale=0.1))  # the machine runs 10x faster than estimated
    lines = ["G21 G90 F3000"] + [f"G1 X{10 + (i % 2) * 20} Y{10 + i * 0.5}" for i in range(40)]
    runner = JobRunner(conn, Job("zigzag", lines), on_progress=lambda p: updates.append(dataclasses.replace(p)))
    updates: list = []
    result = runner.run()
    assert result.ok
    estimate = float(runner._durations.sum())
    mid = [u for u in updates if 0.2 < u.fraction < 0.8 and u.eta is not None and u.elapsed > 0.3]
    assert mid, "progress was reported during the job"
    # uncorrected, the ETA would be (1 - fraction) * estimate; observed 10x faster it is far less
    assert all(u.eta < 0.5 * (1 - u.fraction) * estimate for u in mid)
    assert [u.fraction for u in updates] == sorted(u.fraction for u in updates)


def test_machine_coordinate_moves_are_checked_too(make_connection):
    conn = make_connection(sim_url("laser"))
    result = JobRunner(conn, Job("g53", ["G90", "G0 X10 Y10", "G53 G0 X50 Y-20"])).run()  # machine X 50 > 0
    assert result.state == "refused" and "machine" in result.message
    assert JobRunner(conn, Job("g53 ok", ["G90", "G0 X10 Y10", "G53 G0 X-50 Y-20"])).run().ok
    assert conn.fresh_status().mpos[:2] == (-50.0, -20.0)
