"""Widgets of the Assemble screen's attempt: the forecast always in view, and the run's outcomes to tick.

:class:`ForecastStatus` shows where the attempt is (guide, check, run, log, done), the predicted physical success
and the expected attempts (the last :class:`station.services.assemble.Forecast`), and what the keys do next.
:class:`OutcomeTable` lists the causal graph's events in order: y happened, n did not, u not reached (space cycles,
backspace clears), implied outcomes dim in brackets, as on the Trials screen; a simulated world's report fills it
read-only.
"""

from __future__ import annotations

from rich.text import Text
from textual.binding import Binding
from textual.message import Message
from textual.widgets import DataTable, Static

from station.trialformat import NO, NOT_REACHED, OUTCOMES, YES, goal_reached, resolve_outcomes

STYLE = {YES: "bold green", NO: "bold red", NOT_REACHED: "yellow"}
#: What to do next at each stage, in keys.
NEXT = {
    None: "pick a scenario and a layout, press Enter",
    "guide": "n/p: steps; place the parts, then c: check them",
    "check": "c: check again; f: moved as it says (check again); a: accept as placed, go to the run",
    "run": "r: run (a simulated world runs it; otherwise say what happened: y/n/u per event)",
    "log": "l: log the trial",
    "done": "g: another attempt; k: calibrate the physics on the log; o: re-optimize with it",
}


class ForecastStatus(Static):
    """The attempt's stage, its forecast and the next keys (updated after every check and every logged trial)."""

    DEFAULT_CSS = "ForecastStatus { height: auto; border: round $accent; padding: 0 1; }"

    def show(self, stage: str | None, attempt: int | None = None, forecast=None, busy: str = "",
             extra: str = "") -> None:
        text = Text()
        if stage is not None:
            text.append(f"attempt {attempt} · {stage}\n", style="bold")
        if forecast is not None:
            p = forecast.prediction
            attempts = "never" if p.attempts == float("inf") else f"{p.attempts:.1f}"
            text.append("physical success ")
            text.append(f"{p.probability:.2f}", style="bold green" if p.probability >= 0.8 else "bold yellow")
            text.append(f" ({p.interval[0]:.2f}-{p.interval[1]:.2f}) · expected attempts ")
            text.append(attempts, style="bold")
            text.append(f"\n{forecast.when}\n", style="dim")
        else:
            text.append("physical success: -\n", style="dim")
        if busy:
            text.append(f"{busy}\n", style="italic")
        if extra:
            text.append(f"{extra}\n")
        text.append(NEXT.get(stage, ""), style="dim")
        self.update(text)


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

    def __init__(self, **kwargs) -> None:
        super().__init__(cursor_type="row", zebra_stripes=True, **kwargs)
        self.scenario = None
        self.given: dict[str, str] = {}
        self.read_only = False

    def on_mount(self) -> None:
        self.add_columns("event", "after", "outcome", "at s")

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
                cell = Text(word, style=STYLE[word])
            else:
                cell = Text(f"({word})", style="dim")
            at = f"{self._times[name]:.2f}" if name in self._times else ""
            self.add_row(name, after, cell, at, key=name)
        self.move_cursor(row=min(max(row, 0), max(self.row_count - 1, 0)))
        complete = not problems and all(outcomes.values())
        success = goal_reached(self.scenario, outcomes) if complete else None
        self.post_message(self.Changed(str(problems[0]).replace("outcome.", "", 1) if problems else "", complete,
                                       success))

    def _current(self) -> str | None:
        if self.scenario is None or self.read_only or not self.row_count:
            return None
        return self.scenario.graph_order[self.cursor_row]

    def action_outcome(self, word: str) -> None:
        name = self._current()
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
        name = self._current()
        if name is None:
            return
        cycle = (*OUTCOMES, "")
        following = cycle[(cycle.index(self.given.get(name, "")) + 1) % len(cycle)]
        if following:
            self.given[name] = following
        else:
            self.given.pop(name, None)
        self.refill()  # the cursor stays: space is pressed again on the same event
