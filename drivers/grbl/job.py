"""Jobs on a GRBL machine: pre-flight, dry run, frame, start, hold, resume, abort, resume from line N.

The job runner lives here; what a job is and reports (:class:`Job`, :class:`JobProgress`, :class:`JobResult`,
:func:`frame_lines`) is in :mod:`drivers.grbl.job_types`, and the pre-flight checks (travel, line lengths, a job
written for the other kind of machine) in :mod:`drivers.grbl.preflight`; both are importable from here too.

Safety rules (they are the point of this module)
------------------------------------------------
- Pre-flight, before any byte of the job is sent: the job must lie in the machine's travel, as
  :mod:`drivers.grbl.preflight` explains (with homing, the machine space of GRBL's soft limits; without, the job's
  own size and the way from the head to it).
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

import dataclasses
import math
import threading
import time
from collections.abc import Callable

import numpy as np

from drivers.errors import DeviceStateError, JobRefused, ProtocolError
from drivers.gcode import GcodeError, Toolpath, WorkOffsets, interpret
from drivers.gcode_layers import LayerMark, layer_at, layer_marks, pause_lines
from drivers.grbl.connection import GrblConnection, StreamStopped
from drivers.grbl.job_types import FINAL_STATES, Job, JobProgress, JobResult, frame_lines
from drivers.grbl.planner import line_seconds
from drivers.grbl.preflight import (
    LINE_BUFFER_SIZE,
    SPAN_WORDS,
    check_line_lengths,
    check_machine_space,
    check_placed,
    check_span,
    commanded_extent,
    job_kind,
    kind_warning,
    offset_note,
)
from drivers.grbl.protocol import Error

__all__ = ["FINAL_STATES", "LINE_BUFFER_SIZE", "SPAN_WORDS", "Job", "JobProgress", "JobResult", "JobRunner",
           "commanded_extent", "frame_lines", "job_kind", "kind_warning"]

#: States of a job that ran and did not finish: each has a line to resume from.
RESUMABLE_STATES = ("stopped", "aborted", "error", "position_lost")

#: Seconds between two progress snapshots while lines are confirmed (a change of state makes one at once).
SNAPSHOT_INTERVAL = 0.05


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
        self._progress = JobProgress(lines_total=len(job.lines))
        self._sent = 0  # lines written and job lines confirmed: plain counts, folded into the snapshot when read
        self._acked = 0
        self._last_snapshot = 0.0
        self._progress_lock = threading.Lock()  # snapshots are replaced from the job thread and the caller's
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
        self._wco: np.ndarray | None = None  # the work offset the job started with (the toolpath's machine = + this)
        self._frozen = False  # the stream stopped: the planner's fill no longer says which line ran
        self._pauses = pause_lines(job.lines)  # the job's own program pauses (M0): a pen change, for one
        self._marks = layer_marks(job.lines)
        self._pause_started: float | None = None
        self.pause_line: int | None = None  # 0-based job line of the program pause the machine waits at, or None
        self._stopped_pause: int | None = None  # the pause the job was stopped at: it resumes there (pen not changed)

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
            if conn.homing_enabled:
                # GRBL locks a homing machine at power-up (HOMING_INIT_LOCK) until it homes: only then do its machine
                # coordinates, its soft limits and the pre-flight's machine space mean the machine's travel
                raise DeviceStateError(
                    f"{conn.url}: machine is locked ({conn.alarm or 'homing is on ($22=1) and it has not homed'}): "
                    "home it ($H), then set work zero where the job should start unless G54 holds it already "
                    "(jog there, G10 L20 P1 X0 Y0)")
            raise DeviceStateError(f"{conn.url}: machine is in alarm ({conn.alarm or 'locked'}); unlock it ($X) "
                                   "and set work zero again if the position was lost (G10 L20 P1 X0 Y0)")
        if status is not None and status.state not in ("Idle", "Check"):
            raise DeviceStateError(f"{conn.url}: machine is busy ({status.label}); wait for Idle")
        conn.refresh()  # confirm the settings and offsets now, not from the connect time
        if self.is_laser and not conn.laser_mode:
            raise JobRefused(
                f"job {self.job.name!r}: laser job refused: laser mode is off ($32={int(conn.settings.get(32, 0))}); "
                "with $32=0 the laser stays on while stopped and burns. Set $32=1 first"
            )
        check_line_lengths(self.job, conn.rx_size)
        self._lines, self._origin = self._build_lines()
        self._last_origin = np.maximum.accumulate(np.array(self._origin, dtype=int))  # O(1) progress lookups
        # start from where the machine stands: relative moves and the first travel are then checked too
        start = None
        if status is not None:
            wpos = status.work_position(conn.work_offset())
            if wpos is not None:
                start = wpos
        wco = np.array(conn.work_offset(), dtype=float)
        # the offsets table too: a job that sets G92, G10 L2/L20 or selects G55.. runs where those put it
        toolpath = interpret(self._lines, start=start, wco=wco,
                             offsets=WorkOffsets.from_report(conn.offsets, conn.parser_state))
        self._toolpath, self._wco = toolpath, wco
        check_placed(self.job.name, toolpath, self._origin)
        durations = line_seconds(toolpath, self._lines, conn.settings, laser_mode=conn.laser_mode)
        self._durations = durations
        self._cumulative = np.cumsum(durations)
        checked = {"lines": len(self._lines), "estimate_s": float(durations.sum()),
                   "homing": conn.homing_enabled}
        extent = toolpath.extent()
        if extent is not None:
            lo, hi = extent
            checked.update(extent_lo=lo.tolist(), extent_hi=hi.tolist(), work_offset=wco.tolist())
            note = offset_note(toolpath, self._lines, self._origin)
            if conn.homing_enabled:
                check_machine_space(self.job.name, conn, lo, hi, wco, note)
            else:
                check_span(self.job.name, conn, toolpath, lo, hi, note)
        return checked

    def _build_lines(self) -> tuple[list[str], list[int]]:
        start = self.from_line - 1
        lines: list[str] = []
        origin: list[int] = []
        if start > 0:
            state = self.job.toolpath.states[start]
            if not state.rebuildable:
                raise JobRefused(
                    f"job {self.job.name!r}: cannot resume from line {self.from_line}: the job sets a work offset "
                    "(G92) where the head stood when it ran, and a reset clears it; send it from line 1 with the "
                    "head where it started, or set work zero with G10 L20 P1 in the job instead")
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
            resume = None
            try:
                self._update(force=True, report=False)
                self._frozen = True  # before the reset empties the planner (it would read as "every line ran")
                self.connection.soft_reset(wait=True)  # GRBL's reset stops motion and the laser at once
                laser_off = self._laser_off()
                resume = self._resume_line(self.connection.status)  # the line the machine stood on
            except Exception:  # noqa: BLE001 - the port may be the thing that failed
                pass
            where = f"; resume from line {resume}" if resume is not None else ""
            self._finish("error", f"job {self.job.name!r} stopped by an internal error ({type(error).__name__}: "
                         f"{error}); the machine was reset" + ("" if laser_off else "; check that the laser is off")
                         + where, laser_off=laser_off, resume=resume)
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
            self._set_progress(stage="holding")

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
        self._end_pause()
        if self.result is None:
            self._set_progress(stage="running", message="")

    def abort(self) -> None:
        """Stop now: soft reset (0x18) first, then the job thread switches the laser off with ``M5 S0``."""
        self._aborted = True
        self._update(force=True, report=False)  # the line being executed, from the planner's fill before the reset
        self._frozen = True  # before the reset empties the planner (it would read as "every line ran")
        self._stop.set()  # first: the stream writes no line after this (checked under the port's write lock)
        try:
            self.connection.soft_reset(wait=False)
        except Exception:  # noqa: BLE001 - the port may already be gone; the job thread reports it
            pass

    # ------------------------------------------------------------------ program pauses

    @property
    def layers(self) -> list[LayerMark]:
        """The job's layers (a multi-pen plot's marks; empty for a job written without them)."""
        return list(self._marks)

    def layer(self, line: int | None = None) -> LayerMark | None:
        """The layer of the 0-based job ``line`` (default: the line being executed), or None."""
        return layer_at(self._marks, self.progress.current_line if line is None else line)

    def pause_message(self, line: int) -> str:
        """What to tell the maker at the program pause on 0-based ``line``: which pen to put in at a pen change."""
        mark = next((m for m in self._marks if m.pause == line), None)
        if mark is not None:
            return f'pen change: put in pen "{mark.pen}" for {mark.label.split(" (pen")[0]}'
        return f"program pause (M0) at line {line + 1}"

    def _watch(self, event: str, data) -> None:
        """Status reports while the job runs: the machine holding at one of the job's ``M0`` lines is a program
        pause (GRBL's feed hold, entered by the program itself), told apart from a hold the user asked for."""
        if event != "status" or self.result is not None or not self._start_time or self.dry_run:
            return
        label = getattr(data, "label", "")
        if label == "Hold:0" and self._pause_started is None and self._hold_started is None and self._pauses:
            self._update(force=True, report=False)
            current = self.progress.current_line
            at = [p for p in self._pauses if p <= current <= p + 2]
            if at:
                self._pause_started = time.monotonic()
                self.pause_line = at[-1]
                self._update("paused", self.pause_message(at[-1]))
        elif self._pause_started is not None and not label.startswith("Hold"):
            self._end_pause()
            self._update("running", "")

    def _end_pause(self) -> None:
        if self._pause_started is not None:
            self._held += time.monotonic() - self._pause_started
            self._pause_started = None
            self.pause_line = None

    # ------------------------------------------------------------------ running

    @property
    def progress(self) -> JobProgress:
        """The job's progress now: the latest snapshot with the lines sent and confirmed up to this moment (the rest
        of it, ETA and the line being executed, is at most :data:`SNAPSHOT_INTERVAL` old while lines are
        confirmed)."""
        with self._progress_lock:
            return self._counted()

    def _counted(self) -> JobProgress:
        # with the lock held
        p = self._progress
        if p.lines_sent != self._sent or p.lines_acked != self._acked:
            p = self._progress = dataclasses.replace(p, lines_sent=self._sent, lines_acked=self._acked)
        return p

    def _set_progress(self, **changes) -> JobProgress:
        """Replace the progress snapshot with ``changes`` applied (fields by their names: ``stage``, ``done``...)."""
        with self._progress_lock:
            self._progress = dataclasses.replace(self._counted(), **changes)
            return self._progress

    def _update(self, state: str | None = None, message: str | None = None, *, force: bool = False,
                report: bool = True) -> None:
        now = time.monotonic()
        if state is None and message is None and not force and now - self._last_snapshot < SNAPSHOT_INTERVAL:
            return  # a stream confirms a line every millisecond: a snapshot each time would cost more than the line
        self._last_snapshot = now
        with self._progress_lock:
            p = self._counted()
            stage = state or p.stage
            held = self._held + (now - self._hold_started if self._hold_started else 0.0) + (
                now - self._pause_started if self._pause_started else 0.0)
            elapsed = max(0.0, now - self._start_time - held) if self._start_time else 0.0
            total = float(self._cumulative[-1]) if len(self._cumulative) else 0.0
            status = self.connection.status
            in_planner = 0
            if status is not None and status.planner_free is not None:
                in_planner = max(0, self.connection.planner_size - status.planner_free)
            executed = max(0, self._acked_streamed - in_planner)
            executed = min(executed, len(self._cumulative))
            done = float(self._cumulative[executed - 1]) if executed else 0.0
            current_line = p.current_line
            if executed and len(self._last_origin) and not self._frozen:
                current_line = max(int(self._last_origin[executed - 1]) + 1, self.from_line - 1)
            # never backwards (a later status report may show a fuller planner than the acknowledgements suggested)
            # 100 % only once done: the machine may still move after the last motion line was counted as executed
            fraction = p.fraction
            if total > 0:
                fraction = max(fraction, min(0.999, done / total))
            elif self._lines:
                fraction = max(fraction, min(0.999, executed / len(self._lines)))
            if stage == "done":
                fraction, eta = 1.0, 0.0
            elif stage in FINAL_STATES:
                # ended early: the time estimate of the lines that ran is not the job's share (a job stopped by its
                # last line had run all of its motion), so at most the share of its lines confirmed
                confirmed = p.lines_acked / p.lines_total if p.lines_total else 0.0
                fraction, eta = min(fraction, confirmed, 0.999), None
            elif done > 0 and elapsed > 0.2:
                rate = done / elapsed  # estimated seconds of job per real second: corrects the estimate
                eta = (total - done) / max(rate, 1e-6)
            else:
                eta = total if total else None
            p = self._progress = dataclasses.replace(
                p, stage=stage, message=p.message if message is None else message, elapsed=elapsed, done=fraction,
                eta=eta, current_line=current_line)
        # at most 10 updates a second, but every change of state
        if report and self.on_progress and (state or now - self._last_report >= 0.1):
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
        self._sent = self._acked = 0

        def on_ack(result) -> None:
            self._acked_streamed = result.index + 1
            # a line answered with an error did not run (in a dry run it was checked: that is the point)
            if self._origin[result.index] >= 0 and (result.status == "ok" or self.dry_run):
                self._acked += 1
            self._update()

        def on_sent(index: int) -> None:
            self._sent = index + 1

        self._start_time = time.monotonic()
        try:
            if self.dry_run:
                return self._dry_run(on_ack)
            self._update("running")
            conn.add_listener(self._watch)
            try:
                conn.stream(self._lines, on_ack=on_ack, on_sent=on_sent, stop=self._stop, timeout=math.inf)
            finally:
                conn.remove_listener(self._watch)
        except StreamStopped as stopped:
            self._stopped_pause = self.pause_line
            self._end_pause()
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
        # ask at once rather than wait for the next poll: a dry run's end is what its user waits for
        status = conn.fresh_status(1.0)
        if status is None or status.state != "Idle":
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
        alarm = conn.alarm if reason == "alarm" else None
        # Leave the machine safe: a reset stops everything and switches the laser off in the controller (after
        # alarms 1 and 2 GRBL waits for it, and after 2 it is unlocked again). After an abort it was sent already.
        recovered = ""
        if not aborted:
            recovered = conn.recover()
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
        if alarm is not None:
            locked = conn.alarm is not None or not recovered
            message = f"job stopped by {alarm}; " + (f"{recovered}; " if recovered else "") + (
                alarm.recovery if locked else alarm.cause)
        return self._finish("stopped", message + where, laser_off=laser_off, resume=resume)

    def _resume_line(self, status) -> int | None:
        """Where to resume a job that ended early (1-based): the line the machine was executing, run again whole.

        The machine's position after the stop (GRBL keeps it through a feed hold, an error's reset and, not
        guaranteed, a reset in motion) finds the segment it stood on, near the line the planner's fill last
        pointed to; without a position, that line itself. None in a dry run (nothing ran).
        """
        if self.dry_run or not self._origin:
            return None
        if self._stopped_pause is not None:
            return self._stopped_pause + 1  # stopped while it waited for a pen: the pause comes again first
        guess = max(self.progress.current_line, self.from_line - 1)  # 0-based job line
        line = guess
        toolpath = self._toolpath
        if status is not None and status.mpos is not None and toolpath is not None and len(toolpath.line):
            # in the work coordinates the job started in: a reset clears a G92 the job set
            wco = self._wco if self._wco is not None else np.array(self.connection.work_offset())
            position = np.array(status.mpos, dtype=float) - wco
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
        wco = self._wco if self._wco is not None else np.array(conn.work_offset())
        position = np.array(status.mpos) - wco  # in the work coordinates the job started in, as the toolpath's
        toolpath = self._toolpath or interpret(self._lines)
        first = stopped.first_unconfirmed if stopped.first_unconfirmed is not None else 0
        sent = self.progress.lines_sent
        candidates = range(min(sent, len(self._lines)) - 1, max(first, 1) - 2, -1)
        for index in candidates:
            state = toolpath.states[index + 1]
            placed = state.position + state.shift
            if state.position_known and np.allclose(placed[:2], position[:2], atol=0.01):
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
        if resume is None and state in RESUMABLE_STATES and self.progress.lines_sent:
            # every ending of a job that ran says where to go on: at least the line the planner's fill pointed to
            resume = self._resume_line(None)
        self._update(state, message)
        self.result = JobResult(
            state=state, message=message, lines_total=len(self.job.lines), lines_acked=self.progress.lines_acked,
            elapsed=self.progress.elapsed, resume_line=resume, errors=errors or [], laser_off=laser_off,
        )
        return self.result
