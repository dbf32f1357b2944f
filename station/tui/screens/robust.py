"""Optimize screen: a robust layout of a contraption scenario, with live progress (thesis 4.5-4.7).

Pick a scenario, set the simulation budget and seed, press o (Enter in a field, or the button): the PSP is learned
from simulations and the layout optimized in a thread worker while a panel shows the phase, simulations done of the
budget, the cross-validated accuracy and the best PSP. Then the predicted per-event probabilities, the optimized
layout beside the scenario's initial one (a table and side views) and the result's own simulation are shown. s stops
a run cleanly (finished simulations stay in the cache); w writes the layout JSON to the station's data folder.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.css.query import NoMatches
from textual.screen import Screen
from textual.widgets import Button, DataTable, Footer, Header, Input, Label, Select, Static

from station.services import robust as service
from station.services.outlook import disagreement, success_headline
from station.services.predict import layout_outlook
from station.services.reporting import Progress
from station.services.robust import DEFAULT_BUDGET, DEFAULT_SETTINGS, SETTINGS_CHOICES, thesis_budget
from station.services.station_home import data_dir
from station.tui.messages import OptimizationEnded, ProgressReported
from station.tui.registry import ScreenEntry
from station.tui.widgets.picture import HalfBlockPicture
from station.tui.widgets.progress import ProgressPanel
from station.tui.widgets.scenario_select import scenario_choices, select_scenario
from station.tui.work import Work, run_work


def is_run_progress(progress: Progress) -> bool:
    """Whether ``progress`` is the optimization's own (it counts simulations of the budget), not the plain progress
    of the prediction that follows it."""
    return getattr(progress, "simulations", None) is not None


def describe_progress(progress: Progress) -> str:
    """A robust run's progress line: simulations of the budget, the CV accuracy and best PSP once known; the
    prediction of the optimized layout's physical success after it (a plain progress) in its own words."""
    if not is_run_progress(progress):
        total = "" if progress.total is None else f"/{progress.total:g}"
        return f"predicting its physical success on the table: {progress.stage} {progress.done:g}{total}"
    parts = [f"simulations {progress.simulations}/{progress.budget}"]
    if progress.cv_accuracy is not None:
        parts.append(f"CV accuracy {progress.cv_accuracy:.2f}")
    if progress.best_psp is not None:
        parts.append(f"best PSP {progress.best_psp:.3f}")
    if progress.detail:
        parts.append(progress.detail)
    return "   ".join(parts)


