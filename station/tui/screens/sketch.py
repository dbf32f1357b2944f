"""Sketch retrieval screen (thesis 3.4): draw a rough pattern, get matching drawing-machine designs.

Draw strokes on the pad with the mouse (press, drag, release; a few strokes with gaps are fine). Set the symmetry
order to draw one sector only: the strokes are copied around the pad's centre (construction lines show the
sectors). f (or the Find button) searches every machine in a worker thread (the first search builds the candidate
databases, about half a minute, then they are cached); the ranked candidates appear as small previews. Click a
preview or press 1-5 to open that design on the Drawing machines screen. u undoes the last stroke, c clears.
"""

from __future__ import annotations

import numpy as np
from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.screen import Screen
from textual.widgets import Button, Footer, Header, Input, Label, ProgressBar, Static

from station.errors import USER_ERRORS
from station.services.reporting import Progress, Reporter
from station.services.sketch import RetrieveOptions, candidate_curve, retrieve, sketch_from_strokes
from station.services.sketch import make_retriever as retriever_service
from station.tui.messages import CandidatesFound, ProgressReported
from station.tui.registry import ScreenEntry
from station.tui.widgets.canvas import PatternCanvas
from station.tui.widgets.sketch_pad import SketchPad
from station.tui.work import run_work

#: Candidates shown.
TOP = 5


def make_retriever(report: Reporter):
    """The retriever the screen uses (every machine, databases cached in the station's cache directory).

    ``report`` is told how a database build goes, and stops it between its steps.
    """
    return retriever_service(report=report)


class CandidatePreview(Vertical):
    """One ranked candidate: a label and a small drawing; a click opens it."""

    DEFAULT_CSS = """
    CandidatePreview { height: 11; border: round $primary-darken-3; padding: 0 1; }
    CandidatePreview:hover { border: round $accent; }
    CandidatePreview PatternCanvas { height: 8; min-height: 4; }
    CandidatePreview Label { height: 1; }
    """

    def __init__(self, rank: int, candidate, curve: np.ndarray) -> None:
        super().__init__(id=f"candidate-{rank}")
        self.rank = rank
        self.candidate = candidate
        self.curve = curve

    def compose(self) -> ComposeResult:
        radii = "/".join(map(str, self.candidate.radii))
        yield Label(f"[b]{self.rank}[/b] {self.candidate.machine} {radii}  d={self.candidate.distance:.4f}")
        yield PatternCanvas()

    def on_mount(self) -> None:
        self.query_one(PatternCanvas).set_polylines([self.curve], ["bright_cyan"])

    def on_click(self) -> None:
        self.screen.open_candidate(self.rank)


