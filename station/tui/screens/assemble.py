"""Assemble screen: one physical attempt of a contraption layout, from its step-by-step guide to the logged trial
(thesis 4.8.1, 5.2.3), and what the log then teaches.

Pick a scenario and a layout (a LAYOUT.json path, a layout named in the scenario, or nothing for the scenario's own
layout) and press Enter (or the button): the guide is built in a worker, drawn here with the current step highlighted,
and shown on the station's projector (simulated by default), which follows the steps. n / p step through the parts
(under the steps, every design parameter of the current part: its value, tolerance, how to set it and what it means at
the table, e.g. its underside's height above the table and its tilt), t shows the tolerance map (how carefully each part
must be placed), e writes the 1:1 PDF sheets and the SVG to the station's data folder (``guides/``, named by the
scenario, the layout and a hash of its values, so that one layout's export never replaces another's), j writes the
layout's laser-cut jigs there (``jigs/``, named the same: ``station jigs``'s files) and queues their laser job on the
Machines screen, 0 shows the calibrate frame. The jigs switch builds the guide on the layout's laser-cut jigs (its
steps set the parts they carry on them; a simulated world's maker cuts them on the laser twin first). The Robust
layouts screen opens its result here with a.

The attempt is :class:`station.services.assemble.Assembly`'s, the one ``station assemble`` walks through: c after
placing the parts checks them with the station's camera (``sim://camera`` by default; with a simulated world,
``sim://world?seed=S`` in the World field, the simulated maker places them first and the camera sees them where they
are): the camera frame with the check drawn on it, a table of every tagged part (how far it is off, within its
tolerance or not, what to do), and the projector shows an arrow per misplaced part to where it must go. f says they
were moved as the check said and checks again, a accepts them as placed, r runs the contraption (the world runs it
and reports; on a real table tick what happened: y / n / u per event), l logs the trial with the check and the
physics profile, g starts another attempt. k calibrates the physics on the scenario's logged trials (the Calibrate >
Simulator fit, of every material value as ``station loop`` fits them) and puts the profile in the Physics field; o
re-optimizes the layout with it and puts the new LAYOUT.json in the Layout field; s stops either.

The box at the top left always shows the attempt's stage, its predicted physical success and expected attempts (made
again after the guide, every check and every logged trial); the progress of a check, a calibration or a
re-optimization is right under it, above the fields, where no status text can push it out of view. The footer's
labels are short so that every key shows in 160 columns. Every slow step is one service call in a worker
(:func:`station.tui.work.run_work`) that ends with its own message (:mod:`station.tui.messages`); the guide, the check
and the forecast are drawn by their widgets (:mod:`station.tui.widgets.assemble_guide`,
:mod:`station.tui.widgets.assemble_check`, :mod:`station.tui.widgets.assemble_flow`).
"""

from __future__ import annotations

from pathlib import Path

from PIL import Image
from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.css.query import NoMatches
from textual.screen import Screen
from textual.widgets import Button, DataTable, Footer, Header, Input, Label, Select, Static, Switch

from station.errors import USER_ERRORS
from station.services import assemble as flow
from station.services import check as checks
from station.services import guide as service
from station.services.jig_plan import plan_guide_jigs
from station.services.jigs import cut_jigs, write_jig_outputs
from station.services.layout_choice import describe_choice
from station.services.projectors import configured_projector, mapping_of, open_projector
from station.services.reporting import Reporter
from station.tui.messages import (
    AttemptForecast,
    AttemptLogged,
    AttemptRan,
    GuideBuilt,
    GuideExported,
    JigsMade,
    LayoutReoptimized,
    PartsChecked,
    PhysicsCalibrated,
    ProgressReported,
    StepProjected,
)
from station.tui.registry import ScreenEntry
from station.tui.widgets.assemble_check import CheckTable, check_lines
from station.tui.widgets.assemble_flow import NEXT, ForecastStatus
from station.tui.widgets.assemble_guide import PartParameters, StepsTable, ToleranceTable
from station.tui.widgets.outcomes import OutcomeTable
from station.tui.widgets.picture import HalfBlockPicture
from station.tui.widgets.progress import ProgressPanel
from station.tui.widgets.scenario_select import scenario_choices, select_scenario
from station.tui.work import run_work

#: The frames drawn here (and sent to a projector of another size, which letterboxes them).
FRAME_SIZE = (960, 600)


