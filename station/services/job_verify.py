"""A job run on the GRBL twin at virtual time before it is sent: its time as the firmware's planner runs it, a record
that the laser is dark on every travel, and that it stays within the machine's travel.

Used by ``station send --verify`` and the Machines screen's preview. The job goes through the station's own
streamer and pre-flight to a simulated GRBL (:mod:`drivers.sim.grbl`) on a virtual clock (``clock=virtual``, no
wire time), set up as the machine it is meant for: the profile's twin, with the machine's own settings (``$$``)
and work offset when the station is connected to it. What the twin executed (every planner block, where it started
and ended, the laser's power, whether it started from rest) gives:

- the time estimate of GRBL's planner (:func:`drivers.grbl.planner.plan_times`: acceleration, junction speeds,
  its 15-block look-ahead) plus the dwells, next to the same planner on the job's G-code as the streamer reads it
  before it runs (its ETA: :func:`drivers.grbl.planner.line_seconds`);
- the travels (rapid blocks) on which the laser was not dark (a machine with ``$32=0`` fires on a ``G0``);
- the job's machine-space extent against the travel, and any alarm the twin raised.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from common.progress import Progress, Reporter
from drivers.gcode import GcodeError, interpret
from drivers.grbl import GrblConnection, Job, JobRunner
from drivers.grbl.planner import MotionBlock, line_seconds, plan_times
from drivers.profiles import MachineProfile
from station.errors import ServiceError, station_errors

__all__ = ["JobVerification", "twin_url", "verify_job", "verify_summary"]

_RUNS = itertools.count(1)


@station_errors
@dataclass(frozen=True)
class JobVerification:
    """What the twin found. Times in seconds, lengths in mm, extents in machine mm ``[x, y, z]``."""

    name: str
    state: str  # the twin's job result: done, refused, stopped ...
    message: str
    estimate_s: float  # GRBL's planner on the executed blocks, plus dwells
    preflight_s: float  # the same planner on the G-code as read before it runs (the streamer's ETA)
    twin_clock_s: float  # the twin's own clock (one speed per block)
    blocks: int
    from_rest: int  # blocks the planner started from rest (syncs: dwells, spindle changes)
    burn_mm: float  # laser on (or pen down on a plotter: spindle power > 0 on feed moves)
    travel_mm: float
    lit_travels: tuple[tuple[int, str], ...] = ()  # (twin line number, block) of rapids with the laser on
    laser: bool = False
    extent_lo: tuple[float, ...] | None = None
    extent_hi: tuple[float, ...] | None = None
    bounds_lo: tuple[float, ...] | None = None
    bounds_hi: tuple[float, ...] | None = None
    homing: bool = True
    within_travel: bool = True
    alarms: tuple[int, ...] = ()
    outline: tuple[tuple[tuple[float, float], ...], ...] = field(default=(), compare=False)
    block_seconds: tuple[float, ...] = field(default=(), compare=False)  # per executed block, GRBL's planner

    @property
    def ok(self) -> bool:
        return self.state == "done" and not self.lit_travels and self.within_travel and not self.alarms

    def to_dict(self) -> dict:
        return {
            "job": self.name, "state": self.state, "message": self.message, "ok": self.ok,
            "estimate_s": self.estimate_s, "preflight_s": self.preflight_s, "twin_clock_s": self.twin_clock_s,
            "blocks": self.blocks, "from_rest": self.from_rest, "burn_mm": self.burn_mm,
            "travel_mm": self.travel_mm, "laser": self.laser,
            "lit_travels": [{"line": n, "block": text} for n, text in self.lit_travels],
            "extent_lo": self.extent_lo, "extent_hi": self.extent_hi, "bounds_lo": self.bounds_lo,
            "bounds_hi": self.bounds_hi, "homing": self.homing, "within_travel": self.within_travel,
            "alarms": list(self.alarms),
        }


@station_errors
def twin_url(profile: MachineProfile | None, laser: bool, settings: Mapping[int, float] | None = None,
             name: str | None = None) -> str:
    """The twin of the machine: the built-in profile of its kind, the machine's settings over it."""
    kind = profile.kind if profile is not None else ("laser" if laser else "plotter")
    query = [f"profile={kind}", "clock=virtual", "wire=0", "time_scale=1",
             f"name={name or f'verify-{os.getpid()}-{next(_RUNS)}'}"]
    for key, value in sorted((settings or {}).items()):
        if isinstance(key, int) and 0 <= key <= 132 and np.isfinite(value):
            query.append(f"s{key}={float(value):g}")
    if settings and 22 in settings:
        query.append(f"homing={int(settings[22])}")
    return "sim://grbl?" + "&".join(query)


