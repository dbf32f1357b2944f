"""The station's GRBL machines as one service: connections, the job queue, sending a job and the job history.

``station send`` and the Machines screen both drive a :class:`MachineSessions` (the TUI app holds one): the send of a
job is written here once, with its pre-flight, its homing/frame policy, its program pauses (a multi-pen plot's pen
changes), its abort and the record of every send in the job history. What a send needs a person to answer (trace
the frame first? start the job now? the pen is in?) goes through a :class:`SendPolicy`: the command line answers from
its flags and standard input, the screen from a dialog and its keys. The faces only ask those questions and show
progress; everything they need from the driver (the connection's state, a job's layers, its toolpath) comes through
this module.

A send is blocking: the command line calls it on its main thread, the screen in a worker. It returns the
:class:`~drivers.grbl.JobResult` of the job (or of its frame, when the job was not started after it).
"""

from __future__ import annotations

import contextlib
import sqlite3
import threading
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import serial

from cam.place import Placement, place_lines
from common.progress import ProgressCallback, Reporter
from common.signals import HandledSignals
from drivers.errors import DeviceStateError, JobRefused
from drivers.gcode import GcodeError, clean_line, drawn_polylines
from drivers.gcode_layers import LayerMark, layer_at, layer_marks
from drivers.grbl import GrblConnection, Job, JobProgress, JobResult, JobRunner, list_ports
from drivers.grbl.job import FINAL_STATES, kind_warning
from drivers.grbl.protocol import Feedback
from drivers.profiles import MachineProfile, ProfileError, load_profile
from station.db import open_database
from station.devices import DeviceEntry
from station.devices import machine_profile as machine_profile_of
from station.errors import ServiceError, StationError, as_station_error, station_errors
from station.joblog import INTERRUPTED, JobLog, JobRecord, local_time
from station.paths import database_path
from station.services.job_queue import JobMode, JobQueue, JobState, QueuedJob, frame_job
from station.services.job_verify import JobVerification, verify_job, verify_summary

__all__ = [
    "BAUD_RATES",
    "FINAL_STATES",
    "INTERRUPTED",
    "JobMode",
    "JobProgress",
    "JobResult",
    "JobState",
    "JobVerification",
    "LayerMark",
    "MachineSessions",
    "Placement",
    "QueuedJob",
    "SendPolicy",
    "drawn_polylines",
    "feedback_text",
    "job_history",
    "layer_at",
    "list_ports",
    "load_job",
    "machine_profile",
    "parse_placement",
    "verify_summary",
]

#: The standard serial baud rates a port can be opened at (pyserial's).
BAUD_RATES: tuple[int, ...] = tuple(serial.SerialBase.BAUDRATES)

#: Seconds between two looks at a running job (a stop asked for, a program pause to announce).
POLL_INTERVAL = 0.1


@station_errors
class SendPolicy:
    """The questions a send asks the person at the machine; this base answers as nobody is there would: no frame
    first, a pause is not announced (the job waits at it until :meth:`MachineSessions.resume`)."""

    def frame_first(self, job: Job) -> bool:
        """The machine has no homing ($22=0) and ``job`` is a laser job: it burns wherever work zero is set. True
        traces its frame (laser at frame power) before it."""
        return False

    def start_after_frame(self, job: Job) -> bool:
        """The frame has been traced: True starts ``job`` itself."""
        return True

    def paused(self, message: str, resume: Callable[[], None], stop: Callable[[], None]) -> None:
        """The job waits at a program pause (``message`` says which pen to put in): call ``resume`` once it may go
        on, ``stop`` to end it there. Called once per pause, from the thread that sends."""

    def warn(self, message: str) -> None:
        """Something the person should know before the job runs (a job written for the other kind of machine)."""

    def ended(self, result: JobResult, progress: JobProgress) -> None:
        """The send ended: called with its result and last progress before the queue records it (a screen shows the
        end first, so that whoever reads the job's state finds the screen saying it)."""


@station_errors
def feedback_text(data) -> str | None:
    """The text of a controller's ``[MSG:...]`` feedback event, else None (what a console shows of listener data)."""
    return data.text if isinstance(data, Feedback) and data.kind == "MSG" else None


@station_errors
def machine_profile(name: str | None, default: str = "plotter") -> MachineProfile:
    """A machine profile: a built-in name (``plotter``, ``laser``) or a TOML file."""
    return load_profile(name or default)


@station_errors
def device_profile(device: DeviceEntry) -> MachineProfile:
    """The machine profile of a configured plotter or laser (its built-in profile, or the file ``station.toml``
    names); a file gone or turned bad since the configuration was read is a station error naming the device."""
    try:
        return machine_profile_of(device)
    except ProfileError as error:
        raise ServiceError(f"{device.name}: {error}", field="profile", value=device.name) from None


