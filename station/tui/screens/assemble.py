"""Assemble screen: a contraption layout as a step-by-step assembly guide (thesis 4.8.1, 5.2.3).

Pick a scenario and a layout (a LAYOUT.json path, a layout named in the scenario, or nothing for the scenario's own
layout) and press Enter (or the button): the guide is built in a worker, drawn here with the current step highlighted,
and shown on the station's projector (simulated by default), which follows the steps. n / p step through the parts
(under the steps, every design parameter of the current part: its value, tolerance, how to set it and what it means at
the table, e.g. its underside's height above the table and its tilt), t shows the tolerance map (how carefully each part
must be placed), e writes the 1:1 PDF sheets and the SVG to the station's data folder (``guides/``, named by the
scenario, the layout and a hash of its values, so that one layout's export never replaces another's), j writes the
layout's laser-cut jigs there (``jigs/``, named the same: ``station jigs``'s files) and queues their laser job on the
Machines screen, 0 shows the calibrate frame. c checks the placed parts with the station's camera (``sim://camera`` by
default, shown the guide's tags at their designed poses): the camera frame with the check drawn on it, a table of every
tagged part (how far it is off, within its tolerance or not, what to do), the predicted success as placed, and the
projector shows an arrow per misplaced part to where it must go; press c again after moving them. The jigs
switch builds the guide on the layout's laser-cut jigs (its steps set the parts they carry on them; a simulated world's
maker cuts them on the laser twin first). The Robust layouts screen opens its result here with a.

The whole attempt (:mod:`station.services.assemble`, as ``station assemble``): c after placing the parts checks them
(with a simulated world, ``sim://world?seed=S`` in the World field, the simulated maker places them first and the
camera sees them where they are), f says they were moved as the check said and checks again, a accepts them as
placed, r runs the contraption (the world runs it and reports; on a real table tick what happened: y / n / u per
event), l logs the trial with the check and the physics profile, g starts another attempt. k calibrates the
physics on the scenario's logged trials (the Calibrate > Simulator fit, of every material value as ``station loop``
fits them) and puts the profile in the Physics field; o
re-optimizes the layout with it and puts the new LAYOUT.json in the Layout field. The box at the top left always
shows the attempt's stage, its predicted physical success and expected attempts (made again after the guide, every
check and every logged trial); the progress of a check, a calibration or a re-optimization is right under it, above
the fields, where no status text can push it out of view. The footer's labels are short so that every key shows
in 160 columns.
"""

from __future__ import annotations

from pathlib import Path

from PIL import Image
from rich.text import Text
from textual import on, work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.css.query import NoMatches
from textual.message import Message
from textual.screen import Screen
from textual.widgets import Button, DataTable, Footer, Header, Input, Label, Select, Static, Switch

from design.errors import DesignError
from drivers.errors import DriverError
from projector.errors import ProjectorError
from projector.overlay import misplaced
from station.errors import StationError
from station.paths import data_dir
from station.services import assemble as flow
from station.services import check as checks
from station.services import guide as service
from station.services.projectors import configured_projector, mapping_of, open_projector
from station.tui.registry import ScreenEntry
from station.tui.screens._assemble_flow import AttemptFlow
from station.tui.widgets.assemble_flow import ForecastStatus
from station.tui.widgets.outcomes import OutcomeTable
from station.tui.widgets.picture import HalfBlockPicture
from station.tui.widgets.progress import ProgressPanel, ProgressReported
from station.tui.widgets.scenario_select import scenario_choices, select_scenario

#: The frames drawn here (and sent to a projector of another size, which letterboxes them).
FRAME_SIZE = (960, 600)
CARE_STYLE = {"tight": "red", "normal": "dark_orange", "loose": "green"}
#: How the parameters table says each is set (projector.guide.SET_WITH).
HOW_TEXT = {"sheet": "on the sheet", "ruler": "ruler", "jig": "jig", "check": "sheet + camera check"}


class GuideLoaded(Message):
    """A guide was built (``job`` and its ``frames``, the attempt ``assembly``), or could not be (``error``)."""

    def __init__(self, job=None, frames=None, error: str = "", projector: str = "", assembly=None) -> None:
        super().__init__()
        self.job, self.frames, self.error, self.projector = job, frames, error, projector
        self.assembly = assembly


class CheckDone(Message):
    """A check ended: its result (``check``, and the camera frame with the check drawn, ``picture``) or ``error``."""

    def __init__(self, check=None, picture=None, error: str = "") -> None:
        super().__init__()
        self.check, self.picture, self.error = check, picture, error


