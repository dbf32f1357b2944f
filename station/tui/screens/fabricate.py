"""Fabricate screen: the laser-cut parts of the current drawing machine, nested on a sheet, and the laser job.

Opened from the Drawing machines screen (key f there, or f on the home screen), it takes that screen's current
design. The nested sheet is drawn as a picture in the terminal (two pixels per cell with half blocks), beside the
parts list and the job estimate. Tab reaches the fields (scale, kerf, sheet, material); Enter there regenerates.
From the parts table: g regenerates, r reloads the Drawing screen's design, z zooms on the parts, n shows the next
sheet (when the parts need several), w writes parts.svg, laser.gcode, parts.json and sheet.png into the station's
data folder, s queues the jobs for the laser on the Machines screen (where f frames a job and g runs it). t makes a
test card for the material (``station lasertest card``), shows it and queues it for the laser; a photo of the burned
card is read by ``station calibrate material``, whose measured settings the next generation here uses.
"""

from __future__ import annotations

import time
from pathlib import Path

from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import Screen
from textual.widgets import DataTable, Footer, Header, Input, Label, Static

from station.errors import USER_ERRORS, StationError
from station.services.designs import get_machine
from station.services.fabricate import (
    DEFAULT_GAP,
    KERF_SOURCES,
    FabricationRequest,
    FabricationResult,
    fabricate,
    parse_sheet,
    write_outputs,
)
from station.services.lasertest import make_card, write_card
from station.services.station_home import data_dir
from station.tui.messages import FabricationEnded, ProgressReported, TestCardMade
from station.tui.registry import MachineDesign, ScreenEntry
from station.tui.widgets.picture import HalfBlockPicture
from station.tui.widgets.progress import ProgressPanel
from station.tui.work import run_work

DEFAULT_MACHINE = "spirograph"
DEFAULT_SCALE = 8.0


