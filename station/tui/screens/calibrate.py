"""Calibrate screen: the camera's intrinsics and the plane check, one panel each, with progress.

Camera: type a folder of board images (or a number of frames to grab from the station's camera, moving the board
between them) and press Calibrate (or f / g); the views are searched and solved in a worker, the result shows the
RMS, each view's error and which image corners lacked views, and is saved under the station's data folder
(``calibration/cameras/<camera>.json``). Stop cancels between views. Plane: a guide manifest (``station guide
--json``) and optionally a frame file (else a frame from the camera); p checks the plane: the residual at the
reference tags and how far it moved since the last check. The projector's panel
(:class:`station.tui.widgets.projector_calibration.ProjectorCalibrationPanel`) and the simulator's
(:class:`station.tui.widgets.sim_calibration.SimCalibrationPanel`, fitting the material values to the trial log)
stand beside them.
"""

from __future__ import annotations

from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import Screen
from textual.widgets import Button, DataTable, Footer, Header, Input, Label, Static

from station.services import calibrate as service
from station.services.trials import logged_trials
from station.tui.messages import CameraCalibrated, PlaneChecked, ProgressReported
from station.tui.registry import ScreenEntry
from station.tui.widgets.progress import ProgressPanel
from station.tui.widgets.projector_calibration import ProjectorCalibrationPanel
from station.tui.widgets.sim_calibration import SimCalibrationPanel
from station.tui.work import Work, run_work


class CameraPanel(Vertical):
    """Intrinsics from a folder of board images or frames grabbed from the camera: progress, views, result."""

    DEFAULT_CSS = """
    CameraPanel { width: 1fr; border: round $primary-darken-2; padding: 0 1; }
    CameraPanel Input { width: 100%; }
    CameraPanel #camera-buttons { height: auto; }
    CameraPanel Button { margin-right: 1; min-width: 10; }
    CameraPanel #camera-views { height: auto; max-height: 16; }
    CameraPanel #camera-result { height: auto; }
    """

    #: The running calibration, which Stop asks to stop (None before the first).
    _work: Work | None = None

    def compose(self) -> ComposeResult:
        yield Label("[b]Camera intrinsics[/b] (ChArUco board: `station calibrate board --pdf`)")
        yield Input(placeholder="folder of board images", id="camera-folder")
        yield Input(placeholder="or frames to grab from the camera (e.g. 15)", id="camera-count", type="integer")
        with Horizontal(id="camera-buttons"):
            yield Button("Calibrate", id="camera-run", variant="primary")
            yield Button("Stop", id="camera-stop", disabled=True)
        yield ProgressPanel("give a folder (f) or a number of frames (g)", id="camera-progress")
        yield Static("", id="camera-result")
        yield DataTable(id="camera-views", cursor_type="row", zebra_stripes=True)

    def on_mount(self) -> None:
        self.query_one("#camera-views", DataTable).add_columns("view", "corners", "RMS px / skipped")

    def say(self, text: str) -> None:
        self.query_one("#camera-result", Static).update(Text(text))

    @on(Button.Pressed, "#camera-run")
    def _run_pressed(self) -> None:
        folder = self.query_one("#camera-folder", Input).value.strip()
        self.start(folder=folder) if folder else self.start(count_text=self.query_one("#camera-count", Input).value)

    @on(Button.Pressed, "#camera-stop")
    def stop(self) -> None:
        if self._work is not None:
            self._work.stop()
        self.say("stopping…")

    def start(self, folder: str | None = None, count_text: str | None = None) -> None:
        """Calibrate from ``folder``, or grab ``count_text`` frames (a whole number) from the station's camera."""
        count = None
        if not folder:
            text = (count_text or "").strip()
            if not text.isdigit() or int(text) < 1:
                self.say(f"give a folder of board images, or a whole number of frames to grab (got {text!r})")
                return
            count = int(text)
        self.query_one("#camera-views", DataTable).clear()
        self.query_one("#camera-progress", ProgressPanel).start(None, "starting…")
        self.query_one("#camera-stop", Button).disabled = False
        self.say("")
        self.calibrate(folder or None, count)

    def calibrate(self, folder: str | None, count: int | None) -> None:
        """Calibrate in a worker; progress and the end arrive as messages."""
        request = service.CameraCalibrationRequest(images=folder, capture=count)
        self._work = run_work(self, lambda report: service.calibrate_camera(request, report=report),
                              CameraCalibrated, group="calibrate-camera")

    def on_progress_reported(self, message: ProgressReported) -> None:
        message.stop()
        self.query_one("#camera-progress", ProgressPanel).show(message.progress)

    def on_camera_calibrated(self, message: CameraCalibrated) -> None:
        message.stop()
        self.query_one("#camera-stop", Button).disabled = True
        if not message.ok:
            said = "stopped; nothing saved" if message.stopped else message.error
            self.query_one("#camera-progress", ProgressPanel).say(said)
            self.say(said)
            return
        done = message.result
        result = done.result
        table = self.query_one("#camera-views", DataTable)
        for view in result.views:
            table.add_row(view.name, str(view.corners),
                          f"{view.rms_px:.3f}" if view.skipped is None else view.skipped)
        self.say("\n".join(service.camera_summary(result, views=False) + [f"saved {done.path}"]))
        self.query_one("#camera-progress", ProgressPanel).say(f"done: RMS {result.intrinsics.rms_px:.3f} px")


