"""The question ctrl+q asks while a machine job runs: abort it (laser off) and quit, or keep it running.

Quitting without asking would close the connection under the job: the machine would stop wherever it was and the
job history show it ``interrupted``. Not an area (no ``SCREEN``): the app pushes it over whatever screen is shown.
"""

from __future__ import annotations

from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import ModalScreen
from textual.widgets import Button, Static

#: The answers :class:`ConfirmQuitScreen` dismisses with.
KEEP, ABORT_AND_QUIT = "keep", "abort-and-quit"


class ConfirmQuitScreen(ModalScreen[str]):
    """Ask before quitting while ``title`` runs on ``device``; dismissed with :data:`KEEP` or :data:`ABORT_AND_QUIT`.

    Parameters
    ----------
    title : str
        The running job's title.
    device : str
        The device it runs on.
    state : str
        What the job is doing (``running``, ``framing``, ``checking``).
    laser : bool
        The job drives a laser (said in the question: quitting switches it off).
    """

    DEFAULT_CSS = """
    ConfirmQuitScreen { align: center middle; }
    ConfirmQuitScreen #dialog { width: 72; height: auto; border: thick $error; background: $surface; padding: 1 2; }
    ConfirmQuitScreen #buttons { height: auto; margin-top: 1; }
    ConfirmQuitScreen Button { width: 1fr; margin: 0 1; }
    """

    # Keep running is the safe answer: Escape, k and Enter on the focused button give it.
    BINDINGS = [
        Binding("k,escape", "answer('keep')", "Keep running"),
        Binding("a", "answer('abort-and-quit')", "Abort the job and quit"),
    ]

    def __init__(self, title: str, device: str, state: str, *, laser: bool = False) -> None:
        super().__init__()
        self.job_title, self.device, self.state, self.laser = title, device, state, laser

    def compose(self) -> ComposeResult:
        off = " and the laser is switched off" if self.laser else ""
        question = Text.assemble(
            (f"A job is {self.state} on {self.device}: ", "bold"), (repr(self.job_title), "bold"),
            f"\n\nQuitting now aborts it: the machine stops at once (soft reset){off}. "
            "Keep it running (ctrl+q again once it is done), or abort it and quit.",
        )
        with Vertical(id="dialog"):
            yield Static(question, id="question")
            with Horizontal(id="buttons"):
                yield Button("Keep running (k)", id="keep", variant="primary")
                yield Button("Abort and quit (a)", id="abort", variant="error")

    def on_mount(self) -> None:
        self.query_one("#keep", Button).focus()

    @on(Button.Pressed, "#keep")
    def _keep(self) -> None:
        self.dismiss(KEEP)

    @on(Button.Pressed, "#abort")
    def _abort(self) -> None:
        self.dismiss(ABORT_AND_QUIT)

    def action_answer(self, answer: str) -> None:
        self.dismiss(answer)
