"""Pre-flight checks of a GRBL job, before any byte of it is sent: line lengths, the machine's travel, and whether
the job looks written for the kind of machine it is sent to.

With homing (``$22=1``) every point of the job (work coordinates + the current work offset, from where the head
stands) must lie in the machine space GRBL's soft limits use (-travel..0 per axis, or 0..+travel for an axis whose
``$23`` bit is set when GRBL was built with HOMING_FORCE_SET_ORIGIN, ``Z`` in ``[OPT:]``). Without homing, machine
zero is wherever the head stood at power-up: the job's own size on each axis must fit the travel (``$130``-``$132``),
and so must the way from where the head stands to the job; the refusal says by how much ("this job is 300.0 mm
wide; your machine travels 200.0 mm in X").

Both checks see the job where it runs: a job that moves its work coordinates (``G92``, ``G10 L2``/``L20``,
``G54``-``G59``, ``G43.1``) has the moves after that placed by the offsets (GRBL's ``$#`` and ``$G``, read before the
job), and a refusal names the line that moved them. A job that sets an offset where the head's position cannot be
known (after a ``G38`` probe, or a ``G28`` whose stored position is not known) is refused: nobody can tell where the
rest of it runs.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from drivers.errors import JobRefused
from drivers.gcode import GcodeError, Toolpath, clean_line, tokenize
from drivers.grbl.connection import GrblConnection
from drivers.grbl.job_types import Job

__all__ = ["LINE_BUFFER_SIZE", "SPAN_WORDS", "check_line_lengths", "check_machine_space", "check_placed",
           "check_span", "offset_note", "commanded_extent", "job_kind", "kind_warning"]

#: GRBL's line buffer (LINE_BUFFER_SIZE): a block has at most 79 characters after comments and spaces are removed.
LINE_BUFFER_SIZE = 80


def check_line_lengths(job: Job, rx_size: int) -> None:
    """Every line of ``job`` fits GRBL's line buffer and its serial RX buffer (``rx_size`` bytes, from ``$I``); else
    :class:`JobRefused` naming the first line that does not."""
    for number, raw in enumerate(job.lines, start=1):
        length = len(clean_line(raw))
        if length >= LINE_BUFFER_SIZE or length + 1 > rx_size - 1:
            raise JobRefused(f"job {job.name!r}: line {number} has {length} characters; GRBL takes at most "
                             f"{LINE_BUFFER_SIZE - 1} (error:11 otherwise)")


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


def _job_line(origin: Sequence[int] | None, index: int) -> int | None:
    """The 1-based job line of streamed line ``index`` (None for a line the runner added)."""
    if origin is None:
        return index + 1
    return origin[index] + 1 if 0 <= index < len(origin) and origin[index] >= 0 else None


def offset_note(toolpath: Toolpath, lines: Sequence[str], origin: Sequence[int] | None = None) -> str:
    """``"line 3 (G92X-100) moves the job's work coordinates"``: where a job moves its work coordinates, for a
    refusal (``""`` when it never does)."""
    moved = [index for index in toolpath.offset_lines() if _job_line(origin, index) is not None]
    if not moved:
        return ""
    index = moved[0]
    more = f" and {len(moved) - 1} more line(s)" if len(moved) > 1 else ""
    return f"line {_job_line(origin, index)} ({clean_line(lines[index])}){more} moves the job's work coordinates"


def check_placed(name: str, toolpath: Toolpath, origin: Sequence[int] | None = None) -> None:
    """Every move of the job runs where the interpreter can tell: else :class:`JobRefused` naming the line that set
    a work offset where the head's position was not known (after a probe or a go-home to an unknown place)."""
    index = toolpath.unplaced_line()
    if index is None:
        return
    setting = next((i for i in toolpath.offset_lines() if not toolpath.states[i + 1].frame_known), index)
    where = _job_line(origin, setting)
    raise JobRefused(f"job {name!r}: line {where} sets a work offset where the head's position is not known (after "
                     "a G38 probe or a G28/G30 to an unknown place), so the pre-flight cannot tell where the moves "
                     "after it run; set the offset before that move, or with G10 L2 (absolute)")


def check_machine_space(name: str, conn: GrblConnection, lo: np.ndarray, hi: np.ndarray, wco: np.ndarray,
                        note: str = "") -> None:
    """A homed machine: every point of the job (``lo``..``hi`` in work mm, in the work coordinates the job starts
    in, plus the work offset ``wco`` it starts with) inside the machine space GRBL's soft limits use; else
    :class:`JobRefused` naming each axis that leaves it; ``note`` (:func:`offset_note`) says where the job moved
    its work coordinates."""
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
        raise JobRefused(f"job {name!r} leaves the machine's travel ($130-$132 with work offset "
                         f"{', '.join(f'{v:.2f}' for v in wco)}{'; ' + note if note else ''}): "
                         + "; ".join(bad) + ". Set work zero where the job should start (jog there, then "
                         "G10 L20 P1 X0 Y0), after homing ($H) if the machine has not homed since it was switched on")


def check_span(name: str, conn: GrblConnection, toolpath: Toolpath, lo: np.ndarray, hi: np.ndarray,
               note: str = "") -> None:
    """A machine without homing: machine zero is wherever the head stood at power-up, so machine coordinates
    say nothing about the machine's ends. What is known: the job's own size on each axis, and the way from
    where the head stands to the job, must each fit the travel ($130-$132)."""
    travel = np.array(conn.travel, dtype=float)
    own_lo, own_hi = commanded_extent(toolpath)
    named = np.isfinite(own_lo)  # the axes the job moves on its own
    too_big = [
        f"this job is {own_hi[i] - own_lo[i]:.1f} mm {SPAN_WORDS[i]}; your machine travels {travel[i]:.1f} mm "
        f"in {'XYZ'[i]} (${130 + i})"
        for i in _longer_than_travel(own_hi - own_lo, travel, named)
    ]
    if too_big:
        raise JobRefused(f"job {name!r} does not fit the machine{f' ({note})' if note else ''}: "
                         + "; ".join(too_big)
                         + ". Scale the job down (station plot --size), or check $130-$132 if the machine "
                         "travels further")
    start = toolpath.start[0]  # where the head stands (the first segment leaves from there)
    too_far = [
        f"the head stands at {'XYZ'[i]} {start[i]:.1f} and the job goes to {'XYZ'[i]} {own_lo[i]:.1f}.."
        f"{own_hi[i]:.1f}: {hi[i] - lo[i]:.1f} mm of travel, more than the {travel[i]:.1f} mm your machine has"
        for i in _longer_than_travel(hi - lo, travel, named)
    ]
    if too_far:
        raise JobRefused(f"job {name!r} cannot run from where the head stands (no homing: the job runs "
                         f"relative to work zero{'; ' + note if note else ''}): " + "; ".join(too_far)
                         + ". Jog the head to where the job should start, set work zero there (G10 L20 P1 X0 Y0) "
                         "and send the frame first")


def _longer_than_travel(spans: np.ndarray, travel: np.ndarray, named: np.ndarray) -> list[int]:
    """The axes (0, 1, 2) among ``named`` whose span (mm) is longer than a configured travel (``$13x`` > 0)."""
    return [i for i in range(3) if travel[i] > 0 and named[i] and spans[i] > travel[i] + 1e-3]


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
