"""The Machines screen's left column: the device's live status, the job queue table and the job's progress.

Each widget shows what it is given (a connection, the queue's entries, a runner's progress); the screen owns the
connections and the queue.
"""

from __future__ import annotations

from collections.abc import Iterable

from rich.markup import escape
from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Vertical
from textual.widgets import DataTable, Label, ProgressBar, Static

from station.services.job_queue import QueuedJob
from station.services.machine_sessions import DeviceEntry, GrblConnection, JobProgress


def status_lines(device: DeviceEntry | None, conn: GrblConnection | None, jog_step: float) -> list[str]:
    """The status panel's lines (Rich markup; what devices and users wrote is escaped).

    Parameters
    ----------
    device : DeviceEntry or None
        The selected device (None: no plotter or laser is configured).
    conn : GrblConnection or None
        Its open connection, if any.
    jog_step : float
        The jog step in mm.
    """
    if device is None:
        return ["no plotter or laser configured"]
    lines = [f"[b]{escape(device.label)}[/b]  {escape(device.url)}"]
    if conn is None:
        lines.append("not connected (c connects)")
        return lines
    status = conn.status
    state = "position lost" if conn.position_lost else (status.label if status else "?")
    colour = "red" if conn.position_lost or state.startswith("Alarm") else (
        "yellow" if state.startswith(("Hold", "Door")) else "green")
    lines.append(f"state [{colour}]{escape(state)}[/{colour}]   jog step {jog_step:g} mm")
    if status is not None:
        wco = conn.wco or conn.work_offset()
        for name, position in (("WPos", status.work_position(wco)), ("MPos", status.machine_position(wco))):
            if position:
                lines.append(f"{name} " + "  ".join(f"{a} {v:8.3f}" for a, v in zip("XYZ", position)))
        if status.planner_free is not None:
            buffers = (f"planner {conn.planner_size - status.planner_free}/{conn.planner_size} blocks"
                       f"   RX {conn.rx_size - status.rx_free}/{conn.rx_size} bytes")
        else:  # the machine's $10 leaves the buffer state out of its reports (the station never changes it)
            buffers = f"planner and RX not reported ($10={int(conn.settings.get(10, 1))})"
        lines.append(f"{buffers}   feed {status.feed or 0:.0f} mm/min  S {status.spindle or 0:.0f}")
    if conn.alarm is not None:
        lines.append(f"[red]{escape(str(conn.alarm))}[/red]")
        lines.append(f"  recovery: {escape(str(conn.alarm.recovery))}")
    if conn.fault:
        lines.append(f"[red]{escape(str(conn.fault))}[/red]")
    return lines


class MachineStatus(Static):
    """The selected device: name and URL, state, positions, planner and RX buffer, alarm and its recovery."""

    def show(self, device: DeviceEntry | None, conn: GrblConnection | None, jog_step: float) -> None:
        self.update("\n".join(status_lines(device, conn, jog_step)))


class JobQueueTable(DataTable):
    """The job queue: number, title, device, lines and state of each job (a row cursor, never focused: the
    screen's keys act on the next job of the selected device)."""

    def __init__(self, **kwargs) -> None:
        super().__init__(cursor_type="row", **kwargs)
        self.can_focus = False

    def on_mount(self) -> None:
        self.add_columns("#", "job", "device", "lines", "state")

    def show(self, jobs: Iterable[QueuedJob]) -> None:
        self.clear()
        for entry in jobs:
            self.add_row(str(entry.number), Text(entry.title[:28]), entry.device, str(len(entry.job.lines)),
                         str(entry.state))


def progress_text(progress: JobProgress) -> str:
    """``42.0%  84/200 lines  ETA 1:05  running``."""
    eta = "--:--" if progress.eta is None else f"{int(progress.eta) // 60}:{int(progress.eta) % 60:02d}"
    return (f"{progress.fraction * 100:5.1f}%  {progress.lines_acked}/{progress.lines_total} lines  ETA {eta}  "
            f"{progress.state}")


class JobProgressRow(Vertical):
    """A progress bar and its line: percent, lines confirmed, ETA and the runner's state."""

    def compose(self) -> ComposeResult:
        yield ProgressBar(total=100, show_eta=False, id="progress")
        yield Label("", id="progress-label")

    def show(self, progress: JobProgress) -> None:
        self.query_one("#progress", ProgressBar).update(progress=progress.fraction * 100)
        self.query_one("#progress-label", Label).update(progress_text(progress))
