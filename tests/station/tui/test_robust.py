"""The Optimize screen: live progress, then per-event probabilities and the optimized layout beside the initial."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from textual.widgets import Button, DataTable, Input, Select, Static

from design.robust import PSPSettings
from station.tui.screens.robust import RobustScreen, scenario_choices
from station.tui.widgets.progress import ProgressPanel

from ...conftest import opened

TINY = PSPSettings(n_initial=24, n_successes=10, max_exploration_steps=2, max_active_steps=1)

pytestmark = pytest.mark.skipif(not any(n == "simple" for n, _ in scenario_choices()), reason="no SIMPLE scenario")


async def wait_until_idle(app, pilot, seconds=120):
    for _ in range(int(seconds * 10)):
        await pilot.pause(0.1)
        if not app.screen._optimizing:
            return
    raise AssertionError("the optimization did not finish")


async def wait_until_reporting(screen, pilot, seconds=120):
    """Until the run has reported its first progress (it is under way: a stop now stops a running optimization)."""
    for _ in range(int(seconds * 10)):
        await pilot.pause(0.1)
        if screen.query_one(ProgressPanel).stage:
            return
    raise AssertionError("the optimization reported no progress")


def open_screen(app) -> RobustScreen:
    screen = app.screen
    assert isinstance(screen, RobustScreen)
    screen.simulation_workers = 1
    screen.psp_settings = TINY
    return screen


async def test_optimize_shows_progress_probabilities_and_layouts(tmp_path):
    async with opened(tmp_path, "o", wait=False) as (app, pilot):
        assert app.screen.name == "optimize"
        screen = open_screen(app)
        simple = dict(scenario_choices())["simple"]
        screen.query_one("#scenario", Select).value = simple
        screen.query_one("#budget", Input).value = "24"
        seen = []
        original = screen._show_progress
        screen._show_progress = lambda progress: (seen.append(progress), original(progress))
        screen.query_one("#optimize", Button).press()
        await pilot.pause()
        await wait_until_idle(app, pilot)
        optimizing = [p for p in seen if hasattr(p, "phase")]  # then the optimized layout's physical success
        assert optimizing and optimizing[-1].phase == "done" and len(optimizing) < len(seen)
        assert {p.phase for p in optimizing} >= {"exploration", "optimization"}
        events = screen.query_one("#events", DataTable)
        assert events.row_count == 6  # five events and the product
        layout = screen.query_one("#layout", DataTable)
        assert [str(layout.get_row(k)[0]) for k in layout.rows] == ["track.x", "track.z", "track.roll"]
        panel = screen.query_one("#progress-panel", ProgressPanel)
        assert panel.bar.progress == screen.result.n_simulations and panel.stage == "done"
        assert f"simulations {screen.result.n_simulations}/{screen.result.budget}" in panel.message
        status = str(screen.query_one("#status", Static).render())
        assert status.startswith("SIMPLE: physical success on the table ") and "PSP" not in status
        assert f"kept {screen.result.kept_candidate()}" in status
        assert screen.query_one("#picture").image is not None
        await pilot.press("w")
        await pilot.pause()
        wrote = str(screen.query_one("#status", Static).render())
        assert wrote.startswith("wrote ")
        assert json.loads(Path(wrote.removeprefix("wrote ").strip()).read_text())["physical_success"]["samples"] == 48
        # a opens the result on the Assemble screen: its guide, from the layout just written (with its model)
        await pilot.press("a")
        for _ in range(3):
            await pilot.pause()
            await app.workers.wait_for_complete()
        assemble = app.screen
        assert assemble.name == "assemble" and assemble.job is not None
        assert assemble.job.guide.scenario == "SIMPLE" and assemble.job.layout.format == "LAYOUT.json"


async def test_stop_ends_a_run_cleanly_and_bad_budget_is_refused(tmp_path):
    async with opened(tmp_path, "o", wait=False) as (app, pilot):
        screen = open_screen(app)
        screen.query_one("#budget", Input).value = "3"
        screen.action_optimize()
        await pilot.pause()
        assert "budget must be an integer >= 20" in str(screen.query_one("#status", Static).render())
        assert not screen._optimizing
        screen.query_one("#budget", Input).value = "200"
        screen.action_optimize()
        await wait_until_reporting(screen, pilot)
        screen.action_stop()
        await wait_until_idle(app, pilot)
        assert "stopped" in str(screen.query_one("#status", Static).render())
        assert screen.result is None and not screen.query_one("#optimize", Button).disabled


async def test_enter_in_the_budget_field_starts_a_run_that_s_stops(tmp_path):
    """Letter keys type into a focused field (o does nothing there); Enter starts, and s then stops the run."""
    async with opened(tmp_path, "o", wait=False) as (app, pilot):
        screen = open_screen(app)
        screen.query_one("#budget", Input).focus()
        await pilot.press("end", *["backspace"] * 6, "2", "0", "0", "o")
        await pilot.pause()
        assert screen.query_one("#budget", Input).value == "200" and not screen._optimizing
        await pilot.press("enter")
        await pilot.pause()
        assert screen._optimizing and not isinstance(app.focused, Input)
        await wait_until_reporting(screen, pilot)
        await pilot.press("s")
        await wait_until_idle(app, pilot)
        assert "stopped" in str(screen.query_one("#status", Static).render())


async def test_contraption_screen_opens_the_optimizer_on_its_scenario(tmp_path):
    import shutil

    from design.contraption.catalog import resolve_scenario_path

    async with opened(tmp_path, "c", wait=False) as (app, pilot):
        contraption = app.screen
        assert contraption.load("ballrun")
        await pilot.press("o")
        await pilot.pause()
        assert app.screen.name == "optimize"
        select = app.screen.query_one("#scenario", Select)
        assert str(select.value).endswith("ballrun.toml")
        # a scenario file of the user's own (not an example) is added to the list and chosen
        own = tmp_path / "my_run.toml"
        shutil.copy(resolve_scenario_path("simple"), own)
        await pilot.press("escape")
        await pilot.press("c")
        await pilot.pause()
        assert app.screen.load(str(own))
        await pilot.press("o")
        await pilot.pause()
        select = app.screen.query_one("#scenario", Select)
        assert select.value == str(own.resolve())
        assert any(label == "my_run" for label, _ in select._options)


async def test_the_settings_choice_reaches_the_pipeline(tmp_path):
    async with opened(tmp_path, "o", wait=False) as (app, pilot):
        screen = app.screen
        screen.simulation_workers = 1  # psp_settings stays None: the Select decides
        screen.query_one("#scenario", Select).value = dict(scenario_choices())["simple"]
        screen.query_one("#budget", Input).value = "24"
        assert screen.query_one("#settings", Select).value == "recommended"  # the station's default
        screen.query_one("#settings", Select).value = "thesis"
        await pilot.press("o")
        await pilot.pause()
        await wait_until_idle(app, pilot)
        assert screen.result is not None and screen.result.n_simulations <= 24
        assert screen.result.settings == PSPSettings()  # the thesis's, as published


async def test_side_view_says_no_layout_yet_before_a_run(tmp_path):
    # The picture widget came from the Fabricate screen and said "(no sheet yet)" here.
    async with opened(tmp_path, "o", wait=False) as (app, pilot):
        screen = open_screen(app)
        shown = str(screen.query_one("#picture").render())
        assert "no layout yet" in shown and "sheet" not in shown


async def test_enter_on_a_bad_budget_keeps_the_field_to_mend(tmp_path):
    """A refused budget leaves the focus in its field, so the digits typed next go there (not to the table)."""
    async with opened(tmp_path, "o", wait=False) as (app, pilot):
        screen = open_screen(app)
        screen.query_one("#budget", Input).focus()
        await pilot.press("end", *["backspace"] * 6, "enter")
        await pilot.pause()
        assert "budget must be an integer >= 20, got ''" in str(screen.query_one("#status", Static).render())
        assert app.focused is screen.query_one("#budget", Input) and not screen._optimizing
        await pilot.press("2", "5")
        assert screen.query_one("#budget", Input).value == "25"
