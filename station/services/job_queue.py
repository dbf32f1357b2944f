"""The machine job queue: G-code jobs waiting on (or done by) the station's GRBL devices, in typed states.

Pure Python (no Textual): the Machines screen holds one :class:`JobQueue`, and a command could too. An entry's
state changes only through the queue's methods, which refuse what cannot happen (starting a job that is done, two
jobs at once, finishing a job that is not being sent) with a :class:`JobStateError` naming the job, its state and
the action. Every send (a run, a frame or a dry run) is recorded in the station's job history
(:class:`station.joblog.JobLog`): a row when it starts, how far it got while it runs, and how it ended.

States
------
A job is ``queued``; sending it makes it ``running`` (the job itself), ``framing`` (its bounding box traced) or
``checking`` (a dry run in GRBL's check mode). A frame or a dry run ends ``framed`` / ``checked`` when it went well,
else the job is ``queued`` again. A run ends in the runner's own states (:data:`drivers.grbl.job.FINAL_STATES`):
``done``, ``stopped``, ``aborted``, ``refused``, ``position_lost`` or ``error``; a stop from outside the station (a
signal to ``station send``) ends it ``interrupted``. A job can be sent again while it is queued, framed, checked,
stopped or interrupted; a stopped or interrupted run keeps the line to resume from (:attr:`QueuedJob.resume_line`),
and its next run starts there.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum

from drivers.grbl import Job, JobResult, frame_lines
from drivers.profiles import MachineProfile
from station.errors import ServiceError, station_errors
from station.joblog import JOB_KINDS, JobLog

__all__ = [
    "ACTIVE_STATES",
    "READY_STATES",
    "JobMode",
    "JobQueue",
    "JobState",
    "JobStateError",
    "QueuedJob",
    "frame_job",
]


class JobState(str, Enum):
    """Where a queued job stands; a ``str`` whose value is what the queue table shows (``"queued"``...)."""

    QUEUED = "queued"
    FRAMING = "framing"
    FRAMED = "framed"
    CHECKING = "checking"
    CHECKED = "checked"
    RUNNING = "running"
    DONE = "done"
    STOPPED = "stopped"
    ABORTED = "aborted"
    REFUSED = "refused"
    POSITION_LOST = "position_lost"
    ERROR = "error"
    INTERRUPTED = "interrupted"  # stopped from outside the station (a signal to ``station send``)

    def __str__(self) -> str:  # "running", not "JobState.RUNNING", in f-strings on every Python version
        return self.value


class JobMode(str, Enum):
    """How a job is sent: the job itself, its frame, or a dry run (the keys of :data:`station.joblog.JOB_KINDS`)."""

    RUN = "run"
    FRAME = "frame"
    DRY = "dry"

    def __str__(self) -> str:
        return self.value

    @property
    def kind(self) -> str:
        """The job history's ``kind`` column: ``run``, ``frame`` or ``dry run``."""
        return JOB_KINDS[self.value]


#: States a job can be sent from.
READY_STATES = frozenset({JobState.QUEUED, JobState.STOPPED, JobState.FRAMED, JobState.CHECKED,
                          JobState.INTERRUPTED})

#: Run states that keep the line the next run resumes from.
RESUMED_STATES = frozenset({JobState.STOPPED, JobState.INTERRUPTED})

#: The state of a job while it is sent, by mode.
ACTIVE_STATES = {JobMode.RUN: JobState.RUNNING, JobMode.FRAME: JobState.FRAMING, JobMode.DRY: JobState.CHECKING}

#: A frame or dry run that went well leaves the job in this state (one that did not leaves it queued).
_CHECKED_STATES = {JobMode.FRAME: JobState.FRAMED, JobMode.DRY: JobState.CHECKED}