class RobustScreen(Screen):
    """Optimize a contraption layout with live progress, then show probabilities and layouts."""

    CSS = """
    RobustScreen #controls { width: 36; padding: 0 1; }
    RobustScreen #controls Input { width: 100%; }
    RobustScreen #controls Button { width: 100%; margin-top: 1; }
    RobustScreen #progress-panel { height: auto; border: round $accent; padding: 0 1; }
    RobustScreen #results { width: 1fr; }
    RobustScreen #tables { height: auto; max-height: 50%; }
    RobustScreen #events, RobustScreen #layout { width: 1fr; height: auto; max-height: 20; }
    RobustScreen #picture { height: 1fr; min-height: 8; }
    RobustScreen .heading { text-style: bold; margin-top: 1; }
    """

    # Priority: the screen's inputs take integers only, so these letters are never typed into them.
    BINDINGS = [
        Binding("o", "optimize", "Optimize", priority=True),
        Binding("s", "stop", "Stop", priority=True),
        Binding("w", "write", "Write layout", priority=True),
        Binding("a", "assemble", "Assemble it", priority=True),
    ]

    def __init__(self) -> None:
        super().__init__(name="optimize")
        #: Local worker processes (None: all cores); tests set 1 to simulate in the worker thread.
        self.simulation_workers: int | None = None
        #: PSP settings that override the "Settings" choice (tests shrink them); None: the choice decides.
        self.psp_settings = None
        #: The optimized layout (design.robust.RobustLayout) once a run has ended.
        self.result = None
        self.outlook = None
        self._optimized_progress: Progress | None = None
        self.problem = None
        self._work: Work | None = None
        self._optimizing = False
        self._pending_scenario: str | None = None

    def compose(self) -> ComposeResult:
        yield Header()
        with Horizontal():
            with Vertical(id="controls"):
                yield Label("Scenario", classes="heading")
                choices = scenario_choices()
                yield Select([(label, path) for label, path in choices], id="scenario", allow_blank=not choices,
                             value=choices[0][1] if choices else Select.BLANK)
                yield Label("Simulation budget")
                yield Input(str(DEFAULT_BUDGET), id="budget", type="integer")
                yield Label("Seed")
                yield Input("0", id="seed", type="integer")
                yield Label("Settings")
                settings = Select([(name, name) for name in SETTINGS_CHOICES], id="settings", allow_blank=False,
                                  value=DEFAULT_SETTINGS)
                settings.tooltip = "\n".join(f"{k}: {v}" for k, v in SETTINGS_CHOICES.items())
                yield settings
                yield Button("Optimize (o)", id="optimize", variant="primary")
                yield Button("Stop (s)", id="stop", disabled=True)
                yield Static("", id="status")
            with Vertical(id="results"):
                yield ProgressPanel("Pick a scenario and press o (Enter in the budget or seed field).",
                                    describe=describe_progress, total=DEFAULT_BUDGET, id="progress-panel")
                with Horizontal(id="tables"):
                    yield DataTable(id="events", cursor_type="row", zebra_stripes=True)
                    yield DataTable(id="layout", cursor_type="row", zebra_stripes=True)
                yield HalfBlockPicture(id="picture", empty="(no layout yet: o optimizes)")
        yield Footer()

    def on_mount(self) -> None:
        self.query_one("#events", DataTable).add_columns("event", "predicted P", "simulated")
        self.query_one("#layout", DataTable).add_columns("parameter", "initial", "optimized", "range")
        if self._pending_scenario is not None:
            path, self._pending_scenario = self._pending_scenario, None
            self.choose_scenario(path)

    # -- controls ----------------------------------------------------------------------------------------------
    @on(Select.Changed, "#scenario")
    def _scenario_changed(self, event: Select.Changed) -> None:
        if event.value is Select.BLANK:
            return
        self.query_one("#budget", Input).value = str(thesis_budget(Path(str(event.value)).stem))

    @on(Button.Pressed, "#optimize")
    def _optimize_pressed(self) -> None:
        self.action_optimize()

    @on(Input.Submitted, "#budget, #seed")
    def _field_submitted(self) -> None:
        # Letter keys type into a focused field, so o cannot start a run from there; Enter does, and focus leaves the
        # field so that s can stop the run.
        self.query_one("#events", DataTable).focus()
        self.action_optimize()

    @on(Button.Pressed, "#stop")
    def _stop_pressed(self) -> None:
        self.action_stop()

    def _set_status(self, text: str | Text, style: str = "") -> None:
        """Show ``text`` (a string is plain text in ``style``: paths, typed values and error messages are never
        read as markup; a :class:`~rich.text.Text` keeps its own styles)."""
        self.query_one("#status", Static).update(text if isinstance(text, Text) else Text(text, style=style))

    def _read_int(self, widget_id: str, name: str, minimum: int) -> int | None:
        text = self.query_one(f"#{widget_id}", Input).value.strip()
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < minimum:
            self._set_status(f"{name} must be an integer >= {minimum}, got {text!r}", style="red")
            self.query_one(f"#{widget_id}", Input).focus()  # back to the field to mend, where typing goes
            return None
        return value

    def choose_scenario(self, path: str) -> None:
        """Select the scenario file ``path`` (added to the list if it is not an example), ready for ``o``."""
        try:
            select = self.query_one("#scenario", Select)
        except NoMatches:  # not composed yet: chosen on mount
            self._pending_scenario = path
            return
        select_scenario(select, path)

    def action_optimize(self) -> None:
        if self._optimizing:
            self._set_status("a run is in progress; s stops it")
            return
        scenario = self.query_one("#scenario", Select).value
        if scenario is Select.BLANK:
            self._set_status("no scenario chosen", style="red")
            return
        budget = self._read_int("budget", "budget", 20)
        seed = self._read_int("seed", "seed", 0)
        if budget is None or seed is None:
            return
        self._optimizing = True
        self.query_one("#optimize", Button).disabled = True
        self.query_one("#stop", Button).disabled = False
        self.query_one(ProgressPanel).start(budget)
        self._set_status(f"optimizing {Path(str(scenario)).stem} ...")
        settings = self.psp_settings or service.psp_settings(str(self.query_one("#settings", Select).value))
        self.run_optimization(str(scenario), budget, seed, settings)

    def action_stop(self) -> None:
        if self._optimizing and self._work is not None:
            self._work.stop()
            self._set_status("stopping (finished simulations stay cached) ...")

    def action_write(self) -> Path | None:
        """Write the layout (with its success model) to the station's data folder; its path."""
        if self.result is None or self.problem is None:
            self._set_status("nothing to write yet")
            return None
        folder = data_dir() / "layouts"
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"{self.result.scenario.lower()}-seed{self.result.seed}.json"
        payload = self.result.to_json(self.problem)
        if self.outlook is not None:
            payload["physical_success"] = self.outlook.to_json()
        path.write_text(json.dumps(payload, indent=2) + "\n", encoding="utf-8")
        self._set_status(f"wrote {path}")
        return path

    def action_assemble(self) -> None:
        """Write the layout and open it on the Assemble screen (its guide, steps and tolerances)."""
        path = self.action_write()
        if path is None:
            return
        assemble = self.app.open_area_if_installed("assemble")
        if assemble is not None:
            assemble.open_layout(str(self.problem.scenario.source), str(path))

    # -- the work (a thread) -----------------------------------------------------------------------------------
    def run_optimization(self, scenario_path: str, budget: int, seed: int, settings) -> None:
        """Optimize in a worker; progress and the end reach the screen as messages, in the order they happened."""
        workers = self.simulation_workers

        def optimize(report):
            problem = service.load_problem(scenario_path)
            result = service.optimize(problem, budget, seed, settings, workers=workers, report=report)
            outlook = layout_outlook(problem, problem.to_real(result.u), seed=seed, workers=workers, report=report)
            return problem, result, service.layouts_picture(problem, result.u), outlook

        self._work = run_work(self, optimize, OptimizationEnded, group="robust")

    def on_progress_reported(self, message: ProgressReported) -> None:
        self._show_progress(message.progress)

    def _show_progress(self, progress: Progress) -> None:
        if is_run_progress(progress):
            self._optimized_progress = progress  # the panel ends on the optimization's figures, not the prediction's
        self.query_one(ProgressPanel).show(progress)

    def on_optimization_ended(self, message: OptimizationEnded) -> None:
        self._optimizing = False
        self.query_one("#optimize", Button).disabled = False
        self.query_one("#stop", Button).disabled = True
        if message.stopped:
            self._set_status(message.error)
        elif message.error:
            self._set_status(Text(f"cannot optimize: {message.error}", "red"))
        else:
            self._finished(*message.result)

    def _finished(self, problem, result, png: bytes, outlook) -> None:
        self.problem, self.result, self.outlook = problem, result, outlook
        events = self.query_one("#events", DataTable)
        events.clear()
        simulated = dict(zip(result.event_names, result.simulated_events))
        labels = getattr(problem, "event_labels", {})
        for name, p in zip(result.factor_names, result.factor_probabilities):
            note = " (quasi-det.)" if name in result.quasi_deterministic else ""
            events.add_row(Text(labels.get(name, name)), f"{p:.3f}{note}",
                           "success" if simulated.get(name) else "failure", key=name)
        events.add_row("[b]model's score (PSP, product)[/b]", f"{result.psp:.3f}",
                       "success" if result.simulated_success else "failure", key="__psp__")
        layout = self.query_one("#layout", DataTable)
        layout.clear()
        initial = problem.to_real(problem.initial_layout())
        optimized = problem.to_real(result.u)
        for i, name in enumerate(problem.parameter_names):
            layout.add_row(name, f"{initial[i]:.4g}", f"{optimized[i]:.4g}",
                           f"[{problem.lower[i]:.4g}, {problem.upper[i]:.4g}]", key=name)
        self.query_one("#picture", HalfBlockPicture).set_png(png)
        verdict = "succeeds" if result.simulated_success else "FAILS"
        headline = (success_headline(outlook, when="placed by the guide") + "; " if outlook is not None else "")
        warning = disagreement(result.psp, outlook.probability if outlook is not None else None)
        self._set_status(f"{result.scenario}: {headline}the optimized layout {verdict} in simulation; "
                         f"{result.n_simulations} simulations ({result.n_new_simulations} new), "
                         f"{result.seconds:.1f} s; kept {result.kept_candidate()}. w writes it."
                         + (f" Note: {warning}." if warning else ""))
        moved = float(np.linalg.norm(result.u - problem.initial_layout()))
        if self._optimized_progress is not None:
            self.query_one(ProgressPanel).show(self._optimized_progress)
        self.query_one(ProgressPanel).say(
            f"simulations {result.n_simulations}/{result.budget}   CV accuracy {result.cv_accuracy:.2f}   "
            f"success model's own score (PSP) {result.psp:.3f}   moved {moved:.2f} (normalized) from the initial "
            "layout")


SCREEN = ScreenEntry(
    name="optimize",
    key="o",
    title="Robust layouts",
    description="optimize a contraption layout for robustness (PSP, per-event probabilities)",
    factory=RobustScreen,
    order=55,
)
