"""Place a laser job on the stock by camera: the camera's picture of the bed with the job's outline drawn on it at
true scale (through the bed's registration, ``station calibrate bed``), moved and turned with keys or snapped onto
the stock the camera finds, verified on the twin, then queued at that placement.

Opened from the Machines screen with ``b`` for its next job on the selected laser. The work is
:class:`station.services.bed.BedPlacement` and the app's machine sessions
(:meth:`station.services.machine_sessions.MachineSessions.verify` and ``place``).

Keys: arrows move the job by the step, [ ] change the step, , . turn it by the turn step (< > by 15 degrees),
s snap it onto the stock, g grab a new frame, k register the bed now (engraves four marks on scrap), v verify on
the twin, w write the picture (PNG) to the data folder, Enter queue the placed job, Escape back.
"""

from __future__ import annotations

from pathlib import Path

from PIL import Image
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical
from textual.screen import Screen
from textual.widgets import Footer, Header, Static

from station.errors import USER_ERRORS, StationError
from station.services import bed as bed_service
from station.services.machine_sessions import verify_summary
from station.services.station_home import data_dir
from station.tui.messages import BedFrameGrabbed, BedRegistered, JobVerified
from station.tui.widgets.picture import HalfBlockPicture
from station.tui.work import run_work

__all__ = ["BedPlacementScreen", "MOVE_STEPS"]

MOVE_STEPS = (0.5, 1.0, 5.0, 10.0, 50.0)
TURN_STEP = 1.0


