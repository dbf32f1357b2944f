"""The Assemble screen: a layout's guide, stepped through with n / p, the projector following, the tolerance map."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from textual.widgets import DataTable, Input, Static

from station.devices import default_devices
from station.tui.screens.assemble import AssembleScreen

from ...conftest import opened, settle

LAYOUT = Path(__file__).resolve().parents[2] / "data" / "robust" / "simple-layout-with-model.json"
SIMPLE = Path(__file__).resolve().parents[3] / "examples" / "scenarios" / "simple.toml"


@pytest.fixture(autouse=True)
def small_forecasts(monkeypatch):
    """The forecast the screen keeps in view: a few simulations in the worker thread (a pool's start-up and 60
    simulations per forecast are the real screen's, not what these tests are about)."""
    monkeypatch.setattr(AssembleScreen, "forecast_samples", 6)
    monkeypatch.setattr(AssembleScreen, "simulation_workers", 1)


async def test_a_layout_is_stepped_through_and_the_projector_follows(tmp_path):
    async with opened(tmp_path, "a") as (app, pilot):
        screen = app.screen
        assert isinstance(screen, AssembleScreen)
        screen.open_layout(str(SIMPLE), str(LAYOUT))
        await settle(app, pilot)
        assert screen.job is not None, str(screen.query_one("#status", Static).render())
        steps = screen.query_one("#steps", DataTable)
        names = [str(steps.get_row_at(i)[1]) for i in range(steps.row_count)]
        assert names == [part.name for part in screen.job.guide.parts] and names[-1] == "ball"
        assert screen.step == 1
        projector = screen.projector
        assert projector is not None and projector.frames, "the projector shows the first step"
        shown = len(projector.frames)
        await pilot.press("n")
        await settle(app, pilot)
        assert screen.step == 2 and len(projector.frames) == shown + 1
        assert "dominoes" in str(screen.query_one("#caption", Static).render())
        await pilot.press("n", "n", "n")  # past the last step: stays there
        await settle(app, pilot)
        assert screen.step == len(names)
        await pilot.press("p")
        await settle(app, pilot)
        assert screen.step == len(names) - 1
        await pilot.press("0")
        await settle(app, pilot)
        assert screen.step == 0 and "calibrate" in str(screen.query_one("#caption", Static).render())
        # the tolerance map: the layout carries its model, so the track's parameters have a delta
        tolerances = screen.query_one("#tolerances", DataTable)
        assert not tolerances.display
        await pilot.press("t")
        assert tolerances.display and tolerances.row_count >= 1
        assert {str(tolerances.get_row_at(i)[1]) for i in range(tolerances.row_count)} >= {"track.x"}
        status = str(screen.query_one("#status", Static).render())
        assert "tolerances from model" in status
        assert "NOT at true scale: projector has no calibration of its own" in status  # the projector's own, none
        # e writes the PDF and the SVG to the data folder
        await pilot.press("e")
        await settle(app, pilot)
        status = str(screen.query_one("#status", Static).render())
        assert status.startswith("wrote "), status
        pdf = Path(status.split()[1])
        assert pdf.suffix == ".pdf" and pdf.read_bytes().startswith(b"%PDF") and pdf.with_suffix(".svg").exists()


async def test_a_bad_layout_is_one_line_and_nothing_breaks(tmp_path):
    async with opened(tmp_path, "a") as (app, pilot):
        screen = app.screen
        screen.open_layout(str(SIMPLE), str(tmp_path / "missing.json"))
        await settle(app, pilot)
        status = str(screen.query_one("#status", Static).render())
        assert status.startswith("cannot build the guide:") and "missing.json" in status
        assert screen.job is None
        # the scenario's own layout, with the field left empty
        screen.query_one("#layout", Input).value = ""
        screen.action_build()
        await settle(app, pilot)
        assert screen.job is not None and screen.job.guide.tolerance_source == "none"


async def test_c_checks_the_placed_parts_with_the_camera_and_the_projector_follows(tmp_path):
    from station.tui.widgets.picture import HalfBlockPicture

    async with opened(tmp_path, "a") as (app, pilot):
        screen = app.screen
        screen.open_layout(str(SIMPLE.with_name("ballrun.toml")), "success")
        await settle(app, pilot)
        assert screen.job is not None, str(screen.query_one("#status", Static).render())
        shown = len(screen.projector.frames)
        await pilot.press("c")  # the station's camera: sim://camera, shown the guide's tags where they belong
        await settle(app, pilot)
        assert screen.check is not None, str(screen.query_one("#status", Static).render())
        table = screen.query_one("#check", DataTable)
        assert table.display and table.row_count == len(screen.job.guide.parts)  # tagged parts, then by eye
        rows = {str(table.get_row_at(i)[0]): table.get_row_at(i) for i in range(table.row_count)}
        goblet = rows["goblet"]
        assert float(goblet[4]) < 0.3 and "in place" in str(goblet[8])  # placed as designed: nothing to do
        assert "by eye" in str(rows["top_track"][6])
        caption = str(screen.query_one("#caption", Static).render())
        assert "tagged parts measured" in caption and "no success-model score" in caption
        picture = screen.query_one("#frame", HalfBlockPicture)
        assert picture.full is not None and picture.full.size == (1920, 1080)  # the camera's frame, drawn on
        assert len(screen.projector.frames) == shown + 1  # the projector shows the check
        await pilot.press("c")  # again, after moving the parts: the plane is found again
        await settle(app, pilot)
        assert screen.check.report.plane is not None and screen.check.report.plane.moved_mm < 0.5


async def test_the_whole_attempt_on_a_simulated_world_with_the_forecast_in_view(tmp_path):
    """Build, c (the simulated maker places, the camera checks), f (moved as said, checked again), r (the world
    runs), l (logged): the forecast box says the stage and the physical success after every step."""
    from station.services.trials import open_store
    from station.tui.widgets.assemble_flow import ForecastStatus
    from station.tui.widgets.outcomes import OutcomeTable

    async with opened(tmp_path, "a") as (app, pilot):
        screen = app.screen
        screen.query_one("#world", Input).value = "sim://world?seed=4&place_mm=3"
        screen.open_layout(str(SIMPLE.with_name("ballrun.toml")), "success")
        await settle(app, pilot)
        assembly = screen.assembly
        assert assembly is not None and assembly.world is not None, str(screen.query_one("#status", Static).render())
        box = screen.query_one("#forecast", ForecastStatus)
        assert "attempt 1 · guide" in str(box.render()) and "physical success" in str(box.render())
        assert screen.forecast is not None and screen.forecast.when == "designed"
        await pilot.press("c")
        await settle(app, pilot)
        assert assembly.stage == "check" and screen.check is assembly.check and screen.forecast.when == "as placed"
        placed = assembly.world.placed()
        table = screen.query_one("#check", DataTable)
        rows = {str(table.get_row_at(i)[0]): table.get_row_at(i) for i in range(table.row_count)}
        for name in ("goblet", "low_plank", "stop"):  # the table says how far the world's parts really are
            part = next(p for p in assembly.parts if p.name == name)
            truth = np.subtract(placed[name]["center_mm"], part.center_mm)
            assert abs(float(rows[name][2]) - truth[0]) < 0.6 and abs(float(rows[name][3]) - truth[1]) < 0.6
        await pilot.press("f")
        await settle(app, pilot)
        assert len(assembly.checks) == 2 and assembly.fixes == 1
        await pilot.press("r")  # after a check: accepted as placed, the world runs it
        await settle(app, pilot)
        outcomes = screen.query_one("#outcomes", OutcomeTable)
        assert assembly.stage == "log" and outcomes.display and outcomes.read_only
        assert [str(outcomes.get_row_at(i)[2]) for i in range(outcomes.row_count)] == list(
            assembly.outcomes.values())
        await pilot.press("l")
        await settle(app, pilot)
        assert assembly.stage == "done" and assembly.trial_id is not None
        with open_store() as store:  # the station database the screen logs to (the test home's)
            (trial,) = store.trials()
        assert trial["check"] is not None and trial["outcomes"] == assembly.outcomes
        assert "this run" in screen.forecast.when and "attempt 1 · done" in str(box.render())
        await pilot.press("g")  # another attempt: the log has one trial, so this is attempt 2
        await settle(app, pilot)
        assert screen.assembly is not assembly and screen.assembly.attempt == 2


async def test_with_jigs_on_a_simulated_world_the_check_reads_the_side_camera_too(tmp_path):
    """The jigs switch on and a simulated world: c checks with both cameras (the world serves the side one), the
    table has the side camera's row for the track on its stand J1, saying how high it stands and what to do."""
    from textual.widgets import Switch

    from station.services.world import as_placed_layout

    async with opened(tmp_path, "a") as (app, pilot):
        screen = app.screen
        screen.query_one("#world", Input).value = "sim://world?seed=3&jig_mm=3&jig_deg=3"
        screen.query_one("#jigs", Switch).value = True
        screen.open_layout(str(SIMPLE), "success")
        await settle(app, pilot)
        assembly = screen.assembly
        assert assembly is not None and assembly.job.jigs is not None, str(screen.query_one("#status", Static).render())
        await pilot.press("c")
        await settle(app, pilot)
        assert screen.check is assembly.check and screen.check.report.measured_by["track.z"] == "side"
        table = screen.query_one("#check", DataTable)
        rows = {str(table.get_row_at(i)[0]): table.get_row_at(i) for i in range(table.row_count)}
        side = rows["track (side, jig J1)"]
        names = list(assembly.job.scenario.design_space.names)
        truth = dict(zip(names, as_placed_layout(assembly.job.scenario, assembly.job.guide, assembly.world)))
        off = truth["track.z"] - dict(zip(names, assembly.job.layout.x))["track.z"]
        assert str(side[6]) == "NO" and f"{'lower' if off > 0 else 'raise'} `track`'s lower end" in str(side[8])
        caption = str(screen.query_one("#caption", Static).render())
        assert "side camera: 1 of 1 jig stands read, 1 to raise, lower or tilt" in caption
        assert "measured by the side camera: track.z, track.roll" in caption
        await pilot.press("f")  # the maker set them again as it said: the side camera finds them where they go
        await settle(app, pilot)
        rows = {str(table.get_row_at(i)[0]): table.get_row_at(i) for i in range(table.row_count)}
        side = rows["track (side, jig J1)"]
        assert (str(side[6]), str(side[8])) == ("yes", "`track` is at its height and tilt")
        assert "side camera: 1 of 1 jig stands read, 0 to raise, lower or tilt" in str(
            screen.query_one("#caption", Static).render())


async def test_a_real_table_is_ticked_and_logged_and_keys_out_of_turn_are_said(tmp_path):
    from station.tui.widgets.outcomes import OutcomeTable

    async with opened(tmp_path, "a") as (app, pilot):
        screen = app.screen
        screen.open_layout(str(SIMPLE), "success")
        await settle(app, pilot)
        await pilot.press("l")  # nothing run yet
        assert "the attempt is at 'guide'" in str(screen.query_one("#status", Static).render())
        await pilot.press("c")
        await settle(app, pilot)
        await pilot.press("a", "r")
        await settle(app, pilot)
        table = screen.query_one("#outcomes", OutcomeTable)
        assert table.display and table.has_focus and not table.read_only
        await pilot.press("y", "y", "n")  # ball rolls, hits the domino, the first does not topple: the rest implied
        await pilot.pause()
        assert "a failure; l logs it" in str(screen.query_one("#status", Static).render())
        await pilot.press("l")
        await settle(app, pilot)
        assert screen.assembly.stage == "done"
        assert screen.assembly.outcomes["first_topples"] == "no" and screen.assembly.success is False


@pytest.mark.slow  # ~20 s: three guides with tolerance maps, a fit and an optimization (run with -m slow)
async def test_k_calibrates_the_physics_on_the_log_and_o_reoptimizes_with_it(tmp_path):
    """Trials of SIMPLE in the log (as a real table's maker logs them): k fits the materials and puts the profile
    in the Physics field, o optimizes the layout under it and puts the LAYOUT.json in the Layout field; g then
    builds the next attempt from both."""
    from calibration.sim_fit import FitSettings
    from design.contraption.physics_profile import load_profile
    from design.robust.psp import PSPSettings
    from station.services.trials import build_trial, layout_values, load_trial_scenario, open_store

    simple = load_trial_scenario("simple")
    layout = layout_values(simple, simple.layout("success"))
    with open_store() as store:
        for i in range(6):  # the first dominoes fall half of the time: something to fit
            given = {"last_stops": "yes"} if i % 2 else {"ball_rolls": "yes", "ball_hits_domino": "yes",
                                                         "first_topples": "no"}
            store.add(build_trial(simple, layout, given))
    async with opened(tmp_path, "a") as (app, pilot):
        screen = app.screen
        screen.fit_settings = FitSettings(draws=2, sobol=4, rounds=1, per_round=2, held_out=0.0)
        screen.optimize_budget, screen.optimize_settings = 20, PSPSettings(n_initial=12, max_exploration_steps=2)
        screen.open_layout(str(SIMPLE), "success")
        await settle(app, pilot)
        await pilot.press("k")
        await settle(app, pilot)
        physics = screen.query_one("#physics", Input).value
        assert physics.endswith("simple-calibrated.toml"), str(screen.query_one("#status", Static).render())
        profile = load_profile(physics)
        # every material value, as station loop fits them: the marked ones and the plain numbers
        assert set(profile.values) == set(simple.physics_parameters())
        assert set(simple.uncertain_parameters()) < set(profile.values)
        await pilot.press("o")
        await settle(app, pilot)
        layout_file = screen.query_one("#layout", Input).value
        assert layout_file.endswith("simple-physics.json"), str(screen.query_one("#status", Static).render())
        assert json.loads(Path(layout_file).read_text())["scenario"] == "SIMPLE"
        await pilot.press("g")
        await settle(app, pilot)
        assert screen.assembly.physics == physics and screen.assembly.job.layout.source == layout_file
        assert screen.assembly.attempt == 7


def _footer(app) -> str:
    """The footer's line as drawn (what a maker sees at the bottom of the screen)."""
    import io

    from rich.console import Console

    width, height = app.size
    console = Console(width=width, height=height, file=io.StringIO(), force_terminal=True, record=True)
    console.print(app.screen._compositor.render_update(full=True, screen_stack=app._background_screens,
                                                        simplify=True))
    return console.export_text().splitlines()[height - 1]


def _shown_keys(app) -> list[str]:
    """Every key the screen and its focused widget take, as "KEY label" (the bindings meant to be shown)."""
    return [f"{app.get_key_display(binding)} {binding.description}"
            for _, binding, _, _ in app.screen.active_bindings.values() if binding.show]


def _in_view(screen, widget) -> bool:
    """Whether all of ``widget`` is drawn on the screen (not scrolled or pushed out of its container's view)."""
    from textual.errors import NoWidget

    try:
        geometry = screen.find_widget(widget)
    except NoWidget:
        return False
    return bool(geometry.region) and geometry.visible_region == geometry.region


async def test_every_key_shows_in_the_footer_at_160_columns(tmp_path):
    async with opened(tmp_path, "a") as (app, pilot):
        screen = app.screen
        screen.open_layout(str(SIMPLE), "success")
        await settle(app, pilot)
        keys, footer = _shown_keys(app), _footer(app)
        assert [key for key in keys if key not in footer] == [], footer
        assert {"r", "l", "g", "k", "o"} <= {key.split()[0] for key in keys}
        await pilot.press("c")
        await settle(app, pilot)
        await pilot.press("a", "r")  # a real table: the outcome table takes y / n / u
        await settle(app, pilot)
        keys, footer = _shown_keys(app), _footer(app)
        assert [key for key in keys if key not in footer] == [], footer
        assert {"y", "n", "u", "o"} <= {key.split()[0] for key in keys}


async def test_the_progress_stays_in_view_under_the_forecast_whatever_the_status_says(tmp_path):
    """k (calibrate) on a real table's logged trial: its progress panel is in view from the key on, at 160x50,
    while the status above it says a whole logged trial and the forecast box grows."""
    from calibration.sim_fit import FitSettings
    from station.tui.widgets.progress import ProgressPanel

    async with opened(tmp_path, "a") as (app, pilot):
        screen = app.screen
        screen.fit_settings = FitSettings(draws=2, sobol=4, rounds=1, per_round=2, held_out=0.0)
        screen.open_layout(str(SIMPLE), "success")
        await settle(app, pilot)
        await pilot.press("c")
        await settle(app, pilot)
        await pilot.press("a", "r", "y", "y", "n", "l")
        await settle(app, pilot)
        assert screen.assembly.stage == "done", str(screen.query_one("#status", Static).render())
        panel = screen.query_one("#check-progress", ProgressPanel)
        await pilot.press("k")
        await pilot.pause()
        assert _in_view(screen, panel) and _in_view(screen, panel.bar)
        await settle(app, pilot)
        assert panel.message.startswith("calibrated:"), panel.message
        assert _in_view(screen, panel) and _in_view(screen, panel.bar)


async def test_the_fields_read_as_hints_and_the_projector_is_named_once(tmp_path):
    async with opened(tmp_path, "a") as (app, pilot):
        screen = app.screen
        world = screen.query_one("#world", Input)
        assert world.placeholder.startswith("e.g. sim://world") and "empty: a real table" in world.placeholder
        assert screen.query_one("#physics", Input).placeholder.startswith("e.g. ")
        screen.open_layout(str(SIMPLE), "success")
        await settle(app, pilot)
        status = str(screen.query_one("#status", Static).render())
        default = next(device.url for device in default_devices() if device.kind == "projector")
        assert f"projector ({default}) follows the steps" in status and "projector projector" not in status


async def test_e_names_the_export_by_scenario_and_layout_and_keeps_another_layouts(tmp_path):
    """Two layouts of SIMPLE exported one after the other: two files, the first left as it was; the same layout
    exported again replaces its own."""
    async with opened(tmp_path, "a") as (app, pilot):
        screen = app.screen
        written = []
        for layout in ("success", "failure", str(LAYOUT), "success"):
            screen.open_layout(str(SIMPLE), layout)
            await settle(app, pilot)
            await pilot.press("e")
            await settle(app, pilot)
            status = str(screen.query_one("#status", Static).render())
            assert status.startswith("wrote "), status
            written.append(Path(status.split()[1]))
        success, failure, model, again = written
        assert success.name.startswith("simple-success-") and failure.name.startswith("simple-failure-")
        assert model.name.startswith("simple-simple-layout-with-model-")
        assert len({success, failure, model}) == 3 and again == success
        assert all(path.exists() and path.with_suffix(".svg").exists() for path in written)


async def test_the_current_parts_parameters_are_shown_with_value_tolerance_and_how_to_set_them(tmp_path):
    async with opened(tmp_path, "a") as (app, pilot):
        screen = app.screen
        screen.open_layout(str(SIMPLE), str(LAYOUT))
        await settle(app, pilot)
        assert screen.job is not None, str(screen.query_one("#status", Static).render())
        lines = screen.query_one("#parameters", Static)
        text = str(lines.render())
        track = screen.job.guide.part("track")
        assert lines.display and [line.split(" = ")[0] for line in text.splitlines()[:3]] == [
            "track.x", "track.z", "track.roll"]
        for setting in track.settings:  # the value, how to set it, and the words with the tolerance
            assert f"{setting.name} = {setting.value:.1f} {setting.unit}" in text
            assert f"{setting.tolerance.delta:.1f}" in text
        assert "[ruler]  height above the table: its underside at the middle" in text
        assert "[sheet + camera check]  left-right on the sheet" in text
        assert f"tilt: {track.elevation.tilt_deg:.1f} deg" in " ".join(text.split())
        await pilot.press("n")  # the dominoes: no design parameter moves them
        await settle(app, pilot)
        assert screen.step == 2 and not lines.display
        await pilot.press("p")
        await settle(app, pilot)
        assert lines.display
        await pilot.press("0")
        await settle(app, pilot)
        assert not lines.display
