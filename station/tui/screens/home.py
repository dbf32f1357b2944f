"""The home screen: the areas of the station, the devices and their state, the database."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical
from textual.screen import Screen
from textual.widgets import DataTable, Footer, Header, Static

from station.devices import DeviceEntry
from station.tui.registry import ScreenEntry


class HomeScreen(Screen):
    """Start page: where to go, what is connected, where the data lives."""

    CSS = """
    HomeScreen #areas { height: auto; padding: 1 2; }
    HomeScreen #devices { height: auto; margin: 0 2; }
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
            yield Static(f"Database: {self.database}", id="database")
        yield Footer()

    def on_mount(self) -> None:
        table = self.query_one("#devices", DataTable)
        table.add_columns("device", "kind", "mode", "port", "state")
        for device in self.devices:
            table.add_row(
                device.name,
                device.kind,
                "simulated" if device.simulated else "real",
                device.url,
                self.app.device_state(device),
                key=device.name,
            )