class BedPlacementScreen(Screen):
    """The camera's picture of the bed with the job on it (module docstring)."""

    CSS = """
    BedPlacementScreen #bed-picture { height: 1fr; }
    BedPlacementScreen #bed-status { height: auto; padding: 0 1; border: round $primary; }
    """
    AUTO_FOCUS = ""
    BINDINGS = [
        Binding("escape", "close", "Back"),
        Binding("enter", "queue", "Queue placed job"),
        Binding("s", "snap", "Snap to stock"),
        Binding("g", "grab", "Grab frame"),
        Binding("k", "register", "Register bed"),
        Binding("v", "verify", "Verify"),
        Binding("w", "write", "Write PNG"),
        Binding("left", "move(-1, 0)", "Move", show=False),
        Binding("right", "move(1, 0)", "Move", show=False),
        Binding("up", "move(0, 1)", "Move", show=False),
        Binding("down", "move(0, -1)", "Move", show=False),
        Binding("left_square_bracket", "step(-1)", "Step-", show=False),
        Binding("right_square_bracket", "step(1)", "Step+", show=False),
        Binding("comma", "turn(1)", "Turn", show=False),
        Binding("full_stop", "turn(-1)", "Turn", show=False),
        Binding("less_than_sign", "turn(15)", "Turn 15", show=False),
        Binding("greater_than_sign", "turn(-15)", "Turn 15", show=False),
    ]

    def __init__(self, machines, entry, device, connection, profile) -> None:
        super().__init__(name="bed-placement")
        self.machines = machines
        self.entry = entry
        self.device = device
        self.connection = connection
        self.profile = profile
        self.session: bed_service.BedPlacement | None = None
        self.step_index = 2
        self.note = ""

    def compose(self) -> ComposeResult:
        yield Header()
        with Vertical():
            yield HalfBlockPicture(id="bed-picture", empty="(grabbing the camera's picture of the bed...)")
            yield Static("", id="bed-status")
        yield Footer()

    def on_mount(self) -> None:
        self.sub_title = f"{self.entry.title} on {self.device.name}"
        try:
            registration = bed_service.load_registration(self.device.name)
        except StationError as error:
            registration, self.note = None, str(error)
        if registration is None:
            self._say(f"the bed of {self.device.name} is not registered yet: k engraves four marks on scrap and "
                      "registers it (station calibrate bed)", "yellow")
            return
        self._start(registration)

    def _start(self, registration) -> None:
        wco = tuple(float(v) for v in self.connection.work_offset())
        lo, hi = self.connection.machine_bounds()
        try:
            self.session = bed_service.BedPlacement(registration, list(self.entry.job.lines), wco,
                                                    travel=((lo[0], lo[1]), (hi[0], hi[1])))
        except USER_ERRORS as error:
            self._say(f"this job cannot be placed: {error}", "red")
            return
        self._grab()

    # ------------------------------------------------------------------ camera

    def _grab(self) -> None:
        """A new picture of the bed from its camera, in a worker."""
        device, connection = self.device, self.connection
        run_work(self, lambda report: bed_service.grab_bed_frame(device.name, device.simulated, connection),
                 BedFrameGrabbed, group="bed-camera")

    def on_bed_frame_grabbed(self, message: BedFrameGrabbed) -> None:
        if not message.ok:
            self._say(f"no picture from the bed's camera: {message.error}", "red")
            return
        self.session.see(message.result)
        self._show()

    def _show(self) -> None:
        if self.session is None or self.session.frame is None:
            return
        self.query_one(HalfBlockPicture).set_image(Image.fromarray(self.session.picture()))
        self._say(self.note)

    def _say(self, text: str, style: str = "") -> None:
        lines = []
        if self.session is not None:
            lines.append(f"{self.session.describe()} · step {MOVE_STEPS[self.step_index]:g} mm")
        if text:
            lines.append(f"[{style}]{text}[/]" if style else text)
        lines.append("arrows move · [ ] step · , . turn 1° · < > turn 15° · s snap to stock · g grab · k register · "
                     "v verify · w write PNG · Enter queue · Esc back")
        self.query_one("#bed-status", Static).update("\n".join(lines))

    # ------------------------------------------------------------------ keys

    def action_move(self, dx: int, dy: int) -> None:
        if self.session is not None:
            step = MOVE_STEPS[self.step_index]
            self.session.move(dx * step, dy * step)
            self.note = ""
            self._show()

    def action_step(self, direction: int) -> None:
        self.step_index = max(0, min(len(MOVE_STEPS) - 1, self.step_index + direction))
        self._show() if self.session is not None and self.session.frame is not None else self._say(self.note)

    def action_turn(self, degrees: float) -> None:
        if self.session is not None:
            self.session.turn(float(degrees) * TURN_STEP)
            self.note = ""
            self._show()

    def action_snap(self) -> None:
        if self.session is None:
            return
        self.note = ("snapped onto the stock: its lower-left corner 5 mm inside the sheet's, along its edge"
                     if self.session.snap() else "no stock found in the picture (g grabs a new one)")
        self._show()

    def action_grab(self) -> None:
        if self.session is not None:
            self._grab()

    def action_register(self) -> None:
        self._say("engraving four registration marks and registering the bed...")
        laser, connection = self.device.name, self.connection
        request = bed_service.BedCalibrationRequest(laser=laser)
        run_work(self, lambda report: bed_service.calibrate_bed(request, connection=connection, report=report),
                 BedRegistered, group="bed-camera")

    def on_bed_registered(self, message: BedRegistered) -> None:
        if not message.ok:
            self._say(f"bed registration failed: {message.error}", "red")
            return
        self.note = " ".join(bed_service.bed_summary(message.result)[:1])
        self._start(message.result.registration)

    def action_verify(self) -> None:
        if self.session is None:
            return
        self._say("running the placed job on the twin...")
        try:
            lines = self.session.placed_lines()
        except USER_ERRORS as error:
            self._say(f"cannot verify: {error}", "red")
            return
        sessions, device, title, profile = self.machines.sessions, self.device.name, self.entry.title, self.profile
        run_work(self, lambda report: sessions.verify(device, lines, title=title, profile=profile, laser=True),
                 JobVerified, group="bed-verify")

    def on_job_verified(self, message: JobVerified) -> None:
        if not message.ok:
            self._say(f"cannot verify: {message.error}", "red")
            return
        self.note = " · ".join(line.strip() for line in verify_summary(message.result))
        self._say(self.note, "green" if message.result.ok else "red")

    def action_write(self) -> None:
        if self.session is None or self.session.frame is None:
            return
        path = Path(data_dir()) / "bed-placement.png"
        Image.fromarray(self.session.picture()).save(path)
        self.note = f"wrote {path}"
        self._show()

    def action_queue(self) -> None:
        if self.session is None:
            return
        p = self.session.placement
        try:
            lines = self.session.placed_lines()
        except USER_ERRORS as error:
            self._say(f"cannot place this job: {error}", "red")
            return
        title = f"{self.entry.title.split(' @ ')[0]} @ {p.x:.1f},{p.y:.1f},{p.angle:.1f}"
        # queued: the job itself moves (the unplaced one must not be sent by the next g); sent before (framed,
        # checked, stopped): the placed one is a new job
        placed = self.machines.sessions.place(self.entry, lines, title)
        self.machines._refresh_queue()
        self.machines._show_preview(placed)
        self.app.pop_screen()

    def action_close(self) -> None:
        self.app.pop_screen()


def open_bed_placement(machines) -> None:
    """Open the placement for the Machines screen's next job on its selected laser (or say why not)."""
    device = machines.device
    if device is None or device.kind != "laser":
        machines._say("select the laser (v) to place a job on its bed")
        return
    conn = machines.connection()
    if conn is None:
        machines._say("not connected: press c")
        return
    entry = machines.next_job()
    if entry is None:
        machines._say("no queued job for the laser to place")
        return
    machines.app.push_screen(BedPlacementScreen(machines, entry, device, conn, machines.profile_for(device)))


def verify_next_job(machines) -> None:
    """Run the Machines screen's next job on the twin of its machine at virtual time (its settings and work offset
    when connected) and say what it found: the time with acceleration, the laser dark on travels, the travel."""
    device = machines.device
    entry = machines.next_job()
    if device is None or entry is None:
        machines._say("no queued job for this device to verify")
        return
    try:
        profile = machines.profile_for(device)
    except StationError as error:
        machines._say(f"cannot verify: {error}", "red")
        return
    machines._say(f"running {entry.title!r} on the twin of {device.name}...")
    sessions, lines, laser = machines.sessions, entry.job.lines, entry.job.laser

    def verify(report):
        try:
            return sessions.verify(device.name, lines, title=entry.title, profile=profile, laser=laser)
        except USER_ERRORS as error:
            raise StationError(f"cannot verify {entry.title!r}: {error}") from None

    run_work(machines, verify, JobVerified, group="verify")