class SketchScreen(Screen):
    """Sketch pad, symmetry order, ranked candidates."""

    CSS = """
    SketchScreen #side { width: 48; }
    SketchScreen #controls { height: auto; padding: 0 1; }
    SketchScreen #controls Input { width: 12; }
    SketchScreen #controls Button { min-width: 8; margin-left: 1; }
    SketchScreen #status { height: auto; padding: 0 1; color: $text-muted; }
    SketchScreen #progress { padding: 0 1; }
    SketchScreen #candidates { height: 1fr; }
    """

    BINDINGS = [
        Binding("f", "find", "Find designs"),
        Binding("u", "undo", "Undo stroke"),
        Binding("c", "clear", "Clear"),
        # 1..TOP open the candidate of that rank
        *(Binding(str(rank), f"open({rank})", f"Open #{rank}", show=False) for rank in range(1, TOP + 1)),
    ]

    def __init__(self) -> None:
        super().__init__(name="sketch")
        #: The retriever, once its databases are built or loaded (kept for the next searches).
        self.retriever = None
        #: The ranked candidates shown (station.services.sketch's retrieval candidates).
        self.candidates: list = []

    def compose(self) -> ComposeResult:
        yield Header()
        with Horizontal():
            yield SketchPad(id="pad")
            with Vertical(id="side"):
                with Horizontal(id="controls"):
                    yield Label("symmetry ")
                    yield Input("1", id="symmetry", type="integer", max_length=2)
                    yield Button("Find", id="find", variant="primary")
                    yield Button("Clear", id="clear")
                yield Static("Draw with the mouse, then press f.", id="status")
                yield ProgressBar(total=100, show_eta=False, id="progress")
                yield VerticalScroll(id="candidates")
        yield Footer()

    def on_mount(self) -> None:
        self.pad.focus()

    # -- helpers ---------------------------------------------------------------------------------------------------
    @property
    def pad(self) -> SketchPad:
        return self.query_one("#pad", SketchPad)

    def set_status(self, text: str) -> None:
        # Plain text: error messages quote the user's sketch file and input, never read as markup.
        self.query_one("#status", Static).update(Text(text))

    def symmetry(self) -> int | None:
        """The symmetry order typed in, or ``None`` (and a status message) when it is not valid."""
        text = self.query_one("#symmetry", Input).value.strip() or "1"
        try:
            k = int(text)
        except ValueError:
            k = 0
        if not 1 <= k <= 24:
            self.set_status(f"symmetry order must be a whole number from 1 to 24, got {text!r}")
            return None
        return k

    # -- events ----------------------------------------------------------------------------------------------------
    @on(Input.Changed, "#symmetry")
    def _symmetry_changed(self, event: Input.Changed) -> None:
        k = self.symmetry()
        if k is not None:
            self.pad.set_symmetry(k)

    @on(Input.Submitted, "#symmetry")
    def _symmetry_submitted(self) -> None:
        # A focused field takes letter keys (f would type there): Enter finds, and the pad gets the keys back.
        self.pad.focus()
        self.action_find()

    @on(Button.Pressed, "#find")
    def _find_pressed(self) -> None:
        self.action_find()

    @on(Button.Pressed, "#clear")
    def _clear_pressed(self) -> None:
        self.action_clear()

    @on(SketchPad.Changed)
    def _pad_changed(self) -> None:
        self.set_status(f"{len(self.pad.strokes)} stroke(s); press f to find designs")

    # -- actions ---------------------------------------------------------------------------------------------------
    def action_undo(self) -> None:
        self.pad.undo()

    def action_clear(self) -> None:
        self.pad.clear()
        self.candidates = []
        self.query_one("#candidates", VerticalScroll).remove_children()

    def action_find(self) -> None:
        k = self.symmetry()
        if k is None:
            return
        strokes = [list(s) for s in self.pad.strokes]
        try:
            sketch = sketch_from_strokes(strokes, symmetry=k, center=self.pad.center(), source="sketch pad")
        except USER_ERRORS as error:
            self.set_status(f"cannot use this sketch: {error}")
            return
        self.set_status("searching…")
        self.search(sketch)

    def show_progress(self, progress: Progress) -> None:
        """A database build's progress: its message as the status, its stage's share in the bar."""
        fraction = progress.fraction
        self.set_status(progress.message if fraction is None else f"{progress.message} ({100 * fraction:.0f}%)")
        self.query_one("#progress", ProgressBar).update(total=progress.total, progress=progress.done)

    def search(self, sketch) -> None:
        """Rank the candidates in a worker (building the databases first, once); a newer search replaces it."""
        retriever = self.retriever

        def find(report):
            found = retriever if retriever is not None else make_retriever(report)
            result = retrieve(sketch, RetrieveOptions(top=TOP), retriever=found)
            return found, result, [candidate_curve(c, 512) for c in result.candidates]

        run_work(self, find, CandidatesFound, group="sketch-search")

    def on_progress_reported(self, message: ProgressReported) -> None:
        self.show_progress(message.progress)

    def on_candidates_found(self, message: CandidatesFound) -> None:
        if message.stopped:
            return
        if message.error:
            self.set_status(f"cannot use this sketch: {message.error}")
            return
        self.retriever, result, curves = message.result
        self.show_candidates(result.candidates, curves, result.timings["total"])

    def show_candidates(self, candidates: list, curves: list[np.ndarray], seconds: float) -> None:
        self.candidates = list(candidates)
        self.query_one("#progress", ProgressBar).update(total=100, progress=100)
        box = self.query_one("#candidates", VerticalScroll)
        box.remove_children()
        box.mount_all([CandidatePreview(i, c, curve) for i, (c, curve) in enumerate(zip(candidates, curves), 1)])
        if not candidates:
            self.set_status("no design: no machine has a gear radius equal to this symmetry order; try a smaller one")
            return
        self.set_status(f"{len(candidates)} designs in {seconds:.2f} s; click one or press 1-{len(candidates)}")

    def action_open(self, rank: int) -> None:
        self.open_candidate(rank)

    def open_candidate(self, rank: int) -> None:
        """Open candidate ``rank`` (1-based) on the Drawing machines screen."""
        if not 1 <= rank <= len(self.candidates):
            self.set_status(f"no candidate #{rank}; draw and press f first")
            return
        candidate = self.candidates[rank - 1]
        params = dict(candidate.params)
        try:
            drawing_ready = self.app.get_screen("drawing").is_mounted
        except KeyError:  # no Drawing screen installed
            self.set_status("the Drawing machines screen is not available")
            return
        if drawing_ready:
            self.app.open_design(candidate.machine, params)
        else:
            # open_design fills the Drawing screen's widgets, which exist only once it has been shown: show it
            # first, then load the design after that screen's first refresh.
            self.app.action_open_area("drawing")
            self.app.call_after_refresh(self.app.open_design, candidate.machine, params)


SCREEN = ScreenEntry(
    name="sketch",
    key="s",
    title="Sketch retrieval",
    description="draw a rough pattern, get matching drawing-machine designs",
    factory=SketchScreen,
    order=20,
)