class AssembleScreen(AttemptFlow, Screen):
    """Step through a layout's assembly guide; the projector follows."""

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

    def __init__(self) -> None:
        super().__init__(name="assemble")
        self.job = None
        self.frames = None
        #: The step shown (1-based); 0 is the calibrate frame.
        self.step = 0
        self.projector = None
        self._projector_context = None
        self._pending: tuple[str, str] | None = None
        #: The last check (a station.services.check.CheckJob), and the guide job it was made against.
        self.check = None
        self._check_job = None
        self._init_flow()

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
                yield DataTable(id="steps", cursor_type="row", zebra_stripes=True)
                yield Static("", id="parameters")
                yield DataTable(id="tolerances", cursor_type="row", zebra_stripes=True)
                yield DataTable(id="check", cursor_type="row", zebra_stripes=True)
                yield OutcomeTable(id="outcomes", on_change=self.outcomes_changed)
        # compact, without the palette's key (ctrl+p still opens it): every key fits in 160 columns, the outcome
        # table's y / n / u included
        yield Footer(compact=True, show_command_palette=False)

    def on_mount(self) -> None:
        self.query_one("#steps", DataTable).add_columns("step", "part", "kind", "tag", "centre mm", "care")
        self.query_one("#parameters", Static).display = False
        table = self.query_one("#tolerances", DataTable)
        table.add_columns("part", "parameter", "± delta", "predicted", "measured")
        table.display = False
        check = self.query_one("#check", DataTable)
        check.add_columns("part", "tag", "du mm", "dv mm", "dist mm", "turn deg", "ok", "cost", "what to do")
        check.display = False
        self.query_one("#outcomes", OutcomeTable).display = False
        self._show_forecast()
        if self._pending is not None:
            scenario, layout = self._pending
            self._pending = None
            self.open_layout(scenario, layout)

    def on_unmount(self) -> None:
        self._close_projector()

    # -- controls -------------------------------------------------------------------------------------------------
    def _set_status(self, text: str | Text, style: str = "") -> None:
        self.query_one("#status", Static).update(text if isinstance(text, Text) else Text(text, style=style))

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
        layout = self.query_one("#layout", Input).value.strip()
        view = self.query_one("#view", Select).value
        self._set_status("building the guide (outlines, order, tolerances)…")
        self.query_one("#steps", DataTable).focus()
        world = self.query_one("#world", Input).value.strip() or None
        physics = self.query_one("#physics", Input).value.strip() or None
        jigs = self.query_one("#jigs", Switch).value
        if self.assembly is not None:
            self.assembly.close()
        self._build(str(scenario), layout or None, None if view == "auto" else str(view), world, physics, jigs)

    @work(thread=True, exclusive=True, group="assemble")
    def _build(self, scenario: str, layout: str | None, view: str | None, world: str | None = None,
               physics: str | None = None, jigs: bool = False) -> None:
        from station.db import database_url
        from station.services.trials import open_store

        said = self._ensure_projector()
        try:
            with open_store(database_url()) as store:
                assembly = flow.open_assembly(scenario, layout, view=view, world=world, physics=physics, jigs=jigs,
                                              projector=self.projector, store=store, samples=self.forecast_samples,
                                              workers=self.simulation_workers)
            frames = service.projected_frames(assembly.job, FRAME_SIZE)
        except (DesignError, ProjectorError, StationError, DriverError, OSError) as error:
            self.post_message(GuideLoaded(error=f"cannot build the guide: {error}"))
            return
        self.post_message(GuideLoaded(assembly.job, frames, projector=said, assembly=assembly))

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
        except (DriverError, StationError) as error:
            return f"{said}: {error}"
        return f"{said} ({device.url}) follows the steps"

    def _close_projector(self) -> None:
        context, self._projector_context, self.projector = self._projector_context, None, None
        if context is not None:
            try:
                context.__exit__(None, None, None)
            except DriverError:
                pass  # closing a projector that has gone: nothing left to blank

    def on_guide_loaded(self, message: GuideLoaded) -> None:
        if message.job is None:
            self._set_status(message.error, "red")
            return
        self.job, self.frames = message.job, message.frames
        self.physics = self.query_one("#physics", Input).value.strip() or None
        self._attempt_started(message.assembly)
        guide = self.job.guide
        steps = self.query_one("#steps", DataTable)
        steps.clear()
        for part in guide.parts:
            care = Text(part.care or "-", style=CARE_STYLE.get(part.care or "", ""))
            steps.add_row(str(part.step), Text(part.name), str(part.kind),
                          "-" if part.tag_id is None else str(part.tag_id),
                          f"({part.center_mm[0]:.1f}, {part.center_mm[1]:.1f})", care, key=part.name)
        self._fill_tolerances()
        mapping = None if self.projector is None else mapping_of(self.projector)  # the one the steps go through
        scale = "" if mapping is None else f"; {mapping.scale_text()}"
        source = {"none": "no tolerances (the layout carries no success model)"}.get(
            guide.tolerance_source, f"tolerances from {guide.tolerance_source}")
        self._set_status(f"{guide.scenario}: {self.job.layout.describe()}, {guide.view} view, {len(guide.parts)} "
                         f"parts, {source}. {message.projector}{scale}. n/p: steps, t: tolerances, e: export")
        self.show_step(1 if guide.parts else 0)

    def _fill_tolerances(self) -> None:
        table = self.query_one("#tolerances", DataTable)
        table.clear()
        for part in self.job.guide.parts:
            for tolerance in part.tolerances:
                delta = "-" if tolerance.delta is None else f"{tolerance.delta:.1f} {tolerance.unit}"
                if tolerance.bound_limited:  # only a lower bound: the layout sits at its range's end
                    delta = f">= {delta} (range end)"
                table.add_row(Text(part.name), Text(tolerance.parameter), delta,
                              "-" if tolerance.predicted is None else f"{tolerance.predicted:.2f}",
                              "-" if tolerance.measured is None else f"{tolerance.measured:.2f}")

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
            self.query_one("#steps", DataTable).move_cursor(row=self.step - 1)
        self._fill_parameters()
        if self.projector is not None:
            self._project(self.step)

    def _fill_parameters(self) -> None:
        """The current step's part: a line per design parameter that moves it, with its value, tolerance, how to set
        it and what it means at the table (hidden on the calibrate frame and for a part no parameter moves)."""
        lines = self.query_one("#parameters", Static)
        part = self.job.guide.parts[self.step - 1] if self.step and self.job is not None else None
        settings = () if part is None else part.settings
        text = Text()
        for setting in settings:  # the meaning carries the tolerance: "... 58.7 mm (+-5.3 mm)"
            if text:
                text.append("\n")
            text.append(f"{setting.name} = {setting.value:.1f} {setting.unit}", style="bold")
            text.append(f"  [{HOW_TEXT.get(setting.set_with, setting.set_with)}]  ", style="cyan")
            text.append(setting.meaning)
        lines.update(text)
        lines.display = bool(settings)

    @work(thread=True, exclusive=True, group="projector")
    def _project(self, step: int) -> None:
        """Show ``step`` (0: the calibrate frame) on the projector, drawn at the projector's own size (the terminal's
        frames are smaller; one scaled up would be letterboxed, and no longer true to scale once calibrated)."""
        try:
            service.show_step(self.job, self.projector, step or None)
        except DriverError as error:
            self.app.call_from_thread(self._set_status, f"projector: {error}", "red")

    def action_next_step(self) -> None:
        self.show_step(self.step + 1)

    def action_previous_step(self) -> None:
        self.show_step(max(self.step - 1, 1) if self.step > 0 else 0)

    def action_calibrate_frame(self) -> None:
        self.show_step(0)

    def action_tolerances(self) -> None:
        table = self.query_one("#tolerances", DataTable)
        table.display = not table.display
        if table.display and self.job is not None and not table.row_count:
            self._set_status("no tolerances: the layout carries no success model (station tolerances --verify N "
                             "estimates them by simulation)")

    # -- the camera check -----------------------------------------------------------------------------------------
    def action_check(self) -> None:
        if self.job is None:
            self._set_status("no guide yet: build one, place the parts, then press c", "red")
            return
        if not self._need("guide", "check"):
            return
        self.query_one("#check-progress", ProgressPanel).start(None, "grabbing a frame from the camera…")
        self._check(self.job)

    @work(thread=True, exclusive=True, group="check")
    def _check(self, job, fix: bool = False) -> None:
        """Grab a frame from the station's camera (the parts placed, or moved as the last check said with ``fix``),
        check it, draw it; the projector then shows the check."""
        try:
            check = self._check_attempt(fix)
            picture = checks.camera_overlay(check)
        except (DesignError, ProjectorError, StationError, DriverError, ValueError, OSError) as error:
            self.post_message(CheckDone(error=f"cannot check: {error}"))
            return
        self.post_message(CheckDone(check, picture))
        if self.projector is not None and self.job is job:
            try:
                self.assembly.project_check()
            except DriverError as error:
                self.app.call_from_thread(self._set_status, f"projector: {error}", "red")

    def on_progress_reported(self, message: ProgressReported) -> None:
        self.query_one("#check-progress", ProgressPanel).show(message.progress)

    def on_check_done(self, message: CheckDone) -> None:
        panel = self.query_one("#check-progress", ProgressPanel)
        if message.check is None:
            panel.say(message.error)
            self._set_status(message.error, "red")
            return
        self.check = message.check
        report = message.check.report
        table = self.query_one("#check", DataTable)
        table.clear()
        for part in report.parts:
            error = part.error
            numbers = (["-"] * 4 if error is None else
                       [f"{error[0]:+.1f}", f"{error[1]:+.1f}", f"{error[2]:.1f}", f"{error[3]:+.1f}"])
            # the check's one rule: no zone on the sheet (*) and off by 1 mm / 1 deg or more is to move
            star = "*" if part.within_tolerance is None and error is not None else ""
            ok = (Text("-", style="dim") if error is None else Text("NO" + star, style="bold red")
                  if misplaced(part) else Text("yes" + star, style="green"))
            table.add_row(Text(part.name), str(part.tag_id), *numbers, ok,
                          "-" if part.cost is None else f"{part.cost:.2f}", Text(part.instruction), key=part.name)
        for name in report.by_eye:
            table.add_row(Text(name), "-", "", "", "", "", Text("by eye", style="dim"), "-",
                          Text("check by eye against the sheet"), key=f"eye:{name}")
        table.display = True
        self.query_one("#frame", HalfBlockPicture).set_image(Image.fromarray(message.picture))
        lines = checks.summary_lines(report, message.check.physical)
        if any(part.found and part.within_tolerance is None for part in report.parts):
            lines.append(f"yes*/NO*: {checks.no_zone_words()}")
        if report.prediction_note:
            lines.append(report.prediction_note)
        self.query_one("#caption", Static).update(Text("\n".join(lines)))
        panel.say(lines[0])
        self._set_status("checked: " + "; ".join(lines[:2]) + ". Move the parts as the table says and press f to "
                         "check again (a: accept as placed); n/p go back to the steps")
        self._refresh_forecast()

    @on(DataTable.RowSelected, "#steps")
    def _row_selected(self, event: DataTable.RowSelected) -> None:
        self.show_step(event.cursor_row + 1)

    def action_export(self) -> None:
        if self.job is None:
            self._set_status("no guide yet: build one first", "red")
            return
        folder = data_dir() / "guides"
        folder.mkdir(parents=True, exist_ok=True)
        stem = folder / service.export_name(self.job)
        self._set_status("writing the PDF and the SVG…")
        self._export(stem.with_suffix(".pdf"), stem.with_suffix(".svg"))

    @work(thread=True, exclusive=True, group="export")
    def _export(self, pdf: Path, svg: Path) -> None:
        try:
            job = service.export_guide(self.job, pdf=pdf, svg=svg)
        except (ProjectorError, StationError, OSError) as error:
            self.app.call_from_thread(self._set_status, f"cannot export: {error}", "red")
            return
        pages = len(job.guide.pages)
        self.app.call_from_thread(self._set_status, f"wrote {pdf} ({pages} sheets and the steps; print at 100 %, "
                                  f"check the 100 mm bar) and {svg}")

    def action_jigs(self) -> None:
        if self.job is None:
            self._set_status("no guide yet: build one first", "red")
            return
        folder = data_dir() / "jigs" / service.export_name(self.job)
        self._set_status("planning the jigs and their laser job…")
        self._jigs(self.job, folder)

    @work(thread=True, exclusive=True, group="jigs")
    def _jigs(self, job, folder: Path) -> None:
        from station.services.jig_plan import plan_guide_jigs
        from station.services.jigs import cut_jigs, write_jig_outputs

        try:
            result = cut_jigs(job, plan_guide_jigs(job))
            write_jig_outputs(result, folder)
        except (DesignError, ProjectorError, StationError, DriverError, OSError) as error:
            self.app.call_from_thread(self._set_status, f"cannot make the jigs: {error}", "red")
            return
        self.app.call_from_thread(self._jigs_written, result, folder)

    def _jigs_written(self, result, folder: Path) -> None:
        """Say what was written, and queue each sheet's laser job on the Machines screen (nothing moves until the
        maker frames and starts it there)."""
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
        except (DriverError, StationError, ValueError) as error:
            self._set_status(f"{words}; the laser refused the job: {error}", "red")
            return
        self._set_status(f"{words}; their laser job is queued on the Machines screen (m: f frames it, g cuts)")


SCREEN = ScreenEntry(
    name="assemble",
    key="a",
    title="Assemble",
    description="one attempt: the guide (sheets or projector), the camera check, the run, the log",
    factory=AssembleScreen,
    order=60,
)