class FabricateScreen(Screen):
    """Parts, nesting and laser job of the current design."""

    CSS = """
    FabricateScreen #sidebar { width: 45%; max-width: 60; min-width: 36; border-right: solid $primary-darken-2; }
    FabricateScreen #design { height: auto; padding: 0 1; text-style: bold; }
    FabricateScreen .field { height: 3; }
    FabricateScreen .field Label { width: 16; padding: 1 1 0 1; }
    FabricateScreen .field Input { width: 1fr; }
    FabricateScreen #parts { height: 1fr; border: round $panel-lighten-2; }
    FabricateScreen #parts:focus { border: round $accent; }
    FabricateScreen .field Input:focus { border: tall $accent; }
    FabricateScreen #part { height: auto; padding: 0 1; color: $warning; }
    FabricateScreen #job { height: auto; padding: 0 1; }
    FabricateScreen #status { height: auto; padding: 0 1; color: $text-muted; }
    FabricateScreen #fabricate-progress { padding: 0 1; }
    FabricateScreen #sheet { border: round $primary-darken-1; }
    """

    BINDINGS = [
        Binding("g", "generate", "Regenerate"),
        Binding("w", "write", "Write files"),
        Binding("s", "send", "Send to laser"),
        Binding("r", "reload", "Reload design"),
        Binding("z", "zoom", "Zoom to parts"),
        Binding("n", "next_sheet", "Next sheet"),
        Binding("t", "test_card", "Test card"),
    ]

    def __init__(self) -> None:
        super().__init__(name="fabricate")
        self.design: MachineDesign | None = None
        self.result: FabricationResult | None = None
        self.last_message = ""
        self.part_text = ""
        self.sheet_index = 0

    def compose(self) -> ComposeResult:
        yield Header()
        with Horizontal():
            with Vertical(id="sidebar"):
                yield Static("", id="design")
                with Horizontal(classes="field"):
                    yield Label("scale mm/unit")
                    yield Input(str(DEFAULT_SCALE), id="scale")
                with Horizontal(classes="field"):
                    yield Label("kerf mm")
                    yield Input("", placeholder="material's", id="kerf")
                with Horizontal(classes="field"):
                    yield Label("sheet WxH mm")
                    yield Input("", placeholder="work area", id="sheet-size")
                with Horizontal(classes="field"):
                    yield Label("material")
                    yield Input("", placeholder="plywood_3mm", id="material")
                yield DataTable(id="parts", cursor_type="row", zebra_stripes=True)
                yield Static("", id="part")
                yield Static("", id="job")
                yield ProgressPanel(id="fabricate-progress")
                yield Static("", id="status")
            yield HalfBlockPicture(id="sheet", empty="(no sheet yet)")
        yield Footer()

    def on_mount(self) -> None:
        table = self.query_one("#parts", DataTable)
        table.add_columns("part", "sheet", "size mm", "teeth", "notes")
        # The keys (g, w, s, r) act while the table has focus; Tab reaches the fields, Enter there regenerates.
        table.focus()

    def on_screen_resume(self) -> None:
        design = self._drawing_design()
        if design != self.design or self.result is None:
            self.design = design
            self.action_generate()

    def _drawing_design(self) -> MachineDesign:
        """The Drawing screen's design; in an app without that screen, the default design of DEFAULT_MACHINE."""
        return self.app.current_design() or MachineDesign.defaults(DEFAULT_MACHINE)

    # --- actions ---------------------------------------------------------------------------------------------------
    def action_reload(self) -> None:
        self.design = self._drawing_design()
        self.action_generate()

    def action_generate(self) -> None:
        if self.design is None:
            self.design = self._drawing_design()
        try:
            options = self._options()
        except (ValueError, StationError) as error:
            self._set_status(str(error), style="red")
            return
        machine, params = self.design
        self.query_one("#design", Static).update(
            f"{get_machine(machine).title}: " + ", ".join(f"{k}={v:g}" for k, v in params.items()))
        self._set_status(f"generating the parts at {options['scale']:g} mm per unit…")
        self._generate(machine, dict(params), options)

    @on(Input.Submitted)
    def _field_submitted(self, _event: Input.Submitted) -> None:
        self.query_one("#parts", DataTable).focus()
        self.action_generate()

    def _options(self) -> dict:
        def number(widget_id: str, name: str) -> float:
            text = self.query_one(f"#{widget_id}", Input).value.strip()
            try:
                value = float(text)
            except ValueError:
                raise StationError(f"{name} must be a number, got {text!r}") from None
            return value

        sheet_text = self.query_one("#sheet-size", Input).value.strip()
        material = self.query_one("#material", Input).value.strip() or None
        kerf_text = self.query_one("#kerf", Input).value.strip()
        return {"scale": number("scale", "scale"), "kerf": number("kerf", "kerf") if kerf_text else None,
                "sheet_size": parse_sheet(sheet_text) if sheet_text else None, "material": material}

    def _generate(self, machine: str, params: dict, options: dict) -> None:
        """Generate in a worker (a newer generation replaces a running one); the end arrives as a
        :class:`FabricationEnded` whose result is the fabrication and the seconds it took."""
        request = FabricationRequest(machine, params, options["scale"], kerf=options["kerf"],
                                     sheet_size=options["sheet_size"], gap=DEFAULT_GAP, material=options["material"])

        def generate(report):
            started = time.perf_counter()
            return fabricate(request, report=report), time.perf_counter() - started

        run_work(self, generate, FabricationEnded, group="fabricate")

    def on_progress_reported(self, message: ProgressReported) -> None:
        """A step of the generation: the bar and, as before, the step in the status line."""
        self.query_one(ProgressPanel).show(message.progress)
        self._set_status(f"{message.progress.message}…")

    def on_fabrication_ended(self, message: FabricationEnded) -> None:
        if message.ok:
            self._show(*message.result)
        elif message.error:
            self._failed(message.error)

    def _failed(self, message: str) -> None:
        self.result = None
        self.query_one("#parts", DataTable).clear()
        self.query_one("#job", Static).update("")
        self.query_one("#part", Static).update("")
        self.query_one(HalfBlockPicture).set_png(None)
        self._set_status(f"cannot fabricate this design: {message}", style="red")

    def _show(self, result: FabricationResult, seconds: float) -> None:
        self.result = result
        table = self.query_one("#parts", DataTable)
        table.clear()
        for part in result.summary["parts"]:
            width, height = part["size_mm"]
            teeth = str(part["info"].get("teeth", ""))
            table.add_row(part["name"], str(part["sheet"]), f"{width:.0f}×{height:.0f}", teeth,
                          "; ".join(part["notes"])[:60])
        self.show_sheet(0)
        count = len(result.sheets)
        more = f", {count} sheets (n: next sheet)" if count > 1 else ""
        self._set_status(f"{len(result.summary['parts'])} parts in {seconds:.1f} s{more} — w: write files, "
                         "s: send to laser")

    def show_sheet(self, index: int) -> None:
        """Show sheet ``index`` (0-based): its picture, usage and laser job."""
        if self.result is None:
            return
        self.sheet_index = index % len(self.result.sheets)
        output = self.result.sheets[self.sheet_index]
        summary = self.result.summary
        sheet = summary["sheets"][self.sheet_index]
        job, material = sheet["job"], summary["job"]
        estimate = job["estimate_seconds"]
        count = len(self.result.sheets)
        self.query_one("#job", Static).update(
            f"sheet {output.index} of {count}: {summary['sheet_mm'][0]:g}×{summary['sheet_mm'][1]:g} mm, "
            f"usage {100 * sheet['usage']:.1f}% (parts fill {100 * sheet['envelope_usage']:.0f}% of their corner)\n"
            f"laser: {material['material']} on {material['profile']}, kerf {summary['kerf_mm']:g} mm "
            f"{KERF_SOURCES[summary['kerf_source']]}, about {estimate['total'] / 60:.1f} min "
            f"(cut {estimate['cut'] / 60:.1f}, engrave {estimate['engrave'] / 60:.1f}, "
            f"travel {estimate['travel'] / 60:.1f})\n"
            f"travel {job['travel_mm']:.0f} mm (unordered {job['travel_mm_unordered']:.0f} mm), "
            f"{len(output.gcode.splitlines())} G-code lines")
        picture = self.query_one(HalfBlockPicture)
        picture.crop = None
        picture.set_png(output.png)

    def action_next_sheet(self) -> None:
        if self.result is not None:
            self.show_sheet(self.sheet_index + 1)

    @on(DataTable.RowHighlighted, "#parts")
    def _part_highlighted(self, event: DataTable.RowHighlighted) -> None:
        """The highlighted part's facts and notes in full (the table truncates them)."""
        if self.result is None or event.cursor_row is None:
            return
        parts = self.result.summary["parts"]
        if not 0 <= event.cursor_row < len(parts):
            return
        part = parts[event.cursor_row]
        info = part["info"]
        holes = part["holes"]
        facts = [f"{part['name']}: {part['size_mm'][0]:.1f}×{part['size_mm'][1]:.1f} mm, "
                 f"{holes} hole{'' if holes == 1 else 's'}"]
        if "teeth" in info:
            facts.append(f"{info['teeth']} teeth, module {info['module_mm']:.3f} mm, pitch radius "
                         f"{info['pitch_radius_mm']:.2f} mm")
        self.part_text = "; ".join(facts) + "".join(f"\nnote: {note}" for note in part["notes"])
        self.query_one("#part", Static).update(self.part_text)

    def action_zoom(self) -> None:
        """Toggle between the whole sheet and the corner the parts use."""
        picture = self.query_one(HalfBlockPicture)
        if picture.crop is not None or self.result is None:
            picture.set_crop(None)
            return
        sheet = self.result.sheets[self.sheet_index].sheet
        # The PNG's top row is the sheet's far edge (y up on the sheet): the parts sit in the bottom-left corner.
        right = min(1.0, sheet.used_width / sheet.width)
        top = max(0.0, 1.0 - sheet.used_height / sheet.height)
        picture.set_crop((0.0, top, right, 1.0))

    def action_write(self) -> Path | None:
        if self.result is None:
            self._set_status("nothing to write yet")
            return None
        stamp = time.strftime("%Y%m%d-%H%M%S")
        folder = data_dir() / "fabrication" / f"{self.result.machine}-{stamp}"
        files = write_outputs(self.result, folder)
        self._set_status(f"written to {folder}")
        self.notify(f"parts.svg, laser.gcode, parts.json, sheet.png in {folder}", title="Fabrication files")
        return files["gcode"]

    def action_send(self) -> None:
        """Hand the job to the Machines screen's laser queue (it frames first, then runs)."""
        if self.result is None:
            self._set_status("nothing to send yet")
            return
        queue = getattr(self.app.machines_screen(), "queue_job", None)
        if queue is None:
            path = self.action_write()
            self._set_status(f"the Machines screen cannot take jobs here; the G-code is in {path}")
            return
        count = len(self.result.sheets)
        material = self.result.summary["job"]["material"]
        jobs = [(f"{self.result.machine} parts ({material})" + (f", sheet {o.index}/{count}" if count > 1 else ""),
                 o.gcode) for o in self.result.sheets]
        # Show the Machines screen first, so that its queue table exists when the jobs arrive.
        self.app.action_open_area("machines")
        self.app.call_after_refresh(self._queue_on_machines, queue, jobs)

    def action_test_card(self) -> None:
        """A test card for the material field's material: written, shown, and queued for the laser."""
        material = self.query_one("#material", Input).value.strip() or "plywood_3mm"
        self._set_status(f"making a test card for {material}…")
        folder = data_dir() / "lasertest" / f"{material}-{time.strftime('%Y%m%d-%H%M%S')}"

        def make(_report):
            output = make_card("laser", material)
            return output, write_card(output, folder)

        run_work(self, make, TestCardMade, group="test-card")

    def on_test_card_made(self, message: TestCardMade) -> None:
        if not message.ok:
            self._set_status(f"cannot make a test card: {message.error}", style="red")
            return
        output, files = message.result
        manifest = output.manifest
        picture = self.query_one(HalfBlockPicture)
        picture.crop = None
        picture.set_png(output.png)
        self.query_one("#job", Static).update(
            f"test card: {manifest['material']}, {manifest['card_mm'][0]:g}×{manifest['card_mm'][1]:g} mm, "
            f"{len(manifest['powers'])} powers × {len(manifest['feeds_mm_min'])} feeds, about "
            f"{manifest['estimate_seconds'] / 60:.0f} min\nthen: station calibrate material --image PHOTO "
            f"--card {files['json']}")
        self.notify(f"burn it, photograph it on a light surface, then: station calibrate material --image PHOTO "
                    f"--card {files['json']}", title="Test card", timeout=20)
        queue = getattr(self.app.machines_screen(), "queue_job", None)
        if queue is None:
            self._set_status(f"test card written to {files['json'].parent}")
            return
        self.app.action_open_area("machines")
        self.app.call_after_refresh(self._queue_on_machines, queue,
                                    [(f"test card ({manifest['material']})", output.gcode)])

    def _queue_on_machines(self, queue, jobs: list[tuple[str, str]]) -> None:
        for title, gcode in jobs:
            try:
                queue("laser", gcode, title=title, laser=True)
            except (*USER_ERRORS, ValueError) as error:
                self._set_status(f"the laser refused the job: {error}", style="red")
                self.notify(str(error), severity="error", title="Job not queued")
                return
        titles = ", ".join(title for title, _ in jobs)
        self._set_status(f"sent to the laser: {titles}")
        self.notify(f"{titles}: on the Machines screen, f frames a job, g starts it", title="Laser job queued")

    def _set_status(self, message: str, style: str = "") -> None:
        """Show ``message`` as plain text in ``style``: it carries what the user typed (a material, a sheet size),
        paths and error messages, which are never read as markup."""
        self.last_message = message
        self.query_one("#status", Static).update(Text(message, style=style))


SCREEN = ScreenEntry(
    name="fabricate",
    key="f",
    title="Fabricate",
    description="laser-cut the current drawing machine: gears, arms, plates, nested sheet, laser job",
    factory=FabricateScreen,
    order=40,
)
