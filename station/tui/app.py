"""The station's Textual app."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from textual import messages
from textual.app import App
from textual.binding import Binding
from textual.screen import Screen

from station.services.machine_sessions import MachineSessions
from station.services.station_home import DeviceEntry, default_devices, open_station_database, shared_job_log
from station.tui.registry import MachineDesign, ScreenEntry, discover_screens
from station.tui.screens.confirm_quit import ABORT_AND_QUIT, ConfirmQuitScreen
from station.tui.screens.home import HomeScreen

#: Device kinds the station can drive today (plotter and laser over GRBL, the camera, the projector).
DRIVEN_KINDS = frozenset({"plotter", "laser", "camera", "projector"})


class StationApp(App):
    """Crafting Chaos station.

    Parameters
    ----------
    devices : tuple of DeviceEntry, optional
        Devices to show and use; every device simulated by default.
    database : path, optional
        The SQLite trial database; the user's data directory by default.
    areas : sequence of ScreenEntry, optional
        The area screens to install; every discovered one by default (tests leave some out).
    """

    TITLE = "Crafting Chaos station"
    SUB_TITLE = "simulated devices"
    BINDINGS = [
        Binding("ctrl+q", "quit", "Quit", priority=True),
        Binding("escape", "home", "Home"),
    ]

    def __init__(self, devices: tuple[DeviceEntry, ...] | None = None, database: str | Path | None = None,
                 areas: Sequence[ScreenEntry] | None = None) -> None:
        super().__init__()
        self.devices = devices if devices is not None else default_devices()
        self.database_path, self.database = open_station_database(database)
        # the machines and their jobs: one for the app, which the Machines screen and the screens that queue jobs drive
        self.machine_sessions = MachineSessions(shared_job_log(self.database_path), source="tui")
        self.areas: list[ScreenEntry] = list(areas) if areas is not None else discover_screens()
        self._aborting_to_exit = False
        if all(d.simulated for d in self.devices):
            self.sub_title = "all devices simulated"
        else:
            self.sub_title = f"{sum(not d.simulated for d in self.devices)} real device(s)"

    def on_mount(self) -> None:
        self.install_screen(HomeScreen(self.areas, self.devices, str(self.database_path)), name="home")
        for entry in self.areas:
            self.install_screen(entry.factory(), name=entry.name)
        self.push_screen("home")

    def device_state(self, device: DeviceEntry) -> str:
        """A short state for the home screen; drivers refine this as they connect."""
        if device.kind not in DRIVEN_KINDS:
            return "no driver yet"
        return "ready (simulated)" if device.simulated else "not connected"

    def action_open_area(self, name: str) -> None:
        """Show an area screen on top of home (one level deep: Escape returns home)."""
        while len(self.screen_stack) > 2:
            self.pop_screen()
        if self.screen.name != "home" and len(self.screen_stack) > 1:
            self.pop_screen()
        self.push_screen(name)

    def open_area_if_installed(self, name: str) -> Screen | None:
        """Open area ``name`` and return its screen; an area that is not installed is a warning, not a crash."""
        if not any(entry.name == name for entry in self.areas):
            self.notify(f"the {name} area is not installed", severity="warning")
            return None
        self.action_open_area(name)
        return self.get_screen(name)

    def action_home(self) -> None:
        while len(self.screen_stack) > 2:
            self.pop_screen()
        if self.screen.name != "home" and len(self.screen_stack) > 1:
            self.pop_screen()

    def open_design(self, machine: str, params: dict[str, Any]) -> None:
        """Open a drawing-machine design on the Drawing machines screen (used by sketch retrieval and others); in an
        app without that screen, a warning."""
        drawing = self.open_area_if_installed("drawing")
        if drawing is not None:
            drawing.load_design(machine, params)

    def current_design(self) -> MachineDesign | None:
        """The Drawing machines screen's design (used by Explore, Fabricate, Plot); None in an app without it."""
        try:
            drawing = self.get_screen("drawing")
        except KeyError:
            return None
        return drawing.current_design()

    def current_contraption(self) -> tuple[str, str] | None:
        """The Contraptions screen's scenario file and layout (a name in the file, or "" for its defaults), for the
        Trials screen; None in an app without that screen or before a scenario is loaded."""
        try:
            contraption = self.get_screen("contraption")
        except KeyError:
            return None
        scenario = getattr(contraption, "scenario", None)
        if scenario is None:
            return None
        name = contraption.layout_names[contraption.layout_index]
        return scenario.source, "" if name == "file default" else name

    def current_assembly(self) -> tuple[str, str] | None:
        """The Assemble screen's scenario file and layout (a file, a name in the scenario, or "" for its own), for
        the Trials screen: those of the guide it built, else those in its fields; None in an app without that screen
        or before it was opened."""
        try:
            assemble = self.get_screen("assemble")
        except KeyError:
            return None
        chosen = getattr(assemble, "chosen_layout", None)
        return chosen() if chosen is not None else None

    def machines_screen(self) -> Screen | None:
        """The Machines screen (it owns the device sessions and the job queues); None in an app without it."""
        try:
            return self.get_screen("machines")
        except KeyError:
            return None

    def _active_job(self):
        """The Machines screen and the job it is sending now (None when idle, or in an app without it)."""
        machines = self.machines_screen()
        return machines, machines.active_job() if hasattr(machines, "active_job") else None

    async def action_quit(self) -> None:
        """Quit (ctrl+q, the command palette); while a machine job runs, ask first.

        The answer is either keep the job running, or abort it (soft reset, then ``M5 S0``: the laser is off), wait
        until it has ended and is recorded in the job history, and quit, saying how the job ended.
        """
        machines, job = self._active_job()
        if job is None:
            self.exit()
            return
        if isinstance(self.screen, ConfirmQuitScreen):
            return  # already asking

        def answered(answer: str | None) -> None:
            if answer == ABORT_AND_QUIT:
                machines.abort_then(self._exit_saying)

        self.push_screen(ConfirmQuitScreen(job.title, job.device, job.state, laser=job.job.laser), answered)

    def on_exit_app(self, event: messages.ExitApp) -> None:
        """In a browser (``station serve``), a session whose browser went away (tab closed, Wi-Fi lost) is told to
        quit with no one left to ask: a running job is aborted as ctrl+q's "abort and quit" does (soft reset, laser
        off, ``M5 S0``), and the app exits once the job has ended and is recorded (``aborted``, with its resume line).

        A terminal's app is not changed: it is asked with ctrl+q (:meth:`action_quit`), and closing the connection
        under a job on exit (:meth:`MachinesScreen.shutdown`) aborts it too, without waiting for the record.
        """
        if not self.is_web or self._aborting_to_exit:
            return
        machines, job = self._active_job()
        if job is None:
            return
        event.prevent_default()
        self._aborting_to_exit = True
        machines.abort_then(self._exit_saying)

    def _exit_saying(self, message: str) -> None:
        """Exit once an aborted job has ended, saying how it ended."""
        self.exit(message=f"chaos-station: {message}")

    def on_unmount(self) -> None:
        self.machine_sessions.close()
        self.machine_sessions.queue.log.close()
        self.database.close()
