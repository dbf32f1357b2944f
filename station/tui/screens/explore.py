"""Guided exploration screen (thesis 3.5): freeze features of the drawing, explore the rest with sliders.

Opened from the Drawing machines screen (key x there, or x on the home screen), it takes that screen's current design.
PoIs are marked on the canvas (○ curvature maximum, × crossing; ◉ highlighted, ● selected, ◆ frozen). Select one or
two PoIs (n/b or the table's cursor, Enter or Space to select, or click near a PoI on the canvas), press 1-5 to
freeze a feature, then move the invariant-space sliders (left/right previews live, Enter or a click releases and
re-projects). o sends the explored design back to the Drawing machines screen.

Every computation runs in a thread worker; one lock serializes the explorer, so the screen never freezes.
"""

from __future__ import annotations

import copy
import threading

import numpy as np
from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.screen import Screen
from textual.widgets import DataTable, Footer, Header, Static

from station.services.explore import drop_last_invariant, keep_invariant, move_slider, release_slider, start_session
from station.tui.messages import ExplorerBuilt, ExplorerChanged, PreviewMoved
from station.tui.registry import MachineDesign, ScreenEntry
from station.tui.widgets.explore_canvas import ExploreCanvas, nearest_poi, poi_markers
from station.tui.widgets.explore_slider import InvariantSlider
from station.tui.work import run_work

DEFAULT_MACHINE = "cycloid_drawing_machine"
INVARIANT_KEYS = {"1": "position", "2": "curvature", "3": "angle", "4": "radial", "5": "distance"}
#: How many explorer states ctrl+z can go back through.
UNDO_DEPTH = 30


def coordinate(value: float) -> str:
    """A PoI coordinate with three decimals; a crossing at the centre reads ``0.000``, not ``-0.000``."""
    text = f"{value:.3f}"
    return "0.000" if text == "-0.000" else text


