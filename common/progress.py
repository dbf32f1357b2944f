"""One progress type and one way to report and cancel, for every long piece of work: design computations, device
jobs and station services.

A long function takes one keyword, ``report: Reporter | None = None``, and starts with
``report = Reporter.of(report)``. It tells how it goes with ``report("grid", i, n, "radii 3/7")`` (or
``report.emit(...)`` with a subclass of :class:`Progress` that adds typed fields of its own, e.g. a GRBL job's
lines or a robust run's CV accuracy), and at each safe point between units of work ``report.check()``; both raise
:class:`Cancelled` once the reporter's stop check says so. Without a reporter the work reports to nobody and runs
to its end.

Front ends make the reporter: the CLI with rich's progress bars (:mod:`station.progress_view`) and a stop on Ctrl-C,
the TUI with a Textual ``ProgressBar`` and a Stop button. Nothing here prints: a library that writes to stderr would
garble a TUI.

Examples
--------
>>> seen = []
>>> report = Reporter(seen.append)
>>> report("build", 1, 4, "machine 1 of 4")
>>> seen[0].fraction
0.25
>>> stopping = Reporter(stop=lambda: True)
>>> try:
...     stopping("build", 2, 4)
... except Cancelled as stop:
...     print(stop)
stopped on request
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any


@dataclass(frozen=True)
class Progress:
    """A snapshot of long work.

    Parameters
    ----------
    stage : str
        What is being done, a short word or two ("grid", "optimize", "streaming"); a new stage starts a new bar.
    done : float
        Units of the stage done so far.
    total : float or None
        Units the stage will take, or None when unknown (an indeterminate bar).
    message : str
        One line for a person ("Cycloid Drawing Machine: grid 3/7 radii"); may be empty.
    """

    stage: str
    done: float = 0
    total: float | None = None
    message: str = ""

    @property
    def fraction(self) -> float | None:
        """``done / total`` clipped to [0, 1], or None when the total is unknown or zero."""
        if not self.total:
            return None
        return min(1.0, max(0.0, self.done / self.total))


ProgressCallback = Callable[[Progress], None]


class Cancelled(RuntimeError):
    """The work was asked to stop and stopped between two units of work.

    The one stop exception of the whole tree. It is a RuntimeError so that a caller that only guards against
    failures still sees a stop as the work not finishing.

    Parameters
    ----------
    message : str
        What stopped and what was kept, for a person.
    new_simulations : int
        Simulations the stopped work made; they are kept in ``cache`` (0 for work that simulates nothing).
    cache : Path, optional
        The simulation cache that keeps them.
    partial : object, optional
        What the work had done when it stopped, when it can hand that back (a loop run's log).
    """

    def __init__(self, message: str = "stopped on request", *, new_simulations: int = 0,
                 cache: Path | None = None, partial: Any = None) -> None:
        super().__init__(message)
        self.new_simulations = new_simulations
        self.cache = cache
        self.partial = partial


def _no_stop() -> bool:
    return False


class Reporter:
    """Where long work says how it goes, and asks whether to stop.

    Parameters
    ----------
    callback : ProgressCallback, optional
        Called with each :class:`Progress`; None reports to nobody.
    stop : callable, optional
        ``stop()`` True asks the work to stop: :meth:`check` (and every report) then raises :class:`Cancelled`.
        None never stops.
    """

    def __init__(self, callback: ProgressCallback | None = None, *, stop: Callable[[], bool] | None = None) -> None:
        self.callback = callback
        self._stop = stop if stop is not None else _no_stop  # private: `report.stop()` would read as an order

    @classmethod
    def of(cls, report: Reporter | ProgressCallback | None) -> Reporter:
        """The reporter a function was given: itself; None: one that reports to nobody and never stops; a bare
        progress callback: a reporter on it that never stops."""
        if isinstance(report, Reporter):
            return report
        if report is not None and not callable(report):
            raise TypeError(f"report must be a Reporter, a progress callback or None, got {type(report).__name__}")
        return cls(report)

    @property
    def stopping(self) -> bool:
        """Whether a stop was asked for (without raising: for work that must tidy up before it stops)."""
        return bool(self._stop())

    def __call__(self, stage: str, done: float = 0, total: float | None = None, message: str = "") -> None:
        """Report a plain :class:`Progress`, then honour a stop."""
        self.emit(Progress(stage, done, total, message))

    def emit(self, progress: Progress) -> None:
        """Report ``progress`` (any subclass), then honour a stop."""
        if self.callback is not None:
            self.callback(progress)
        self.check()

    def tell(self, progress: Progress) -> None:
        """Report ``progress`` without asking to stop: for a callback that runs where raising would lose work (a
        worker's result arriving) or on a thread that is not the work's."""
        if self.callback is not None:
            self.callback(progress)

    def check(self) -> None:
        """Raise :class:`Cancelled` if a stop was asked for."""
        if self._stop():
            raise Cancelled("stopped on request")

    def mapped(self, change: Callable[[Progress], Progress]) -> Reporter:
        """A reporter with this one's stop whose progress reaches this one's callback through ``change`` (work
        called by other work, its progress said in the caller's words)."""
        callback = self.callback
        return Reporter(None if callback is None else (lambda progress: callback(change(progress))), stop=self._stop)
