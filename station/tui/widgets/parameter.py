"""A focusable slider (continuous parameters) or stepper (discrete parameters) with live bounds.

The control never shows a value outside its current bounds: the screen that owns it recomputes the bounds of every
control whenever one moves (the feasible interval of each parameter with the others fixed), so an infeasible value is
never reachable. A discrete stepper asks its owner for the next feasible value instead of simply adding one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rich.text import Text
from textual import events
from textual.message import Message
from textual.widget import Widget

from station.tui.widgets.bounded_keys import bounded_value_bindings, one_line_control_css

BAR_WIDTH = 20


def _decimals(lower: float, upper: float) -> int:
    """Decimal places that show about three significant digits of the span (0 for a span of 100 or more)."""
    span = upper - lower
    if not math.isfinite(span) or span <= 0:
        span = max(abs(lower), abs(upper), 1.0)
    return max(0, 2 - math.floor(math.log10(span)))


def _plain(value: float, decimals: int) -> str:
    """``value`` with ``decimals`` places, trailing zeros dropped (``3``, ``0.25``), never ``-0``."""
    text = f"{value:.{decimals}f}"
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def format_bounds(lower: float, upper: float) -> str:
    """The interval ``[lower, upper]`` for people: ``(0…3]`` rather than ``[4.94e-324…3]``.

    The feasible interval's ends are feasible values; where a constraint is strict (``d > 0``) the end lies a few
    ulps inside the boundary. Such an end, within a billionth of the span of a round number, is shown as that number
    with an open bracket; every other end is rounded to about three significant digits of the span, closed.
    """
    decimals = _decimals(lower, upper)
    tolerance = 1e-9 * max(upper - lower, abs(lower), abs(upper), 1e-300)

    def end(value: float) -> tuple[str, bool]:
        rounded = round(value, decimals)
        is_open = value != rounded and abs(value - rounded) <= tolerance
        return _plain(rounded, decimals), is_open

    low, low_open = end(lower)
    high, high_open = end(upper)
    return f"{'(' if low_open else '['}{low}…{high}{')' if high_open else ']'}"


def format_value(value: float, lower: float, upper: float) -> str:
    """A slider's value with one more decimal place than its bounds (a fine step shows), fixed width."""
    decimals = _decimals(lower, upper) + 1
    text = f"{value:.{decimals}f}"
    return "0" + text[2:] if text.startswith("-0") and float(text) == 0 else text


@dataclass(frozen=True)
class ParameterState:
    """What a control shows: its value and the bounds in which it may move."""

    value: float
    lower: float
    upper: float


class ParameterControl(Widget, can_focus=True):
    """One design parameter: a slider when ``discrete`` is False, a stepper when True.

    Parameters
    ----------
    parameter_name : str
        The model's parameter name (shown, and sent in messages).
    discrete : bool
        Integer stepper instead of a slider.
    state : ParameterState
        Initial value and bounds.
    description : str
        Shown as the tooltip.
    """

    DEFAULT_CSS = one_line_control_css("ParameterControl")

    BINDINGS = bounded_value_bindings(lambda direction, size: f"{direction}, {size!r}")

    class Changed(Message):
        """The user moved the control; ``value`` is already inside the control's bounds."""

        def __init__(self, control: ParameterControl, name: str, value: float) -> None:
            super().__init__()
            self.parameter_control = control
            self.name = name
            self.value = value

        @property
        def control(self) -> ParameterControl:
            return self.parameter_control

    class StepRequested(Message):
        """A discrete stepper wants the next feasible value in ``direction`` (+1 or -1)."""

        def __init__(self, control: ParameterControl, name: str, direction: int) -> None:
            super().__init__()
            self.parameter_control = control
            self.name = name
            self.direction = direction

        @property
        def control(self) -> ParameterControl:
            return self.parameter_control

    def __init__(
        self,
        parameter_name: str,
        *,
        discrete: bool,
        state: ParameterState,
        description: str = "",
        id: str | None = None,
    ) -> None:
        super().__init__(id=id)
        self.parameter_name = parameter_name
        self.discrete = discrete
        self.state = state
        if description:
            self.tooltip = description

    # --- state -------------------------------------------------------------------------------------------------
    def set_state(self, state: ParameterState) -> None:
        """Show a new value and bounds (called by the owner; posts no message)."""
        self.state = state
        self.refresh()

    @property
    def value(self) -> float:
        return self.state.value

    def _clamped(self, value: float) -> float:
        return min(max(value, self.state.lower), self.state.upper)

    def _propose(self, value: float) -> None:
        value = self._clamped(value)
        if value != self.state.value:
            self.state = ParameterState(value, self.state.lower, self.state.upper)
            self.refresh()
            self.post_message(self.Changed(self, self.parameter_name, value))

    # --- actions -----------------------------------------------------------------------------------------------
    def action_nudge(self, direction: int, size: str) -> None:
        if self.discrete:
            self.post_message(self.StepRequested(self, self.parameter_name, int(direction)))
            return
        span = self.state.upper - self.state.lower
        step = span / (1000 if size == "fine" else 50)
        self._propose(self.state.value + direction * step)

    def action_to_bound(self, which: str) -> None:
        if self.discrete:
            return
        self._propose(self.state.lower if which == "lower" else self.state.upper)

    def on_click(self, event: events.Click) -> None:
        self.focus()
        if self.discrete:
            # Clicking the left arrow steps down, the right arrow steps up.
            label_end = self._label_width()
            if event.x < label_end + 3:
                self.post_message(self.StepRequested(self, self.parameter_name, -1))
            else:
                self.post_message(self.StepRequested(self, self.parameter_name, 1))
            return
        bar_start = self._label_width() + 1
        position = (event.x - bar_start) / max(BAR_WIDTH - 1, 1)
        if 0 <= position <= 1:
            self._propose(self.state.lower + position * (self.state.upper - self.state.lower))

    # --- rendering ---------------------------------------------------------------------------------------------
    def _label_width(self) -> int:
        return 10

    def render(self) -> Text:
        label = f"{self.parameter_name:<{self._label_width()}}"
        text = Text(label, style="bold")
        value, lower, upper = self.state.value, self.state.lower, self.state.upper
        if self.discrete:
            text.append(" ◀ ", style="cyan")
            text.append(f"{int(round(value)):>4d}", style="bold")
            text.append(" ▶ ", style="cyan")
            text.append(f" gear radius  [{int(lower)}…{int(upper)}]", style="dim")
            return text
        span = upper - lower
        fraction = 0.5 if span <= 0 else (value - lower) / span
        knob = int(round(fraction * (BAR_WIDTH - 1)))
        text.append("[")
        text.append("━" * knob, style="cyan")
        text.append("●", style="bold yellow")
        text.append("─" * (BAR_WIDTH - 1 - knob), style="dim")
        text.append("] ")
        text.append(f"{format_value(value, lower, upper):>7}", style="bold")
        text.append(f" {format_bounds(lower, upper)}", style="dim")
        return text
