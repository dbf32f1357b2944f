"""Jobs on a GRBL machine: pre-flight, dry run, frame, start, hold, resume, abort, resume from line N.

Safety rules (they are the point of this module)
------------------------------------------------
- Pre-flight, before any byte of the job is sent. With homing (``$22=1``) every point of the job (work coordinates
  + the current work offset, from where the head stands) must lie in the machine space GRBL's soft limits use
  (-travel..0 per axis, or 0..+travel for an axis whose ``$23`` bit is set when GRBL was built with
  HOMING_FORCE_SET_ORIGIN, ``Z`` in ``[OPT:]``). Without homing, machine zero is wherever the head stood at power-up:
  the job's own size on each axis must fit the travel (``$130``-``$132``), and so must the way from where the head
  stands to the job; the refusal says by how much ("this job is 300.0 mm wide; your machine travels 200.0 mm in X").
- A laser job (a laser profile, or a controller in laser mode) is refused unless ``$32=1`` is confirmed by re-reading
  the settings; every laser job ends with ``M5 S0``.
- Abort sends the soft reset (0x18) at once, which stops motion and switches the laser off in the controller; then
  ``M5 S0`` is sent as soon as the controller accepts G-code again. Errors, alarms and a lost ``ok`` take the same
  path. A vanished port leaves the machine "position lost": nothing resumes on its own.
- Progress comes from acknowledged lines corrected by the planner's fill, and the job is complete only when the
  machine is idle after the last line (``G4 P0`` is answered when all motion is done): only a finished job shows
  100 %; a job that ended early shows at most the share of its lines the machine confirmed with ``ok``.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from drivers.errors import DeviceStateError, JobRefused, ProtocolError
from drivers.gcode import GcodeError, Toolpath, clean_line, interpret, tokenize
from drivers.grbl.connection import GrblConnection, StreamStopped
from drivers.grbl.protocol import Error

__all__ = ["Job", "JobProgress", "JobResult", "JobRunner", "commanded_extent", "frame_lines", "job_kind",
           "kind_warning"]

#: GRBL's line buffer (LINE_BUFFER_SIZE): a block has at most 79 characters after comments and spaces are removed.
LINE_BUFFER_SIZE = 80


@dataclass
class Job:
    """A G-code program to run.

    Parameters
    ----------
    name : str
    lines : list of str
        The program, one block per line (as in the file; line numbers below are 1-based into this list).
    laser : bool
        A laser job (refused unless laser mode ``$32=1``; always ends with ``M5 S0``).
    pen_up : sequence of str
        Lines that make the tool safe for travel (pen up / laser off); used when resuming from a line.
    """

    name: str
    lines: list[str]
    laser: bool = False
    pen_up: Sequence[str] = ("M5",)

    @classmethod
    def from_text(cls, name: str, text: str, **kwargs) -> Job:
        return cls(name, text.splitlines(), **kwargs)

    @classmethod
    def from_file(cls, path: str | Path, **kwargs) -> Job:
        """A job from a G-code text file (UTF-8 or ASCII); a file that is not text is refused with its name."""
        path = Path(path)
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError as error:
            raise JobRefused(
                f"job {path.name!r}: not a G-code text file (byte {error.start} is not UTF-8 text)"
            ) from None
        return cls.from_text(path.name, text, **kwargs)

    @cached_property
    def toolpath(self) -> Toolpath:
        return interpret(self.lines)

    def extent(self) -> tuple[np.ndarray, np.ndarray] | None:
        return self.toolpath.extent()


#: States a job ends in (the runner's :class:`JobResult` states).
FINAL_STATES = ("done", "stopped", "aborted", "refused", "position_lost", "error")


@dataclass
class JobProgress:
    """A snapshot of a running job. ``lines_acked`` counts the job's lines GRBL answered with ``ok`` (in a dry run,
    every answered line: each one was checked); ``eta`` is None once the job ended."""

    state: str = "idle"
    lines_total: int = 0
    lines_sent: int = 0
    lines_acked: int = 0
    fraction: float = 0.0
    elapsed: float = 0.0
    eta: float | None = None
    message: str = ""
    current_line: int = 0  # 0-based job line the machine is (about) executing: acknowledged minus planned


@dataclass
class JobResult:
    """How a job ended.

    ``state`` is ``done``, ``aborted``, ``stopped`` (lost ``ok``, error, alarm), ``refused`` or ``position_lost``.
    ``resume_line`` (1-based) is where to continue with ``from_line``, when that is safe to suggest.
    """

    state: str
    message: str
    lines_total: int
    lines_acked: int
    elapsed: float
    resume_line: int | None = None
    errors: list[tuple[int, str]] = field(default_factory=list)
    laser_off: bool = True

    @property
    def ok(self) -> bool:
        return self.state == "done"


#: What a job's size along X, Y and Z is called in a refusal.
SPAN_WORDS = ("wide", "deep", "tall")


def commanded_extent(toolpath: Toolpath) -> tuple[np.ndarray, np.ndarray]:
    """Per axis, the extent of the job's own coordinates: from the first move that names the axis on.

    Before a job first names an axis, that axis stays where the head happened to stand, which says nothing about
    the job's size; a relative (``G91``) first move starts from there, so its start counts. NaN for an axis the job
    never moves.
    """
    lo, hi = np.full(3, np.nan), np.full(3, np.nan)
    if len(toolpath.line) == 0 or len(toolpath.commanded) == 0:
        return lo, hi
    for axis in range(3):
        named = np.flatnonzero(toolpath.commanded[toolpath.line, axis])
        if len(named) == 0:
            continue
        first = named[0]
        values = toolpath.end[first:, axis]
        if not toolpath.states[toolpath.line[first] + 1].absolute:
            values = np.append(values, toolpath.start[first, axis])
        lo[axis], hi[axis] = values.min(), values.max()
    return lo, hi


def frame_lines(
    lo: Sequence[float], hi: Sequence[float], *, laser_power: float | None = None, feed: float = 3000.0,
    pen_up: Sequence[str] = (),
) -> list[str]:
    """A job that traces the rectangle ``lo``-``hi`` (work mm): with the laser at ``laser_power`` (an S value,
    low enough not to mark) or with the pen up."""
    x0, y0, x1, y1 = lo[0], lo[1], hi[0], hi[1]
    corners = [(x1, y0), (x1, y1), (x0, y1), (x0, y0)]
    lines = ["G21 G90 G94", *pen_up, f"G0 X{x0:.3f} Y{y0:.3f}"]
    if laser_power is not None:
        lines.append(f"M3 S{laser_power:g}")
        lines += [f"G1 X{x:.3f} Y{y:.3f} F{feed:g}" for x, y in corners]
        lines.append("M5 S0")
    else:
        lines += [f"G0 X{x:.3f} Y{y:.3f}" for x, y in corners]
    return lines


class JobRunner:
    """Runs one job on a connection.

    Parameters
    ----------
    connection : GrblConnection
    job : Job
    from_line : int
        1-based line to start from; the modal state (units, distance mode, feed, power, position) of the lines
        before is rebuilt first.
    dry_run : bool
        Run in GRBL's check mode (``$C``): every line is parsed, nothing moves; errors are collected.
    on_progress : callable, optional
        Called with a :class:`JobProgress` (from the job thread).
    """

    def __init__(
        self,
        connection: GrblConnection,
        job: Job,
        *,
        from_line: int = 1,
        dry_run: bool = False,
        on_progress: Callable[[JobProgress], None] | None = None,
    ) -> None:
        if from_line < 1 or from_line > max(1, len(job.lines)):
            raise JobRefused(f"job {job.name!r}: from_line must be between 1 and {len(job.lines)}, got {from_line}")
        self.connection = connection
        self.job = job
        self.from_line = from_line
        self.dry_run = dry_run
        self.on_progress = on_progress
        self.progress = JobProgress(lines_total=len(job.lines))
        self.result: JobResult | None = None
        self._stop = threading.Event()
        self._aborted = False
        self._thread: threading.Thread | None = None
        self._start_time = 0.0
        self._hold_started: float | None = None
        self._held = 0.0
        self._lines: list[str] = []
        self._origin: list[int] = []  # job line index of each streamed line (-1 for added lines)
        self._durations = np.zeros(0)
        self._cumulative = np.zeros(0)
        self._last_origin = np.zeros(0, dtype=int)
        self._last_report = 0.0
        self._acked_streamed = 0
        self._toolpath: Toolpath | None = None  # of the streamed lines, from where the head stood (pre-flight)
        self._frozen = False  # the stream stopped: the planner's fill no longer says which line ran

    # ------------------------------------------------------------------ pre-flight

    @property
    def is_laser(self) -> bool:
        return self.job.laser or self.connection.laser_mode

    def preflight(self) -> dict:
        """Check the job against the machine before any motion; returns what was checked.

        Raises
        ------
        DeviceStateError
            Position lost, alarm, or the machine is busy.
        JobRefused
            Outside the travel, laser mode not confirmed, a line longer than the RX buffer.
        """
        conn = self.connection
        if conn.position_lost:
            raise DeviceStateError(f"{conn.url}: position lost ({conn.fault}); reconnect and home ($H) first")
        status = conn.fresh_status() or conn.status
        if status is not None and status.state == "Alarm":
            raise DeviceStateError(f"{conn.url}: machine is in alarm ({conn.alarm or 'locked'}); "
                                   "home ($H) or unlock ($X) first")
        if status is not None and status.state not in ("Idle", "Check"):
            raise DeviceStateError(f"{conn.url}: machine is busy ({status.label}); wait for Idle")
        conn.refresh()  # confirm the settings and offsets now, not from the connect time
        if self.is_laser and not conn.laser_mode:
            raise JobRefused(
                f"job {self.job.name!r}: laser job refused: laser mode is off ($32={int(conn.settings.get(32, 0))}); "
                "with $32=0 the laser stays on while stopped and burns. Set $32=1 first"
            )
        for number, raw in enumerate(self.job.lines, start=1):
            length = len(clean_line(raw))
            if length >= LINE_BUFFER_SIZE or length + 1 > conn.rx_size - 1:
                raise JobRefused(f"job {self.job.name!r}: line {number} has {length} characters; GRBL takes at most "
                                 f"{LINE_BUFFER_SIZE - 1} (error:11 otherwise)")
        self._lines, self._origin = self._build_lines()
        self._last_origin = np.maximum.accumulate(np.array(self._origin, dtype=int))  # O(1) progress lookups
        # start from where the machine stands: relative moves and the first travel are then checked too
        start = None
        if status is not None:
            wpos = status.work_position(conn.work_offset())
            if wpos is not None:
                start = wpos
        toolpath = interpret(self._lines, start=start, wco=conn.work_offset())
        self._toolpath = toolpath
        rapid = min(conn.settings.get(110, 500.0), conn.settings.get(111, 500.0))
        durations = toolpath.durations(rapid_rate=rapid)
        self._durations = durations
        self._cumulative = np.cumsum(durations)
        checked = {"lines": len(self._lines), "estimate_s": float(durations.sum()),
                   "homing": conn.homing_enabled}
        extent = toolpath.extent()
        if extent is not None:
            lo, hi = extent
            wco = np.array(conn.work_offset())
            checked.update(extent_lo=lo.tolist(), extent_hi=hi.tolist(), work_offset=wco.tolist())
            if conn.homing_enabled:
                self._check_machine_space(lo, hi, wco)
            else:
                self._check_span(toolpath, lo, hi)
        return checked

    def _check_machine_space(self, lo: np.ndarray, hi: np.ndarray, wco: np.ndarray) -> None:
        """A homed machine: every point (work + work offset) inside the machine space GRBL's soft limits use."""
        conn = self.connection
        travel = np.array(conn.travel, dtype=float)
        allowed_lo, allowed_hi = (np.array(bound, dtype=float) for bound in conn.machine_bounds())
        mlo, mhi = lo + wco, hi + wco
        # X and Y are always checked, Z when the job moves it; an axis whose travel is 0 is not configured and is
        # checked only when GRBL itself checks it (soft limits on: then it must stay at 0)
        check = hi - lo > 1e-9
        check[:2] = True
        check &= (travel > 0) | conn.soft_limits
        bad = [
            f"{axis} {wlo:.2f}..{whi:.2f} (machine {mlo_:.2f}..{mhi_:.2f}, travel {alo:.2f}..{ahi:.2f})"
            for axis, wlo, whi, mlo_, mhi_, alo, ahi, checked in zip(
                "XYZ", lo, hi, mlo, mhi, allowed_lo, allowed_hi, check)
            if checked and (mlo_ < alo - 1e-3 or mhi_ > ahi + 1e-3)
        ]
        if bad:
            raise JobRefused(f"job {self.job.name!r} leaves the machine's travel ($130-$132 with work offset "
                             f"{', '.join(f'{v:.2f}' for v in wco)}): " + "; ".join(bad))

    def _check_span(self, toolpath: Toolpath, lo: np.ndarray, hi: np.ndarray) -> None:
        """A machine without homing: machine zero is wherever the head stood at power-up, so machine coordinates
        say nothing about the machine's ends. What is known: the job's own size on each axis, and the way from
        where the head stands to the job, must each fit the travel ($130-$132)."""
        conn = self.connection
        travel = np.array(conn.travel, dtype=float)
        own_lo, own_hi = commanded_extent(toolpath)
        known = travel > 0
        too_big = [
            f"this job is {own_hi[i] - own_lo[i]:.1f} mm {SPAN_WORDS[i]}; your machine travels {travel[i]:.1f} mm "
            f"in {'XYZ'[i]} (${130 + i})"
            for i in range(3)
            if known[i] and np.isfinite(own_lo[i]) and own_hi[i] - own_lo[i] > travel[i] + 1e-3
        ]
        if too_big:
            raise JobRefused(f"job {self.job.name!r} does not fit the machine: " + "; ".join(too_big)
                             + ". Scale the job down (station plot --size), or check $130-$132 if the machine "
                             "travels further")
        start = toolpath.start[0]  # where the head stands (the first segment leaves from there)
        too_far = [
            f"the head stands at {'XYZ'[i]} {start[i]:.1f} and the job goes to {'XYZ'[i]} {own_lo[i]:.1f}.."
            f"{own_hi[i]:.1f}: {hi[i] - lo[i]:.1f} mm of travel, more than the {travel[i]:.1f} mm your machine has"
            for i in range(3)
            if known[i] and np.isfinite(own_lo[i]) and hi[i] - lo[i] > travel[i] + 1e-3
        ]
        if too_far:
            raise JobRefused(f"job {self.job.name!r} cannot run from where the head stands (no homing: the job runs "
                             "relative to work zero): " + "; ".join(too_far) + ". Jog the head to where the job "
                             "should start, set work zero there (G10 L20 P1 X0 Y0) and send the frame first")

    def _build_lines(self) -> tuple[list[str], list[int]]:
        start = self.from_line - 1
        lines: list[str] = []
        origin: list[int] = []
        if start > 0:
            state = self.job.toolpath.states[start]
            for line in state.preamble(self.job.pen_up if not self.is_laser else ("M5",)):
                lines.append(line)
                origin.append(-1)
        for index in range(start, len(self.job.lines)):
            lines.append(self.job.lines[index])
            origin.append(index)
        if self.is_laser and not self.dry_run:
            lines.append("M5 S0")
            origin.append(-1)
        if not self.dry_run:
            lines.append("G4 P0")  # answered only when every motion is finished
            origin.append(-1)
        return lines, origin

    # ------------------------------------------------------------------ control

    def start(self) -> threading.Thread:
        """Run in a background thread (see :attr:`result` when it ends)."""
        self._thread = threading.Thread(target=self.run_safely, name=f"job-{self.job.name}", daemon=True)
        self._thread.start()
        return self._thread

    def run_safely(self) -> JobResult:
        """:meth:`run`, but whatever goes wrong the job ends with a result and a reset machine (state ``"error"``).

        What job threads and workers call: a bug must not leave a laser burning, nor a caller waiting for a thread
        that died without a result.
        """
        try:
            return self.run()
        except Exception as error:  # noqa: BLE001 - the last line of defence; the message names the failure
            laser_off = False
            try:
                self.connection.soft_reset(wait=True)  # GRBL's reset stops motion and the laser at once
                laser_off = self._laser_off()
            except Exception:  # noqa: BLE001 - the port may be the thing that failed
                pass
            self._finish("error", f"job {self.job.name!r} stopped by an internal error ({type(error).__name__}: "
                         f"{error}); the machine was reset" + ("" if laser_off else "; check that the laser is off"),
                         laser_off=laser_off)
            return self.result

    def wait(self, timeout: float | None = None) -> JobResult | None:
        """Wait up to ``timeout`` s for the job; its result, or None while it runs."""
        if self._thread is not None:
            self._thread.join(timeout)
        return self.result

    @property
    def running(self) -> bool:
        """True while the job thread is alive (False before :meth:`start` and once it ended)."""
        return self._thread is not None and self._thread.is_alive()

    def hold(self) -> None:
        """Feed hold (``!``): decelerates to a stop; in laser mode the laser is off while held."""
        self.connection.feed_hold()
        if self.result is None:
            if self._hold_started is None:
                self._hold_started = time.monotonic()
            self.progress.state = "holding"

    def resume(self) -> None:
        """Cycle start (``~``) after a hold. GRBL ignores it while still decelerating (``Hold:1``), so then it is
        sent from a helper thread as soon as the hold is complete (never blocks the caller)."""
        conn = self.connection
        status = conn.status
        if status is not None and status.label == "Hold:1":
            def when_stopped() -> None:
                conn.wait_for(lambda: conn.status is not None and conn.status.label != "Hold:1", 10.0)
                conn.cycle_start()

            threading.Thread(target=when_stopped, name="grbl-resume", daemon=True).start()
        else:
            conn.cycle_start()
        if self._hold_started is not None:
            self._held += time.monotonic() - self._hold_started
            self._hold_started = None
        if self.result is None:
            self.progress.state = "running"

    def abort(self) -> None:
        """Stop now: soft reset (0x18) first, then the job thread switches the laser off with ``M5 S0``."""
        self._aborted = True
        self._frozen = True  # before the reset empties the planner (it would read as "every line ran")
        self._stop.set()  # first: the stream writes no line after this (checked under the port's write lock)
        try:
            self.connection.soft_reset(wait=False)
        except Exception:  # noqa: BLE001 - the port may already be gone; the job thread reports it
            pass

    # ------------------------------------------------------------------ running

    def _update(self, state: str | None = None, message: str | None = None) -> None:
        p = self.progress
        if state:
            p.state = state
        if message is not None:
            p.message = message
        now = time.monotonic()
        held = self._held + (now - self._hold_started if self._hold_started else 0.0)
        p.elapsed = max(0.0, now - self._start_time - held) if self._start_time else 0.0
        total = float(self._cumulative[-1]) if len(self._cumulative) else 0.0
        status = self.connection.status
        in_planner = 0
        if status is not None and status.planner_free is not None:
            in_planner = max(0, self.connection.planner_size - status.planner_free)
        executed = max(0, self._acked_streamed - in_planner)
        executed = min(executed, len(self._cumulative))
        done = float(self._cumulative[executed - 1]) if executed else 0.0
        if executed and len(self._last_origin) and not self._frozen:
            p.current_line = max(int(self._last_origin[executed - 1]) + 1, self.from_line - 1)
        # never backwards (a later status report may show a fuller planner than the acknowledgements suggested)
        # 100 % only once done: the machine may still move after the last motion line was counted as executed
        if total > 0:
            p.fraction = max(p.fraction, min(0.999, done / total))
        elif self._lines:
            p.fraction = max(p.fraction, min(0.999, executed / len(self._lines)))
        if p.state == "done":
            p.fraction = 1.0
            p.eta = 0.0
        elif p.state in FINAL_STATES:
            # ended early: the time estimate of the lines that ran is not the job's share (a job stopped by its
            # last line had run all of its motion), so at most the share of its lines confirmed
            confirmed = p.lines_acked / p.lines_total if p.lines_total else 0.0
            p.fraction = min(p.fraction, confirmed, 0.999)
            p.eta = None
        elif done > 0 and p.elapsed > 0.2:
            rate = done / p.elapsed  # estimated seconds of job per real second: corrects the estimate
            p.eta = (total - done) / max(rate, 1e-6)
        else:
            p.eta = total if total else None
        # at most 10 updates a second, but every change of state
        if self.on_progress and (state or now - self._last_report >= 0.1):
            self._last_report = now
            self.on_progress(p)

    def check(self) -> JobResult | None:
        """The pre-flight alone: None when the job may run, else how :meth:`run` would end (``refused``, or
        ``position_lost``) without sending any of it."""
        conn = self.connection
        try:
            self._update("preflight")
            self.preflight()
        except (JobRefused, DeviceStateError, GcodeError) as error:
            state = "position_lost" if conn.position_lost else "refused"
            message = f"job {self.job.name!r}: {error}" if isinstance(error, GcodeError) else str(error)
            return self._finish(state, message, laser_off=True)
        return None

    def run(self) -> JobResult:
        """Run the job (blocking) and return its :class:`JobResult`; never raises for device trouble."""
        conn = self.connection
        self._acked_streamed = 0
        self._start_time = 0.0
        conn.recover_lost_ok()  # a lost reply of an earlier command: the next stream starts from an empty counter
        refused = self.check()
        if refused is not None:
            return refused
        job_acked = [0]

        def on_ack(result) -> None:
            self._acked_streamed = result.index + 1
            # a line answered with an error did not run (in a dry run it was checked: that is the point)
            if self._origin[result.index] >= 0 and (result.status == "ok" or self.dry_run):
                job_acked[0] += 1
                self.progress.lines_acked = job_acked[0]
            self._update()

        def on_sent(index: int) -> None:
            self.progress.lines_sent = index + 1

        self._start_time = time.monotonic()
        try:
            if self.dry_run:
                return self._dry_run(on_ack)
            self._update("running")
            conn.stream(self._lines, on_ack=on_ack, on_sent=on_sent, stop=self._stop, timeout=math.inf)
        except StreamStopped as stopped:
            return self._stopped(stopped)
        return self._finish("done", f"job {self.job.name!r} done: {len(self.job.lines)} lines", laser_off=True)

    def _dry_run(self, on_ack) -> JobResult:
        conn = self.connection
        self._update("dry-run")
        try:
            conn.command("$C")
        except (ProtocolError, DeviceStateError) as error:
            return self._finish("refused", f"dry run: cannot enter check mode: {error}")
        errors: list[tuple[int, str]] = []
        try:
            results = conn.stream(self._lines, on_ack=on_ack, stop=self._stop, stop_on_error=False,
                                  timeout=math.inf)
        except StreamStopped as stopped:
            conn.soft_reset()  # also leaves check mode
            return self._finish("stopped", f"dry run stopped: {stopped}", laser_off=True)
        for result in results:
            if result.status == "error":
                line = self._origin[result.index] + 1
                errors.append((line, f"line {line} {result.text!r}: {Error(result.error)}"))
        conn.expect_reset()
        try:
            conn.command("$C")  # leaving check mode resets GRBL
        except (ProtocolError, DeviceStateError):
            conn.soft_reset()
        conn.wait_for(lambda: conn.status is not None and conn.status.state == "Idle", 2.0)
        if errors:
            return self._finish("stopped", f"dry run: {len(errors)} line(s) rejected", errors=errors)
        return self._finish("done", f"dry run: all {len(self.job.lines)} lines accepted (check mode)")

    def _stopped(self, stopped: StreamStopped) -> JobResult:
        conn = self.connection
        self._frozen = True
        if conn.position_lost:
            # where to go on once the machine is homed again: the line it was (about) executing
            return self._finish("position_lost", str(conn.fault), laser_off=False,
                                resume=self._resume_line(None))
        reason = stopped.reason
        aborted = self._aborted or reason == "stopped"
        status_before = conn.status
        lost_ok = reason == "fault" and "lost ok" in (conn.fault or "")
        fault_text = conn.fault
        # Leave the machine safe: a reset stops everything and switches the laser off in the controller.
        # (After an abort the reset was sent already; alarms 1 and 2 need one to continue.)
        if not aborted:
            conn.soft_reset(wait=True)
        else:
            conn.wait_for(lambda: not conn._expect_banner or conn.position_lost, conn.banner_timeout)
        conn.wait_for(lambda: conn.status is not None and conn.status.state in ("Idle", "Alarm"), 1.0)
        if lost_ok:
            conn.clear_fault()  # dealt with: the reset emptied GRBL's buffers and the counter
        laser_off = self._laser_off()
        resume = None
        if lost_ok:
            resume = self._resume_after_lost_ok(stopped, status_before)
            waiting = sum(1 for r in stopped.results if r.status in ("pending", "unconfirmed"))
            message = (f"lost ok: the controller went idle with empty buffers while {waiting} line(s) still waited "
                       "for a reply (no ok was assumed); stream stopped, machine reset while idle (position kept), "
                       "laser off")
            conn._log("info", f"job {self.job.name!r}: {fault_text}")
            if resume == 0:
                return self._finish("done", f"job {self.job.name!r} done (every line ran; {message})",
                                    laser_off=laser_off)
            if resume is not None:
                message += f"; resume from line {resume}"
            return self._finish("stopped", message, laser_off=laser_off, resume=resume)
        resume = self._resume_line(conn.status)
        where = f"; resume from line {resume}" if resume is not None else ""
        if aborted:
            alarm = conn.alarm
            message = "aborted: soft reset sent, laser off"
            if alarm is not None:
                message += f"; {alarm}; {alarm.recovery}"
            return self._finish("aborted", message + where, laser_off=laser_off, resume=resume)
        message = f"job stopped: {stopped}"
        if conn.alarm is not None and reason == "alarm":
            message = f"job stopped by {conn.alarm}; {conn.alarm.recovery}"
        return self._finish("stopped", message + where, laser_off=laser_off, resume=resume)

    def _resume_line(self, status) -> int | None:
        """Where to resume a job that ended early (1-based): the line the machine was executing, run again whole.

        The machine's position after the stop (GRBL keeps it through a feed hold, an error's reset and, not
        guaranteed, a reset in motion) finds the segment it stood on, near the line the planner's fill last
        pointed to; without a position, that line itself. None in a dry run (nothing ran).
        """
        if self.dry_run or not self._origin:
            return None
        guess = max(self.progress.current_line, self.from_line - 1)  # 0-based job line
        line = guess
        toolpath = self._toolpath
        if status is not None and status.mpos is not None and toolpath is not None and len(toolpath.line):
            position = np.array(status.mpos, dtype=float) - np.array(self.connection.work_offset())
            a, b = toolpath.start, toolpath.end
            direction = b - a
            length2 = np.einsum("ij,ij->i", direction, direction)
            t = np.clip(np.einsum("ij,ij->i", position - a, direction) / np.maximum(length2, 1e-12), 0.0, 1.0)
            distance = np.linalg.norm(a + t[:, None] * direction - position, axis=1)
            origin = np.array(self._origin)[toolpath.line]
            near = (distance < 0.05) & (toolpath.line < max(self.progress.lines_sent, 1)) & (origin >= 0)
            if near.any():
                candidates = origin[near]
                # the path may cross itself: the candidate nearest the planner's guess, the earlier one on a tie
                line = int(candidates[np.lexsort((candidates, np.abs(candidates - guess)))[0]])
                # a segment's end is also the next one's start: standing there, the next line is the one to run
                ends = near & (t >= 1.0 - 1e-9) & (origin == line)
                if ends.any() and not (near & (origin == line) & (t < 1.0 - 1e-9)).any():
                    line = line + 1
        return min(max(line, 0), len(self.job.lines) - 1) + 1

    def _laser_off(self) -> bool:
        """Send ``M5 S0`` if the controller accepts G-code; in alarm lock the reset already switched it off."""
        conn = self.connection
        if conn.position_lost:
            return False
        status = conn.fresh_status() or conn.status
        if status is not None and status.state == "Alarm":
            return True  # GRBL's reset kills the spindle/laser; G-code is locked out until $X/$H
        try:
            conn.command("M5 S0", timeout=3.0)
            return True
        except StreamStopped:
            # its reply was lost: the controller is idle with empty buffers, so M5 S0 ran or the reset that
            # preceded it already switched the laser off
            conn.recover_lost_ok()
            return not conn.position_lost
        except Exception:  # noqa: BLE001
            return status is not None

    def _resume_after_lost_ok(self, stopped: StreamStopped, status) -> int | None:
        """Where to resume after a lost ``ok``: the machine stands at the end of the last line it executed."""
        conn = self.connection
        if status is None or status.mpos is None:
            return None
        wco = np.array(conn.work_offset())
        position = np.array(status.mpos) - wco
        toolpath = interpret(self._lines)
        first = stopped.first_unconfirmed if stopped.first_unconfirmed is not None else 0
        sent = self.progress.lines_sent
        candidates = range(min(sent, len(self._lines)) - 1, max(first, 1) - 2, -1)
        for index in candidates:
            state = toolpath.states[index + 1]
            if state.position_known and np.allclose(state.position[:2], position[:2], atol=0.01):
                # the next line of the job that was not executed (0: none left, the job ran to its end)
                for later in range(index + 1, len(self._lines)):
                    if self._origin[later] >= 0:
                        return self._origin[later] + 1
                return 0
        for later in range(first, len(self._lines)):
            if self._origin[later] >= 0:
                return self._origin[later] + 1
        return None

    def _finish(self, state: str, message: str, *, laser_off: bool = True, resume: int | None = None,
                errors: list | None = None) -> JobResult:
        self._update(state, message)
        self.result = JobResult(
            state=state, message=message, lines_total=len(self.job.lines), lines_acked=self.progress.lines_acked,
            elapsed=self.progress.elapsed, resume_line=resume, errors=errors or [], laser_off=laser_off,
        )
        return self.result