class JobStateError(ServiceError):
    """An action the job's state does not allow (start a job that is done, finish one that is not sent...).

    Attributes
    ----------
    number : int
        The job's number in its queue.
    state : JobState
        Its state when the action was refused.
    action : str
        What was asked (``"run"``, ``"frame"``, ``"dry"``, ``"finish"``).
    """

    def __init__(self, message: str, *, number: int, state: JobState, action: str) -> None:
        super().__init__(message, field="state", value=state)
        self.number = number
        self.state = state
        self.action = action


@station_errors
@dataclass
class QueuedJob:
    """A job waiting on (or done by) one device.

    Attributes
    ----------
    number : int
        1-based, in the order jobs were queued.
    title : str
        What the queue table shows.
    device : str
        The device's name.
    job : drivers.grbl.Job
        The G-code.
    state : JobState
        Changed by :class:`JobQueue` only.
    resume_line : int or None
        The 1-based line a stopped run resumes from (the runner's suggestion), else None.
    message : str
        How the last send ended (the runner's message).
    mode : JobMode or None
        How the job is being sent, while it is (else None).
    """

    number: int
    title: str
    device: str
    job: Job
    state: JobState = JobState.QUEUED
    resume_line: int | None = None
    message: str = ""
    mode: JobMode | None = None
    log_id: int = 0  # its row in the job history while it is sent (0: not recorded)

    @property
    def ready(self) -> bool:
        """The job can be sent (queued, framed, checked or stopped)."""
        return self.state in READY_STATES

    @property
    def active(self) -> bool:
        """The job is being sent (running, framing or checking)."""
        return self.mode is not None

    def describe(self) -> str:
        """``job 2 'squares' (stopped)``: how a refusal names the job."""
        return f"job {self.number} {self.title!r} ({self.state})"


@station_errors
def frame_job(job: Job, title: str, profile: MachineProfile | None) -> Job | None:
    """The job that traces ``job``'s bounding box (pen up, or a laser at its frame power); None without motion.

    Parameters
    ----------
    job : drivers.grbl.Job
        The job to frame.
    title : str
        Its title (the frame is called ``frame of <title>``).
    profile : drivers.profiles.MachineProfile or None
        The machine's profile: the laser's frame power and the machine's feed limit (without it a laser frames at
        S10 and 3000 mm/min).
    """
    extent = job.extent()
    if extent is None:
        return None
    lo, hi = extent
    if job.laser and (profile is None or profile.laser):
        power = profile.laser.frame_power * profile.laser.max_power if profile is not None else 10.0
        lines = frame_lines(lo, hi, laser_power=power, feed=min(3000.0, profile.max_feed if profile else 3000.0))
    else:
        lines = frame_lines(lo, hi, pen_up=job.pen_up)
    return Job(f"frame of {title}", lines, laser=job.laser, pen_up=job.pen_up)


