"""A slider of the guided-exploration invariant space: value in [-2, 2], live bounds, explicit release.

Moving it (left/right, or a click) previews the design; releasing it (Enter, or the end of a click) asks the owner
to re-project onto the invariants, as the thesis does when the mouse button is released.
"""

from __future__ import annotations

from rich.text import Text
from textual import events
from textual.binding import Binding
from textual.message import Message
from textual.widget import Widget

from station.tui.widgets.bounded_keys import bounded_value_bindings, one_line_control_css

SPAN = 2.0
BAR_WIDTH = 25
#: How far left/right (coarse) and shift+left/right (fine) move a slider.
NUDGE = {"coarse": 0.2, "fine": 0.05}


class InvariantSlider(Widget, can_focus=True):
    """One invariant-space slider.

    Parameters
    ----------
    index : int
        The slider's index in the explorer.
    label : str
        Name shown on the left (``"axis 1"`` or a parameter name).
    value, lower, upper : float
        Current value and bounds (within [-2, 2]).
    """

    DEFAULT_CSS = one_line_control_css("InvariantSlider")

    BINDINGS = [
        *bounded_value_bindings(lambda direction, size: f"{direction * NUDGE[size]:g}"),
        Binding("enter", "release", "Release", show=True),
    ]

    class Moved(Message):
        """Preview: the slider's value changed (already inside its bounds)."""

        def __init__(self, slider: InvariantSlider, index: int, value: float) -> None:
            super().__init__()
            self.slider = slider
            self.index = index
            self.value = value

    class Released(Message):
        """The user let go of the slider: re-project."""

        def __init__(self, slider: InvariantSlider, index: int) -> None:
            super().__init__()
            self.slider = slider
            self.index = index

    def __init__(self, index: int, label: str, value: float, lower: float, upper: float, *, id: str | None = None):
        super().__init__(id=id)
        self.index = index
        self.label = label
        self.value = float(value)
        self.lower = float(lower)
        self.upper = float(upper)

    def set_state(self, value: float, lower: float, upper: float) -> None:
        """New value and bounds from the owner (posts nothing)."""
        self.value, self.lower, self.upper = float(value), float(lower), float(upper)
        self.refresh()

    def _propose(self, value: float) -> None:
        value = min(max(float(value), self.lower), self.upper)
        if value != self.value:
            self.value = value
            self.refresh()
            self.post_message(self.Moved(self, self.index, value))

    def action_nudge(self, step: float) -> None:
        self._propose(self.value + step)

    def action_to_bound(self, which: str) -> None:
        self._propose(self.lower if which == "lower" else self.upper)

    def action_release(self) -> None:
        self.post_message(self.Released(self, self.index))

    def _bar_start(self) -> int:
        return len(f"{self.label:<8} ")

    def on_click(self, event: events.Click) -> None:
        offset = event.x - self.styles.padding.left - self._bar_start() - 1
        if 0 <= offset < BAR_WIDTH:
            self._propose(-SPAN + 2 * SPAN * offset / (BAR_WIDTH - 1))
            self.post_message(self.Released(self, self.index))

    def render(self) -> Text:
        cells = []
        for k in range(BAR_WIDTH):
            x = -SPAN + 2 * SPAN * k / (BAR_WIDTH - 1)
            cells.append("─" if self.lower - 1e-9 <= x <= self.upper + 1e-9 else " ")
        position = round((self.value + SPAN) / (2 * SPAN) * (BAR_WIDTH - 1))
        position = min(max(position, 0), BAR_WIDTH - 1)
        text = Text(f"{self.label:<8} ", style="bold")
        text.append("[")
        text.append("".join(cells[:position]), style="cyan")
        text.append("●", style="bold yellow")
        text.append("".join(cells[position + 1 :]), style="cyan")
        text.append("]")
        text.append(f" {self.value:+.2f}  [{self.lower:+.2f}, {self.upper:+.2f}]", style="dim")
        return text
