"""One progress type for every long piece of work: design computations, device jobs and station services.

A long function takes ``progress: ProgressCallback | None`` and calls it with a :class:`Progress` (or a subclass
that adds typed fields of its own, e.g. a GRBL job's lines or a robust run's CV accuracy). It takes
``cancelled: CancelCheck | None`` to be asked, between units of work, whether to stop. :class:`Reporter` bundles
the two so the work itself reads as ``report("grid", i, n, "radii 3/7")``.

Front ends turn it into pictures: the CLI with rich's progress bars (:mod:`station.progress_view`), the TUI with a
Textual ``ProgressBar``. Nothing here prints: a library that writes to stderr would garble a TUI.

Examples
--------
>>> seen = []
>>> report = Reporter(seen.append)
>>> report("build", 1, 4, "machine 1 of 4")
>>> seen[0].fraction
0.25
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass


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
CancelCheck = Callable[[], bool]


class Cancelled(RuntimeError):
    """The work was asked to stop (its cancel check returned True) and stopped between two units of work."""


class Reporter:
    """A progress callback and a cancel check in one, both optional.

    Parameters
    ----------
    callback : ProgressCallback, optional
        Called with each :class:`Progress`; None reports to nobody.
    cancelled : CancelCheck, optional
        Asked by :meth:`check` (and after each report); True makes the work raise :class:`Cancelled`.
    """

    def __init__(self, callback: ProgressCallback | None = None, cancelled: CancelCheck | None = None) -> None:
        self.callback = callback
        self.cancelled = cancelled

    @classmethod
    def of(cls, progress: Reporter | ProgressCallback | None = None,
           cancelled: CancelCheck | None = None) -> Reporter:
        """A reporter from whatever a caller passed: a reporter (kept), a callback, or None."""
        if isinstance(progress, Reporter):
            if cancelled is not None and progress.cancelled is None:
                return cls(progress.callback, cancelled)
            return progress
        return cls(progress, cancelled)

    def __call__(self, stage: str, done: float = 0, total: float | None = None, message: str = "") -> None:
        """Report a plain :class:`Progress`, then honour the cancel check."""
        self.emit(Progress(stage, done, total, message))

    def emit(self, progress: Progress) -> None:
        """Report ``progress`` (any subclass), then honour the cancel check."""
        if self.callback is not None:
            self.callback(progress)
        self.check()

    def check(self) -> None:
        """Raise :class:`Cancelled` if the cancel check says so."""
        if self.cancelled is not None and self.cancelled():
            raise Cancelled("stopped on request")
