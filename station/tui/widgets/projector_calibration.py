"""The Calibrate screen's projector panel: map the projector onto the guide plane with the camera, with progress.

The camera and projector default to the station's (``station devices``), the camera's plane to its last plane fix
(see :mod:`station.services.projector_calibration`); each can be typed instead. Map (or m while the panel has the
focus) shows the Gray code stripes and grabs them in a worker, the :class:`ProgressPanel` following pattern by
pattern; Stop (x) cancels between patterns and blanks the projector. The result (landing error at the check points,
cells, where it was saved) shows below. A screen can bind its own keys to :meth:`ProjectorCalibrationPanel.start`
and :meth:`ProjectorCalibrationPanel.stop`.
"""

from __future__ import annotations

from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.widgets import Button, Input, Label, Static

from station.services import projector_calibration as service
from station.tui.messages import ProgressReported, ProjectorCalibrated
from station.tui.widgets.progress import ProgressPanel
from station.tui.work import Work, run_work

__all__ = ["ProjectorCalibrationPanel"]

#: What the panel says when a mapping was stopped.
STOPPED = "stopped; the projector is blank, nothing saved"


class ProjectorCalibrationPanel(Vertical):
    """Projector mapping: the devices, Map / Stop, progress per pattern, the landing error."""

    DEFAULT_CSS = """
    ProjectorCalibrationPanel { width: 1fr; border: round $primary-darken-2; padding: 0 1; }
    ProjectorCalibrationPanel Input { width: 100%; }
    ProjectorCalibrationPanel #projector-buttons { height: auto; }
    ProjectorCalibrationPanel Button { margin-right: 1; min-width: 10; }
    ProjectorCalibrationPanel #projector-result { height: auto; margin-top: 1; }
    """

    BINDINGS = [
        Binding("m", "start", "Map projector"),
        Binding("x", "stop", "Stop mapping"),
    ]

    #: The running mapping, which Stop asks to stop (None before the first).
    _work: Work | None = None

    def compose(self) -> ComposeResult:
        yield Label("[b]Projector[/b] (Gray code stripes seen by the camera; darken the room)")
        yield Input(placeholder="camera URL (empty: the station's)", id="projector-camera")
        yield Input(placeholder="projector URL (empty: the station's)", id="projector-url")
        yield Input(placeholder="plane fix PLANE.json (empty: the camera's last)", id="projector-plane")
        with Horizontal(id="projector-buttons"):
            yield Button("Map", id="projector-run", variant="primary")
            yield Button("Stop", id="projector-stop", disabled=True)
        yield ProgressPanel("press Map (m) to map the projector", id="projector-progress")
        yield Static("", id="projector-result")

    def say(self, text: str) -> None:
        self.query_one("#projector-result", Static).update(Text(text))

    @property
    def result_text(self) -> str:
        return str(self.query_one("#projector-result", Static).render())

    @on(Button.Pressed, "#projector-run")
    def start(self) -> None:
        """Start a mapping with what the inputs say (a mapping already running is replaced)."""
        values = [self.query_one(f"#projector-{key}", Input).value.strip() or None for key in ("camera", "url",
                                                                                              "plane")]
        self.query_one("#projector-progress", ProgressPanel).start(None, "starting…")
        self.query_one("#projector-stop", Button).disabled = False
        self.say("")
        self.calibrate(*values)

    def action_start(self) -> None:
        self.start()

    @on(Button.Pressed, "#projector-stop")
    def stop(self) -> None:
        """Stop between two patterns (the projector is blanked; nothing is saved)."""
        if self._work is not None:
            self._work.stop()
        self.say("stopping…")

    def action_stop(self) -> None:
        self.stop()

    def calibrate(self, camera: str | None, projector: str | None, plane: str | None) -> None:
        """Map in a worker; progress and the end arrive as messages."""
        request = service.ProjectorCalibrationRequest(camera=camera, projector=projector, plane=plane)
        self._work = run_work(self, lambda report: service.calibrate_projector(request, report=report),
                              ProjectorCalibrated, group="calibrate-projector")

    def on_progress_reported(self, message: ProgressReported) -> None:
        message.stop()
        self.query_one("#projector-progress", ProgressPanel).show(message.progress)

    def on_projector_calibrated(self, message: ProjectorCalibrated) -> None:
        message.stop()
        self.query_one("#projector-stop", Button).disabled = True
        progress = self.query_one("#projector-progress", ProgressPanel)
        if not message.ok:
            said = STOPPED if message.stopped else message.error
            progress.say(said)
            self.say(said)
            return
        done = message.result
        self.say("\n".join(service.projector_summary(done)))
        progress.say(f"done: landing error p95 {done.projector_map.landing_error_mm['p95']:.2f} mm")
