from __future__ import annotations

from textual.widgets import DataTable

from station.devices import default_devices
from station.tui.app import StationApp
from station.tui.registry import discover_screens


async def test_home_shows_simulated_devices_and_database(tmp_path):
    app = StationApp(database=tmp_path / "t.sqlite3")
    async with app.run_test() as pilot:
        await pilot.pause()
        assert app.screen.name == "home"
        table = app.screen.query_one("#devices", DataTable)
        assert table.row_count == len(default_devices())
        modes = {table.get_row(key)[2] for key in table.rows}
        assert modes == {"simulated"}
        states = {table.get_row(key)[0]: table.get_row(key)[4] for key in table.rows}
        # every kind the station drives is "ready" when simulated
        assert states == {"plotter": "ready (simulated)", "laser": "ready (simulated)", "camera": "ready (simulated)",
                          "projector": "ready (simulated)"}
        assert str(tmp_path / "t.sqlite3") in str(app.screen.query_one("#database").render())


async def test_every_area_opens_and_escape_returns_home(tmp_path):
    app = StationApp(database=tmp_path / "t.sqlite3")
    async with app.run_test() as pilot:
        for entry in discover_screens():
            await pilot.press(entry.key)
            await pilot.pause()
            assert app.screen.name == entry.name
            await pilot.press("escape")
            await pilot.pause()
            assert app.screen.name == "home"


async def test_quit_without_a_running_job_does_not_ask(tmp_path):
    app = StationApp(database=tmp_path / "t.sqlite3")
    async with app.run_test() as pilot:
        await pilot.press("ctrl+q")
        await pilot.pause()
        assert app._exit and app.screen.name == "home"


async def test_job_titles_and_paths_are_shown_as_written(tmp_path):
    # Table cells and statics read strings as markup: a G-code file named "[b]box[/b].gcode" showed as "box.gcode".
    from station.db import open_database
    from station.joblog import JobLog

    folder = tmp_path / "[red]home"
    folder.mkdir()
    database = open_database(folder / "t.sqlite3")
    try:
        log = JobLog(database)
        log.finish(log.start("run", "plotter", "[b]box[/b].gcode", 3, "cli"), "done", 3, "done", None)
    finally:
        database.close()
    app = StationApp(database=folder / "t.sqlite3")
    async with app.run_test() as pilot:
        await pilot.pause()
        jobs = app.screen.query_one("#jobs", DataTable)
        assert "[b]box[/b].gcode" in jobs.render_line(1).text  # the first row, under the header
        assert "[red]home" in str(app.screen.query_one("#database").render())