class AssembleScreen(Screen):
    """One attempt: the guide (the projector follows), the check, the run, the log; then calibrate, re-optimize."""

    CSS = """
    AssembleScreen #controls { width: 38; padding: 0 1; overflow-y: auto; }
    AssembleScreen #controls Input, AssembleScreen #controls Select, AssembleScreen #controls Button { width: 100%; }
    AssembleScreen #controls Button { margin-top: 1; }
    AssembleScreen #jigs-row { height: 1; margin-top: 1; }
    AssembleScreen #jigs { border: none; height: 1; padding: 0; width: auto; }
    AssembleScreen #jigs-label { padding: 0 1; }
    AssembleScreen #status { height: auto; margin-top: 1; }
    AssembleScreen #main { width: 1fr; }
    AssembleScreen #frame { height: 1fr; min-height: 10; }
    AssembleScreen #caption { height: auto; padding: 0 1; }
    AssembleScreen #steps, AssembleScreen #tolerances, AssembleScreen #check, AssembleScreen #outcomes {
        height: auto; max-height: 14; }
    AssembleScreen #parameters { height: auto; max-height: 10; padding: 0 1; }
    AssembleScreen .heading { text-style: bold; margin-top: 1; }
    """

    #: Short labels: every key shows in a 160-column footer, the outcome table's y / n / u included (the box at the
    #: top left says which keys come next, and what they do).
    BINDINGS = [
        Binding("n", "next_step", "Next"),
        Binding("p", "previous_step", "Prev"),
        Binding("t", "tolerances", "Tolerances"),
        Binding("e", "export", "Export"),
        Binding("j", "jigs", "Jigs"),
        Binding("c", "check", "Check"),
        Binding("0", "calibrate_frame", "Frame"),
        Binding("f", "fix", "Moved"),
        Binding("a", "accept", "Accept"),
        Binding("r", "run", "Run"),
        Binding("l", "log", "Log"),
        Binding("g", "again", "Again"),
        Binding("k", "calibrate", "Calibrate"),
        Binding("o", "reoptimize", "Re-optimize"),
        Binding("s", "stop", "Stop", show=False),
    ]

    #: Simulations per forecast, and the processes they run in (None: all cores); tests shrink both.
    forecast_samples = flow.DEFAULT_SAMPLES
    simulation_workers: int | None = None
    #: The calibration's sizes (None: the defaults) and the re-optimization's budget; tests shrink them.
    fit_settings = None
    #: k fits every material value, the plain ones within their default ranges (as ``station loop`` does): on a
    #: table the plain numbers are as unknown as the marked ones.
    every_material = True
    optimize_budget = 40
    optimize_settings = None

    def __init__(self) -> None:
        super().__init__(name="assemble")
        self.job = None
        self.frames = None
        #: The step shown (1-based); 0 is the calibrate frame.
        self.step = 0
        self.projector = None
        self._projector_context = None
        self._pending: tuple[str, str] | None = None
        #: The attempt (a station.services.assemble.Assembly), its last check and its last forecast.
        self.assembly = None
        self.check = None
        self.forecast = None
        self.physics: str | None = None
        self._busy = ""
        self._learning = None  # the calibration or re-optimization running (s stops it)

    def compose(self) -> ComposeResult:
        yield Header()
        with Horizontal():
            with Vertical(id="controls"):
                yield ForecastStatus(id="forecast")
                yield ProgressPanel(idle="c: check the placed parts with the camera", id="check-progress")
                yield Label("Scenario", classes="heading")
                choices = scenario_choices()
                yield Select(choices, id="scenario", allow_blank=not choices,
                             value=choices[0][1] if choices else Select.BLANK)
                yield Label("Layout (a file, or a name)")
                yield Input("", placeholder="the scenario's own layout", id="layout")
                yield Label("View")
                yield Select([("chosen from the scenario", "auto"), ("top (the table)", "top"),
                              ("side (the backboard)", "side")], id="view", allow_blank=False, value="auto")
                yield Label("World (empty: a real table)")
                yield Input("", placeholder="e.g. sim://world?seed=1 (empty: a real table)", id="world")
                yield Label("Physics profile (optional)")
                yield Input("", placeholder="e.g. PROFILE.toml (empty: the scenario's)", id="physics")
                with Horizontal(id="jigs-row"):
                    yield Switch(value=False, id="jigs")
                    yield Label("parts on laser-cut jigs", id="jigs-label")
                yield Button("Build the guide (Enter)", id="build", variant="primary")
                yield Static("", id="status")
            with Vertical(id="main"):
                yield HalfBlockPicture(id="frame", empty="(no guide yet: pick a scenario and a layout, press Enter)")
                yield Static("", id="caption")
                yield StepsTable(id="steps", cursor_type="row", zebra_stripes=True)
                yield PartParameters("", id="parameters")
                yield ToleranceTable(id="tolerances", cursor_type="row", zebra_stripes=True)
                yield CheckTable(id="check", cursor_type="row", zebra_stripes=True)
                yield OutcomeTable(id="outcomes", on_change=self.outcomes_changed)
        # compact, without the palette's key (ctrl+p still opens it): every key fits in 160 columns, the outcome
        # table's y / n / u included
        yield Footer(compact=True, show_command_palette=False)

    def on_mount(self) -> None:
        for name in ("#parameters", "#tolerances", "#check", "#outcomes"):
            self.query_one(name).display = False
        self._show_forecast()
        if self._pending is not None:
            scenario, layout = self._pending
            self._pending = None
            self.open_layout(scenario, layout)

    def on_unmount(self) -> None:
        self._close_projector()

    # -- what is shown ------------------------------------------------------------------------------------------
    def _set_status(self, text: str | Text, style: str = "") -> None:
        self.query_one("#status", Static).update(text if isinstance(text, Text) else Text(text, style=style))

    def _show_forecast(self, extra: str = "") -> None:
        a = self.assembly
        self.query_one("#forecast", ForecastStatus).show(None if a is None else a.stage,
                                                         None if a is None else a.attempt, self.forecast,
                                                         self._busy, extra)

    def _set_busy(self, text: str) -> None:
        self._busy = text
        self._show_forecast()

    def _panel(self) -> ProgressPanel:
        return self.query_one("#check-progress", ProgressPanel)

    def on_progress_reported(self, message: ProgressReported) -> None:
        self._panel().show(message.progress)

    # -- the guide ----------------------------------------------------------------------------------------------
    @on(Button.Pressed, "#build")
    @on(Input.Submitted, "#layout")
    @on(Input.Submitted, "#world")
    @on(Input.Submitted, "#physics")
    def _build_pressed(self) -> None:
        self.action_build()

    def open_layout(self, scenario: str, layout: str) -> None:
        """Build the guide of ``layout`` for the scenario file ``scenario`` (used by the Robust layouts screen)."""
        try:
            select = self.query_one("#scenario", Select)
        except NoMatches:  # not composed yet: built on mount
            self._pending = (scenario, layout)
            return
        select_scenario(select, scenario)
        self.query_one("#layout", Input).value = layout
        self.action_build()

    def chosen_layout(self) -> tuple[str, str] | None:
        """The scenario file and the layout chosen here (a file, a name, or "" for the scenario's own), for the
        Trials screen: the built guide's, else the fields' once the maker changed them; None before."""
        if self.job is not None:
            layout = self.job.layout
            text = {"defaults": "", "named": layout.name}.get(layout.format, layout.source)
            return str(self.job.scenario.source), text
        try:
            select = self.query_one("#scenario", Select)
            layout = self.query_one("#layout", Input).value.strip()
        except NoMatches:  # never opened
            return None
        untouched = not layout and select.value == next(iter(scenario_choices()), (None, Select.BLANK))[1]
        return None if untouched or select.value is Select.BLANK else (str(select.value), layout)

    def action_build(self) -> None:
        scenario = self.query_one("#scenario", Select).value
        if scenario is Select.BLANK:
            self._set_status("pick a scenario first", "red")
            return
        layout = self.query_one("#layout", Input).value.strip() or None
        view = self.query_one("#view", Select).value
        view = None if view == "auto" else str(view)
        world = self.query_one("#world", Input).value.strip() or None
        physics = self.query_one("#physics", Input).value.strip() or None
        jigs = self.query_one("#jigs", Switch).value
        self._set_status("building the guide (outlines, order, tolerances)…")
        self.query_one("#steps", StepsTable).focus()
        if self.assembly is not None:
            self.assembly.close()
        samples, workers = self.forecast_samples, self.simulation_workers

        def build(report: Reporter):
            said = self._ensure_projector()
            request = flow.AssemblyRequest(str(scenario), layout, view=view, world=world, physics=physics, jigs=jigs,
                                           samples=samples, workers=workers)
            assembly = flow.open_assembly(request, projector=self.projector)
            return assembly, service.projected_frames(assembly.job, FRAME_SIZE), said

        run_work(self, build, GuideBuilt, group="assemble")

    def _ensure_projector(self) -> str:
        """Open the configured projector once (in the worker: a display takes a moment); what to say about it."""
        if self.projector is not None:
            return ""
        device = configured_projector()
        if device is None:
            return "no projector configured"
        # a projector named as its kind (the default "projector") is said once: "projector (sim://projector)"
        said = "projector" if device.name == device.kind else f"projector {device.name}"
        try:
            context = open_projector(device)
            self.projector = context.__enter__()
            self._projector_context = context
        except USER_ERRORS as error:
            return f"{said}: {error}"
        return f"{said} ({device.url}) follows the steps"

    def _close_projector(self) -> None:
        context, self._projector_context, self.projector = self._projector_context, None, None
        if context is not None:
            try:
                context.__exit__(None, None, None)
            except USER_ERRORS:
                pass  # closing a projector that has gone: nothing left to blank

    def on_guide_built(self, message: GuideBuilt) -> None:
        if not message.ok:
            self._set_status(f"cannot build the guide: {message.error}", "red")
            return
        assembly, self.frames, said = message.result
        self.job = assembly.job
        self.physics = self.query_one("#physics", Input).value.strip() or None
        self.assembly, self.forecast, self.check = assembly, None, None
        self.query_one("#outcomes", OutcomeTable).display = False
        self._refresh_forecast()
        guide = self.job.guide
        self.query_one("#steps", StepsTable).load(guide)
        self.query_one("#tolerances", ToleranceTable).load(guide)
        mapping = None if self.projector is None else mapping_of(self.projector)  # the one the steps go through
        scale = "" if mapping is None else f"; {mapping.scale_text()}"
        source = {"none": "no tolerances (the layout carries no success model)"}.get(
            guide.tolerance_source, f"tolerances from {guide.tolerance_source}")
        self._set_status(f"{guide.scenario}: {self.job.layout.describe()}, {guide.view} view, {len(guide.parts)} "
                         f"parts, {source}. {said}{scale}. n/p: steps, t: tolerances, e: export")
        self.show_step(1 if guide.parts else 0)

    # -- steps ----------------------------------------------------------------------------------------------------
    def show_step(self, step: int) -> None:
        """Show step ``step`` (1-based; 0: the calibrate frame) here and on the projector."""
        if self.frames is None:
            return
        count = len(self.frames.frames)
        self.step = max(0, min(step, count))
        frame = self.frames.calibrate if self.step == 0 else self.frames.frames[self.step - 1]
        self.query_one("#frame", HalfBlockPicture).set_image(Image.fromarray(frame))
        caption = ("calibrate frame: the four reference tags and a grid" if self.step == 0
                   else self.job.steps[self.step - 1])
        self.query_one("#caption", Static).update(Text(caption))
        if self.step:
            self.query_one("#steps", StepsTable).move_cursor(row=self.step - 1)
        part = self.job.guide.parts[self.step - 1] if self.step else None
        self.query_one("#parameters", PartParameters).show(part)
        if self.projector is not None:
            # drawn at the projector's own size (the terminal's frames are smaller; one scaled up would be
            # letterboxed, and no longer true to scale once calibrated)
            job, projector, shown = self.job, self.projector, self.step or None
            run_work(self, lambda report: service.show_step(job, projector, shown), StepProjected, group="projector")

    def on_step_projected(self, message: StepProjected) -> None:
        if message.error:
            self._set_status(f"projector: {message.error}", "red")

    @on(DataTable.RowSelected, "#steps")
    def _row_selected(self, event: DataTable.RowSelected) -> None:
        self.show_step(event.cursor_row + 1)

    def action_next_step(self) -> None:
        self.show_step(self.step + 1)

    def action_previous_step(self) -> None:
        self.show_step(max(self.step - 1, 1) if self.step > 0 else 0)

    def action_calibrate_frame(self) -> None:
        self.show_step(0)

    def action_tolerances(self) -> None:
        table = self.query_one("#tolerances", ToleranceTable)
        table.display = not table.display
        if table.display and self.job is not None and not table.row_count:
            self._set_status("no tolerances: the layout carries no success model (station tolerances --verify N "
                             "estimates them by simulation)")

    # -- export and jigs ------------------------------------------------------------------------------------------
    def action_export(self) -> None:
        if self.job is None:
            self._set_status("no guide yet: build one first", "red")
            return
        self._set_status("writing the PDF and the SVG…")
        job = self.job

        def export(report: Reporter):
            pdf, svg = flow.guide_files(job)
            pdf.parent.mkdir(parents=True, exist_ok=True)
            return pdf, svg, len(service.export_guide(job, pdf=pdf, svg=svg).guide.pages)

        run_work(self, export, GuideExported, group="export")

    def on_guide_exported(self, message: GuideExported) -> None:
        if not message.ok:
            self._set_status(f"cannot export: {message.error}", "red")
            return
        pdf, svg, pages = message.result
        self._set_status(f"wrote {pdf} ({pages} sheets and the steps; print at 100 %, check the 100 mm bar) and {svg}")

    def action_jigs(self) -> None:
        if self.job is None:
            self._set_status("no guide yet: build one first", "red")
            return
        self._set_status("planning the jigs and their laser job…")
        job = self.job

        def jigs(report: Reporter):
            folder = flow.jigs_folder(job)
            result = cut_jigs(job, plan_guide_jigs(job))
            write_jig_outputs(result, folder)
            return result, folder

        run_work(self, jigs, JigsMade, group="jigs")

    def on_jigs_made(self, message: JigsMade) -> None:
        """Say what was written, and queue each sheet's laser job on the Machines screen (nothing moves until the
        maker frames and starts it there)."""
        if not message.ok:
            self._set_status(f"cannot make the jigs: {message.error}", "red")
            return
        result, folder = message.result
        plan = result.plan
        words = f"wrote {len(plan.jigs)} jig{'' if len(plan.jigs) == 1 else 's'} to {folder}"
        if plan.by_hand:
            words += "; by hand: " + ", ".join(f"{b.part} ({b.reason})" for b in plan.by_hand)
        if not result.sheets:
            self._set_status(words + "; nothing to cut")
            return
        queue = getattr(self.app.machines_screen(), "queue_job", None)
        if queue is None:
            self._set_status(f"{words}; send jigs.gcode to the laser (`station send`)")
            return
        count = len(result.sheets)
        try:
            for output in result.sheets:
                queue("laser", output.gcode, title=f"jigs of {self.job.guide.scenario}"
                      + (f", sheet {output.index}/{count}" if count > 1 else ""), laser=True)
        except (*USER_ERRORS, ValueError) as error:
            self._set_status(f"{words}; the laser refused the job: {error}", "red")
            return
        self._set_status(f"{words}; their laser job is queued on the Machines screen (m: f frames it, g cuts)")

    # -- the attempt: check, fix, accept ------------------------------------------------------------------------
    def _need(self, *stages: str) -> bool:
        """Whether the attempt is at one of ``stages``; says what to do otherwise."""
        if self.assembly is None:
            self._set_status("no guide yet: pick a scenario and a layout, press Enter", "red")
            return False
        if self.assembly.stage not in stages:
            self._set_status(f"the attempt is at {self.assembly.stage!r}: {NEXT[self.assembly.stage]}", "yellow")
            return False
        return True

    def action_check(self) -> None:
        if self.job is None:
            self._set_status("no guide yet: build one, place the parts, then press c", "red")
            return
        if self._need("guide", "check"):
            self._panel().start(None, "grabbing a frame from the camera…")
            self._check(fix=False)

    def action_fix(self) -> None:
        if not self._need("check"):
            return
        if self.assembly.check is None:
            self._set_status("no check yet: c checks the placed parts", "yellow")
            return
        self._panel().start(None, "moved as the check said; checking again…")
        self._check(fix=True)

    def _check(self, *, fix: bool) -> None:
        """Check the parts as they stand (placed first, moved as the last check said with ``fix``), draw the
        check on the camera frame; the projector then shows the check."""
        assembly = self.assembly

        def check(report: Reporter):
            result = assembly.check_placed(fix=fix, report=report)
            picture = checks.camera_overlay(result)
            try:
                assembly.project_check()
            except USER_ERRORS as error:  # the check stands without the projector
                return result, picture, f"projector: {error}"
            return result, picture, ""

        run_work(self, check, PartsChecked, group="check")

    def on_parts_checked(self, message: PartsChecked) -> None:
        panel = self._panel()
        if not message.ok:
            error = f"cannot check: {message.error}"
            panel.say(error)
            self._set_status(error, "red")
            return
        self.check, picture, projector = message.result
        table = self.query_one("#check", CheckTable)
        side_off = self.assembly.side_off if self.assembly is not None else ()
        table.load(self.check.report, side_off)
        table.display = True
        self.query_one("#frame", HalfBlockPicture).set_image(Image.fromarray(picture))
        lines = check_lines(self.check, side_off)
        self.query_one("#caption", Static).update(Text("\n".join(lines)))
        panel.say(lines[0])
        if projector:
            self._set_status(projector, "red")
        else:
            self._set_status("checked: " + "; ".join(lines[:2]) + ". Move the parts as the table says and press f "
                             "to check again (a: accept as placed); n/p go back to the steps")
        self._refresh_forecast()

    def action_accept(self) -> None:
        if not self._need("check"):
            return
        self.assembly.accept()
        self._set_status("accepted as placed: r runs the contraption")
        self._show_forecast()

    # -- the forecast ---------------------------------------------------------------------------------------------
    def _refresh_forecast(self) -> None:
        if self.assembly is None:
            return
        self._set_busy("forecasting the physical success…")
        assembly, samples, workers = self.assembly, self.forecast_samples, self.simulation_workers

        def forecast(report: Reporter):
            assembly.samples, assembly.workers = samples, workers
            # its progress is not shown (the panel keeps the check's); a newer forecast stops it
            return assembly.forecast(report=Reporter(stop=lambda: report.stopping))

        # any failure leaves the last forecast in view, said in one line
        run_work(self, forecast, AttemptForecast, group="forecast", errors=(Exception,))

    def on_attempt_forecast(self, message: AttemptForecast) -> None:
        self._busy = ""
        if message.ok:
            self.forecast = message.result
        self._show_forecast(f"no forecast: {message.error}" if message.error else "")

    # -- run and outcomes -----------------------------------------------------------------------------------------
    def action_run(self) -> None:
        if self.assembly is not None and self.assembly.stage == "check":
            self.assembly.accept()  # r after a check: the maker accepts the parts as they stand
        if not self._need("run"):
            return
        table = self.query_one("#outcomes", OutcomeTable)
        if self.assembly.world is None:
            table.load(self.assembly.scenario)
            table.display = True
            table.focus()
            self._set_status("run the contraption, then say what happened to each event: y, n, u (not reached); "
                             "l logs")
            self._show_forecast()
            return
        self._set_busy("the world runs the contraption…")
        assembly = self.assembly
        run_work(self, lambda report: assembly.run(), AttemptRan, group="run")

    def on_attempt_ran(self, message: AttemptRan) -> None:
        self._busy = ""
        if not message.ok:
            self._set_status(f"cannot run: {message.error}", "red")
            self._show_forecast()
            return
        table = self.query_one("#outcomes", OutcomeTable)
        table.load(self.assembly.scenario, self.assembly.outcomes, self.assembly.times)
        table.display = True
        verdict = "a SUCCESS" if self.assembly.success else "a failure"
        self._set_status(f"the world ran it: {verdict}; l logs the trial", "green" if self.assembly.success else "")
        self._show_forecast()

    def outcomes_changed(self, event: OutcomeTable.Changed) -> None:
        """The outcome table's callback: the first problem, or the verdict once every event is said."""
        if self.assembly is None or self.assembly.stage != "run":
            return
        if event.problem:
            self._set_status(event.problem, "yellow")
        elif event.complete:
            self._set_status(f"every event said: {'a success' if event.success else 'a failure'}; l logs it",
                             "green")

    # -- log ------------------------------------------------------------------------------------------------------
    def action_log(self) -> None:
        if self.assembly is not None and self.assembly.stage == "run" and self.assembly.world is None:
            try:
                self.assembly.answer(self.query_one("#outcomes", OutcomeTable).given)
            except USER_ERRORS as error:
                self._set_status(str(error).replace("outcome.", "", 1), "red")
                return
        if not self._need("log"):
            return
        self._set_busy("logging the trial…")
        assembly = self.assembly
        run_work(self, lambda report: assembly.log(), AttemptLogged, group="assemble-db")

    def on_attempt_logged(self, message: AttemptLogged) -> None:
        self._busy = ""
        if not message.ok:
            self._set_status(f"cannot log: {message.error}", "red")
            self._show_forecast()
            return
        verdict = "success" if self.assembly.success else "failure"
        self._set_status(f"logged trial #{message.result} ({self.assembly.scenario.name}, {verdict}); g: another "
                         "attempt, k: calibrate the physics on the log, o: re-optimize", "green")
        self._refresh_forecast()

    def action_again(self) -> None:
        """Another attempt of the same layout (or of the re-optimized one, now in the layout field)."""
        if self.assembly is not None and self.assembly.stage not in ("done", "guide"):
            self._set_status(f"this attempt is at {self.assembly.stage!r}; log it first (l), or build again "
                             "(Enter) to drop it", "yellow")
            return
        self.action_build()

    # -- what the log teaches: calibrate, re-optimize ----------------------------------------------------------------
    def action_calibrate(self) -> None:
        if self.assembly is None:
            self._set_status("no scenario yet: build a guide, log trials, then k", "red")
            return
        self._panel().start(None, "calibrating the physics on the log…")
        self._set_busy("calibrating the simulator on the logged trials (s stops)…")
        scenario, settings, workers = self.assembly.job.scenario, self.fit_settings, self.simulation_workers
        every = self.every_material
        self._learning = run_work(self, lambda report: flow.calibrate_from_log(
            scenario, settings=settings, workers=workers, report=report, every_material=every),
            PhysicsCalibrated, group="calibrate")

    def on_physics_calibrated(self, message: PhysicsCalibrated) -> None:
        path = None
        if message.stopped:
            text = "calibration stopped; its simulations are cached"
        elif message.error:
            text = f"cannot calibrate: {message.error}"
        else:
            path, result = message.result
            path = str(path)
            values = ", ".join(f"{k} = {v:.3g}" for k, v in result.fit.values().items())
            text = f"calibrated: {values}; wrote {path}; o re-optimizes with it, g builds the next attempt with it"
        self._busy = ""
        self._panel().say(text)
        if path is not None:
            self.physics = path
            self.query_one("#physics", Input).value = path
        self._set_status(text, "green" if path else "red")
        self._show_forecast()

    def action_reoptimize(self) -> None:
        if self.assembly is None:
            self._set_status("no scenario yet: build a guide first", "red")
            return
        physics = self.query_one("#physics", Input).value.strip() or None
        current = self.query_one("#layout", Input).value.strip() or None
        self._panel().start(self.optimize_budget, "re-optimizing…")
        self._set_busy(f"re-optimizing the layout{' with ' + Path(physics).name if physics else ''} (s stops)…")
        request = flow.ReoptimizeRequest(self.assembly.job.scenario.source, physics, budget=self.optimize_budget,
                                         settings=self.optimize_settings, current=current,
                                         workers=self.simulation_workers)
        self._learning = run_work(self, lambda report: flow.reoptimize(request, report=report), LayoutReoptimized,
                                  group="calibrate")

    def on_layout_reoptimized(self, message: LayoutReoptimized) -> None:
        path = None
        if message.stopped:
            text = "re-optimization stopped; its simulations are cached"
        elif message.error:
            text = f"cannot re-optimize: {message.error}"
        else:
            path, result, chosen = message.result
            path = str(path)
            text = (f"re-optimized: PSP {result.psp:.3f}{describe_choice(chosen)}; wrote {path}; g builds its guide "
                    "for the next attempt")
        self._busy = ""
        self._panel().say(text)
        if path is not None:
            self.query_one("#layout", Input).value = path
        self._set_status(text, "green" if path else "red")
        self._show_forecast()

    def action_stop(self) -> None:
        if self._learning is not None:
            self._learning.stop()
        self._set_status("stopping (finished simulations stay cached)…")


SCREEN = ScreenEntry(
    name="assemble",
    key="a",
    title="Assemble",
    description="one attempt: the guide (sheets or projector), the camera check, the run, the log",
    factory=AssembleScreen,
    order=60,
)