def job_kind(lines: Sequence[str]) -> str:
    """What a G-code program looks like it was written for: ``"pen"``, ``"laser"`` or ``""`` (cannot tell).

    A writer's mark decides first (``(chaos-station pen plot job ...)`` from ``station plot`` for a pen plotter,
    ``; chaos-station laser job`` from the laser-job writer); then ``M4`` (dynamic laser power, which a pen servo
    never uses) means a laser job, and a program that never switches the spindle on with a power (``M3``/``M4`` and
    ``S`` above 0) means a pen plotter's (it would mark nothing on a laser).
    """
    for raw in lines:
        if "(" in raw or ";" in raw:
            lower = raw.lower()
            if "pen plot" in lower:
                return "pen"
            if "laser job" in lower:
                return "laser"
    spindle_on, power, dynamic = _spindle_words(lines)
    if dynamic:
        return "laser"
    if not (spindle_on and power):
        return "pen"
    return ""


def _spindle_words(lines: Sequence[str]) -> tuple[bool, bool, bool]:
    """Whether ``lines`` use ``M3``/``M4``, an ``S`` above 0, and ``M4``."""
    spindle_on = power = dynamic = False
    for raw in lines:
        block = clean_line(raw)
        if not block or block.startswith("$"):
            continue
        try:
            words = tokenize(block)
        except GcodeError:
            continue  # the pre-flight names bad lines; this is only a hint
        for letter, value in words:
            if letter == "M" and value in (3.0, 4.0):
                spindle_on = True
                dynamic = dynamic or value == 4.0
            elif letter == "S" and value > 0:
                power = True
    return spindle_on, power, dynamic


def kind_warning(job: Job, laser_mode: bool) -> str:
    """A warning when ``job`` looks written for another kind of machine than one in (or out of) laser mode; ``""``
    when it looks right, cannot be told, or the job is marked a laser job (``Job.laser``: checked by the
    pre-flight)."""
    if job.laser:
        return ""
    kind = job_kind(job.lines)
    if laser_mode and kind == "pen":
        spindle_on, power, _ = _spindle_words(job.lines)
        if spindle_on and power:
            return (f"job {job.name!r} looks like a pen-plotter job, but the machine is in laser mode ($32=1): its "
                    "pen commands (M3 S...) fire the laser at that power. Send it to the plotter, or check the job")
        return (f"job {job.name!r} looks like a pen-plotter job (it never switches a laser on with M3/M4 and S), "
                "but the machine is in laser mode ($32=1): it will mark nothing")
    if not laser_mode and kind == "laser":
        return (f"job {job.name!r} looks like a laser job (M4, or a laser job's header), but the machine is not in "
                "laser mode ($32=0): a laser would stay on whenever the machine stops. Set $32=1 and send it with "
                "--laser or a laser profile")
    return ""