@station_errors
def verify_job(lines: Sequence[str], *, name: str = "job", profile: MachineProfile | None = None,
               laser: bool | None = None, settings: Mapping[int, float] | None = None,
               work_offset: Sequence[float] | None = None,
               report: Reporter | None = None) -> JobVerification:
    """Run ``lines`` on the twin at virtual time and say what it did (module docstring).

    ``settings`` (``$N`` -> value) and ``work_offset`` (machine mm) are the real machine's, when known; without
    them the twin is the profile's machine as the station's simulated devices are.

    Raises
    ------
    ServiceError
        A job with no G-code lines, or a line the G-code reader cannot read (naming it).
    """
    from drivers.sim.protocol_sim import machine_named

    lines = list(lines)
    laser = bool(laser) if laser is not None else bool(profile is not None and profile.is_laser)
    try:
        toolpath = interpret(lines)
    except GcodeError as error:
        raise ServiceError(f"job {name!r}: {error}", field="job", value=name) from None
    if len(toolpath.start) == 0:
        raise ServiceError(f"job {name!r}: no motion to verify", field="job", value=name)
    pen_up = tuple(profile.pen.up_commands()) if profile is not None and profile.pen else ("M5",)
    twin_name = f"verify-{os.getpid()}-{next(_RUNS)}"
    url = twin_url(profile, laser, settings, twin_name)
    conn = GrblConnection(url, poll_interval=0.05).open()
    try:
        machine = conn.port.machine
        if work_offset is not None:
            x, y, z = (float(v) for v in work_offset)
            conn.command(f"G10 L2 P1 X{x:.4f} Y{y:.4f} Z{z:.4f}")
            conn.refresh()
        before = len(machine.snapshot().executed)
        start_time = machine.clock.now()

        reporter = Reporter.of(report)

        def lines_done(job_progress) -> None:  # on the job's thread: told, never stopped there
            reporter.tell(Progress("verify", job_progress.fraction, 1.0,
                                   f"twin: {job_progress.lines_acked}/{job_progress.lines_total} lines"))

        job = Job(name, lines, laser=laser, pen_up=pen_up)
        result = JobRunner(conn, job, on_progress=lines_done).run()
        record = machine.snapshot()
        twin_clock = machine.clock.now() - start_time
        bounds = tuple(np.array(b, dtype=float) for b in conn.machine_bounds())
        homing = bool(int(machine.settings[22]))
        twin_settings = dict(machine.settings)
    finally:
        conn.close()
        if machine_named(twin_name) is not None:
            machine_named(twin_name).stop()
    executed = [b for b in record.executed[before:] if not b.jog]
    blocks = [MotionBlock(b.start, b.end, b.rapid, b.feed, b.from_rest) for b in executed]
    planned = plan_times(blocks, twin_settings)
    starts = np.array([b.start for b in executed]) if executed else np.zeros((0, 3))
    ends = np.array([b.end for b in executed]) if executed else np.zeros((0, 3))
    lengths = np.linalg.norm(ends - starts, axis=1) if executed else np.zeros(0)
    rapid = np.array([b.rapid for b in executed], dtype=bool)
    power = np.array([b.power for b in executed], dtype=float)
    # a laser machine's travels must be dark, whatever the job says it is (a job sent without --laser to a
    # machine whose laser mode is off fires on every G0)
    laser_machine = laser or (profile is not None and profile.is_laser)
    lit = tuple((b.line_no, b.text) for b in executed if b.rapid and b.power > 0) if laser_machine else ()
    extent_lo = extent_hi = None
    within = not any(a == 2 for a in record.alarms)
    if executed:
        points = np.concatenate([starts, ends])
        lo, hi = points.min(axis=0), points.max(axis=0)
        extent_lo, extent_hi = tuple(map(float, lo)), tuple(map(float, hi))
        if homing:
            moved = hi - lo > 1e-9
            moved[:2] = True
            within = within and bool(np.all(~moved | ((lo >= bounds[0] - 1e-3) & (hi <= bounds[1] + 1e-3))))
        else:
            travel = np.array([twin_settings[130], twin_settings[131], twin_settings[132]])
            within = within and bool(np.all((travel <= 0) | (hi - lo <= travel + 1e-3)))
    if result.state == "refused" and "travel" in result.message:
        within = False
    outline = _outline(executed)
    return JobVerification(
        name=name, state=result.state, message=result.message,
        estimate_s=planned.total + float(toolpath.dwell.sum()),
        preflight_s=float(line_seconds(toolpath, lines, twin_settings, laser_mode=bool(twin_settings.get(32))).sum()),
        twin_clock_s=float(twin_clock),
        blocks=len(executed), from_rest=sum(1 for b in executed if b.from_rest),
        burn_mm=float(lengths[~rapid & (power > 0)].sum()) if executed else 0.0,
        travel_mm=float(lengths[rapid].sum()) if executed else 0.0, lit_travels=lit, laser=laser_machine,
        extent_lo=extent_lo, extent_hi=extent_hi, bounds_lo=tuple(map(float, bounds[0])),
        bounds_hi=tuple(map(float, bounds[1])), homing=homing, within_travel=within,
        alarms=tuple(record.alarms), outline=outline, block_seconds=tuple(map(float, planned.seconds)))


