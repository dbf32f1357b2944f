"""Machines screen, driven with Textual's pilot against fast simulated machines."""

from __future__ import annotations

import asyncio
from contextlib import asynccontextmanager

import pytest
from textual.widgets import DataTable, Static

from drivers.gcode import clean_line
from station.devices import DeviceEntry
from station.errors import StationError
from station.joblog import JobLog
from station.services.job_queue import JobState
from station.tui.app import StationApp


def sim_url(profile: str, pace: float | None = None) -> str:
    """The URL of a simulated machine on the virtual clock: a job runs as fast as the screen streams it, with the
    simulated timing of the wall clock. ``pace`` (simulated seconds per wall second at most) leaves a test time to
    act while a job runs (abort, quit)."""
    return f"sim://grbl?profile={profile}&clock=virtual" + (f"&pace={pace:g}" if pace else "")


FAST_DEVICES = (
    DeviceEntry("plotter", "plotter", sim_url("plotter"), True),
    DeviceEntry("laser", "laser", sim_url("laser", pace=3), True),
)


def station_app(tmp_path) -> StationApp:
    return StationApp(devices=FAST_DEVICES, database=tmp_path / "t.sqlite3")


async def _until(pilot, predicate, timeout=60.0):
    # A liveness guard, not a timing check: it returns as soon as the predicate holds (the machines run on the
    # virtual clock; the guard allows for a 2-core machine running simulations beside the suite).
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while not predicate():
        assert loop.time() < deadline, "condition not reached in time"
        await pilot.pause(0.05)


@asynccontextmanager
async def machines_screen(tmp_path, size=(160, 48)):
    """The station app showing the Machines screen, its simulated plotter connected: ``(app, pilot, screen)``."""
    app = station_app(tmp_path)
    async with app.run_test(size=size) as pilot:
        await pilot.press("m")
        await pilot.pause()
        screen = app.screen
        assert screen.name == "machines"
        await _until(pilot, lambda: "plotter" in screen.connections)  # simulated devices connect by themselves
        yield app, pilot, screen


async def _connect_laser(pilot, screen):
    """Switch to the laser (v), connect it (c); its connection."""
    await pilot.press("v")
    assert screen.device.name == "laser"
    await pilot.press("c")
    await _until(pilot, lambda: "laser" in screen.connections)
    return screen.connections["laser"]


async def _start_burn(pilot, screen):
    """Queue a laser job and start it (g); its entry, once the laser has confirmed a few lines."""
    entry = screen.queue_job("laser", _square(n=8, size=40, laser=True), title="burn")
    await pilot.press("g")
    await _until(pilot, lambda: screen.runner is not None and screen.runner.progress.lines_acked > 5)
    return entry


def _assert_laser_off_since_the_last_reset(conn):
    record = conn.port.machine.snapshot()
    assert record.resets
    after = [s for s in record.samples if s.t >= record.resets[-1]]
    assert after and all(s.power == 0.0 for s in after)


def _square(n=4, size=20.0, laser=False):
    lines = ["G21", "G90"]
    lines += ["M4 S500"] if laser else ["M3 S50"]
    for i in range(n):
        x0 = 20 + i * (size + 5)
        lines += [f"G0 X{x0} Y20", "M3 S30" if not laser else "",
                  f"G1 X{x0 + size} Y20 F3000", f"G1 X{x0 + size} Y{20 + size}", f"G1 X{x0} Y{20 + size}",
                  f"G1 X{x0} Y20", "M3 S50" if not laser else ""]
    lines.append("G0 X0 Y0")
    return "\n".join(line for line in lines if line)


async def test_machines_screen_connects_runs_a_queued_job_and_shows_progress(tmp_path):
    async with machines_screen(tmp_path) as (app, pilot, screen):
        conn = screen.connections["plotter"]
        await _until(pilot, lambda: conn.status is not None)
        await _until(pilot, lambda: "Idle" in screen.status_text and "planner" in screen.status_text)
        assert "RX 0/128 bytes" in screen.status_text
        gcode = _square()
        entry = screen.queue_job("plotter", gcode, title="squares")
        table = screen.query_one("#queue", DataTable)
        assert table.row_count == 1
        await pilot.press("g")
        await _until(pilot, lambda: entry.state == "done", timeout=30)
        assert "100.0%" in str(screen.query_one("#progress-label").render())
        preview = screen.query_one("#preview")
        assert len(preview.polylines) == 4 and set(preview._colors) == {"green"}  # every square drawn
        executed = [b.text for b in conn.port.machine.snapshot().executed]
        expected = [clean_line(x) for x in gcode.splitlines() if clean_line(x).startswith(("G0", "G1"))]
        assert executed == expected


