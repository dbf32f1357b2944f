"""Fabricate screen: takes the Drawing screen's design, shows the sheet, parts and estimate, writes files."""

from __future__ import annotations

from textual.widgets import DataTable, Input, Static

from design.machines import get_machine
from station.tui.screens.fabricate import FabricateScreen, HalfBlockPicture
from station.tui.widgets.progress import ProgressPanel

from ...conftest import opened


async def wait_for(pilot, screen, condition, steps=2400):
    # Generous: a loaded CI machine may take long to generate a sheet; the condition, not the clock, is tested.
    for _ in range(steps):
        await pilot.pause(0.05)
        if condition():
            return
    raise AssertionError(f"timed out; status: {screen.last_message}")


async def show_design(app, pilot, machine: str, params: dict) -> None:
    """Open the Drawing machines screen on ``machine`` with ``params``, as one does before fabricating it."""
    await pilot.press("d")
    for _ in range(5):
        await pilot.pause(0.05)
    app.open_design(machine, params)
    for _ in range(5):
        await pilot.pause(0.05)


async def test_fabricate_shows_the_current_design_sheet_and_parts(tmp_path):
    async with opened(tmp_path) as (app, pilot):
        await show_design(app, pilot, "spirograph", {"r_f": 5, "r_r": 2, "d": 1.0})
        assert app.get_screen("drawing").current_design()[1]["r_r"] == 2
        # "Fabricate" from the Drawing machines screen itself.
        app.get_screen("drawing").action_fabricate()
        await pilot.pause()
        screen = app.screen
        assert isinstance(screen, FabricateScreen)
        await wait_for(pilot, screen, lambda: screen.result is not None)
        assert screen.result.params["r_r"] == 2
        # The progress panel followed the work to its end, and the end's summary was not overwritten by a step.
        panel = screen.query_one(ProgressPanel)
        assert panel.stage == "sheets" and panel.bar.total and panel.bar.progress == panel.bar.total
        assert screen.last_message.startswith("2 parts in "), screen.last_message
        table = screen.query_one("#parts", DataTable)
        assert table.row_count == 2
        names = {table.get_row_at(i)[0] for i in range(table.row_count)}
        assert names == {"fixed ring", "rolling gear"}
        assert "min" in str(screen.query_one("#job", Static).render())
        picture = screen.query_one(HalfBlockPicture)
        text = picture.render_text(60, 20)
        assert "▀" in text.plain and len(text.spans) > 100
        # z zooms on the corner the parts use, z again shows the whole sheet.
        whole = picture.image.size
        await pilot.press("z")
        assert picture.crop is not None and picture.image.size[0] < whole[0]
        await pilot.press("z")
        assert picture.crop is None and picture.image.size == whole
        # Moving through the parts shows each one's facts in full.
        table.move_cursor(row=1)
        await pilot.pause()
        assert "rolling gear" in screen.part_text and "module" in screen.part_text
        # Another scale: regenerate with Enter in the field.
        field = screen.query_one("#scale", Input)
        field.value = "6"
        field.focus()
        await pilot.press("enter")
        await wait_for(pilot, screen, lambda: screen.result is not None and screen.result.scale == 6.0)
        # Write the files.
        gcode = screen.action_write()
        assert gcode is not None and gcode.exists() and gcode.read_text().rstrip().endswith("M5 S0")
        assert (gcode.parent / "sheet.png").exists()


async def test_a_bad_field_is_reported_without_a_crash(tmp_path):
    async with opened(tmp_path, "f", wait=False) as (app, pilot):
        screen = app.screen
        await wait_for(pilot, screen, lambda: screen.result is not None)
        screen.query_one("#sheet-size", Input).value = "tiny"
        screen.action_generate()
        await pilot.pause()
        assert "sheet 'tiny'" in screen.last_message  # the service names the field, not the CLI flag
        screen.query_one("#sheet-size", Input).value = "60x60"
        screen.action_generate()
        await wait_for(pilot, screen, lambda: "cannot fabricate" in screen.last_message)
        assert screen.result is None