def _outline(executed) -> tuple:
    """The burned (or drawn) polylines in machine XY, for a preview."""
    paths: list[list[tuple[float, float]]] = []
    current: list[tuple[float, float]] = []
    for block in executed:
        if block.rapid or block.power <= 0:
            if len(current) > 1:
                paths.append(current)
            current = []
            continue
        if not current:
            current = [(block.start[0], block.start[1])]
        current.append((block.end[0], block.end[1]))
    if len(current) > 1:
        paths.append(current)
    return tuple(tuple(p) for p in paths)


def _duration(seconds: float) -> str:
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


@station_errors
def verify_summary(done: JobVerification) -> list[str]:
    """The verification in a few lines for a person."""
    if done.blocks == 0 and done.state != "done":
        return [f"verify {done.name}: {done.state} on the twin: {done.message}"]
    lines = [f"verify {done.name}: {done.state} on the twin; about {_duration(done.estimate_s)} with acceleration "
             f"(GRBL's planner on the blocks the twin ran; {_duration(done.preflight_s)} read from the G-code), "
             f"{done.blocks} blocks, "
             f"{done.from_rest} from rest"]
    what = "laser on" if done.laser else "drawing"
    lines.append(f"  {done.burn_mm:.0f} mm {what}, {done.travel_mm:.0f} mm of travel")
    if done.laser:
        if done.lit_travels:
            number, text = done.lit_travels[0]
            lines.append(f"  NOT dark on {len(done.lit_travels)} travel(s): the first is line {number} ({text}); "
                         "the machine is not in laser mode ($32=0) or the job turns the laser on for travels")
        else:
            lines.append("  laser dark on every travel")
    if done.extent_lo is not None:
        lo, hi = done.extent_lo, done.extent_hi
        where = (f"machine X {lo[0]:.1f}..{hi[0]:.1f}, Y {lo[1]:.1f}..{hi[1]:.1f}")
        if done.homing:
            space = (f"travel X {done.bounds_lo[0]:.1f}..{done.bounds_hi[0]:.1f}, "
                     f"Y {done.bounds_lo[1]:.1f}..{done.bounds_hi[1]:.1f}")
        else:
            space = "no homing: its span against $130-$132"
        lines.append(f"  {'within' if done.within_travel else 'OUTSIDE'} the machine's travel ({where}; {space})")
    elif not done.within_travel:
        lines.append("  OUTSIDE the machine's travel")
    if done.state != "done":
        lines.append(f"  {done.message}")
    if done.alarms:
        lines.append(f"  the twin raised ALARM:{', ALARM:'.join(map(str, done.alarms))}")
    return lines
