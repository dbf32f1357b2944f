"""Contraption screen: load a chain-reaction scenario, see its causal graph, simulate a layout and watch it unfold.

Type an example name (``simple``, ``ballrun``, ...) or a path and press Enter. The table lists the causal graph's
events (with their parents and join), and their states during and after a simulation; the canvas shows the side
view (x-z) of the bodies, redrawn at each change of state.

Keys: r simulate · l next layout (file default, then the file's named layouts) · t real-time pacing on/off.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from rich.markup import escape
from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import Screen
from textual.widgets import DataTable, Footer, Header, Input, Static

from station.errors import USER_ERRORS
from station.services.contraption import (
    example_names,
    layout_view,
    open_scenario,
    physics_client,
    shown_path,
    side_view,
    simulate,
    world_ropes,
)
from station.tui.messages import SimulationEnded, SimulationStepped
from station.tui.registry import ScreenEntry
from station.tui.widgets.canvas import PatternCanvas
from station.tui.work import run_work

STATE_STYLE = {"asleep": "dim", "awake": "bold yellow", "success": "bold green", "failure": "bold red"}
TYPE_COLOURS = {
    "Ball": "red",
    "DominoRun": "dark_orange",
    "Track": "blue",
    "Lever": "green",
    "Goblet": "magenta",
    "Pulley": "cyan",
}


#: Colour of ropes in the side view.
ROPE_COLOUR = "yellow"


def side_view_polylines(scenario, snapshot, ropes=()) -> tuple[list[np.ndarray], list[str]]:
    """The side view's outlines and ropes (:func:`station.services.contraption.side_view`), with a colour per
    primitive type."""
    view = side_view(scenario, snapshot, ropes)
    colours = [ROPE_COLOUR if kind == "rope" else TYPE_COLOURS.get(kind, "white") for kind, _ in view]
    return [line for _, line in view], colours


class ContraptionScreen(Screen):
    """Scenario, causal graph, simulation."""

    CSS = """
    ContraptionScreen #left { width: 1fr; min-width: 60; }
    ContraptionScreen #summary { height: auto; padding: 0 1; }
    ContraptionScreen #events { height: 1fr; }
    ContraptionScreen #status { height: auto; padding: 0 1; }
    ContraptionScreen #view { width: 1fr; border: round $primary-darken-2; }
    """

    BINDINGS = [
        Binding("r", "simulate", "Simulate"),
        Binding("l", "next_layout", "Next layout"),
        Binding("t", "toggle_pacing", "Real time on/off"),
        Binding("o", "optimize", "Optimize layout"),
    ]

    def __init__(self) -> None:
        super().__init__(name="contraption")
        #: The scenario loaded (from station.services.contraption.open_scenario).
        self.scenario = None
        self.layout_names: list[str] = ["file default"]
        self.layout_index = 0
        self.realtime = True
        self.running = False
        self.result = None
        self._bounds = None
        self._client = None  # one pybullet client for the screen's life (runs are sequential)

    def compose(self) -> ComposeResult:
        yield Header(show_clock=False)
        with Horizontal():
            with Vertical(id="left"):
                yield Input(
                    placeholder=f"scenario: {', '.join(example_names())} or a path, then Enter", id="scenario-input"
                )
                yield Static("", id="summary")
                yield DataTable(id="events", cursor_type="row", zebra_stripes=True)
                yield Static("", id="status")
            yield PatternCanvas(id="view")
        yield Footer()

    def on_mount(self) -> None:
        table = self.query_one("#events", DataTable)
        for column, width in (("event", None), ("type", None), ("after", None), ("state", 8), ("woke", 6),
                              ("at", 6)):
            table.add_column(column, key=column, width=width)
        self.load("simple")
        table.focus()  # keys go to the screen's bindings until the user clicks or tabs into the scenario field

    # -- loading -------------------------------------------------------------------------------------------------
    @on(Input.Submitted, "#scenario-input")
    def _submitted(self, event: Input.Submitted) -> None:
        if event.value.strip() and self.load(event.value.strip()):
            self.query_one("#events", DataTable).focus()

    def load(self, text: str) -> bool:
        """Load a scenario by example name or path; errors are shown, never raised."""
        if self.running:
            self.set_status("a simulation is running", style="yellow")
            return False
        try:
            scenario = open_scenario(text)
        except USER_ERRORS as error:
            self.set_status(str(error), style="red")
            return False
        self.scenario = scenario
        order = {"success": 0, "failure": 1}
        self.layout_names = ["file default", *sorted(scenario.layouts, key=lambda n: (order.get(n, 2), n))]
        self.layout_index = self.layout_names.index("success") if "success" in scenario.layouts else 0
        self.result = None
        self._fill_events()
        self._show_summary()
        self._draw_layout()
        self.set_status(f"loaded {shown_path(scenario.source)}; press r to simulate")
        return True

    def current_layout(self) -> np.ndarray:
        name = self.layout_names[self.layout_index]
        return self.scenario.default_layout() if name == "file default" else self.scenario.layout(name)

    def _show_summary(self) -> None:
        s = self.scenario
        space = s.design_space
        params = ", ".join(
            f"{n}={v:g}" for n, v in zip(space.names, self.current_layout())
        ) or "none"
        # The name, description and layout names come from the scenario file: escaped, never read as markup.
        text = (
            f"[b]{escape(s.name)}[/b] — {escape(s.description)}\n"
            f"{len(s.objects)} objects, {len(s.events)} events (root {escape(s.root)}), {space.dim} design "
            f"parameters\nlayout [b]{escape(self.layout_names[self.layout_index])}[/b]: {escape(params)}"
        )
        self.query_one("#summary", Static).update(text)

    def _fill_events(self) -> None:
        table = self.query_one("#events", DataTable)
        table.clear()
        for spec in self.scenario.event_specs:
            joined = (" & " if spec.join == "all" else " | ").join(spec.after) or "(root)"
            state = "awake" if not spec.after else "asleep"
            table.add_row(spec.name, spec.type, joined, self._styled(state), "", "", key=spec.name)

    @staticmethod
    def _styled(state: str) -> Text:
        return Text(state, style=STATE_STYLE.get(state, ""))

    def set_status(self, text: str | Text, style: str = "") -> None:
        """Show ``text`` (a string is plain text in ``style``: paths, scenario names and error messages come from
        the user's files and are never read as markup; a :class:`~rich.text.Text` keeps its own styles)."""
        self.query_one("#status", Static).update(text if isinstance(text, Text) else Text(text, style=style))

    def _draw(self, snapshot, ropes=()) -> None:
        lines, colours = side_view_polylines(self.scenario, snapshot, ropes)
        self.query_one("#view", PatternCanvas).set_polylines(lines, colours, bounds=self._bounds)

    def _draw_layout(self) -> None:
        try:
            if self._client is None:
                self._client = physics_client()
            snapshot, ropes = layout_view(self.scenario, self.current_layout(), client=self._client)
        except USER_ERRORS as error:  # pragma: no cover - a validated scenario builds
            self.set_status(str(error), style="red")
            return
        lines, _ = side_view_polylines(self.scenario, snapshot, ropes)
        if lines:
            stacked = np.concatenate(lines)
            lo, hi = stacked.min(axis=0), stacked.max(axis=0)
            pad = 0.1 * (hi - lo) + 1e-3
            self._bounds = (lo[0] - pad[0], lo[1] - pad[1], hi[0] + pad[0], hi[1] + pad[1])
        self._draw(snapshot, ropes)

    # -- actions -------------------------------------------------------------------------------------------------
    def action_next_layout(self) -> None:
        if self.scenario is None or self.running:
            return
        self.layout_index = (self.layout_index + 1) % len(self.layout_names)
        self.result = None  # the last run's verdict belongs to the previous layout
        self._fill_events()
        self._show_summary()
        self._draw_layout()
        self.set_status(f"layout {self.layout_names[self.layout_index]}; press r to simulate")

    def action_optimize(self) -> None:
        """Open the Robust layouts screen on this scenario (its file; o there starts the optimization)."""
        if self.scenario is None or not Path(self.scenario.source).is_file():
            self.set_status("load a scenario file first", style="yellow")
            return
        optimizer = self.app.open_area_if_installed("optimize")
        if optimizer is not None:
            optimizer.choose_scenario(self.scenario.source)

    def action_toggle_pacing(self) -> None:
        self.realtime = not self.realtime
        self.set_status(f"real-time pacing {'on' if self.realtime else 'off'}")

    def action_simulate(self) -> None:
        if self.scenario is None or self.running:
            return
        self.running = True
        self._fill_events()
        self.set_status("simulating…")
        self.simulate_worker(self.scenario, self.current_layout(), self.realtime)

    def simulate_worker(self, scenario, x: np.ndarray, realtime: bool) -> None:
        """Simulate in a worker: each change of the events' states arrives as a :class:`SimulationStepped`, the
        verdict as a :class:`SimulationEnded`."""
        if self._client is None:
            self._client = physics_client()
        client = self._client

        def run(_report):
            started = time.perf_counter()

            def on_change(t: float, states: dict[str, str], world) -> None:
                if realtime:
                    # Pace the run so that a person can follow the events (simulated time = wall time).
                    delay = started + t - time.perf_counter()
                    if delay > 0:
                        time.sleep(delay)
                self.post_message(SimulationStepped(t, dict(states), world.snapshot(), world_ropes(world)))

            return simulate(scenario, x, record=True, on_change=on_change, client=client)

        run_work(self, run, SimulationEnded, group="contraption")

    def on_simulation_stepped(self, message: SimulationStepped) -> None:
        self._update_states(message.t, message.states, message.snapshot, message.ropes)

    def on_simulation_ended(self, message: SimulationEnded) -> None:
        if not message.ok:
            self._finished(None, Text(f"cannot simulate: {message.error}", "red"))
            return
        outcome = message.result
        if not outcome.valid:
            problems = "; ".join(p.message for p in outcome.problems)
            self._finished(None, Text.assemble(("impossible layout: ", "red"), problems))
            return
        result = outcome.result
        verdict = ("SUCCESS", "bold green") if result.success else ("FAILURE", "bold red")
        summary = Text.assemble(
            verdict, f": {result.n_successful_events}/{len(result.events)} events, "
            f"{result.duration:.2f} s simulated in {result.steps} steps"
        )
        self._finished(result, summary)

    def _update_states(self, t: float, states: dict[str, str], snapshot, ropes=()) -> None:
        table = self.query_one("#events", DataTable)
        for name, state in states.items():
            table.update_cell(name, "state", self._styled(state))
        self.set_status(f"t = {t:.3f} s")
        self._draw(snapshot, ropes)

    def _finished(self, result, summary: str | Text) -> None:
        self.running = False
        self.result = result
        if result is not None:
            table = self.query_one("#events", DataTable)
            for name, outcome in result.events.items():
                table.update_cell(name, "state", self._styled(outcome.state))
                table.update_cell(name, "woke", "" if outcome.woke is None else f"{outcome.woke:.3f}")
                table.update_cell(name, "at", "" if outcome.time is None else f"{outcome.time:.3f}")
            self._draw(result.end, result.ropes_end)
        self.set_status(summary)


SCREEN = ScreenEntry(
    name="contraption",
    key="c",
    title="Contraptions",
    description="chain-reaction scenarios: causal graph, simulation, event states",
    factory=ContraptionScreen,
    order=20,
)