class ExploreScreen(Screen):
    """Points of Interest, invariants and invariant-space sliders on one design."""

    CSS = """
    ExploreScreen #sidebar { width: 64; border-right: solid $primary-darken-2; }
    ExploreScreen #design { height: auto; padding: 0 1; }
    ExploreScreen #pois { height: 1fr; border: round $panel-lighten-2; }
    ExploreScreen #pois:focus { border: round $accent; }
    ExploreScreen InvariantSlider:focus { background: $accent 50%; text-style: bold; }
    ExploreScreen #invariants { height: auto; padding: 0 1; color: $success; }
    ExploreScreen #sliders { height: auto; max-height: 8; }
    ExploreScreen #status { height: auto; padding: 0 1; color: $text-muted; }
    ExploreScreen #canvas { border: round $primary-darken-1; }
    """

    BINDINGS = [
        Binding("n", "cycle_poi(1)", "Next PoI"),
        Binding("b", "cycle_poi(-1)", "Prev PoI"),
        Binding("space", "toggle_select", "Select"),
        Binding("1", "keep('position')", "Position"),
        Binding("2", "keep('curvature')", "Curvature"),
        Binding("3", "keep('angle')", "Angle"),
        Binding("4", "keep('radial')", "Radial"),
        Binding("5", "keep('distance')", "Distance"),
        Binding("backspace", "drop_invariant", "Drop last"),
        Binding("o", "send_back", "Open in Drawing"),
        Binding("r", "reload", "Reload design"),
        Binding("ctrl+z", "undo", "Undo"),
    ]

    def __init__(self) -> None:
        super().__init__(name="explore")
        #: The exploration session (station.services.explore.start_session), None until one is built.
        self.explorer = None
        self.lock = threading.Lock()
        self.highlighted: int | None = None
        self.selected: list[int] = []
        self.preview: np.ndarray | None = None
        self.loaded_design: tuple[str, dict] | None = None
        self.last_message = ""
        #: Explorer states before each release or invariant change (newest last), for ctrl+z.
        self.history: list = []

    def compose(self) -> ComposeResult:
        yield Header()
        with Horizontal():
            with Vertical(id="sidebar"):
                yield Static("loading…", id="design")
                yield DataTable(id="pois", cursor_type="row", zebra_stripes=True)
                yield Static("", id="invariants")
                sliders = VerticalScroll(id="sliders")
                sliders.can_focus = False  # its sliders take the focus (a focused container shows nothing)
                yield sliders
                yield Static("", id="status")
            yield ExploreCanvas(id="canvas")
        yield Footer()

    def on_mount(self) -> None:
        table = self.query_one("#pois", DataTable)
        table.add_columns("id", "type", "x", "y", "feature")

    def on_screen_resume(self) -> None:
        design = self._drawing_design()
        if design != self.loaded_design or self.explorer is None:
            self.load(*design)

    def _drawing_design(self) -> MachineDesign:
        """The Drawing screen's design; in an app without that screen, the default design of DEFAULT_MACHINE."""
        return self.app.current_design() or MachineDesign.defaults(DEFAULT_MACHINE)

    # --- explorer work (threads) --------------------------------------------------------------------------------
    def load(self, machine: str, params: dict) -> None:
        """Start a session on a design (in a worker)."""
        self.loaded_design = (machine, dict(params))
        self._set_status(f"finding the points of interest of {machine}…")
        self._build(machine, dict(params))

    def _build(self, machine: str, params: dict) -> None:
        def build(_report):
            explorer = start_session(machine, params)
            with self.lock:
                self.explorer = explorer
                self.history.clear()  # a new design: the old states belong to another session
            return f"{len(explorer.pois)} points of interest found", True

        run_work(self, build, ExplorerBuilt, group="explore-build")

    def _edit(self, change) -> None:
        """Run ``change()`` on the session in a worker, under the lock; it returns the status line and whether the
        selection resets, or (a line, None) when nothing changed. Edits run one after the other, in order."""

        def edit(_report):
            with self.lock:
                return change()

        run_work(self, edit, ExplorerChanged, group="explore-ops", exclusive=False)

    def _keep(self, kind: str, ids: list[int]) -> None:
        def keep():
            explorer = self.explorer
            if explorer is None:
                return "", None
            before = copy.deepcopy(explorer)
            invariant = keep_invariant(explorer, kind, ids)
            self._remember(before)
            message = f"kept {invariant.label}: {len(explorer.sliders)} slider(s)"
            if explorer.subspace.redundant:
                message += " (redundant with the machine: base parameters kept)"
            return message, True

        self._edit(keep)

    def _drop(self) -> None:
        def drop():
            explorer = self.explorer
            if explorer is None or not explorer.invariants:
                return "", None
            self._remember(copy.deepcopy(explorer))
            return f"dropped {drop_last_invariant(explorer)}", True

        self._edit(drop)

    def _preview(self, index: int, value: float) -> None:
        def preview(_report):
            with self.lock:
                explorer = self.explorer
                if explorer is None or index >= len(explorer.values):
                    return None
                moved = move_slider(explorer, index, value)
            return moved.curve, moved.sliders

        run_work(self, preview, PreviewMoved, group="explore-preview")

    def _release(self, index: int, value: float) -> None:
        def release():
            explorer = self.explorer
            if explorer is None or index >= len(explorer.values):
                return "", None
            self._remember(copy.deepcopy(explorer))
            result = release_slider(explorer, index, value)
            errors = ", ".join(f"{label} {'lost' if not np.isfinite(e) else f'{e:.2g}'}"
                               for label, e in result.errors_after.items())
            message = f"released: drawing changed by {result.shape_change:.2%}" + (f"; errors {errors}" if errors
                                                                                    else "")
            if result.lost:
                message += f"; lost {', '.join(result.lost)}"
            if result.warning:
                message += f"; {result.warning}"
            return message, False

        self._edit(release)

    def _remember(self, state) -> None:
        """Keep ``state`` for undo (called by the workers with the lock held); a deep copy costs about 1 ms."""
        self.history.append(state)
        del self.history[:-UNDO_DEPTH]

    def _undo(self) -> None:
        def undo():
            if not self.history:
                return "nothing to undo", None
            self.explorer = self.history.pop()
            left = len(self.history)
            return f"undone ({left} more step{'s' if left != 1 else ''} to undo)", True

        self._edit(undo)

    async def on_explorer_built(self, message: ExplorerBuilt) -> None:
        if message.ok:
            await self._after_change(*message.result)
        elif message.error:
            self._set_status(f"cannot explore this design: {message.error}")

    async def on_explorer_changed(self, message: ExplorerChanged) -> None:
        if message.error:
            self._warn(message.error)
            return
        if not message.ok:
            return
        text, reset_selection = message.result
        if reset_selection is not None:
            await self._after_change(text, reset_selection)
        elif text:
            self._set_status(text)

    def on_preview_moved(self, message: PreviewMoved) -> None:
        if message.ok and message.result is not None:
            self._show_preview(*message.result)

    # --- UI updates (main thread) -------------------------------------------------------------------------------
    async def _after_change(self, message: str, reset_selection: bool) -> None:
        explorer = self.explorer
        if explorer is None:
            return
        self.preview = None
        if reset_selection:
            self.selected = []
        self.selected = [i for i in self.selected if i < len(explorer.pois)]
        table = self.query_one("#pois", DataTable)
        table.clear()
        for p in explorer.pois:
            feature = f"κ {p.curvature:.3g}" if p.curvature is not None else f"{np.degrees(p.angle):.1f}°"
            table.add_row(str(p.id), p.kind, coordinate(p.xy[0]), coordinate(p.xy[1]), feature, key=str(p.id))
        if self.highlighted is None or self.highlighted >= len(explorer.pois):
            self.highlighted = 0 if explorer.pois else None
        design = ", ".join(f"{k}={v:.4g}" for k, v in explorer.design.items())
        self.query_one("#design", Static).update(f"[b]{explorer.machine.title}[/b]\n{design}")
        await self._sync_sliders()
        self._show_invariants()
        self._set_status(message)
        self._draw()

    async def _sync_sliders(self) -> None:
        explorer = self.explorer
        container = self.query_one("#sliders", VerticalScroll)
        existing = list(container.query(InvariantSlider))
        sliders = explorer.sliders
        if [w.label for w in existing] != [s.name for s in sliders]:
            await container.remove_children()
            await container.mount_all(
                [InvariantSlider(s.index, s.name, s.value, s.lower, s.upper, id=f"slider-{s.index}") for s in sliders]
            )
        else:
            for widget, s in zip(existing, sliders):
                widget.set_state(s.value, s.lower, s.upper)

    def _show_preview(self, curve: np.ndarray, sliders) -> None:
        self.preview = curve
        for widget, s in zip(self.query(InvariantSlider), sliders):
            widget.set_state(s.value, s.lower, s.upper)
        if self.explorer is not None:
            design = ", ".join(f"{k}={v:.4g}" for k, v in self.explorer.design.items())
            self.query_one("#design", Static).update(f"[b]{self.explorer.machine.title}[/b] (moved)\n{design}")
        self._draw()

    def _show_invariants(self) -> None:
        explorer = self.explorer
        if explorer is None or not explorer.invariants:
            text = "no invariant · select PoIs, then 1 position 2 curvature 3 angle 4 radial 5 distance"
        else:
            current = explorer.invariant_pois()
            text = "frozen: " + ", ".join(
                f"{inv.label} (now {','.join('lost' if i is None else str(i) for i in current[inv.label])})"
                for inv in explorer.invariants
            )
        if self.selected:
            text += f"\nselected: {', '.join(map(str, self.selected))}"
        self.query_one("#invariants", Static).update(text)

    def _draw(self) -> None:
        explorer = self.explorer
        if explorer is None:
            return
        canvas = self.query_one("#canvas", ExploreCanvas)
        frozen = [i for ids in explorer.invariant_pois().values() for i in ids if i is not None]
        markers = poi_markers(explorer.pois, self.highlighted, self.selected, frozen)
        if self.preview is not None:
            polylines, colors = [explorer.curve, self.preview], ["grey37", "cyan"]
            markers = [m for m in markers if m.char in ("◆", "●", "◉")]
        else:
            polylines, colors = [explorer.curve], ["cyan"]
        everything = np.concatenate(polylines)
        canvas.set_polylines(polylines, colors, markers=markers, bounds=(*everything.min(0), *everything.max(0)))

    def _set_status(self, text: str) -> None:
        # Plain text: error messages quote parameter values, never read as markup.
        self.last_message = text
        self.query_one("#status", Static).update(Text(text))

    def _warn(self, text: str) -> None:
        self._set_status(text)
        self.notify(text, severity="warning", title="Explore", markup=False)

    # --- events and actions -------------------------------------------------------------------------------------
    @on(DataTable.RowHighlighted, "#pois")
    def row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        if event.row_key is not None and event.row_key.value is not None:
            self.highlighted = int(event.row_key.value)
            self._draw()

    @on(DataTable.RowSelected, "#pois")
    def row_selected(self, event: DataTable.RowSelected) -> None:
        if event.row_key is not None and event.row_key.value is not None:
            self.highlighted = int(event.row_key.value)
            self.action_toggle_select()

    @on(ExploreCanvas.Clicked)
    def canvas_clicked(self, event: ExploreCanvas.Clicked) -> None:
        if self.explorer is None:
            return
        poi = nearest_poi(self.explorer.pois, event.xy)
        if poi is not None:
            self.highlighted = poi
            self.query_one("#pois", DataTable).move_cursor(row=poi)
            self.action_toggle_select()

    @on(InvariantSlider.Moved)
    def slider_moved(self, event: InvariantSlider.Moved) -> None:
        self._preview(event.index, event.value)

    @on(InvariantSlider.Released)
    def slider_released(self, event: InvariantSlider.Released) -> None:
        self._set_status("re-projecting onto the invariants…")
        self._release(event.index, event.slider.value)

    def action_cycle_poi(self, step: int) -> None:
        if self.explorer is None or not self.explorer.pois:
            return
        count = len(self.explorer.pois)
        self.highlighted = ((self.highlighted or 0) + step) % count
        self.query_one("#pois", DataTable).move_cursor(row=self.highlighted)
        self._draw()

    def action_toggle_select(self) -> None:
        if self.highlighted is None:
            return
        if self.highlighted in self.selected:
            self.selected.remove(self.highlighted)
        else:
            self.selected = (self.selected + [self.highlighted])[-2:]
        self._show_invariants()
        self._draw()

    def action_keep(self, kind: str) -> None:
        if self.explorer is None:
            return
        needed = 2 if kind == "distance" else 1
        ids = self.selected[-needed:] if self.selected else ([self.highlighted] if self.highlighted is not None else [])
        if len(ids) != needed:
            self._warn(f"{kind} needs {needed} selected PoI(s): select with Space or Enter, or click on the canvas")
            return
        self._set_status(f"computing the invariant subspace for {kind}:{','.join(map(str, ids))}…")
        self._keep(kind, list(ids))

    def action_drop_invariant(self) -> None:
        self._drop()

    def action_undo(self) -> None:
        """Go back to the explorer state before the last release, kept invariant or dropped invariant."""
        self._undo()

    def action_reload(self) -> None:
        self.load(*self._drawing_design())

    def action_send_back(self) -> None:
        if self.explorer is None:
            return
        # No lock here: a worker holding it may be waiting for this (main) thread; reading the design is harmless.
        machine, params = self.explorer.machine.name, self.explorer.design
        self.app.open_design(machine, params)


SCREEN = ScreenEntry(
    name="explore",
    key="x",
    title="Guided exploration",
    description="Freeze what you like in a drawing (points of interest) and explore the rest with sliders",
    factory=ExploreScreen,
    order=15,
)