@station_errors
def parse_placement(text: str) -> Placement:
    """``X,Y,ANGLE`` as a :class:`~cam.place.Placement`; the error names what is wrong."""
    try:
        return Placement.parse(text)
    except GcodeError as error:
        raise ServiceError(str(error).replace("placement: ", ""), field="place", value=text) from None


@station_errors
def load_job(path: str | Path, *, profile: MachineProfile | None = None, laser: bool = False,
             place: Placement | None = None) -> Job:
    """A G-code file as a job for a machine with ``profile`` (its pen-up lines; a laser profile makes it a laser
    job), moved and turned to ``place``.

    Raises
    ------
    ServiceError
        No such file, not text, not placeable (``field="place"``, naming the line), or no G-code line in it.
    """
    path = Path(path)
    if not path.is_file():
        raise ServiceError(f"job {str(path)!r}: no such file", field="job", value=str(path))
    laser = laser or (profile is not None and profile.is_laser)
    pen_up = tuple(profile.pen.up_commands()) if profile is not None and profile.pen else ("M5",)
    job = Job.from_file(path, laser=laser, pen_up=pen_up)
    if place is not None:
        try:
            job = Job(job.name, place_lines(job.lines, place), laser=job.laser, pen_up=job.pen_up)
        except GcodeError as error:
            raise ServiceError(f"job {job.name!r}: {error}", field="place", value=place) from None
    if not any(clean_line(line) for line in job.lines):
        raise ServiceError(f"job {str(path)!r}: the file has no G-code lines (it is empty or only comments)",
                           field="job", value=str(path))
    return job


@station_errors
@contextlib.contextmanager
def job_history(warn: Callable[[Exception], None]) -> Iterator[JobLog]:
    """The station database's job history; a broken database is ``warn``-ed about once and nothing is recorded."""
    try:
        connection = open_database(database_path())
    except (StationError, OSError, sqlite3.Error) as error:
        warn(error)
        yield JobLog(None)
        return
    try:
        yield JobLog(connection, on_error=warn)
    finally:
        connection.close()


@station_errors
def recent_jobs(limit: int = 20) -> tuple[Path, list[JobRecord]]:
    """The station database's path and its latest ``limit`` jobs, newest first (``station jobs``); a database that
    cannot be opened is an error naming it."""
    path = database_path()
    connection = open_database(path)
    try:
        return path, JobLog(connection).recent(limit)
    finally:
        connection.close()


@dataclass
class _Send:
    """The send in progress: its queue entry, runner, and a stop asked for with its cause."""

    device: str
    entry: QueuedJob
    runner: JobRunner | None = None
    stop: threading.Event | None = None
    cause: str = ""