async def test_abort_key_works_from_the_console_and_leaves_the_laser_off(tmp_path):
    async with machines_screen(tmp_path) as (app, pilot, screen):
        conn = await _connect_laser(pilot, screen)
        entry = await _start_burn(pilot, screen)
        assert entry.state == "running"
        await pilot.press("colon")  # focus the console: ctrl+x must still abort
        await pilot.press("ctrl+x")
        await _until(pilot, lambda: entry.state == "aborted", timeout=15)
        _assert_laser_off_since_the_last_reset(conn)
        assert "ALARM:3" in screen.status_text  # reset during motion: guided recovery is shown
        screen.set_focus(None)  # leave the console input
        await pilot.pause()
        await pilot.press("h")  # home clears the alarm
        await _until(pilot, lambda: conn.status is not None and conn.status.state == "Idle", timeout=15)


async def test_queue_job_refuses_unknown_device(tmp_path):
    async with machines_screen(tmp_path) as (app, pilot, screen):
        with pytest.raises(StationError, match="no device 'mill'"):
            screen.queue_job("mill", "G0 X1")
        assert screen.jobs == []


async def test_plot_key_on_the_drawing_screen_plots_the_pattern_and_ends_pen_up(tmp_path):
    app = station_app(tmp_path)
    async with app.run_test(size=(160, 48)) as pilot:
        await pilot.press("d")
        await pilot.pause()
        machine, params = app.screen.current_design()
        await pilot.press("l")
        await _until(pilot, lambda: app.screen.name == "machines")
        screen = app.screen
        await _until(pilot, lambda: len(screen.jobs) == 1, timeout=30)
        entry = screen.jobs[0]
        assert entry.device == "plotter" and machine in entry.title
        assert screen.device.name == "plotter"
        await _until(pilot, lambda: "plotter" in screen.connections and screen.connections["plotter"].status)
        await pilot.press("g")
        await _until(pilot, lambda: entry.state == "done", timeout=60)
        record = screen.connections["plotter"].port.machine.snapshot()
        drawn = [b for b in record.executed if not b.rapid and b.text.startswith("G1")]
        assert len(drawn) > 100  # the pattern's polyline, not a stand-in
        pen_up = app.screen.profile_for(screen.device).pen.up
        assert record.samples[-1].power == pen_up  # the servo is left holding the pen up
        # the job is in the station's history, and on the home screen
        (logged,) = JobLog(app.database).recent()
        assert (logged.kind, logged.device, logged.status) == ("run", "plotter", "done")
        assert logged.lines_acked == logged.lines_total == len(entry.job.lines)
        await pilot.press("escape")
        await pilot.pause()
        jobs = app.screen.query_one("#jobs", DataTable)
        assert jobs.row_count == 1 and "done" in [str(c) for c in jobs.get_row_at(0)]


def _console_text(screen) -> str:
    from textual.widgets import RichLog

    return "\n".join(strip.text for strip in screen.query_one("#console", RichLog).lines)


async def test_console_shows_messages_as_text_in_colour_and_wraps_long_lines(tmp_path):
    # The console printed "[red]hello world ...[/red]" literally and cut long lines at the panel's edge.
    async with machines_screen(tmp_path) as (app, pilot, screen):
        await pilot.press("colon")
        line = "hello world [b]bold[/b] " + " ".join(f"word{k}" for k in range(40)) + " THE-END"
        # The first words are typed; the rest is pasted into the field (300 key presses took half a minute).
        await pilot.press(*"hello ")
        from textual.widgets import Input

        field = screen.query_one("#console-input", Input)
        assert field.value == "hello "
        field.value = line
        await pilot.press("enter")
        await _until(pilot, lambda: "THE-END:" in screen.last_message)
        await pilot.pause(0.2)
        shown = _console_text(screen)
        assert "[red]" not in shown and "[/red]" not in shown
        assert "[b]bold[/b]" in shown  # the user's text is shown as typed, not read as markup
        assert "THE-END" in shown  # the tail of the long line wrapped onto the next lines
        from textual.widgets import RichLog

        log = screen.query_one("#console", RichLog)
        assert max(strip.cell_length for strip in log.lines) <= log.scrollable_content_region.width
        said = [strip for strip in log.lines if "hello world" in strip.text]
        assert said and any(segment.style and segment.style.color and segment.style.color.name == "red"
                            for segment in said[-1])
        message = screen.query_one("#message").render()
        assert "[b]bold[/b]" in str(message)