@station_errors
class JobQueue:
    """Jobs for the station's devices, one sent at a time, each send recorded in the job history.

    Parameters
    ----------
    log : station.joblog.JobLog, optional
        The job history; by default one that records nothing.
    source : str
        Who sends the jobs, recorded with each (``"tui"``).
    progress_interval : float
        Seconds between two progress records of a running job (the history is a database: not every ``ok``).
    clock : callable
        Monotonic seconds, for the progress interval (tests pass their own).
    """

    def __init__(self, log: JobLog | None = None, *, source: str = "", progress_interval: float = 2.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.log = log if log is not None else JobLog(None)
        self.source = source
        self.progress_interval = progress_interval
        self.clock = clock
        self.jobs: list[QueuedJob] = []
        self._counter = 0
        self._last_logged = -float("inf")

    def add(self, device: str, gcode: str, title: str | None = None, *, laser: bool = False,
            pen_up: tuple[str, ...] = ("M5",)) -> QueuedJob:
        """Queue ``gcode`` for the device named ``device``; returns the entry (``queued``).

        Raises
        ------
        ServiceError
            If the G-code has no line with text.
        """
        if not gcode.strip():
            raise ServiceError("the job is empty", field="gcode", value=gcode)
        self._counter += 1
        job = Job(title or f"job-{self._counter}", gcode.splitlines(), laser=laser, pen_up=pen_up)
        entry = QueuedJob(self._counter, title or f"job {self._counter}", device, job)
        self.jobs.append(entry)
        return entry

    @property
    def active(self) -> QueuedJob | None:
        """The job being sent now (running, framing or checking), or None."""
        return next((entry for entry in self.jobs if entry.active), None)

    def next_for(self, device: str | None) -> QueuedJob | None:
        """The first job that can be sent on ``device`` (on any device with None), or None."""
        return next((entry for entry in self.jobs if entry.ready and device in (None, entry.device)), None)

    @staticmethod
    def start_line(entry: QueuedJob, mode: JobMode | str) -> int:
        """The 1-based line a send of ``entry`` in ``mode`` starts from: a run of a stopped job resumes at its
        :attr:`~QueuedJob.resume_line` (when the runner suggested one), everything else starts at line 1."""
        if JobMode(mode) is JobMode.RUN and entry.state in RESUMED_STATES and entry.resume_line:
            return entry.resume_line
        return 1

    def start(self, entry: QueuedJob, mode: JobMode | str, lines_total: int | None = None) -> int:
        """Mark ``entry`` as sent in ``mode`` and record the send; returns :meth:`start_line` (as it was before).

        ``lines_total`` is the number of lines sent (a frame's, not the job's; default the job's).

        Raises
        ------
        JobStateError
            If another job is being sent, or ``entry`` cannot be sent from its state.
        """
        mode = JobMode(mode)
        if not entry.ready:
            allowed = ", ".join(state.value for state in JobState if state in READY_STATES)
            raise JobStateError(f"cannot {_VERBS[mode]} {entry.describe()}: a job is sent from {allowed}",
                                number=entry.number, state=entry.state, action=mode.value)
        running = self.active
        if running is not None:
            raise JobStateError(f"cannot {_VERBS[mode]} {entry.describe()}: {running.describe()} is being sent "
                                "(one job at a time)", number=entry.number, state=entry.state, action=mode.value)
        from_line = self.start_line(entry, mode)
        title = entry.title if mode is JobMode.RUN else f"{mode.kind} of {entry.title}"
        total = len(entry.job.lines) if lines_total is None else lines_total
        entry.log_id = self.log.start(mode.kind, entry.device, title, total, self.source)
        entry.state = ACTIVE_STATES[mode]
        entry.mode = mode
        self._last_logged = -float("inf")
        return from_line

    def progress(self, entry: QueuedJob, lines_acked: int, layer: dict | None = None,
                 resume_line: int | None = None) -> None:
        """Record how far the job being sent has got (at most once per ``progress_interval``), with the layer of
        a multi-pen plot it stands on and the line being executed (where a station killed now resumes)."""
        if not entry.active:
            return
        now = self.clock()
        if now - self._last_logged >= self.progress_interval:
            self._last_logged = now
            self.log.progress(entry.log_id, lines_acked, resume_line, layer=layer)

    def finish(self, entry: QueuedJob, result: JobResult, layer: dict | None = None) -> JobState:
        """Record how the send of ``entry`` ended (with the layer of a multi-pen plot it stood on) and move the job
        to its next state (returned).

        Raises
        ------
        JobStateError
            If ``entry`` is not being sent.
        """
        if not entry.active:
            raise JobStateError(f"cannot finish {entry.describe()}: it is not being sent",
                                number=entry.number, state=entry.state, action="finish")
        self.log.finish(entry.log_id, result.state, result.lines_acked, result.message, result.resume_line, layer)
        mode, entry.mode, entry.log_id = entry.mode, None, 0
        entry.message = result.message
        if mode is JobMode.RUN:
            entry.state = JobState(result.state)
            entry.resume_line = result.resume_line if entry.state in RESUMED_STATES else None
        else:
            entry.state = _CHECKED_STATES[mode] if result.ok else JobState.QUEUED
            entry.resume_line = None
        return entry.state


_VERBS = {JobMode.RUN: "run", JobMode.FRAME: "frame", JobMode.DRY: "dry-run"}