@station_errors
class MachineSessions:
    """The station's connected GRBL machines and their jobs (module docstring).

    Parameters
    ----------
    log : station.joblog.JobLog, optional
        The job history every send is recorded in; by default one that records nothing.
    source : str
        Who sends (``"tui"``, ``"station send"``), recorded with each job.
    """

    def __init__(self, log: JobLog | None = None, *, source: str = "") -> None:
        self.queue = JobQueue(log, source=source)
        self.connections: dict[str, GrblConnection] = {}
        self._send: _Send | None = None
        self._lock = threading.Lock()

    # ------------------------------------------------------------------ connections

    def connect(self, name: str, url: str, baud: int | None = None,
                listener: Callable[[str, object], None] | None = None) -> GrblConnection:
        """Open the machine ``name`` at ``url`` (blocking: a real board resets and says hello); ``listener`` hears
        its events (``status``, ``log``, ``alarm``, ``fault``, ``message``)."""
        conn = GrblConnection(url, baud or 115200)
        if listener is not None:
            conn.add_listener(listener)
        conn.open()
        self.connections[name] = conn
        return conn

    def disconnect(self, name: str) -> None:
        """Close ``name``'s connection; a job running on it is aborted first (soft reset, laser off)."""
        conn = self.connections.pop(name, None)
        if conn is None:
            return
        send = self._send
        if send is not None and send.device == name and send.runner is not None:
            send.runner.abort()
        conn.close()

    def connection(self, name: str | None) -> GrblConnection | None:
        """The open connection of ``name``, or None."""
        return self.connections.get(name) if name is not None else None

    def close(self) -> None:
        """Abort the running job and close every connection (the station is closing)."""
        self.abort()
        for name in list(self.connections):
            self.disconnect(name)

    @contextlib.contextmanager
    def session(self, name: str, url: str, baud: int | None = None) -> Iterator[GrblConnection]:
        """:meth:`connect` for the length of a ``with`` block (``station send``)."""
        conn = self.connect(name, url, baud)
        try:
            yield conn
        finally:
            self.disconnect(name)

    # ------------------------------------------------------------------ manual control

    def _open(self, name: str) -> GrblConnection:
        conn = self.connection(name)
        if conn is None:
            raise ServiceError(f"{name}: not connected", field="device", value=name)
        return conn

    def command(self, name: str, line: str, timeout: float = 90.0) -> list[str]:
        """Send one line (G-code or a ``$`` command) and wait for its ``ok``; the controller's feedback
        (``[MSG:...]``, ``[GC:...]``...) as ``"[KIND:text]"`` lines."""
        replies = self._open(name).command(line, timeout=timeout)
        return [f"[{reply.kind}:{reply.text}]" for reply in replies if isinstance(reply, Feedback)]

    def jog(self, name: str, move: tuple[int, int, int], step: float) -> list[str]:
        """Jog ``name`` by ``step`` mm along the signs of ``move`` (x, y, z)."""
        feed = 1000.0 if move[2] else 3000.0
        words = " ".join(f"{axis}{d * step:g}" for axis, d in zip("XYZ", move) if d)
        return self.command(name, f"$J=G91 G21 {words} F{feed:g}")

    def override(self, name: str, kind: str, action: str) -> None:
        """A real-time override (``feed``, ``+10``/``-10``/``reset``)."""
        self._open(name).override(kind, action)

    @property
    def sending(self) -> bool:
        """A job is being streamed now (its runner has started and not ended)."""
        send = self._send
        return send is not None and send.runner is not None and send.runner.result is None

    @property
    def runner(self) -> JobRunner | None:
        """The runner of the job being sent, or None."""
        send = self._send
        return send.runner if send is not None else None

    def hold(self, name: str | None = None) -> None:
        """Feed hold: the running job's (the laser off while held), else the machine ``name``'s."""
        if self.sending:
            self._send.runner.hold()
        elif (conn := self.connection(name)) is not None:
            conn.feed_hold()

    def resume(self, name: str | None = None) -> None:
        """Cycle start after a hold or a program pause."""
        if self.sending:
            self._send.runner.resume()
        elif (conn := self.connection(name)) is not None:
            conn.cycle_start()

    def abort(self, name: str | None = None) -> bool:
        """Soft reset now (motion stops, laser off); a running job then sends ``M5 S0`` and ends ``aborted``.
        Without a running job, the machine ``name`` is reset. True when a job was running."""
        if self.sending:
            self._send.runner.abort()
            return True
        if (conn := self.connection(name)) is not None:
            conn.soft_reset(False)
        return False

    def interrupt(self, cause: str) -> None:
        """Stop the running send because of ``cause`` (``"SIGINT (Ctrl-C)"``): it is aborted as :meth:`abort`
        does and ends ``interrupted`` with the line to resume from. Safe from a signal handler."""
        send = self._send
        if send is not None and send.stop is not None:
            send.cause = cause
            send.stop.set()

    # ------------------------------------------------------------------ jobs

    def add(self, device: str, gcode: str | Job, title: str | None = None, *, laser: bool = False,
            pen_up: Sequence[str] = ("M5",)) -> QueuedJob:
        """Queue a job (G-code text, or a :class:`~drivers.grbl.Job`) for ``device``."""
        if isinstance(gcode, Job):
            entry = self.queue.add(device, "\n".join(gcode.lines) or " ", title or gcode.name, laser=gcode.laser,
                                   pen_up=tuple(gcode.pen_up))
            entry.job = gcode
            return entry
        return self.queue.add(device, gcode, title, laser=laser, pen_up=tuple(pen_up))

    def place(self, entry: QueuedJob, lines: Sequence[str], title: str) -> QueuedJob:
        """``entry`` moved to its placed ``lines``: the job itself while it is queued (the unplaced one must not be
        sent next), else a new queued job."""
        if entry.state is JobState.QUEUED:
            entry.job = Job(entry.job.name, list(lines), laser=entry.job.laser, pen_up=entry.job.pen_up)
            entry.title = title
            return entry
        return self.add(entry.device, "\n".join(lines) + "\n", title, laser=entry.job.laser,
                        pen_up=entry.job.pen_up)

    def verify(self, name: str | None, lines: Sequence[str], *, title: str, profile: MachineProfile | None,
               laser: bool) -> JobVerification:
        """``lines`` run on the twin of the machine ``name`` at virtual time: with its settings and work offset when
        it is connected, else the profile's machine (:func:`station.services.job_verify.verify_job`)."""
        conn = self.connection(name)
        settings = ({k: float(v) for k, v in conn.settings.items() if isinstance(k, int)}
                    if conn is not None else None)
        return verify_job(list(lines), name=title, profile=profile, laser=laser or bool(conn and conn.laser_mode),
                          settings=settings, work_offset=conn.work_offset() if conn is not None else None)

    def send(self, device: str, entry: QueuedJob, mode: JobMode | str = JobMode.RUN, *,
             from_line: int | None = None, profile: MachineProfile | None = None, policy: SendPolicy | None = None,
             report: Reporter | ProgressCallback | None = None) -> JobResult:
        """Send ``entry`` to ``device`` in ``mode`` (the job, its frame, a dry run) and wait for the end.

        ``from_line`` (1-based) starts a run or a dry run there (by default line 1, or where a stopped run stood:
        :meth:`JobQueue.start_line`); ``profile`` is the machine's (a laser's frame power).

        ``policy`` is warned of a job written for the other kind of machine (a pen plot's servo commands fire a laser).
        The pre-flight (travel, laser mode, the machine's state) runs before any byte of the job; a laser job from
        its first line on a machine without homing first asks ``policy`` whether to trace its frame. Each send is
        recorded in the job history as it starts, runs and ends. ``report`` hears the job's
        :class:`~drivers.grbl.JobProgress` (from the streaming thread). :meth:`abort` ends it ``aborted``,
        :meth:`interrupt` (or Ctrl-C on the calling thread) ``interrupted``; either way the laser is switched off.

        Raises
        ------
        ServiceError
            ``device`` is not connected, or nothing to frame.
        JobStateError
            Another job is being sent, or ``entry`` cannot be sent from its state.
        """
        mode = JobMode(mode)
        conn = self._open(device)
        policy = policy or SendPolicy()
        if self._send is not None:
            running = self._send.entry
            raise ServiceError(f"{running.describe()} is being sent (one job at a time)", field="state",
                               value=running.state)
        job = entry.job
        warning = kind_warning(job, conn.laser_mode)
        if warning:  # a job written for the other kind of machine (a pen plot on a laser)
            policy.warn(warning)
        if (mode is JobMode.RUN and job.laser and (from_line or self.queue.start_line(entry, mode)) == 1
                and not conn.homing_enabled and conn.laser_mode):
            # without homing the job burns wherever work zero was set: the frame shows where, at low power
            refused = JobRunner(conn, job).check()  # a job that cannot run is refused before anything is offered
            if refused is not None:
                self.queue.start(entry, mode)
                policy.ended(refused, JobProgress("refused", len(job.lines)))
                self.queue.finish(entry, refused)
                return refused
            if policy.frame_first(job):
                framed = self._stream(device, conn, entry, JobMode.FRAME, None, profile, policy, report)
                if not framed.ok or not policy.start_after_frame(job):
                    return framed
        return self._stream(device, conn, entry, mode, from_line, profile, policy, report)

    def _stream(self, device: str, conn: GrblConnection, entry: QueuedJob, mode: JobMode, from_line: int | None,
                profile: MachineProfile | None, policy: SendPolicy,
                report: Reporter | ProgressCallback | None) -> JobResult:
        job = entry.job
        if mode is JobMode.FRAME:
            job = frame_job(entry.job, entry.title, profile)
            if job is None:
                raise ServiceError(f"job {entry.title}: no motion to frame", field="job", value=entry.title)
        # a frame traces the whole job; a run or a dry run starts where asked (a stopped run: where it stood)
        start = from_line if from_line is not None and mode is not JobMode.FRAME else self.queue.start_line(entry, mode)
        runner = JobRunner(conn, job, from_line=start, dry_run=mode is JobMode.DRY,
                           on_progress=Reporter.of(report).tell)
        with self._lock:
            self.queue.start(entry, mode, len(job.lines))
            send = self._send = _Send(device, entry, runner, threading.Event())
        asked: int | None = None
        try:
            runner.start()
            while runner.wait(0) is None and runner.running:
                if send.stop.wait(POLL_INTERVAL):
                    break
                progress = runner.progress
                pause = runner.pause_line
                if progress.state == "paused" and pause is not None:
                    if asked != pause:
                        asked = pause
                        policy.paused(progress.message, runner.resume, runner.abort)
                else:
                    asked = None
                resume = progress.current_line + 1 if progress.lines_acked and mode is not JobMode.DRY else None
                self.queue.progress(entry, progress.lines_acked, _layer_record(runner), resume)
            if send.stop.is_set() and runner.result is None:
                return self._interrupted(conn, runner, entry, send.cause or "a stop", policy)
        except KeyboardInterrupt:  # Python's own Ctrl-C on the calling thread
            return self._interrupted(conn, runner, entry, "Ctrl-C", policy)
        except BaseException:
            runner.abort()  # whatever went wrong here, the machine does not go on alone
            with self._lock:
                self._send = None
            raise
        result = runner.wait(None)
        policy.ended(result, runner.progress)
        with self._lock:
            self.queue.finish(entry, result, _layer_record(runner, result.resume_line))
            self._send = None
        return result

    def _interrupted(self, conn: GrblConnection, runner: JobRunner, entry: QueuedJob, cause: str,
                     policy: SendPolicy) -> JobResult:
        """Abort ``runner``'s job after a stop from outside and end it ``interrupted``: the laser switched off as the
        driver does it (soft reset, then ``M5 S0``; once more from here if the job thread does not end in time),
        the line the machine stood on kept, the history written."""
        runner.abort()
        done = runner.wait(10.0)
        progress = runner.progress
        if done is not None:
            laser_off, resume = done.laser_off, done.resume_line
        else:  # the job thread did not end: reset from here (GRBL's reset switches the spindle and laser off)
            try:
                laser_off = conn.soft_reset(wait=True, timeout=3.0)
            except Exception:  # noqa: BLE001 - a vanished port: nothing more can be done from here
                laser_off = False
            resume = progress.current_line + 1 if progress.lines_acked and not runner.dry_run else None
        tool = "laser" if runner.is_laser else "spindle"
        parts = [f"interrupted by {cause}: job aborted, soft reset sent",
                 f"{tool} off" if laser_off else f"{tool} not confirmed off: check the machine"]
        if conn.alarm is not None:
            parts.append(f"{conn.alarm}; {conn.alarm.recovery}")
        if resume is not None:
            parts.append(f"resume from line {resume}")
        result = JobResult(state=INTERRUPTED, message="; ".join(parts), lines_total=len(runner.job.lines),
                           lines_acked=progress.lines_acked, elapsed=progress.elapsed, resume_line=resume,
                           laser_off=laser_off)
        policy.ended(result, progress)
        with self._lock:
            self.queue.finish(entry, result, _layer_record(runner, resume))
            self._send = None
        return result


