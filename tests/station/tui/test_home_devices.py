"""The home screen's devices table: each device's probed state, found off the UI thread, shown as plain text."""

from __future__ import annotations

from types import MappingProxyType

from textual.widgets import DataTable

from station.devices import DeviceEntry
from station.tui.app import StationApp
from station.tui.screens.home import PROBING

from ...conftest import settle

DEVICES = (
    DeviceEntry("plotter", "plotter", "sim://grbl?profile=plotter", True, "plotter"),
    DeviceEntry("bench", "laser", "/dev/ttyUSB99", False, "laser"),
    DeviceEntry("cam", "camera", "sim://camera", True),
    DeviceEntry("clip", "camera", "/nonexistent/clip.avi", False),
    DeviceEntry("net", "plotter", "socket://[b]host[/b]:23", False, "plotter"),
    DeviceEntry("odd", "plotter", "ftp://x", False, "plotter"),
    # loop:// echoes and never answers: its probe takes its whole timeout
    DeviceEntry("slow", "plotter", "loop://", False, "plotter", MappingProxyType({"timeout": 1.5})),
)


def probed(table: DataTable) -> dict[str, str]:
    return {str(table.get_row(key)[0]): str(table.get_row(key)[5]) for key in table.rows}


async def test_home_shows_each_devices_probed_state_without_waiting_for_it(tmp_path):
    app = StationApp(devices=DEVICES, database=tmp_path / "t.sqlite3")
    async with app.run_test(size=(240, 40)) as pilot:
        await pilot.pause()
        table = app.screen.query_one("#devices", DataTable)
        # the screen is up before the slow probe answers: probes never run on the UI thread
        assert probed(table)["slow"] == PROBING
        await settle(app, pilot)
        states = probed(table)
        assert states["plotter"] == "connected: Grbl 1.1h, Idle"
        assert states["bench"] == "not connected: no such port"
        assert states["cam"] == "open: 1920x1080"
        assert states["clip"] == "not available: no such video file"
        assert states["slow"] == "not connected: no GRBL banner within 1.5 s"
        assert states["odd"].startswith("probe failed: device URL 'ftp://x' matches no driver")
        # a state quoting a URL is shown as written, not read as markup
        assert states["net"].startswith("not connected: cannot open port 'socket://[b]host[/b]:23'")
        net_line = next(table.render_line(1 + row).text for row, key in enumerate(table.rows) if key == "net")
        assert "cannot open port 'socket://[b]host[/b]:23'" in net_line
        # the readiness column is as before
        assert str(table.get_row("plotter")[4]) == "ready (simulated)"

