"""The Contraption screen: load a scenario, see its causal graph, simulate and watch the states change."""

from __future__ import annotations

import numpy as np
from textual.widgets import DataTable, Input

from station.tui.app import StationApp
from station.tui.widgets.canvas import PatternCanvas


async def open_contraption_screen(app, pilot):
    """Press c on the home screen and return the Contraption screen."""
    await pilot.press("c")
    await pilot.pause()
    return app.screen


async def _wait_idle(app, pilot, screen, limit=400):
    for _ in range(limit):
        await pilot.pause(0.05)
        if not screen.running:
            return
    raise AssertionError("simulation did not finish")


async def test_contraption_screen_simulates_and_updates_states(tmp_path):
    app = StationApp(database=tmp_path / "t.sqlite3")
    async with app.run_test(size=(160, 45)) as pilot:
        screen = await open_contraption_screen(app, pilot)
        assert screen.name == "contraption"
        table = screen.query_one("#events", DataTable)
        assert table.row_count == 5  # SIMPLE by default
        assert str(table.get_cell("ball_rolls", "state")) == "awake"
        assert str(table.get_cell("last_stops", "state")) == "asleep"
        assert screen.layout_names[screen.layout_index] == "success"
        assert screen.query_one("#view", PatternCanvas).polylines  # the side view is drawn

        screen.realtime = False
        changes = []
        original = screen._update_states
        screen._update_states = lambda t, states, *rest: (changes.append(dict(states)), original(t, states, *rest))
        await pilot.press("r")
        await _wait_idle(app, pilot, screen)
        assert screen.result is not None and screen.result.success
        assert all(str(table.get_cell(name, "state")) == "success" for name in screen.scenario.events)
        assert "SUCCESS" in str(screen.query_one("#status").render())
        # The states were seen changing one event after another.
        assert len(changes) >= 5
        assert changes[0]["last_stops"] == "asleep"

        await pilot.press("l")  # next layout: failure
        assert screen.layout_names[screen.layout_index] == "failure"
        await pilot.press("r")
        await _wait_idle(app, pilot, screen)
        assert not screen.result.success
        assert str(table.get_cell("ball_hits_domino", "state")) == "failure"


async def test_contraption_screen_loads_by_name_and_reports_errors(tmp_path):
    app = StationApp(database=tmp_path / "t.sqlite3")
    async with app.run_test(size=(160, 45)) as pilot:
        screen = await open_contraption_screen(app, pilot)
        field = screen.query_one("#scenario-input", Input)
        field.value = "ballrun"
        await field.action_submit()
        await pilot.pause()
        assert screen.scenario.name == "BALLRUN"
        assert screen.query_one("#events", DataTable).row_count == 8
        field.value = str(tmp_path / "missing.toml")
        await field.action_submit()
        await pilot.pause()
        assert screen.scenario.name == "BALLRUN"  # unchanged
        assert "missing.toml" in str(screen.query_one("#status").render())


async def test_ropes_are_drawn_in_the_side_view(tmp_path):
    app = StationApp(database=tmp_path / "t.sqlite3")
    async with app.run_test(size=(160, 45)) as pilot:
        screen = await open_contraption_screen(app, pilot)
        view = screen.query_one("#view", PatternCanvas)
        assert "yellow" not in view._colors  # SIMPLE has no rope
        assert screen.load("longchain")
        await pilot.pause()
        ropes = [line for line, colour in zip(view.polylines, view._colors) if colour == "yellow"]
        assert len(ropes) == 1 and len(ropes[0]) == 3  # end, guide, end
        np.testing.assert_allclose(ropes[0][1], [-0.454, 0.36])  # the fixed guide, in the (x, z) side view


async def test_switching_layout_clears_the_previous_verdict(tmp_path):
    # The status kept "SUCCESS" of the success layout after l showed the failure layout.
    app = StationApp(database=tmp_path / "t.sqlite3")
    async with app.run_test(size=(160, 45)) as pilot:
        screen = await open_contraption_screen(app, pilot)
        screen.realtime = False
        await pilot.press("r")
        await _wait_idle(app, pilot, screen)
        status = screen.query_one("#status")
        assert "SUCCESS" in str(status.render())
        await pilot.press("l")
        await pilot.pause()
        shown = str(status.render())
        assert "SUCCESS" not in shown and "layout failure" in shown and "press r" in shown
        assert screen.result is None


async def test_a_typed_name_in_an_error_is_shown_as_typed(tmp_path):
    # The status was read as markup: "[b]nope[/b]" came back as "nope".
    app = StationApp(database=tmp_path / "t.sqlite3")
    async with app.run_test(size=(160, 45)) as pilot:
        screen = await open_contraption_screen(app, pilot)
        assert not screen.load("[b]nope[/b]")
        await pilot.pause()
        assert "[b]nope[/b]" in str(screen.query_one("#status").render())
