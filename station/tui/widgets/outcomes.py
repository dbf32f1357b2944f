"""The events of a run to tick, in the causal graph's order (the Trials and Assemble screens).

y happened, n did not, u not reached, space cycles, backspace clears; outcomes that follow from the others are shown
dim in brackets (events after one that did not happen are not reached; the events a "yes" needed happened) and need
no key. After every change the table says :class:`OutcomeTable.Changed` (the first problem: an impossible tick, or
the first event still to say; whether every event has an outcome) to its ``on_change`` callback, at once (a status
line set after a change must not be overwritten by a message arriving later), or posts it without one. A simulated
world's report fills it read-only (:meth:`OutcomeTable.load` with ``outcomes``), with the events' times.
"""

from __future__ import annotations

from collections.abc import Callable

from rich.text import Text
from textual.binding import Binding
from textual.message import Message
from textual.widgets import DataTable

from station.trialformat import NO, NOT_REACHED, OUTCOMES, YES, goal_reached, resolve_outcomes

#: How each outcome looks.
OUTCOME_STYLE = {YES: "bold green", NO: "bold red", NOT_REACHED: "yellow"}


class OutcomeTable(DataTable):
    """The events to tick after a run (see the module notes). ``given`` holds what the maker said."""

    BINDINGS = [
        Binding("y", "outcome('yes')", "Happened"),
        Binding("n", "outcome('no')", "Did not"),
        Binding("u", "outcome('not-reached')", "Not reached"),
        Binding("space", "cycle", "Cycle", show=False),
        Binding("backspace", "outcome('')", "Clear", show=False),
    ]

    class Changed(Message):
        """The outcomes changed: ``problem`` is the first thing wrong ("" when none), ``complete`` whether every
        event has an outcome."""

        def __init__(self, problem: str, complete: bool, success: bool | None) -> None:
            super().__init__()
            self.problem, self.complete, self.success = problem, complete, success

    def __init__(self, *, times: bool = True, on_change: Callable[[OutcomeTable.Changed], None] | None = None,
                 **kwargs) -> None:
        super().__init__(cursor_type="row", zebra_stripes=True, **kwargs)
        self.scenario = None
        #: What the maker said, event -> outcome word (implied outcomes are not in it).
        self.given: dict[str, str] = {}
        self.read_only = False
        self._times: dict[str, float] = {}
        self._columns = ("event", "after", "outcome", *(("at s",) if times else ()))
        self.on_change = on_change

    def on_mount(self) -> None:
        for column in self._columns:
            self.add_column(column, key=column)

    def load(self, scenario, outcomes: dict[str, str] | None = None, times: dict[str, float] | None = None) -> None:
        """Show ``scenario``'s events: to tick, or (``outcomes``) as a world reported them, read-only."""
        self.scenario, self.read_only = scenario, outcomes is not None
        self.given = dict(outcomes or {})
        self._times = dict(times or {})
        self.refill()

    def refill(self) -> None:
        outcomes, problems = resolve_outcomes(self.scenario, self.given)
        row = self.cursor_row
        self.clear()
        for name in self.scenario.graph_order:
            spec = self.scenario.event(name)
            after = (" & " if spec.join == "all" else " | ").join(spec.after) or "(start)"
            word = outcomes[name]
            if word is None:
                cell = Text("?", style="dim")
            elif name in self.given:
                cell = Text(word, style=OUTCOME_STYLE[word])
            else:
                cell = Text(f"({word})", style="dim")
            at = (f"{self._times[name]:.2f}" if name in self._times else "",) if len(self._columns) > 3 else ()
            self.add_row(name, after, cell, *at, key=name)
        self.move_cursor(row=min(max(row, 0), max(self.row_count - 1, 0)))
        complete = not problems and all(outcomes.values())
        success = goal_reached(self.scenario, outcomes) if complete else None
        change = self.Changed(str(problems[0]).replace("outcome.", "", 1) if problems else "", complete, success)
        if self.on_change is not None:
            self.on_change(change)
        else:
            self.post_message(change)

    def current_event(self) -> str | None:
        """The highlighted event (None when there is none, or the table is read-only)."""
        if self.scenario is None or self.read_only or not self.row_count:
            return None
        return self.scenario.graph_order[self.cursor_row]

    def action_outcome(self, word: str) -> None:
        name = self.current_event()
        if name is None:
            return
        if word:
            self.given[name] = word
        else:
            self.given.pop(name, None)
        self.refill()
        if word:
            self.action_cursor_down()

    def action_cycle(self) -> None:
        name = self.current_event()
        if name is None:
            return
        cycle = (*OUTCOMES, "")
        following = cycle[(cycle.index(self.given.get(name, "")) + 1) % len(cycle)]
        if following:
            self.given[name] = following
        else:
            self.given.pop(name, None)
        self.refill()  # the cursor stays: space is pressed again on the same event
