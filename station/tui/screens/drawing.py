"""Drawing machines screen: pick a machine, move its parameters inside their feasible bounds, see the pattern live
with the mechanism at the current time."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.screen import Screen
from textual.widgets import Footer, Header, Select, Static

from station.errors import USER_ERRORS
from station.services.designs import get_machine
from station.services.drawing import feasible_interval, machine_choices, mechanism_at, pattern, validate_design
from station.tui.messages import PatternComputed
from station.tui.registry import MachineDesign, ScreenEntry
from station.tui.widgets.canvas import Marker, PatternCanvas
from station.tui.widgets.parameter import ParameterControl, ParameterState
from station.tui.work import run_work

HISTORY_LIMIT = 200
FRAMES_PER_SECOND = 12
#: Animation speed: turns of the driving gear per second of wall time.
TURNS_PER_SECOND = 0.5


def points_for_period(period: float) -> int:
    """Enough samples for a smooth preview: ~400 per turn of the driving gear, within [2048, 20000]."""
    turns = period / (2 * math.pi) if math.isfinite(period) and period > 0 else 1.0
    return int(min(20000, max(2048, 400 * turns)))


def mechanism_to_drawing(shapes: Any) -> tuple[list[np.ndarray], list[Marker]]:
    """Turn a model's mechanism shapes into polylines and markers.

    Shapes are duck-typed so that a machine added by a plug-in may bring its own: anything with a ``polyline()``
    method draws that (ellipses), with ``center`` and ``radius`` a circle, with ``start``/``end`` a segment, with
    ``points`` a polyline, with ``position`` (or ``xy``) a point.
    """
    polylines: list[np.ndarray] = []
    markers: list[Marker] = []
    angles = np.linspace(0.0, 2.0 * np.pi, 97)
    for shape in shapes or ():
        if callable(getattr(shape, "polyline", None)):
            polylines.append(np.asarray(shape.polyline(), dtype=float).reshape(-1, 2))
        elif hasattr(shape, "center") and hasattr(shape, "radius"):
            cx, cy = np.asarray(shape.center, dtype=float)
            polylines.append(np.column_stack((cx + shape.radius * np.cos(angles), cy + shape.radius * np.sin(angles))))
        elif hasattr(shape, "start") and hasattr(shape, "end"):
            polylines.append(np.array([shape.start, shape.end], dtype=float))
        elif hasattr(shape, "points"):
            polylines.append(np.asarray(shape.points, dtype=float).reshape(-1, 2))
        else:
            xy = getattr(shape, "position", None)
            if xy is None:
                xy = getattr(shape, "xy", None)
            if xy is not None:
                markers.append(Marker(tuple(np.asarray(xy, dtype=float)[:2]), "●", "yellow"))
    return polylines, markers


class DrawingScreen(Screen):
    """Pick a machine and explore its parameters; the pattern redraws live."""

    CSS = """
    DrawingScreen #sidebar { width: 62; border-right: solid $primary-darken-2; }
    DrawingScreen #controls { height: 1fr; }
    DrawingScreen #status { height: auto; padding: 0 1; color: $text-muted; }
    DrawingScreen #canvas { border: round $primary-darken-1; }
    """

    BINDINGS = [
        Binding("p", "toggle_animation", "Play/pause"),
        Binding("ctrl+z", "undo", "Undo"),
        Binding("ctrl+r", "reset", "Defaults"),
        Binding("x", "explore", "Explore"),
        Binding("f", "fabricate", "Fabricate"),
        Binding("l", "plot", "Plot"),
    ]

    def __init__(self) -> None:
        super().__init__(name="drawing")
        self._choices = machine_choices()
        self.machine = get_machine(self._choices[0][1])
        self.params: dict[str, float] = self.machine.defaults()
        self.history: list[tuple[str, dict[str, float]]] = []
        self.pattern: np.ndarray | None = None
        self.period: float = float("nan")
        self.time: float = 0.0
        self.animating = False
        self._timer = None

    # --- layout --------------------------------------------------------------------------------------------------
    def compose(self) -> ComposeResult:
        yield Header()
        with Horizontal():
            with Vertical(id="sidebar"):
                yield Select(
                    self._choices,
                    value=self.machine.name,
                    allow_blank=False,
                    id="machine",
                )
                controls = VerticalScroll(id="controls")
                controls.can_focus = False  # its sliders take the focus (a focused container shows nothing)
                yield controls
                yield Static("", id="status")
            yield PatternCanvas(id="canvas")
        yield Footer()

    async def on_mount(self) -> None:
        await self._rebuild_controls()
        self._refresh_bounds()
        self.recompute_pattern()

    async def _rebuild_controls(self) -> None:
        container = self.query_one("#controls", VerticalScroll)
        await container.remove_children()
        controls = []
        for parameter in self.machine.parameters:
            discrete = parameter.kind == "discrete"
            value = float(self.params[parameter.name])
            controls.append(
                ParameterControl(
                    parameter.name,
                    discrete=discrete,
                    state=ParameterState(value, float(parameter.lower), float(parameter.upper)),
                    description=parameter.description,
                    id=f"param-{parameter.name}",
                )
            )
        await container.mount_all(controls)

    def controls(self) -> dict[str, ParameterControl]:
        return {c.parameter_name: c for c in self.query(ParameterControl)}

    # --- the design ----------------------------------------------------------------------------------------------
    def current_design(self) -> MachineDesign:
        """The machine's name and a copy of its parameters (used by Explore, Fabricate, Plot)."""
        return MachineDesign(self.machine.name, dict(self.params))

    def load_design(self, machine: str, params: dict[str, float]) -> None:
        """Show ``machine`` with ``params`` (validated; a bad design is reported and nothing changes)."""
        try:
            model = get_machine(machine)
            validated = validate_design(model, params)
        except USER_ERRORS as error:
            self.notify(str(error), severity="error", title="Cannot open design", markup=False)
            return
        self._remember()
        if not self.is_mounted:
            # Never shown yet: compose and on_mount build the controls and the pattern from these.
            self.machine, self.params = model, dict(validated)
            return
        self._set_design(model, validated)

    def _set_design(self, model: Any, params: dict[str, float]) -> None:
        machine_changed = model.name != self.machine.name
        self.machine = model
        self.params = dict(params)
        select = self.query_one("#machine", Select)
        if select.value != model.name:
            with self.prevent(Select.Changed):
                select.value = model.name
        if machine_changed:
            self.run_worker(self._after_machine_change(), exclusive=True, group="controls")
        else:
            self._refresh_bounds()
            self.recompute_pattern()

    async def _after_machine_change(self) -> None:
        await self._rebuild_controls()
        self._refresh_bounds()
        self.recompute_pattern()

    def _remember(self) -> None:
        self.history.append((self.machine.name, dict(self.params)))
        del self.history[:-HISTORY_LIMIT]

    def _refresh_bounds(self) -> None:
        """Recompute every control's bounds with the others fixed: infeasible values are never reachable."""
        for parameter in self.machine.parameters:
            control = self.controls().get(parameter.name)
            if control is None:
                continue
            value = float(self.params[parameter.name])
            if parameter.kind == "discrete":
                lower, upper = float(parameter.lower), float(parameter.upper)
            else:
                try:
                    lower, upper = feasible_interval(self.machine, self.params, parameter.name)
                except USER_ERRORS:
                    lower = upper = value
            control.set_state(ParameterState(value, float(lower), float(upper)))

    # --- events --------------------------------------------------------------------------------------------------
    @on(Select.Changed, "#machine")
    def machine_selected(self, event: Select.Changed) -> None:
        if event.value == self.machine.name or event.value is Select.BLANK:
            return
        model = get_machine(str(event.value))
        self._remember()
        self._set_design(model, model.defaults())

    @on(ParameterControl.Changed)
    def parameter_moved(self, event: ParameterControl.Changed) -> None:
        candidate = dict(self.params)
        candidate[event.name] = event.value
        if not self.machine.is_feasible(candidate):
            # Bounds come from the feasible interval, so this only happens at a numerical edge: stay put.
            self._refresh_bounds()
            self._set_status("that value is not feasible; bounds refreshed")
            return
        self._remember()
        self.params = candidate
        self._refresh_bounds()
        self.recompute_pattern()

    @on(ParameterControl.StepRequested)
    def parameter_stepped(self, event: ParameterControl.StepRequested) -> None:
        found = self.next_feasible_step(event.name, event.direction)
        if found is None:
            self._set_status(f"{event.name}: no feasible value further {'up' if event.direction > 0 else 'down'}")
            return
        self._remember()
        self.params = found
        self._refresh_bounds()
        self.recompute_pattern()

    def next_feasible_step(self, name: str, direction: int) -> dict[str, float] | None:
        """The nearest design in ``direction`` along discrete parameter ``name`` that is feasible.

        Continuous parameters are clamped into their new feasible intervals when the step alone is infeasible (the
        bounds of a slider depend on the gears), so a gear change keeps the rest of the design as far as possible.
        """
        parameter = next(p for p in self.machine.parameters if p.name == name)
        value = int(round(self.params[name]))
        for candidate_value in range(value + direction, int(parameter.upper if direction > 0 else parameter.lower)
                                     + direction, direction):
            candidate = dict(self.params)
            candidate[name] = candidate_value
            if self.machine.is_feasible(candidate):
                return candidate
            repaired = self._repair(candidate)
            if repaired is not None:
                return repaired
        return None

    def _repair(self, candidate: dict[str, float]) -> dict[str, float] | None:
        continuous = [p.name for p in self.machine.parameters if p.kind != "discrete"]
        repaired = dict(candidate)
        for _ in range(2):
            for name in continuous:
                try:
                    lower, upper = feasible_interval(self.machine, repaired, name)
                except USER_ERRORS:
                    continue
                if lower <= upper:
                    repaired[name] = min(max(repaired[name], lower), upper)
            if self.machine.is_feasible(repaired):
                return repaired
        return None

    # --- pattern -------------------------------------------------------------------------------------------------
    def recompute_pattern(self) -> None:
        """Sample the pattern in a worker (a newer design replaces a running one)."""
        machine, params = self.machine, dict(self.params)

        def sample(_report):
            return (machine.name, params, *pattern(machine, params, points_for_period))

        run_work(self, sample, PatternComputed, group="pattern")

    def on_pattern_computed(self, message: PatternComputed) -> None:
        if message.ok:
            self._show_pattern(*message.result)
        elif message.error:
            self._set_status(f"cannot draw: {message.error}")

    def _show_pattern(self, machine: str, params: dict[str, float], period: float, pattern: np.ndarray) -> None:
        if machine != self.machine.name or params != self.params:
            return  # a newer design is already being computed
        self.pattern = pattern
        self.period = period
        self.time = self.time % period if period > 0 else 0.0
        self._draw()
        turns = period / (2 * math.pi)
        self._set_status(
            f"{self.machine.title}: period {turns:.4g} turns, {len(pattern)} points · "
            f"{'playing' if self.animating else 'p: play'} · ctrl+z undo ({len(self.history)})"
        )

    def _draw(self) -> None:
        if self.pattern is None:
            return
        canvas = self.query_one("#canvas", PatternCanvas)
        polylines: list[np.ndarray] = [self.pattern]
        colors = ["grey50" if self.animating else "cyan"]
        markers: list[Marker] = []
        if self.animating and self.period > 0:
            fraction = (self.time % self.period) / self.period
            traced = self.pattern[: max(2, int(fraction * len(self.pattern)))]
            polylines.append(traced)
            colors.append("cyan")
        try:
            parts, markers = mechanism_to_drawing(mechanism_at(self.machine, self.params, self.time))
        except USER_ERRORS:
            parts = []
        polylines.extend(parts)
        colors.extend(["magenta"] * len(parts))
        everything = np.concatenate([p for p in polylines if len(p)])
        bounds = (*everything.min(axis=0), *everything.max(axis=0))
        canvas.set_polylines(polylines, colors, markers=markers, bounds=bounds)

    def _set_status(self, text: str) -> None:
        # Plain text: error messages quote parameter values and design files, never read as markup.
        self.query_one("#status", Static).update(Text(text))

    # --- actions -------------------------------------------------------------------------------------------------
    def action_toggle_animation(self) -> None:
        self.animating = not self.animating
        if self.animating and self._timer is None:
            self._timer = self.set_interval(1 / FRAMES_PER_SECOND, self._tick)
        elif not self.animating and self._timer is not None:
            self._timer.stop()
            self._timer = None
        self._draw()

    def _tick(self) -> None:
        if self.period > 0:
            self.time = (self.time + 2 * math.pi * TURNS_PER_SECOND / FRAMES_PER_SECOND) % self.period
        self._draw()

    def action_undo(self) -> None:
        if not self.history:
            self._set_status("nothing to undo")
            return
        machine, params = self.history.pop()
        self._set_design(get_machine(machine), params)

    def action_reset(self) -> None:
        self._remember()
        self._set_design(self.machine, self.machine.defaults())

    def action_explore(self) -> None:
        self.app.open_area_if_installed("explore")

    def action_fabricate(self) -> None:
        self.app.open_area_if_installed("fabricate")

    def action_plot(self) -> None:
        """Queue this pattern on the pen plotter (Machines screen: f frames, g starts)."""
        machine, params = self.current_design()
        machines = self.app.open_area_if_installed("machines")
        if machines is not None:
            machines.plot_design(machine, params, device="plotter")


SCREEN = ScreenEntry(
    name="drawing",
    key="d",
    title="Drawing machines",
    description="Spirograph, elliptic Spirograph, Cycloid Drawing Machine, Hoot-Nanny: patterns live",
    factory=DrawingScreen,
    order=10,
)
