"""What a GRBL job is, what it reports while it runs and how it ends: :class:`Job`, :class:`JobProgress`,
:class:`JobResult`; and :func:`frame_lines`, the job that traces another's bounding box."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from common.progress import Progress
from drivers.errors import JobRefused
from drivers.gcode import Toolpath, interpret

__all__ = ["FINAL_STATES", "Job", "JobProgress", "JobResult", "frame_lines"]


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

_UNSET = object()


@dataclass(frozen=True, init=False)
class JobProgress(Progress):
    """A snapshot of a running job, a :class:`common.progress.Progress` so every front end can draw it.

    ``state`` is the stage (``idle``, ``preflight``, ``running``, ``holding``, ``dry-run`` or one of
    :data:`FINAL_STATES`) and ``fraction`` the share of the job done (``done`` of a ``total`` of 1): read-only aliases
    of ``stage`` and ``done``. The constructor keeps its positional order ``(state, lines_total, lines_sent,
    lines_acked, fraction, elapsed, eta, message, current_line)``; it also takes ``stage``/``done``/``total`` by
    keyword, as :func:`dataclasses.replace` passes them.

    ``lines_acked`` counts the job's lines GRBL answered with ``ok`` (in a dry run, every answered line: each one
    was checked); ``eta`` is None once the job ended; ``current_line`` is the 0-based job line the machine is
    (about) executing: acknowledged minus planned.
    """

    lines_total: int = 0
    lines_sent: int = 0
    lines_acked: int = 0
    elapsed: float = 0.0
    eta: float | None = None
    current_line: int = 0

    def __init__(self, state: str = "idle", lines_total: int = 0, lines_sent: int = 0, lines_acked: int = 0,
                 fraction: float = 0.0, elapsed: float = 0.0, eta: float | None = None, message: str = "",
                 current_line: int = 0, *, stage: object = _UNSET, done: object = _UNSET,
                 total: float | None = 1.0) -> None:
        if stage is not _UNSET:
            state = stage
        if done is not _UNSET:
            fraction = done
        if total != 1.0:
            raise ValueError(f"JobProgress counts the job's share done: total must be 1, got {total!r}")
        # Frozen: fields are set through object.__setattr__, as dataclasses do in their own __init__.
        for name, value in (("stage", state), ("done", fraction), ("total", 1.0), ("message", message),
                            ("lines_total", lines_total), ("lines_sent", lines_sent), ("lines_acked", lines_acked),
                            ("elapsed", elapsed), ("eta", eta), ("current_line", current_line)):
            object.__setattr__(self, name, value)

    @property
    def state(self) -> str:
        """Alias of ``stage``."""
        return self.stage

    @property
    def fraction(self) -> float:
        """Alias of ``done``: the share of the job done, 0..1 (1 only once the job is done)."""
        return self.done


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