async def test_send_queues_the_laser_job_on_the_machines_screen(tmp_path):
    async with opened(tmp_path, "f", wait=False) as (app, pilot):
        screen = app.screen
        await wait_for(pilot, screen, lambda: screen.result is not None)
        await pilot.press("s")
        machines = app.get_screen("machines")
        await wait_for(pilot, screen, lambda: getattr(machines, "jobs", None))
        assert app.screen.name == "machines"
        entry = machines.jobs[-1]
        assert entry.device == "laser" and entry.job.laser
        assert entry.job.lines == screen.result.gcode.splitlines()
        assert "sent to the laser" in screen.last_message
        # the simulated laser connects by itself, so frame/start work at once
        await wait_for(pilot, screen, lambda: "laser" in machines.connections)


async def test_several_sheets_are_shown_in_turn_and_all_sent(tmp_path):
    async with opened(tmp_path) as (app, pilot):
        await show_design(app, pilot, "hoot_nanny", get_machine("hoot_nanny").defaults())
        app.get_screen("drawing").action_fabricate()
        screen = app.get_screen("fabricate")
        await wait_for(pilot, screen, lambda: screen.result is not None)
        screen.query_one("#scale", Input).value = "5"
        screen.query_one("#sheet-size", Input).value = "140x140"
        screen.action_generate()
        await wait_for(pilot, screen, lambda: screen.result is not None and len(screen.result.sheets) == 2)
        assert "2 sheets" in screen.last_message
        first = screen.query_one(HalfBlockPicture).full
        await pilot.press("n")
        assert screen.sheet_index == 1 and "sheet 2 of 2" in str(screen.query_one("#job", Static).render())
        assert screen.query_one(HalfBlockPicture).full is not first
        await pilot.press("s")
        machines = app.get_screen("machines")
        await wait_for(pilot, screen, lambda: len(getattr(machines, "jobs", [])) == 2)
        assert [j.title.endswith(f"sheet {i}/2") for i, j in enumerate(machines.jobs, start=1)] == [True, True]


def test_the_sheet_picture_names_what_it_will_show():
    from station.tui.widgets.picture import HalfBlockPicture as Picture

    assert str(Picture(empty="(no sheet yet)").render_text(40, 10)) == "(no sheet yet)"
    assert HalfBlockPicture is Picture  # the Fabricate screen's picture is the shared widget


async def test_typed_text_in_the_status_is_shown_as_typed(tmp_path):
    # The status was read as markup: a material typed as "[b]oak[/b]" came back as "oak" (and "[red]..." coloured).
    async with opened(tmp_path, "f", wait=False) as (app, pilot):
        screen = app.screen
        await wait_for(pilot, screen, lambda: screen.result is not None)
        screen.query_one("#material", Input).value = "[b]oak[/b]"
        screen.query_one("#material", Input).focus()
        await pilot.press("enter")
        await wait_for(pilot, screen, lambda: "oak" in screen.last_message and "generating" not in screen.last_message)
        assert "[b]oak[/b]" in str(screen.query_one("#status", Static).render())


async def test_without_drawing_and_machines_screens_fabricate_works_on_its_own(tmp_path):
    # The links through the app: no Drawing screen gives the default design, no Machines screen writes the G-code.
    async with opened(tmp_path, "f", wait=False, without=("drawing", "machines")) as (app, pilot):
        screen = app.screen
        assert isinstance(screen, FabricateScreen)
        await wait_for(pilot, screen, lambda: screen.result is not None)
        assert app.current_design() is None
        assert screen.design == ("spirograph", get_machine("spirograph").defaults())
        assert screen.result.machine == "spirograph"
        await pilot.press("s")
        await pilot.pause()
        assert "the Machines screen cannot take jobs here; the G-code is in" in screen.last_message
        assert app.screen is screen and app.machines_screen() is None
