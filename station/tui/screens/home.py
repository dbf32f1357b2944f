"""The home screen: the areas of the station, the devices and their state, the database.

Each device's line shows the state a brief probe finds (:func:`station.services.station_home.probe`, the same as
``station devices``), probed once when the screen is made, each in its own thread worker so that the screen never
waits for a port. Probing again on return would open a real machine's port while the Machines screen may be
streaming to it, so it is not repeated.
"""

from __future__ import annotations

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical
from textual.screen import Screen
from textual.widgets import DataTable, Footer, Header, Static

from station.services.station_home import DeviceEntry, local_time, probe, recent_jobs
from station.tui.messages import DeviceProbed
from station.tui.registry import ScreenEntry
from station.tui.work import run_work

#: Jobs shown on the home screen (``station jobs`` lists more).
RECENT_JOBS = 5

#: The devices table's column of probed states, and what it shows until a probe answers.
PROBE_COLUMN, PROBING = "probe", "probing..."


class HomeScreen(Screen):
    """Start page: where to go, what is connected, where the data lives."""

    # The devices table spans the screen: a probe's answer widens its column after the table is laid out, and a table
    # as wide as its columns would keep the old width on screen until something else lays the screen out again.
    CSS = """
    HomeScreen #areas { height: auto; padding: 1 2; }
    HomeScreen #devices { height: auto; width: 1fr; margin: 0 2; }
    HomeScreen #jobs { height: auto; max-height: 8; margin: 0 2; }
    HomeScreen #database { padding: 1 2; color: $text-muted; }
    HomeScreen .heading { text-style: bold; padding: 0 2; margin-top: 1; }
    """

    def __init__(self, areas: list[ScreenEntry], devices: tuple[DeviceEntry, ...], database: str) -> None:
        super().__init__(name="home")
        self.areas = areas
        self.devices = devices
        self.database = database
        self.bindings_for_areas = [
            Binding(entry.key, f"app.open_area('{entry.name}')", entry.title) for entry in areas
        ]
        for binding in self.bindings_for_areas:
            self._bindings.bind(binding.key, binding.action, binding.description)

    def compose(self) -> ComposeResult:
        yield Header(show_clock=False)
        with Vertical():
            yield Static("Areas", classes="heading")
            lines = [f"[b]{e.key}[/b]  {e.title} — {e.description}" for e in self.areas]
            yield Static("\n".join(lines) or "No areas installed.", id="areas")
            yield Static("Devices", classes="heading")
            yield DataTable(id="devices", cursor_type="row", zebra_stripes=True)
            yield Static("Recent machine jobs", classes="heading")
            yield DataTable(id="jobs", cursor_type="row", zebra_stripes=True)
            yield Static(Text(f"Database: {self.database}"), id="database")
        yield Footer()

    def on_mount(self) -> None:
        table = self.query_one("#devices", DataTable)
        table.add_columns("device", "kind", "mode", "port", "state")
        table.add_column(PROBE_COLUMN, key=PROBE_COLUMN)
        for device in self.devices:
            table.add_row(
                device.name,
                device.kind,
                "simulated" if device.simulated else "real",
                Text(device.url),
                self.app.device_state(device),
                Text(PROBING),
                key=device.name,
            )
            self.probe(device)
        self.query_one("#jobs", DataTable).add_columns("#", "started", "kind", "device", "job", "state", "lines")
        self.show_jobs()

    def on_screen_resume(self) -> None:
        self.show_jobs()

    def probe(self, device: DeviceEntry) -> None:
        """Probe ``device`` off the UI thread (a GRBL probe waits up to its timeout); the state arrives as a
        :class:`DeviceProbed`."""
        run_work(self, lambda _report: (device.name, probe(device)), DeviceProbed, group=f"probe-{device.name}")

    def on_device_probed(self, message: DeviceProbed) -> None:
        """Show a probe's answer as plain text (it quotes URLs and device replies, which are not markup)."""
        if not message.ok:
            return
        name, state = message.result
        table = self.query_one("#devices", DataTable)
        if name in table.rows:
            table.update_cell(name, PROBE_COLUMN, Text(state), update_width=True)

    def show_jobs(self) -> None:
        """The latest machine jobs from the station database (a job run elsewhere shows when home is shown again)."""
        table = self.query_one("#jobs", DataTable)
        table.clear()
        records = recent_jobs(getattr(self.app, "database", None), RECENT_JOBS)
        for record in records:
            state = record.status
            if record.resume_line and state != "done":
                state += f" (resume at {record.resume_line})"
            table.add_row(str(record.id), local_time(record.created_at), record.kind, record.device[:24],
                          Text(record.title[-40:]), state, f"{record.lines_acked}/{record.lines_total}")
        if not records:
            table.add_row("", "", "", "", "no jobs yet: plot a pattern (d, then l) or cut parts (f)", "", "")