class PlanePanel(Vertical):
    """The plane from the reference tags in one frame: residual, moved since the last check."""

    DEFAULT_CSS = """
    PlanePanel { width: 1fr; border: round $primary-darken-2; padding: 0 1; }
    PlanePanel Input { width: 100%; }
    PlanePanel Button { margin-top: 1; }
    PlanePanel #plane-result { height: auto; margin-top: 1; }
    """

    def compose(self) -> ComposeResult:
        yield Label("[b]Plane[/b] (the guide's four reference tags)")
        yield Input(placeholder="guide manifest GUIDE.json (station guide --json)", id="plane-guide")
        yield Input(placeholder="frame image file (empty: grab from the camera)", id="plane-image")
        yield Button("Check plane", id="plane-run", variant="primary")
        yield Static(Text("press p to check the plane"), id="plane-result")

    def say(self, text: str) -> None:
        self.query_one("#plane-result", Static).update(Text(text))

    @on(Button.Pressed, "#plane-run")
    def start(self) -> None:
        guide = self.query_one("#plane-guide", Input).value.strip() or None
        image = self.query_one("#plane-image", Input).value.strip() or None
        self.say("checking…")
        self.check(guide, image)

    def check(self, guide: str | None, image: str | None) -> None:
        """Check the plane in a worker; the end arrives as a message."""
        run_work(self, lambda _report: service.plane_check(image=image, guide=guide), PlaneChecked,
                 group="calibrate-plane")

    def on_plane_checked(self, message: PlaneChecked) -> None:
        message.stop()
        self.say("\n".join(service.plane_summary(message.result)) if message.ok else message.error)


class CalibrateScreen(Screen):
    """Camera intrinsics, the plane check, the projector mapping and the simulator's fit side by side."""

    CSS = """
    CalibrateScreen .panels { height: 1fr; }
    CalibrateScreen SimCalibrationPanel { width: 1fr; height: 1fr; border: round $primary-darken-2; padding: 0 1; }
    """

    BINDINGS = [
        Binding("f", "camera_folder", "Calibrate from folder"),
        Binding("g", "camera_grab", "Grab frames"),
        Binding("s", "camera_stop", "Stop"),
        Binding("p", "plane", "Check plane"),
    ]

    def __init__(self) -> None:
        super().__init__(name="calibrate")

    def compose(self) -> ComposeResult:
        yield Header()
        # two rows: the camera's own geometry above, what builds on it (the projector, the simulator) below
        with Horizontal(classes="panels"):
            yield CameraPanel(id="camera-panel")
            yield PlanePanel(id="plane-panel")
        with Horizontal(classes="panels"):
            yield ProjectorCalibrationPanel(id="projector-panel")
            yield SimCalibrationPanel(trials_source=logged_trials, id="sim-panel")
        yield Footer()

    def action_camera_folder(self) -> None:
        panel = self.query_one(CameraPanel)
        folder = panel.query_one("#camera-folder", Input).value.strip()
        if folder:
            panel.start(folder=folder)
        else:
            panel.say("type the folder of board images first")

    def action_camera_grab(self) -> None:
        panel = self.query_one(CameraPanel)
        panel.start(count_text=panel.query_one("#camera-count", Input).value)

    def action_camera_stop(self) -> None:
        self.query_one(CameraPanel).stop()

    def action_plane(self) -> None:
        self.query_one(PlanePanel).start()


SCREEN = ScreenEntry(
    name="calibrate",
    key="k",
    title="Calibrate",
    description="the camera (ChArUco), the plane, the projector (Gray code), the simulator (from the trials)",
    factory=CalibrateScreen,
    order=58,
)
