"""Progress of long work on the command line: rich's progress bars on a terminal, plain lines anywhere else.

Every long command shows :class:`common.progress.Progress` through :class:`ProgressView`. On a terminal one bar per
stage is redrawn in place (rich, which comes with Textual); in a log file, a pipe or CI a line is written when a
stage starts and each time it passes another tenth, so a log reads as lines, never as carriage returns.
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable
from typing import TextIO

from common.progress import Progress

Describe = Callable[[Progress], str]


def default_describe(progress: Progress) -> str:
    """``stage: done/total  message`` (the counts left out when there is no total)."""
    counts = ""
    if progress.total:
        counts = f" {progress.done:g}/{progress.total:g}"
    text = f"{progress.stage}:{counts}"
    return f"{text}  {progress.message}" if progress.message else text


class ProgressView:
    """A progress callback that draws what it is given.

    Parameters
    ----------
    stream : text stream, optional
        Where to draw (default ``sys.stderr``).
    describe : callable, optional
        ``describe(progress) -> str``, the text beside the bar and of each plain line.
    prefix : str
        Put before each plain line (e.g. ``"send: "``).
    tty : bool, optional
        Force the terminal (True) or plain-line (False) form; default: whether ``stream`` is a terminal.
    quiet_stages : collection of str
        Stages never written as plain lines (a refusal says why in a line of its own).

    Use it as a context manager, so the bars end cleanly when the work ends or fails.
    """

    def __init__(self, stream: TextIO | None = None, describe: Describe = default_describe, prefix: str = "",
                 tty: bool | None = None, quiet_stages: tuple[str, ...] = ()) -> None:
        self.stream = stream or sys.stderr
        self.describe = describe
        self.prefix = prefix
        if tty is None:
            isatty = getattr(self.stream, "isatty", None)
            tty = bool(isatty and isatty())
        self.tty = tty
        self.quiet_stages = frozenset(quiet_stages)
        self._lock = threading.Lock()
        self._stage: str | None = None
        self._tenth = -1
        self._rich = None
        self._task = None

    # -- terminal: rich ----------------------------------------------------------------------------------------
    def _start_rich(self) -> None:
        from rich.console import Console
        from rich.progress import BarColumn, TextColumn, TimeElapsedColumn
        from rich.progress import Progress as RichProgress

        console = Console(file=self.stream, force_terminal=True, highlight=False)
        self._rich = RichProgress(BarColumn(bar_width=30), TextColumn("{task.description}"), TimeElapsedColumn(),
                                  console=console, transient=False, refresh_per_second=10)
        self._rich.start()

    def _draw(self, progress: Progress) -> None:
        if self._rich is None:
            self._start_rich()
        text = self.describe(progress)
        if progress.stage != self._stage or self._task is None:
            if self._task is not None:
                self._rich.stop_task(self._task)
            self._task = self._rich.add_task(text, total=progress.total)
            self._stage = progress.stage
        self._rich.update(self._task, description=text, completed=progress.done, total=progress.total)

    # -- elsewhere: plain lines --------------------------------------------------------------------------------
    def _line(self, progress: Progress) -> None:
        if progress.stage in self.quiet_stages:
            return
        fraction = progress.fraction
        tenth = -1 if fraction is None else int(fraction * 10)
        if progress.stage == self._stage and tenth <= self._tenth:
            return
        if progress.stage != self._stage:
            self._tenth = -1
        self._stage = progress.stage
        self._tenth = max(self._tenth, tenth)
        self.stream.write(f"{self.prefix}{self.describe(progress)}\n")
        self.stream.flush()

    def __call__(self, progress: Progress) -> None:
        with self._lock:
            if self.tty:
                self._draw(progress)
            else:
                self._line(progress)

    def note(self, text: str) -> None:
        """A line of its own (above the bars on a terminal)."""
        with self._lock:
            if self._rich is not None:
                self._rich.console.print(text, markup=False)
            else:
                self.stream.write(text + "\n")
                self.stream.flush()

    def close(self, clear: bool = False) -> None:
        """End the bars (``clear``: remove them, e.g. before a refusal's one line)."""
        with self._lock:
            if self._rich is not None:
                if clear:  # the live display's own flag: rich's Progress only passes its own to it when made
                    self._rich.live.transient = True
                self._rich.stop()
                self._rich = None
                self._task = None

    def __enter__(self) -> ProgressView:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
