"""Calibrate > Simulator: fit the scenarios' uncertain material values to logged trials, with progress and a stop.

A panel for the Calibrate screen: the scenarios (example names or files, comma-separated), the values to fit (blank:
every uncertain one, listed under the field; with "every material value" ticked, the plain numbers too, each within
its default range, as ``station calibrate sim --all-materials`` and ``station loop`` fit them), where the trials
come from (a trial export file, or the station's log when the screen gives
:attr:`SimCalibrationPanel.trials_source`), Start (``c`` or Enter in a field), Stop (``s``), a
:class:`~station.tui.widgets.progress.ProgressPanel`, and the result: each value before and fitted with its
interval, the agreement per event before and after, and the held-out Brier score (the line under the progress,
then the two tables, each as tall as its rows: the panel scrolls, and shows the result from its progress down when a
calibration ends). ``w`` writes the physics profile to the station's data folder (``physics/``), for ``--physics``
and the Robust layouts screen.

The work runs in a thread worker through :func:`station.services.sim_calibration.calibrate_sim` (simulations on the
optimizer's executors and shared cache, so a stopped calibration keeps what it simulated).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.widgets import Button, Checkbox, DataTable, Input, Label, Static

from station.errors import USER_ERRORS
from station.services import sim_calibration as service
from station.services.contraption import open_scenario
from station.services.station_home import data_dir
from station.tui.messages import ProgressReported, SimulatorCalibrated
from station.tui.widgets.progress import ProgressPanel
from station.tui.work import Work, run_work


class SimCalibrationPanel(Vertical):
    """The Calibrate > Simulator panel (see the module notes).

    Parameters
    ----------
    scenarios : str
        The scenarios field's first value (comma-separated names or files).
    trials_source : callable, optional
        ``() -> list of trial dicts`` in the export format: the station's trial log. Without it (or with a file in
        the trials field) the trials come from an export file.
    """

    DEFAULT_CSS = """
    SimCalibrationPanel { height: auto; overflow-y: auto; }
    SimCalibrationPanel #sim-fields { height: auto; }
    SimCalibrationPanel #sim-fields Vertical { width: 1fr; height: auto; padding: 0 1; }
    SimCalibrationPanel #sim-fields Input { width: 100%; }
    SimCalibrationPanel #sim-buttons { height: auto; }
    SimCalibrationPanel #sim-buttons Button { margin-right: 1; }
    SimCalibrationPanel DataTable { height: auto; }
    SimCalibrationPanel #sim-status { height: auto; }
    SimCalibrationPanel .heading { text-style: bold; }
    """

    BINDINGS = [
        Binding("c", "start", "Calibrate"),
        Binding("s", "stop", "Stop"),
        Binding("w", "write", "Write profile"),
    ]

    def __init__(self, scenarios: str = "", trials_source: Callable[[], list[dict]] | None = None, *,
                 id: str | None = None) -> None:
        super().__init__(id=id)
        self._first_scenarios = scenarios
        self.trials_source = trials_source
        #: Local worker processes (None: all cores); tests set 1 to simulate in the worker thread.
        self.simulation_workers: int | None = None
        #: The fit's sizes (None: the defaults); tests shrink them.
        self.fit_settings = None
        self.result = None
        self.calibrating = False
        self._work: Work | None = None
        self._reveal_result = False  # a result was shown and no calibration started since

    def compose(self) -> ComposeResult:
        yield Label("[b]Simulator[/b] (material values fitted to the trial log)")
        with Horizontal(id="sim-fields"):
            with Vertical():
                yield Label("Scenarios", classes="heading")
                yield Input(self._first_scenarios, placeholder="ballrun, simple.toml", id="sim-scenarios")
            with Vertical():
                yield Label("Values to fit (blank: all uncertain)", classes="heading")
                yield Input("", placeholder="wood.friction,steel.restitution", id="sim-params")
            with Vertical():
                yield Label("Trials (export file; blank: the log)", classes="heading")
                yield Input("", placeholder="trials.json", id="sim-trials")
        yield Checkbox("every material value, the plain ones too", False, id="sim-every")
        yield Static("", id="sim-uncertain")
        with Horizontal(id="sim-buttons"):
            yield Button("Calibrate (c)", id="sim-start", variant="primary")
            yield Button("Stop (s)", id="sim-stop", disabled=True)
            yield Button("Write profile (w)", id="sim-write", disabled=True)
        yield ProgressPanel("Name the scenarios and press c (or Enter in a field).", id="sim-progress")
        yield Static("", id="sim-status")
        yield DataTable(id="sim-values", cursor_type="row", zebra_stripes=True)
        # headers on two lines: the six columns fit the Calibrate screen's half width (80 columns) unscrolled
        yield DataTable(id="sim-events", cursor_type="row", zebra_stripes=True, header_height=2)

    def on_mount(self) -> None:
        self.query_one("#sim-values", DataTable).add_columns("value", "before", "fitted", "95 % interval", "range")
        self.query_one("#sim-events", DataTable).add_columns("event", "observed\nyes", "sim\nbefore", "sim\nafter",
                                                             "agree\nbefore", "agree\nafter")
        if self._first_scenarios:
            self._list_uncertain(self._first_scenarios)

    # -- controls ----------------------------------------------------------------------------------------------
    def status(self, text: str | Text, style: str = "") -> None:
        """Show ``text`` under the panel (plain text: file names and errors are never read as markup)."""
        self.query_one("#sim-status", Static).update(text if isinstance(text, Text) else Text(text, style=style))

    @property
    def every_material(self) -> bool:
        """Whether the plain material values are fitted too (the "every material value" box)."""
        return self.query_one("#sim-every", Checkbox).value

    @on(Input.Changed, "#sim-scenarios")
    def _scenarios_changed(self, event: Input.Changed) -> None:
        self._list_uncertain(event.value)

    @on(Checkbox.Changed, "#sim-every")
    def _every_changed(self) -> None:
        self._list_uncertain(self.query_one("#sim-scenarios", Input).value)

    def _list_uncertain(self, text: str) -> None:
        words = []
        for name in _split(text):
            try:
                scenario = open_scenario(name)
            except (ValueError, OSError):
                continue  # still being typed
            values = ", ".join(f"{k} {v:g} in [{lo:g}, {hi:g}]" for k, (v, (lo, hi)) in
                               service.material_ranges(scenario, self.every_material).items()) or "none"
            words.append(f"{scenario.name}: {values}")
        self.query_one("#sim-uncertain", Static).update(Text("\n".join(words)))

    @on(Button.Pressed, "#sim-start")
    @on(Input.Submitted)
    def _start_pressed(self) -> None:
        self.action_start()

    @on(Button.Pressed, "#sim-stop")
    def _stop_pressed(self) -> None:
        self.action_stop()

    @on(Button.Pressed, "#sim-write")
    def _write_pressed(self) -> None:
        self.action_write()

    def action_start(self) -> None:
        if self.calibrating:
            self.status("a calibration is running; s stops it")
            return
        scenarios = _split(self.query_one("#sim-scenarios", Input).value)
        if not scenarios:
            self.status("name at least one scenario", style="red")
            return
        params = _split(self.query_one("#sim-params", Input).value) or None
        trials_file = self.query_one("#sim-trials", Input).value.strip() or None
        if trials_file is None and self.trials_source is None:
            self.status("give a trial export file (station trial export --out FILE.json)", style="red")
            return
        self.calibrating = True
        self._reveal_result = False
        self.query_one("#sim-start", Button).disabled = True
        self.query_one("#sim-stop", Button).disabled = False
        self.query_one(ProgressPanel).start(None, "reading the trials ...")
        self.query_one("#sim-values", DataTable).focus()  # letters reach the bindings, not a field
        self.status(f"calibrating {', '.join(scenarios)} ...")
        self.run_calibration(scenarios, params, trials_file, self.every_material)

    def action_stop(self) -> None:
        if self.calibrating and self._work is not None:
            self._work.stop()
            self.status("stopping (finished simulations stay cached) ...")

    def action_write(self) -> Path | None:
        """Write the fitted physics profile to the data folder's ``physics/``; its path."""
        if self.result is None:
            self.status("nothing to write yet")
            return None
        folder = data_dir() / "physics"
        folder.mkdir(parents=True, exist_ok=True)
        stem = "-".join(s.name.lower() for s in self.result.scenarios)
        path = service.save(self.result, folder / f"{stem}.toml")
        self.status(f"wrote {path}")
        return path

    # -- the work (a thread) -----------------------------------------------------------------------------------
    def run_calibration(self, scenarios: list[str], params: list[str] | None, trials_file: str | None,
                        every_material: bool = False) -> None:
        """Calibrate in a worker; progress and the end arrive as messages."""
        trials_source, settings, workers = self.trials_source, self.fit_settings, self.simulation_workers

        def calibrate(report):
            loaded = [open_scenario(name) for name in scenarios]
            if trials_file is not None:
                trials, source = service.read_trials_json(trials_file), trials_file
            else:
                trials, source = trials_source(), "the trial log"
            request = service.SimCalibrationRequest(tuple(params) if params else None, settings=settings,
                                                    source=source, every_material=every_material, workers=workers)
            return service.calibrate_sim(loaded, trials, request, report=report)

        self._work = run_work(self, calibrate, SimulatorCalibrated, group="sim-calibration",
                              errors=(*USER_ERRORS, ValueError))

    def on_progress_reported(self, message: ProgressReported) -> None:
        message.stop()
        self.query_one(ProgressPanel).show(message.progress)

    def on_simulator_calibrated(self, message: SimulatorCalibrated) -> None:
        message.stop()
        self.calibrating = False
        self.query_one("#sim-start", Button).disabled = False
        self.query_one("#sim-stop", Button).disabled = True
        if not message.ok:
            self.status("stopped; finished simulations are cached" if message.stopped
                        else Text(f"cannot calibrate: {message.error}", "red"))
            self.query_one(ProgressPanel).say("")
            return
        self.result = fit_result = message.result
        fit = fit_result.fit
        values = self.query_one("#sim-values", DataTable)
        values.clear()
        for p in fit.parameters:
            # intervals as "lo-hi" at 3 digits: the five columns fit the screen's half width unscrolled
            values.add_row(p.name, f"{p.before:.4g}", f"{p.value:.4g}", f"{p.interval[0]:.3g}-{p.interval[1]:.3g}",
                           f"{p.range[0]:.3g}-{p.range[1]:.3g}", key=p.name)
        events = self.query_one("#sim-events", DataTable)
        events.clear()
        for a in fit.agreement:
            events.add_row(f"{a.scenario}.{a.event}", f"{a.observed_yes:.2f}", f"{a.predicted_yes_before:.2f}",
                           f"{a.predicted_yes_after:.2f}", f"{a.agreement_before:.2f}", f"{a.agreement_after:.2f}")
        self.query_one("#sim-write", Button).disabled = False
        if fit.brier_before is None:
            brier = "too few trials to hold some out"
        else:
            brier = f"held-out Brier {fit.brier_before:.3f} before, {fit.brier_after:.3f} after"
        self.query_one(ProgressPanel).say(f"{fit.simulations} simulations, {fit.candidates} candidate values")
        self.status(f"{fit.trials} trials fitted, {fit.held_out} held out; {brier}. w writes the profile.")
        self._reveal_result = True
        self.call_after_refresh(self._reveal)

    def _reveal(self) -> None:
        """The result, from the progress down, in view: the fields above it scroll out of the way."""
        self.scroll_to_widget(self.query_one(ProgressPanel), top=True, animate=False)

    def on_resize(self) -> None:
        # a table takes its rows' height a refresh or more after it is filled, and a scroll is clamped to the
        # scrollable height of its moment: scroll again as that grows, until the next calibration starts
        if self._reveal_result:
            self._reveal()


def _split(text: str) -> list[str]:
    return [part.strip() for part in text.split(",") if part.strip()]