def _layer_record(runner: JobRunner | None, resume_line: int | None = None) -> dict | None:
    """The layer of a multi-pen plot the machine stands on (or of ``resume_line``), for the job history."""
    if runner is None or not runner.layers:
        return None
    mark = runner.layer(resume_line - 1 if resume_line else None)
    return mark.to_dict() if mark is not None else None


@station_errors
def job_layer_marks(lines: Sequence[str]) -> list[LayerMark]:
    """The layers of a multi-pen plot (``station plot``'s marks); empty for a job written without them."""
    return layer_marks(list(lines))


@station_errors
def refusal(result: JobResult) -> Exception | None:
    """The error a face raises for a send that was refused (:class:`JobRefused`) or lost the machine's position
    (:class:`DeviceStateError`), else None."""
    if result.state == "refused":
        return as_station_error(JobRefused(result.message))
    if result.state == "position_lost":
        return as_station_error(DeviceStateError(result.message))
    return None


@station_errors
def refused_by_twin(done: JobVerification, *, before_summary: bool = False) -> Exception | None:
    """The refusal of a job ``--verify`` found wrong (:class:`JobRefused`, naming why), else None. With
    ``before_summary``, only a job refused before it moved (its one line says it all, no summary first)."""
    if done.state != "done" and done.blocks == 0:
        return as_station_error(JobRefused(f"--verify: job {done.name!r} fails on the twin: {done.message}"))
    if before_summary or done.ok:
        return None
    if done.state != "done":
        return as_station_error(JobRefused(f"--verify: job {done.name!r} fails on the twin: {done.message}"))
    why = (f"the laser is on during {len(done.lit_travels)} travel(s), the first at line "
           f"{done.lit_travels[0][0]} ({done.lit_travels[0][1]})" if done.lit_travels
           else "it leaves the machine's travel" if not done.within_travel
           else f"the twin raised ALARM:{done.alarms[0]}")
    return as_station_error(JobRefused(f"--verify: job {done.name!r} refused: {why}; not sent"))


__all__ += ["DeviceEntry", "GrblConnection", "HandledSignals", "JobRecord", "device_profile", "job_layer_marks",
            "local_time", "recent_jobs", "refusal", "refused_by_twin"]
