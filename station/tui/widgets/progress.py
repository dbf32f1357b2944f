"""The TUI's picture of :class:`~station.services.reporting.Progress`: the stage, a Textual ``ProgressBar``, a message.

Long work runs through :func:`station.tui.work.run_work`, whose reporter posts each progress to the screen as a
:class:`~station.tui.messages.ProgressReported`; the screen's handler gives it to its :class:`ProgressPanel`::

    def on_progress_reported(self, message: ProgressReported) -> None:
        self.query_one(ProgressPanel).show(message.progress)
"""

from __future__ import annotations

from collections.abc import Callable

from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Vertical
from textual.widgets import ProgressBar, Static

from station.services.reporting import Progress


class ProgressPanel(Vertical):
    """The stage in bold, a bar (indeterminate while the total is unknown) and a message line.

    Parameters
    ----------
    idle : str
        The message before any progress (e.g. what starts the work).
    describe : callable, optional
        ``describe(progress) -> str | Text``, the message line of a progress; default: its ``message``. A robust run
        adds its CV accuracy and best PSP, for example.
    total : float or None
        The bar's total before any progress (an empty bar; None would animate an indeterminate one while idle).
    """

    DEFAULT_CSS = """
    ProgressPanel { height: auto; }
    ProgressPanel .progress-stage { text-style: bold; }
    ProgressPanel ProgressBar { width: 100%; }
    ProgressPanel ProgressBar Bar { width: 1fr; }
    """

    def __init__(self, idle: str = "", describe: Callable[[Progress], str | Text] | None = None,
                 total: float | None = 100, *, id: str | None = None, classes: str | None = None) -> None:
        super().__init__(id=id, classes=classes)
        self._idle = idle
        self._describe = describe or (lambda progress: progress.message)
        self.stage = ""
        self.bar = ProgressBar(total=total, show_eta=False)
        self._stage_line = Static("", classes="progress-stage")
        self._message_line = Static(Text(idle), classes="progress-message")

    def compose(self) -> ComposeResult:
        yield self._stage_line
        yield self.bar
        yield self._message_line

    def show(self, progress: Progress) -> None:
        """Show ``progress``: its stage, ``done`` of ``total`` on the bar, and its message."""
        self.stage = progress.stage
        self._stage_line.update(Text(progress.stage))
        self.bar.update(total=progress.total, progress=progress.done)
        message = self._describe(progress)
        self._message_line.update(message if isinstance(message, Text) else Text(message))

    def start(self, total: float | None, message: str = "") -> None:
        """A new run of ``total`` units: an empty bar, no stage yet."""
        self.stage = ""
        self._stage_line.update("")
        self.bar.update(total=total, progress=0)
        self._message_line.update(Text(message))

    def say(self, message: str | Text) -> None:
        """Replace the message line (e.g. a summary once the work has ended)."""
        self._message_line.update(message if isinstance(message, Text) else Text(message))

    @property
    def message(self) -> str:
        """The message line's text."""
        return str(self._message_line.render())
