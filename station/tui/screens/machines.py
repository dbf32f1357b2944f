"""Machines screen: the GRBL plotter and laser, live.

Connects to the station's devices (simulated by default), shows the live status (state, work and machine position,
planner and RX buffer), a console, jog, home/unlock, and a job queue with frame, dry run, start, hold, resume and
abort, with progress and ETA. Other screens hand jobs over with :meth:`MachinesScreen.queue_job`; ``n`` plots the
Drawing screen's current design as a job for the selected device.

The machines, their connections, the job queue and every send are the app's
:class:`station.services.machine_sessions.MachineSessions` (``station send`` drives the same service): the screen
asks its questions (a dialog: trace the frame of a laser job first on a machine without homing?) and shows progress;
the panels are widgets of their own (``station.tui.widgets.machines_status``, ``machines_console``,
``machines_preview``).

Keys: c connect/disconnect · v switch device · h home · u unlock · arrows jog X/Y, PgUp/PgDn jog Z, [ ] step ·
f frame · y dry run · g start · p hold · r resume · ctrl+x abort (always works, even in the console) · a abort ·
+ / - / = feed override · n plot the current design · b place the next laser job on the stock by camera ·
e run the next job on the twin (time with acceleration, dark travels, travel) · : console.

A multi-pen plot (``station plot`` with several patterns or an SVG) shows its layers in their pens' colours with
each layer's time estimate; at a pen change the job pauses, the screen says which pen to put in, and r resumes.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.css.query import NoMatches
from textual.screen import ModalScreen, Screen
from textual.widget import Widget
from textual.widgets import Footer, Header, Input, Static

from station.errors import USER_ERRORS, StationError
from station.services.job_queue import JobMode, JobQueue, JobState, QueuedJob
from station.services.machine_sessions import (
    JobProgress,
    MachineSessions,
    SendPolicy,
    device_profile,
    feedback_text,
    verify_summary,
)
from station.services.machines import plot_job, sample_pattern
from station.services.plot import format_minutes, job_layers
from station.tui.messages import (
    ConsoleReplied,
    DesignPlotted,
    JobEnding,
    JobSent,
    JobVerified,
    MachineConnected,
    MachineSaid,
    ProgressReported,
    SendAsked,
)
from station.tui.registry import MachineDesign, ScreenEntry
from station.tui.screens.bed_place import open_bed_placement, verify_next_job
from station.tui.widgets.machines_console import MachineConsole
from station.tui.widgets.machines_preview import JobPreview
from station.tui.widgets.machines_status import JobProgressRow, JobQueueTable, MachineStatus
from station.tui.work import run_work

__all__ = ["JOG_STEPS", "MachinesScreen", "QueuedJob", "SCREEN"]

JOG_STEPS = (0.1, 1.0, 10.0, 50.0)

#: Jog keys and the direction (x, y, z) each one moves, by the jog step.
JOG_KEYS = {"left": (-1, 0, 0), "right": (1, 0, 0), "up": (0, 1, 0), "down": (0, -1, 0),
            "pageup": (0, 0, 1), "pagedown": (0, 0, -1)}

#: Feed override keys: the key, GRBL's override action and the binding's description.
FEED_OVERRIDE_KEYS = (("plus", "+10", "Feed +10%"), ("minus", "-10", "Feed -10%"),
                      ("equals_sign", "reset", "Feed 100%"))


#: What the console field starts with after o: the rest is the path of a G-code file to queue (G-code has no such
#: word, so no line meant for the machine starts so).
OPEN_PREFIX = "open "


def layer_estimates(lines: list[str], profile) -> str:
    """``; 3 pens: 1 rosette (blue 0.3 mm) 0:24, 2 star (red 0.5 mm) 0:34, ...`` for a multi-pen plot, else ``""``."""
    layers = job_layers(lines, profile)
    if not layers:
        return ""
    return f"; {len(layers)} pens: " + ", ".join(
        f"{layer.number} {layer.name} ({layer.pen}) {format_minutes(layer.time_s)}" for layer in layers)


class AskScreen(ModalScreen[bool]):
    """A yes/no question of a send (y or Enter: the default answer's opposite is n or Escape)."""

    DEFAULT_CSS = """
    AskScreen { align: center middle; }
    AskScreen > Static { width: 70; height: auto; padding: 1 2; border: thick $warning; background: $surface; }
    """
    BINDINGS = [Binding("y", "answer(True)", "Yes"), Binding("n", "answer(False)", "No"),
                Binding("escape", "answer(False)", "No")]

    def __init__(self, question: str) -> None:
        super().__init__()
        self.question = question

    def compose(self) -> ComposeResult:
        yield Static(Text(f"{self.question}\n\ny yes · n no"))

    def action_answer(self, answer: bool) -> None:
        self.dismiss(answer)


class ScreenPolicy(SendPolicy):
    """The Machines screen's answers to a send's questions: a dialog (asked from the worker that sends, which waits
    for the answer), a program pause said in the message line (r resumes)."""

    def __init__(self, screen: MachinesScreen) -> None:
        self.screen = screen

    def _ask(self, question: str) -> bool:
        answered = threading.Event()
        answer: list[bool] = []

        def done(value: bool | None) -> None:
            answer.append(bool(value))
            answered.set()

        self.screen.post_message(SendAsked(question, done))
        while not answered.wait(0.2):
            if not self.screen.app.is_running:
                return False
        return answer[0]

    def frame_first(self, job) -> bool:
        return self._ask(f"{job.name}: this laser has no homing ($22=0), so the job burns wherever work zero is set. "
                         "Trace its frame first (laser at frame power)?")

    def start_after_frame(self, job) -> bool:
        return self._ask(f"Frame done. Start the laser job {job.name}?")

    def paused(self, message: str, resume, stop) -> None:
        self.screen.post_message(MachineSaid(f"{message}: r resumes", "bold yellow"))

    def warn(self, message: str) -> None:
        self.screen.post_message(MachineSaid(f"warning: {message}", "yellow"))

    def ended(self, result, progress) -> None:
        # shown before the queue records the end: whoever reads the job's state finds the screen saying it
        shown = threading.Event()
        self.screen.post_message(JobEnding(result, progress, shown))
        while not shown.wait(0.2):
            if not self.screen.app.is_running or not self.screen.is_attached:
                return


class MachinesScreen(Screen):
    """Live GRBL machines and their job queue."""

    CSS = """
    MachinesScreen #left { width: 62; }
    MachinesScreen #status { height: auto; padding: 0 1; border: round $primary; }
    MachinesScreen #queue { height: 10; }
    MachinesScreen #progress-row { height: 2; padding: 0 1; }
    MachinesScreen #progress { height: 1; }
    MachinesScreen #progress-label { height: 1; width: 1fr; }
    MachinesScreen #console { height: 1fr; border: round $primary-darken-2; }
    MachinesScreen #console-input { dock: bottom; }
    MachinesScreen #preview { border: round $primary-darken-2; }
    MachinesScreen #message { height: auto; padding: 0 1; }
    """

    #: Nothing is focused when the screen opens, so every key acts (the console field is focused with :).
    AUTO_FOCUS = ""

    BINDINGS = [
        Binding("ctrl+x", "abort", "Abort", priority=True),
        Binding("c", "connect", "Connect"),
        Binding("v", "switch_device", "Device"),
        Binding("g", "start", "Start"),
        Binding("p", "hold", "Hold"),
        Binding("r", "resume", "Resume"),
        Binding("a", "abort", "Abort", show=False),
        Binding("f", "frame", "Frame"),
        Binding("y", "dry_run", "Dry run"),
        Binding("h", "home", "Home"),
        Binding("u", "unlock", "Unlock"),
        Binding("n", "plot_design", "Plot design"),
        Binding("b", "place_on_bed", "Place on bed"),
        Binding("e", "verify_job", "Verify on twin"),
        Binding("colon", "console", "Console"),
        Binding("o", "open_job", "Open job"),
        # "jog(-1, 0, 0)" ...: the tuple's own text is the action's arguments
        *(Binding(key, f"jog{move}", "Jog Z" if move[2] else "Jog", show=False) for key, move in JOG_KEYS.items()),
        Binding("left_square_bracket", "step(-1)", "Step-", show=False),
        Binding("right_square_bracket", "step(1)", "Step+", show=False),
        *(Binding(key, f"override('feed', '{action}')", description, show=False)
          for key, action, description in FEED_OVERRIDE_KEYS),
    ]

    def __init__(self) -> None:
        super().__init__(name="machines")
        self._sessions: MachineSessions | None = None
        self.device_index = 0
        self.jog_step_index = 2
        self.last_message = ""
        self._connecting: set[str] = set()
        self._status_posted = False  # a status redraw is on its way (many status reports, one redraw)
        self._last_preview = 0.0
        self._auto_connected = False
        self._queue_shown: list = []
        self._sending: tuple = (None, JobMode.RUN)  # the entry and mode of the latest send asked for
        self._after_abort = None  # called with the job's last message once an abort for quitting has ended it

    @property
    def sessions(self) -> MachineSessions:
        """The app's machines and jobs (an app without them gets one of the screen's own, recording nothing)."""
        if self._sessions is None:
            self._sessions = getattr(self.app, "machine_sessions", None) or MachineSessions(source="tui")
            self._sessions.queue.log.on_error = lambda error: self._console(f"job history not written: {error}")
        return self._sessions

    @property
    def connections(self) -> dict:
        """The open connections by device name."""
        return self.sessions.connections

    @property
    def runner(self):
        """The runner of the job being sent (its progress, its program pause), or None."""
        return self.sessions.runner

    @property
    def job_queue(self) -> JobQueue:
        """The jobs and their states; each send is recorded in the station database's job history (nothing is
        recorded in an app without a database)."""
        return self.sessions.queue

    @property
    def jobs(self) -> list[QueuedJob]:
        """Every queued job, in order (done ones too)."""
        return self.job_queue.jobs

    @property
    def running_job(self) -> QueuedJob | None:
        """The job being sent (running, framing or checking), or None."""
        return self.job_queue.active

    # ------------------------------------------------------------------ layout

    def compose(self) -> ComposeResult:
        yield Header()
        with Horizontal():
            with Vertical(id="left"):
                yield MachineStatus("", id="status")
                yield JobQueueTable(id="queue")
                yield JobProgressRow(id="progress-row")
                yield Static("", id="message")
            with Vertical():
                yield JobPreview(id="preview")
                yield MachineConsole(id="console")
                yield Input(placeholder=": G-code or $ command, Enter sends", id="console-input")
        yield Footer()

    def on_mount(self) -> None:
        self._render_status()
        self._refresh_queue()  # jobs other screens queued before this one was first shown (the Assemble screen's jigs)

    def on_screen_resume(self) -> None:
        # Focus left in the console field when the user went elsewhere would make the keys type there on return
        # (n then g typed "ng" instead of plotting): the screen comes back with its keys (: returns to the console).
        if isinstance(self.focused, Input):
            self.set_focus(None)
        # connect to the selected device the first time the screen is shown (simulated ones need no hardware)
        if not self._auto_connected:
            self._auto_connected = True
            device = self.device
            if device is not None and device.simulated:
                self.action_connect()

    def on_unmount(self) -> None:
        self.shutdown()

    def shutdown(self) -> None:
        """Stop the job and close every connection (the app is closing)."""
        self.sessions.close()

    # ------------------------------------------------------------------ devices

    @property
    def serial_devices(self) -> list:
        return [d for d in getattr(self.app, "devices", ()) if d.kind in ("plotter", "laser")]

    @property
    def device(self):
        devices = self.serial_devices
        return devices[self.device_index % len(devices)] if devices else None

    def profile_for(self, device):
        """The device's machine profile (a built-in name or the file named in ``station.toml``).

        Raises
        ------
        StationError
            The profile file has gone, or turned bad, since the configuration was read; the message names it.
        """
        return device_profile(device)

    def connection(self, name: str | None = None):
        device = self.device if name is None else next((d for d in self.serial_devices if d.name == name), None)
        return self.connections.get(device.name) if device is not None else None

    def action_switch_device(self) -> None:
        if self.serial_devices:
            self.device_index = (self.device_index + 1) % len(self.serial_devices)
            self._render_status()
            self._say(f"device: {self.device.label}")

    def action_connect(self) -> None:
        device = self.device
        if device is None:
            self._say("no plotter or laser configured")
            return
        if device.name in self.connections:
            self.sessions.disconnect(device.name)  # a job running on it is aborted first
            self._say(f"{device.name}: disconnected")
            self._render_status()
            return
        if device.name in self._connecting:
            return
        self._connecting.add(device.name)
        self._say(f"{device.name}: connecting to {device.url} ...")

        name = device.name

        def connect(report):
            listener = lambda event, data: self._listener(name, event, data)  # noqa: E731
            try:
                return name, self.sessions.connect(name, device.url, listener=listener)
            except USER_ERRORS as error:
                raise StationError(f"{name}: {error}") from None
            finally:
                self._connecting.discard(name)  # a set: safe from the worker; read on the UI thread

        run_work(self, connect, MachineConnected, group=f"connect-{name}", exclusive=False)

    def on_machine_connected(self, message: MachineConnected) -> None:
        if not message.ok:
            self._say(message.error, "red")
            return
        name, conn = message.result
        self._say(f"{name}: GRBL {conn.version} connected (RX buffer {conn.rx_size} bytes, "
                  f"{'laser mode' if conn.laser_mode else 'spindle mode'})")
        self._render_status()

    def _listener(self, name: str, event: str, data) -> None:
        # On the connection's thread, sometimes holding its lock: only posts (never waits for the UI thread, which
        # may be waiting for that lock to abort).
        if event == "status":
            if self.device is not None and self.device.name == name and not self._status_posted:
                self._status_posted = True
                self.post_message(MachineSaid(status=True))
        elif event == "log":
            _, direction, text = data
            if self.sessions.sending and (direction == "out" or (direction == "in" and text == "ok")):
                return  # thousands of lines and oks during a job drown the console (conn.log keeps them)
            self.post_message(MachineSaid(f"{name} {'>' if direction == 'out' else '<'} {text}"
                                          if direction in ("in", "out") else f"{name} ! {text}", console_only=True))
        elif event in ("alarm", "fault"):
            self.post_message(MachineSaid(f"{name}: {data}", "red", status=True))
        elif event == "message" and (text := feedback_text(data)) is not None:
            self.post_message(MachineSaid(f"{name}: {text}"))

    def on_machine_said(self, message: MachineSaid) -> None:
        if message.text:
            if message.console_only:
                self._console(message.text, message.style)
            else:
                self._say(message.text, message.style)
        if message.status:
            self._status_posted = False
            self._render_status()

    def on_send_asked(self, message: SendAsked) -> None:
        self.app.push_screen(AskScreen(message.question), message.answer)

    # ------------------------------------------------------------------ status

    def _shown(self, selector: str, kind: type[Widget]):
        """The screen's widget ``selector``, or None before the screen is composed (jobs may be queued earlier)."""
        try:
            return self.query_one(selector, kind)
        except NoMatches:
            return None

    def _render_status(self) -> None:
        if (panel := self._shown("#status", MachineStatus)) is not None:
            device = self.device
            panel.show(device, self.connections.get(device.name) if device else None, JOG_STEPS[self.jog_step_index])

    @property
    def status_text(self) -> str:
        return str(self.query_one("#status", Static).render())

    def _say(self, message: str, style: str = "") -> None:
        """Show ``message`` under the queue and in the console, as plain text in ``style`` (``"red"``).

        Messages carry what users and devices wrote (console lines, G-code, file names, GRBL replies such as
        ``[MSG:...]``), so they are never parsed as markup: the style is applied to the whole message instead.
        """
        self.last_message = message
        if (shown := self._shown("#message", Static)) is not None:
            shown.update(Text(message, style=style))
        self._console(message, style)

    def _console(self, text: str, style: str = "") -> None:
        if (console := self._shown("#console", MachineConsole)) is not None:
            console.say(text, style)

    # ------------------------------------------------------------------ queue

    def queue_job(self, device: str, gcode: str, title: str | None = None, *, laser: bool | None = None,
                  name: str | None = None) -> QueuedJob:
        """Queue a G-code job for ``device`` (a device name such as ``"plotter"`` / ``"laser"``, or a kind).

        Other screens use this (the Fabricate screen sends its laser job, the Drawing screen a plot). The job is
        checked (pre-flight) when it starts; nothing moves until the user presses ``g`` (or ``f`` to frame).

        Returns the queued entry (``.state`` follows the job).
        """
        target = next((d for d in self.serial_devices if d.name == device), None)
        if target is None:
            target = next((d for d in self.serial_devices if d.kind == device), None)
        if target is None:
            known = ", ".join(d.name for d in self.serial_devices) or "none"
            raise StationError(f"no device {device!r} for the job; known: {known}")
        profile = self.profile_for(target)
        entry = self.job_queue.add(target.name, gcode, title or name,
                                   laser=target.kind == "laser" if laser is None else laser,
                                   pen_up=tuple(profile.pen.up_commands()) if profile.pen else ("M5",))
        self._refresh_queue()
        self.device_index = self.serial_devices.index(target)
        self._show_preview(entry)
        self._render_status()
        if target.simulated and target.name not in self.connections and self.is_mounted:
            # a simulated machine needs no hardware: connect it so that f/g work at once (a real one waits for c,
            # since opening its port resets the board)
            self.action_connect()
        self._say(f"queued {entry.title!r} for {target.name} ({len(entry.job.lines)} lines): f frames, g starts"
                  + layer_estimates(entry.job.lines, profile))
        return entry

    def _refresh_queue(self, changed_only: bool = False) -> None:
        """Redraw the queue table (``changed_only``: only if a job's title or state changed since the last time)."""
        shown = [(entry.title, entry.state) for entry in self.jobs]
        if changed_only and shown == self._queue_shown:
            return
        if (table := self._shown("#queue", JobQueueTable)) is not None:
            table.show(self.jobs)
            self._queue_shown = shown

    def _show_preview(self, entry: QueuedJob, current_line: int | None = None) -> None:
        """Draw the job's toolpath; with ``current_line``, what is done in green and the rest in grey."""
        if (preview := self._shown("#preview", JobPreview)) is not None:
            preview.show_job(entry.job, current_line)

    def next_job(self) -> QueuedJob | None:
        """The first job the selected device can be sent (queued, framed, checked or stopped)."""
        device = self.device
        return self.job_queue.next_for(device.name if device is not None else None)

    # ------------------------------------------------------------------ job control

    def _ready_connection(self):
        conn = self.connection()
        if conn is None:
            self._say("not connected: press c")
            return None
        if self.sessions.sending or self.running_job is not None:
            self._say("a job is running: p holds, r resumes, ctrl+x aborts")
            return None
        return conn

    def action_start(self) -> None:
        self._run_next(JobMode.RUN)

    def action_frame(self) -> None:
        self._run_next(JobMode.FRAME)

    def action_dry_run(self) -> None:
        self._run_next(JobMode.DRY)

    def _run_next(self, mode: JobMode) -> None:
        if self._ready_connection() is None:
            return
        entry = self.next_job()
        if entry is None:
            self._say("no queued job for this device (n plots the current design)")
            return
        try:
            profile = self.profile_for(self.device)
        except StationError as error:
            self._say(f"cannot {mode.kind}: {error}", "red")
            return
        self._say(f"{mode.kind} {entry.title!r} on {entry.device}")
        device, policy = self.device.name, ScreenPolicy(self)
        self._sending = (entry, mode)
        run_work(self, lambda report: self.sessions.send(device, entry, mode, profile=profile, policy=policy,
                                                         report=report), JobSent, group="job", exclusive=False)

    def on_progress_reported(self, message: ProgressReported) -> None:
        if isinstance(message.progress, JobProgress):
            self._show_progress(message.progress)

    def _show_progress(self, progress: JobProgress) -> None:
        now = time.monotonic()
        entry = self.running_job
        self._refresh_queue(changed_only=True)  # the send changes the job's state on its own thread
        if entry is not None and entry.state is JobState.RUNNING and (
                now - self._last_preview > 0.5 or progress.state != "running"):
            self._last_preview = now
            self._show_preview(entry, progress.current_line)
        if (row := self._shown("#progress-row", JobProgressRow)) is not None:
            row.show(progress)

    def on_job_ending(self, message: JobEnding) -> None:
        """The send ended (its state is recorded right after): the end shown."""
        result, progress = message.result, message.progress
        entry = self.running_job
        if entry is not None and entry.state is JobState.RUNNING:
            self._show_preview(entry, len(entry.job.lines) if result.ok else progress.current_line)
        self._say(result.message, style="green" if result.ok else "red")
        for _, text in result.errors[:5]:
            self._console(f"  {text}")
        if (row := self._shown("#progress-row", JobProgressRow)) is not None:
            row.show(progress)
        message.shown.set()

    def on_job_sent(self, message: JobSent) -> None:
        """The send's end recorded: the queue and the status redrawn; quitting goes on once an abort for it ended."""
        entry, mode = self._sending
        if message.error:
            self._say(f"cannot {mode.kind} {entry.title!r}: {message.error}", "red")
        self._refresh_queue()
        self._render_status()
        if self._after_abort is not None and not self.sessions.sending:
            callback, self._after_abort = self._after_abort, None
            callback(message.result.message if message.ok else message.error)

    def _device_name(self) -> str | None:
        return self.device.name if self.device is not None else None

    def action_hold(self) -> None:
        self._safe(self.sessions.hold, self._device_name())
        self._say("feed hold (r resumes)")

    def action_resume(self) -> None:
        self._safe(self.sessions.resume, self._device_name())
        self._say("resume")

    def action_abort(self) -> None:
        """Soft reset now (motion stops, laser off); a running job then sends M5 S0. Always available."""
        if self.sessions.sending:
            self._safe(self.sessions.abort)
            self._say("abort: soft reset sent", style="red")
        elif self.connection() is not None:
            self._safe(self.sessions.abort, self._device_name())
            self._say("abort: soft reset sent (no job was running)", style="red")
        else:
            self._say("abort: not connected")

    def _safe(self, callback, *args) -> None:
        try:
            callback(*args)
        except USER_ERRORS as error:
            self._say(str(error), style="red")

    # ------------------------------------------------------------------ manual control

    def action_override(self, kind: str, action: str) -> None:
        if self.connection() is not None:
            self._safe(self.sessions.override, self._device_name(), kind, action)
            self._say(f"{kind} override {action}")

    def action_step(self, direction: int) -> None:
        self.jog_step_index = max(0, min(len(JOG_STEPS) - 1, self.jog_step_index + direction))
        self._render_status()

    def action_jog(self, dx: int, dy: int, dz: int) -> None:
        conn = self._ready_connection()
        if conn is None:
            return
        step = JOG_STEPS[self.jog_step_index]
        feed = 1000.0 if dz else 3000.0
        words = " ".join(f"{axis}{d * step:g}" for axis, d in zip("XYZ", (dx, dy, dz)) if d)
        self._send_worker(f"$J=G91 G21 {words} F{feed:g}")  # the line MachineSessions.jog sends, shown as typed

    def action_home(self) -> None:
        if self._ready_connection() is not None:
            self._send_worker("$H")

    def action_unlock(self) -> None:
        if self._ready_connection() is not None:
            self._send_worker("$X")

    def action_console(self) -> None:
        self.query_one("#console-input", Input).focus()

    def action_open_job(self) -> None:
        """Type the path of a G-code file (``station plot``'s) in the console field: Enter queues it."""
        field = self.query_one("#console-input", Input)
        field.value = OPEN_PREFIX
        field.focus()

        def after_focus() -> None:
            # the field selects its text when focused: typing would replace the prefix
            field.cursor_position = len(OPEN_PREFIX)

        self.call_after_refresh(after_focus)

    def open_job(self, path: str) -> QueuedJob | None:
        """Queue the G-code file ``path`` for the selected device (a plot of layers shows its pens)."""
        device = self.device
        if device is None:
            self._say("no plotter or laser configured")
            return None
        file = Path(path).expanduser()
        try:
            text = file.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as error:
            self._say(f"cannot open {path}: {getattr(error, 'strerror', None) or error}", "red")
            return None
        try:
            return self.queue_job(device.name, text, file.name)
        except StationError as error:
            self._say(str(error), "red")
            return None

    @on(Input.Submitted, "#console-input")
    def _console_submitted(self, event: Input.Submitted) -> None:
        line = event.value.strip()
        event.input.value = ""
        if not line:
            return
        if line.startswith(OPEN_PREFIX.strip() + " "):
            self.set_focus(None)
            self.open_job(line[len(OPEN_PREFIX):].strip())
            return
        if self._ready_connection() is not None:
            self._send_worker(line)

    def _send_worker(self, line: str) -> None:
        """Send ``line`` (G-code or a ``$`` command) to the selected machine, in a worker; feedback in the console."""
        name = self._device_name()
        if self.connection(name) is None:
            return

        def command(report):
            try:
                return self.sessions.command(name, line)
            except USER_ERRORS as error:
                raise StationError(f"{line}: {error}") from None

        run_work(self, command, ConsoleReplied, group="console", exclusive=False)

    def on_console_replied(self, message: ConsoleReplied) -> None:
        if message.ok:
            for text in message.result:
                self._console(f"  {text}")
        else:
            self._say(message.error, "red")
        self._render_status()

    def action_verify_job(self) -> None:
        """The next job run on the machine's twin at virtual time (station.tui.screens.bed_place)."""
        verify_next_job(self)

    def action_place_on_bed(self) -> None:
        """The next laser job placed on the stock by camera (station.tui.screens.bed_place)."""
        open_bed_placement(self)

    def action_plot_design(self) -> None:
        """Queue the Drawing screen's current design as a plot job for the selected device."""
        machine, params = self.app.current_design() or MachineDesign.defaults("spirograph")
        self.plot_design(machine, params)

    def plot_design(self, machine: str, params: dict, device: str | None = None) -> None:
        """Turn a drawing-machine design into a plot job and queue it (in a worker).

        ``device`` is a device name or kind (``"plotter"``); by default the selected device.
        """
        target = self.device if device is None else next(
            (d for d in self.serial_devices if device in (d.name, d.kind)), None)
        if target is None:
            self._say(f"no {device or 'plotter or laser'} configured")
            return
        def plot(report):
            # sampling takes a moment: in a worker
            try:
                points, _ = sample_pattern(machine, params, 4096)
                text, *_ = plot_job([points], self.profile_for(target), None, None)
            except USER_ERRORS as error:
                raise StationError(f"cannot plot {machine}: {error}") from None
            return target.name, text, f"{machine} plot"

        run_work(self, plot, DesignPlotted, group="plot", exclusive=False)

    def on_job_verified(self, message: JobVerified) -> None:
        """The next job's run on the twin (``e``, :func:`station.tui.screens.bed_place.verify_next_job`)."""
        if not message.ok:
            self._say(message.error, "red")
            return
        self._say(" · ".join(line.strip() for line in verify_summary(message.result)),
                  "green" if message.result.ok else "red")

    def on_design_plotted(self, message: DesignPlotted) -> None:
        if message.ok:
            self.queue_job(*message.result)
        else:
            self._say(message.error, "red")

    # ------------------------------------------------------------------ quitting

    def active_job(self) -> QueuedJob | None:
        """The job being sent now (a run, a frame or a dry run), or None."""
        return self.running_job if self.sessions.sending else None

    def abort_then(self, callback, timeout: float = 20.0) -> None:
        """Abort the running job and call ``callback(message)`` once it has ended (the app quits then).

        The abort is :meth:`action_abort`'s: a soft reset stops motion and the laser at once, then the job sends
        ``M5 S0``; the job's end is recorded in the job history (``aborted``, not ``interrupted``). If the job does
        not end within ``timeout`` s (a port that stopped answering), ``callback`` is called anyway; the app's
        shutdown then resets the machine again and closes the port.
        """
        if self.active_job() is None:
            callback("no job was running")
            return
        self._after_abort = callback
        self.action_abort()

        def timed_out() -> None:
            if self._after_abort is callback:
                self._after_abort = None
                callback(f"the job did not end {timeout:g} s after the abort (soft reset sent); "
                         "check that the laser is off")

        self.set_timer(timeout, timed_out)


SCREEN = ScreenEntry(
    name="machines",
    key="m",
    title="Machines",
    description="GRBL plotter and laser: status, console, jog, frame, start, hold, abort, progress",
    factory=MachinesScreen,
    order=50,
)