async def test_keys_act_on_return_to_the_screen_and_arrows_jog(tmp_path):
    # Focus stayed in the console field after leaving the screen and coming back, so n then g typed "ng"; and the
    # console log, focused when the screen opened, took the up and down arrows (it scrolled instead of jogging).
    from textual.widgets import Input

    async with machines_screen(tmp_path) as (app, pilot, screen):
        await _until(pilot, lambda: screen.connections["plotter"].status)
        conn = screen.connections["plotter"]
        await pilot.press("up")
        await _until(pilot, lambda: any(text.startswith("$J=") and "Y10" in text for _, d, text in conn.log
                                        if d == "out"))
        await pilot.press("colon")
        field = screen.query_one("#console-input", Input)
        assert screen.focused is field
        await pilot.press("escape")  # home
        await pilot.pause()
        assert app.screen.name == "home"
        await pilot.press("m")
        await pilot.pause()
        assert app.screen is screen and not isinstance(screen.focused, Input)
        await pilot.press("n")
        await _until(pilot, lambda: len(screen.jobs) == 1, timeout=30)
        assert field.value == ""


async def test_quit_during_a_job_asks_and_aborts_with_the_laser_off(tmp_path):
    # ctrl+q during a job quit at once: the port closed under the job, recorded as "interrupted 79/242".
    from station.db import open_database
    from station.tui.screens.confirm_quit import ConfirmQuitScreen

    async with machines_screen(tmp_path) as (app, pilot, screen):
        conn = await _connect_laser(pilot, screen)
        entry = await _start_burn(pilot, screen)
        await pilot.press("escape")  # quitting from another screen asks too
        await pilot.pause()
        await pilot.press("ctrl+q")
        await pilot.pause()
        assert isinstance(app.screen, ConfirmQuitScreen) and not app._exit
        await pilot.press("k")  # keep running
        await pilot.pause()
        assert app.screen.name == "home" and entry.state == "running" and not app._exit
        await pilot.press("ctrl+q")
        await pilot.pause()
        assert isinstance(app.screen, ConfirmQuitScreen)
        await pilot.press("a")  # abort the job and quit
        await _until(pilot, lambda: app._exit, timeout=30)
        assert entry.state == "aborted"
        _assert_laser_off_since_the_last_reset(conn)
        assert any("abort" in str(line) for line in app._exit_renderables)
    connection = open_database(tmp_path / "t.sqlite3")
    try:
        (logged,) = JobLog(connection).recent()
    finally:
        connection.close()
    assert (logged.title, logged.status) == ("burn", "aborted")


async def test_connected_message_names_the_version_without_the_build_suffix(tmp_path):
    # '[VER:1.1h.20190825:]' was shown whole: "plotter: GRBL 1.1h.20190825: connected"
    async with machines_screen(tmp_path) as (app, pilot, screen):
        await pilot.pause(0.2)
        said = [line for line in _console_text(screen).splitlines() if "connected" in line and "GRBL" in line]
        assert said and "GRBL 1.1h" in said[0] and "20190825:" not in said[0], said


@pytest.mark.parametrize("start", [True, False])
async def test_a_laser_without_homing_asks_for_its_frame_in_a_dialog(tmp_path, start):
    # the question station send asks at a terminal, answered here in a dialog: the one send of MachineSessions
    devices = (DeviceEntry("laser", "laser", sim_url("laser") + "&homing=0", True),)
    app = StationApp(devices=devices, database=tmp_path / "t.sqlite3")
    async with app.run_test(size=(160, 48)) as pilot:
        await pilot.press("m")
        screen = app.get_screen("machines")
        await _until(pilot, lambda: "laser" in screen.connections)
        conn = screen.connections["laser"]
        entry = screen.queue_job("laser", _square(n=1, laser=True), title="burn")
        await pilot.press("g")
        await _until(pilot, lambda: "Trace its frame first" in str(app.screen.query_one(Static).render()))
        await pilot.press("y")  # the frame at frame power
        await _until(pilot, lambda: "Start the laser job" in str(app.screen.query_one(Static).render()))
        assert entry.state is JobState.FRAMED
        await pilot.press("y" if start else "n")
        await _until(pilot, lambda: entry.state is (JobState.DONE if start else JobState.FRAMED)
                     and not screen.sessions.sending)
        await _until(pilot, lambda: app.screen is screen)
        rows = [(row.kind, row.status) for row in reversed(JobLog(app.database).recent())]
        assert rows == [("frame", "done"), ("run", "done")] if start else [("frame", "done")]
        burned = {b.power for b in conn.port.machine.snapshot().executed if not b.rapid}
        assert (500.0 in burned) is start
