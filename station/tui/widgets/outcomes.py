"""The events of a run to tick, in the causal graph's order (the Trials and Assemble screens).

y happened, n did not, u not reached, space cycles, backspace clears; outcomes that follow from the others are shown
dim in brackets (events after one that did not happen are not reached; the events a "yes" needed happened) and need
no key. After an answer the cursor goes to the first event still to say (the one the hint names), skipping the
implied ones; a key on an implied event never overrides it: one that agrees changes nothing, another is refused and
says which event to change instead. After every change the table says :class:`OutcomeTable.Changed` (the first
problem: an impossible tick, a refused key, or the first event still to say; whether every event has an outcome) to
its ``on_change`` callback, at once (a status line set after a change must not be overwritten by a message arriving
later), or posts it without one. A simulated world's report fills it read-only (:meth:`OutcomeTable.load` with
``outcomes``), with the events' times.
"""

from __future__ import annotations

from collections.abc import Callable

from rich.text import Text
from textual.binding import Binding
from textual.message import Message
from textual.widgets import DataTable

from station.services.trial_outcomes import NO, NOT_REACHED, OUTCOMES, YES, goal_reached, resolve_outcomes

#: How each outcome looks.
OUTCOME_STYLE = {YES: "bold green", NO: "bold red", NOT_REACHED: "yellow"}


class OutcomeTable(DataTable):
    """The events to tick after a run (see the module notes). ``given`` holds what the maker said."""

    BINDINGS = [
        Binding("y", "outcome('yes')", "Yes"),
        Binding("n", "outcome('no')", "No"),
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

    def refill(self, notice: str = "") -> None:
        """Draw the outcomes again and say the change (``notice``: a refused key, said instead of the first
        problem)."""
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
        problem = notice or (str(problems[0]).replace("outcome.", "", 1) if problems else "")
        change = self.Changed(problem, complete and not notice, success)
        if self.on_change is not None:
            self.on_change(change)
        else:
            self.post_message(change)

    def current_event(self) -> str | None:
        """The highlighted event (None when there is none, or the table is read-only)."""
        if self.scenario is None or self.read_only or not self.row_count:
            return None
        return self.scenario.graph_order[self.cursor_row]

    def next_to_say(self) -> str | None:
        """The first event, in the graph's order, that nothing said or implied yet (None: every event has one)."""
        outcomes, _ = resolve_outcomes(self.scenario, self.given)
        return next((name for name, word in outcomes.items() if word is None), None)

    def implied(self, name: str) -> str | None:
        """``name``'s outcome when it follows from what was said (None: said, or still to say)."""
        if name in self.given:
            return None
        return resolve_outcomes(self.scenario, self.given)[0][name]

    def _implied_why(self, name: str, word: str) -> str:
        """Why ``name`` is implied ``word``, naming the event to change instead."""
        outcomes, _ = resolve_outcomes(self.scenario, self.given)
        if word == NOT_REACHED:
            stopped = [p for p in self.scenario.event(name).after if outcomes[p] in (NO, NOT_REACHED)]
            return (f"{name} is not reached: {', '.join(f'{p} is {outcomes[p]!r}' for p in stopped)}; change "
                    f"{stopped[0]} to change it")
        later = next((later for later in self.scenario.graph_order
                      if self.given.get(later) in (YES, NO) and name in self._needed(later)), None)
        if later is None:  # resolve_outcomes implies "yes" only for an event said later: not expected
            return f"{name} is implied {word!r} by the events said"
        return f"{name} happened: {later} is {self.given[later]!r}, so it was reached; change {later} to change it"

    def _needed(self, name: str) -> set[str]:
        """The events that had to happen for ``name`` (said "yes" or "no") to be reached: the parents it waits for
        (all of them, or its only one), and theirs, as :func:`station.trialformat.resolve_outcomes` implies them."""
        needed: set[str] = set()
        todo = [name]
        while todo:
            spec = self.scenario.event(todo.pop())
            for parent in spec.after if spec.join == "all" or len(spec.after) == 1 else ():
                if parent not in needed:
                    needed.add(parent)
                    if self.given.get(parent, YES) in (YES, NO):  # "not-reached" said: nothing above it implied
                        todo.append(parent)
        return needed

    def _say(self, name: str, word: str) -> None:
        """Set ``name`` to ``word`` ("" clears it), unless it is implied; after an answer, move to the first event
        still to say."""
        implied = self.implied(name)
        if implied is not None and word and word != implied:
            self.refill(notice=self._implied_why(name, implied))
            return
        if word and implied is None:
            self.given[name] = word
        elif not word:
            self.given.pop(name, None)
        # an answer that agrees with an implied outcome keeps it implied: it goes on following its causes
        self.refill()
        if word:
            following = self.next_to_say()
            if following is not None:
                self.move_cursor(row=self.scenario.graph_order.index(following))
            elif implied is None:
                self.action_cursor_down()

    def action_outcome(self, word: str) -> None:
        name = self.current_event()
        if name is not None:
            self._say(name, word)

    def action_cycle(self) -> None:
        name = self.current_event()
        if name is None:
            return
        implied = self.implied(name)
        if implied is not None:
            self.refill(notice=self._implied_why(name, implied))
            return
        cycle = (*OUTCOMES, "")
        following = cycle[(cycle.index(self.given.get(name, "")) + 1) % len(cycle)]
        if following:
            self.given[name] = following
        else:
            self.given.pop(name, None)
        self.refill()  # the cursor stays: space is pressed again on the same event
