"""Trials screen: log a physical run of a contraption, list and filter past runs, export them.

After a run, pick the scenario and the layout that was built, then walk the events in the causal graph's order
(the table) and say what happened: y happened, n did not, u not reached, space cycles, backspace clears. Outcomes
that follow from the others are shown dim in brackets (events after one that did not happen are not reached; the
events a "yes" needed happened) and need no key. l logs the trial (one short transaction in the station database);
the list below shows past trials, filtered by the text in the filter field (a scenario name, "success" or
"failure", a name); e exports the listed scenario's trials (or all) to the file in the export field (.json or .csv).
y / n / u still tick the events table's highlighted event while the past trials have the focus. The screen shows
the scenario and layout chosen on the Assemble screen (its guide, or its fields) whenever that choice changes; c
takes the Contraptions screen's. Files and the database are read and written in workers, never on the UI thread.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import Screen
from textual.widgets import Button, DataTable, Footer, Header, Input, Label, Select, Static

from station.errors import USER_ERRORS
from station.services import trials as service
from station.services.predict import outlook_line, predict_trial
from station.services.station_home import data_dir, local_time
from station.tui.messages import OutlookPredicted, TrialLogged, TrialsExported, TrialsListed
from station.tui.registry import ScreenEntry
from station.tui.widgets.outcomes import OutcomeTable
from station.tui.widgets.scenario_select import scenario_select, select_scenario
from station.tui.work import run_work


def matches(trial: dict[str, Any], text: str) -> bool:
    """Whether a trial fits the filter ``text``: words all found in its scenario name, success/failure, who or
    notes (case-insensitive)."""
    haystack = " ".join([trial["scenario"]["name"], "success" if trial["success"] else "failure",
                         trial["who"] or "", trial["notes"] or ""]).lower()
    return all(word in haystack for word in text.lower().split())


class TrialsScreen(Screen):
    """Log what happened in a physical run, event by event; list, filter and export the log."""

    CSS = """
    TrialsScreen #controls { width: 44; padding: 0 1; }
    TrialsScreen #controls Input { width: 100%; }
    TrialsScreen #controls Button { width: 100%; margin-top: 1; }
    TrialsScreen #right { width: 1fr; }
    TrialsScreen #events { height: auto; max-height: 50%; }
    TrialsScreen #trials { height: 1fr; }
    TrialsScreen .heading { text-style: bold; margin-top: 1; }
    """

    #: y / n / u / space / backspace are the events table's own keys (:class:`OutcomeTable`); y / n / u are the
    #: screen's too, so that they stay shown and working while the past trials have the focus.
    BINDINGS = [
        Binding("y", "outcome('yes')", "Yes"),
        Binding("n", "outcome('no')", "No"),
        Binding("u", "outcome('not-reached')", "Not reached"),
        Binding("l", "log", "Log trial"),
        Binding("e", "export", "Export"),
        Binding("c", "from_contraption", "From Contraptions"),
    ]

    #: Simulations behind the physical success shown after each logged trial (0: none).
    prediction_samples = 48

    def __init__(self) -> None:
        super().__init__(name="trials")
        #: The scenario whose events are ticked (a design.contraption Scenario, from the trials service).
        self.scenario = None
        #: The trials listed (after the filter), oldest first.
        self.trials: list[dict[str, Any]] = []
        self._all: list[dict[str, Any]] = []
        self.last_logged: int | None = None
        #: The Assemble screen's choice last shown here (scenario file, layout text).
        self._assembly_choice: tuple[str, str] | None = None

    def compose(self) -> ComposeResult:
        yield Header()
        with Horizontal():
            with Vertical(id="controls"):
                yield Label("Scenario run", classes="heading")
                yield scenario_select()
                yield Label("Layout built (file, or a named one)")
                yield Input(placeholder="success, LAYOUT.json; empty: the file's own", id="layout")
                yield Label("As built (CHECK.json, optional)")
                yield Input(placeholder="CHECK.json", id="as-built")
                yield Label("Who / notes")
                yield Input(placeholder="your name", id="who")
                yield Input(placeholder="what was different this time", id="notes")
                yield Button("Log trial (l)", id="log", variant="primary")
                yield Label("Filter / export", classes="heading")
                yield Input(placeholder="filter: scenario name, success, failure, who", id="filter")
                yield Input(placeholder="export to .json or .csv (empty: trials.json in the data folder)",
                            id="export-path")
                yield Button("Export (e)", id="export")
                yield Static("", id="status")
                yield Static("", id="outlook")
            with Vertical(id="right"):
                yield Static("", id="summary")
                yield OutcomeTable(id="events", times=False, on_change=self.outcomes_changed)
                yield Label("Past trials", classes="heading")
                yield DataTable(id="trials", cursor_type="row", zebra_stripes=True)
        yield Footer()

    def on_mount(self) -> None:
        events = self.query_one("#events", OutcomeTable)
        self.query_one("#trials", DataTable).add_columns("id", "when", "scenario", "result", "events", "layout",
                                                          "who")
        select = self.query_one("#scenario", Select)
        self.take_assembly_choice()
        if self.scenario is None and select.value is not Select.BLANK:
            self.choose_scenario(str(select.value))
        self.refresh_trials()
        events.focus()

    # -- the scenario and its events ---------------------------------------------------------------------------
    @on(Select.Changed, "#scenario")
    def _scenario_changed(self, event: Select.Changed) -> None:
        if event.value != event.select.value:
            return  # a change the Select has made since (the screen chose another scenario meanwhile)
        if event.value is not Select.BLANK and (self.scenario is None or self.scenario.source != str(event.value)):
            self.choose_scenario(str(event.value))

    def choose_scenario(self, path: str, layout: str | None = None) -> bool:
        """Show scenario ``path``'s events to tick (``layout``: the layout field's text; default its "success"
        layout if it has one; "" the scenario's defaults). Used by c (the Contraptions screen's scenario)."""
        try:
            scenario = service.load_trial_scenario(path)
        except USER_ERRORS as error:
            self.set_status(str(error), "red")
            return False
        self.scenario = scenario
        select = self.query_one("#scenario", Select)
        if str(select.value) != path:
            select_scenario(select, path)
        default = "success" if "success" in scenario.layouts else ""
        self.query_one("#layout", Input).value = layout if layout is not None else default
        self.query_one("#summary", Static).update(Text.assemble(
            (scenario.name, "bold"), f" — {len(scenario.events)} events; goal: {', '.join(scenario.leaves())}. "
            "y happened, n did not, u not reached; l logs."))
        self.query_one("#events", OutcomeTable).load(scenario)
        self.set_status(f"{scenario.name}: say what happened to each event, in order")
        return True

    def action_outcome(self, word: str) -> None:
        """y / n / u while the past trials have the focus: the events table's highlighted event."""
        self.query_one("#events", OutcomeTable).action_outcome(word)

    def take_assembly_choice(self) -> bool:
        """Show the scenario and layout chosen on the Assemble screen, when that choice changed since it was last
        shown here (so that a scenario picked here is kept until the maker chooses another there)."""
        choice = self.app.current_assembly() if hasattr(self.app, "current_assembly") else None
        if choice is None or choice == self._assembly_choice:
            return False
        self._assembly_choice = choice
        scenario, layout = choice
        if self.scenario is not None and Path(self.scenario.source).resolve() == Path(scenario).resolve():
            self.query_one("#layout", Input).value = layout  # the same scenario: the ticks already made stay
            return True
        return self.choose_scenario(scenario, layout)

    def action_from_contraption(self) -> None:
        """Take the scenario and layout shown on the Contraptions screen (the one just simulated and built)."""
        current = self.app.current_contraption() if hasattr(self.app, "current_contraption") else None
        if current is None:
            self.set_status("no scenario on the Contraptions screen", "yellow")
            return
        self.choose_scenario(current[0], current[1])

    @property
    def given(self) -> dict[str, str]:
        """What the maker said, event -> outcome word (implied outcomes are not in it)."""
        return self.query_one("#events", OutcomeTable).given

    def outcomes_changed(self, event: OutcomeTable.Changed) -> None:
        if event.problem:
            self.set_status(event.problem, "yellow")
        elif event.complete:
            self.set_status(f"every event said: a {'success' if event.success else 'failure'}; l logs it", "green")

    def current_event(self) -> str | None:
        return self.query_one("#events", OutcomeTable).current_event()

    def set_status(self, text: str, style: str = "") -> None:
        self.query_one("#status", Static).update(Text(text, style=style))

    # -- logging -------------------------------------------------------------------------------------------------
    @on(Button.Pressed, "#log")
    def action_log(self) -> None:
        if self.scenario is None:
            self.set_status("pick a scenario first", "yellow")
            return
        fields = {key: self.query_one(f"#{key}", Input).value.strip() for key in ("layout", "as-built", "who",
                                                                                 "notes")}
        self.set_status("logging…")
        self._log_worker(self.scenario, dict(self.given), fields)

    def _log_worker(self, scenario, given: dict[str, str], fields: dict[str, str]) -> None:
        def log(_report):
            # an empty layout field: the scenario file's own transforms
            layout = service.read_layout_values(scenario, fields["layout"])
            as_built, check = (service.read_as_built(fields["as-built"], scenario, layout) if fields["as-built"]
                               else (None, None))
            record = service.build_trial(scenario, layout, given, as_built=as_built, check=check,
                                         who=fields["who"], notes=fields["notes"])
            # the service's log: a busy database is waited for, and a trial it cannot take is kept in a file
            trial_id = service.log_trial(record).id
            return trial_id, record, service.logged_trials()

        run_work(self, log, TrialLogged, group="trials-log")

    def on_trial_logged(self, message: TrialLogged) -> None:
        if not message.ok:
            self.set_status(message.error.replace("outcome.", "", 1), "red")
            return
        trial_id, record, trials = message.result
        self.last_logged = trial_id
        self.query_one("#notes", Input).value = ""
        self.query_one("#events", OutcomeTable).load(self.scenario)
        verdict = "success" if record["success"] else "failure"
        self.set_status(f"logged trial #{trial_id} ({record['scenario']['name']}, {verdict})", "green")
        self._show_trials(trials)
        if self.prediction_samples:
            self.query_one("#outlook", Static).update(Text("predicting the physical success…", style="dim"))
            self._outlook_worker(trial_id, self.scenario, record)

    def _outlook_worker(self, trial_id: int, scenario, record: dict) -> None:
        """The physical success of the trial's layout (as built) and the attempts to expect, after every log."""
        samples = self.prediction_samples

        def predict(report):
            return trial_id, predict_trial(scenario, record, samples=samples, report=report)

        run_work(self, predict, OutlookPredicted, group="trials-predict")

    def on_outlook_predicted(self, message: OutlookPredicted) -> None:
        if message.stopped:
            return
        if message.error:
            text = Text(f"no prediction: {message.error}", style="yellow")
        else:
            trial_id, result = message.result
            text = Text(f"after trial #{trial_id}: {outlook_line(result)}")
        self.query_one("#outlook", Static).update(text)

    # -- the list, filter and export -----------------------------------------------------------------------------
    def refresh_trials(self) -> None:
        self._list_worker()

    def _list_worker(self) -> None:
        run_work(self, lambda _report: service.logged_trials(), TrialsListed, group="trials-list")

    def on_trials_listed(self, message: TrialsListed) -> None:
        if message.ok:
            self._show_trials(message.result)
        else:
            self.set_status(message.error, "red")

    def _show_trials(self, trials: list[dict[str, Any]]) -> None:
        self._all = trials
        text = self.query_one("#filter", Input).value
        self.trials = [t for t in trials if matches(t, text)]
        table = self.query_one("#trials", DataTable)
        table.clear()
        for trial in reversed(self.trials):  # newest on top
            built = "as built" if trial["as_built"] else "designed"
            result = Text("success", "green") if trial["success"] else Text("failure", "red")
            table.add_row(str(trial["id"]), local_time(trial["created_at"]), trial["scenario"]["name"],
                          result, service.happened_count(trial), built, trial["who"] or "", key=str(trial["id"]))

    @on(Input.Changed, "#filter")
    def _filter_changed(self) -> None:
        self._show_trials(self._all)

    def on_screen_resume(self) -> None:
        self.take_assembly_choice()
        self.refresh_trials()  # another station or the CLI may have logged meanwhile

    @on(Button.Pressed, "#export")
    def action_export(self) -> None:
        path = self.query_one("#export-path", Input).value.strip()
        target = Path(path).expanduser() if path else data_dir() / "trials.json"
        self._export_worker(target, [t["id"] for t in self.trials])

    def _export_worker(self, path: Path, ids: list[int]) -> None:
        def export(_report):
            return path, service.export_logged(path, ids=ids)

        run_work(self, export, TrialsExported, group="trials-export")

    def on_trials_exported(self, message: TrialsExported) -> None:
        if message.ok:
            path, count = message.result
            self.set_status(f"{count} trial(s) exported to {path}", "green")
        else:
            self.set_status(message.error, "red")

SCREEN = ScreenEntry(
    name="trials",
    key="t",
    title="Trials",
    description="log a physical run of a contraption event by event; list, filter and export the trial log",
    factory=TrialsScreen,
    order=58,
)
