"""A multi-pen plot on the Machines screen: opened from a file (o), shown in its pens' colours with its travel and
each layer's time, paused at each pen change with the pen to put in, resumed with r, and its layer in the history."""

from __future__ import annotations

import asyncio
import io

import numpy as np

from cam.layers import PenLayer, write_layers_gcode
from drivers.gcode_layers import layer_marks
from drivers.profiles import load_profile
from station.devices import DeviceEntry
from station.joblog import JobLog
from station.services import plot as plot_service
from station.tui.app import StationApp

DEVICES = (DeviceEntry("plotter", "plotter", "sim://grbl?profile=plotter&clock=virtual", True),)


def square(x: float, y: float, side: float) -> np.ndarray:
    return np.array([[x, y], [x + side, y], [x + side, y + side], [x, y + side], [x, y]], dtype=float)


async def _until(pilot, predicate, timeout=60.0):
        # a liveness guard, not a timing check: the machine runs on the virtual clock
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while not predicate():
        assert loop.time() < deadline, "condition not reached in time"
        await pilot.pause(0.05)


async def test_a_plot_of_three_pens_pauses_for_each_pen_and_r_resumes(tmp_path):
    profile = load_profile("plotter")
    layers = [PenLayer("a", "a", "#1f77b4", [square(40, 40, 30)]), PenLayer("b", "b", "#d62728", [square(80, 40, 30)]),
              PenLayer("c", "c", "#2ca02c", [square(120, 40, 30)])]
    stream = io.StringIO()
    write_layers_gcode(layers, stream, plot_service.writer_options(profile), profile.pen.change)
    job = tmp_path / "squares.gcode"
    job.write_text(stream.getvalue())
    marks = layer_marks(stream.getvalue().splitlines())
    assert len(marks) == 3

    app = StationApp(devices=DEVICES, database=tmp_path / "t.sqlite3")
    async with app.run_test(size=(160, 48)) as pilot:
        await pilot.press("m")
        await pilot.pause()
        screen = app.screen
        await _until(pilot, lambda: "plotter" in screen.connections)
        await pilot.press("o")
        await pilot.pause()
        field = screen.query_one("#console-input")
        assert app.focused is field and field.value == "open "
        field.insert_text_at_cursor(str(job))  # as typed
        await pilot.press("enter")
        await _until(pilot, lambda: screen.jobs)
        # queued with each layer's pen and time estimate
        assert "3 pens: 1 a (a) " in screen.last_message and "3 c (c)" in screen.last_message
        preview = screen.query_one("#preview")
        assert {"#1f77b4", "#d62728", "#2ca02c"} <= set(preview._colors) and "grey27" in preview._colors

        await pilot.press("g")
        await _until(pilot, lambda: screen.runner is not None and screen.runner.progress.state == "paused")
        await _until(pilot, lambda: "r resumes" in screen.last_message)
        assert screen.last_message == 'pen change: put in pen "b" for layer 2/3 "b": r resumes'
        await pilot.press("r")
        await _until(pilot, lambda: screen.runner is not None and screen.runner.pause_line == marks[2].pause)
        await _until(pilot, lambda: 'layer 3/3 "c"' in screen.last_message)
        # stopped at the last pen change: the history keeps the layer it stood on
        await pilot.press("ctrl+x")
        await _until(pilot, lambda: screen.runner is None)
        (record, *_) = JobLog(app.database).recent(1)
        assert record.status == "aborted" and record.layer["number"] == 3
        assert record.resume_line == marks[2].pause + 1
        assert "--from-layer 3 starts it again" in record.resume_hint()
