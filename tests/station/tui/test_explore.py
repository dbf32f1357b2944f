"""The Explore screen: PoIs on the canvas, invariants from keys, invariant-space sliders, send back to Drawing."""

from __future__ import annotations

import numpy as np
from textual.widgets import DataTable

from design.explore import CURVATURE
from station.tui.widgets.explore_canvas import ExploreCanvas
from station.tui.widgets.explore_slider import InvariantSlider

from ...conftest import opened, settle


async def test_explore_screen_full_session(tmp_path):
    async with opened(tmp_path, "d", size=(150, 45)) as (app, pilot):
        app.get_screen("drawing").load_design(
            "cycloid_drawing_machine", {"r_t": 7, "r_e": 4, "d_tf": 9.0, "theta_te": 2.4, "r_s": 3.5, "d_fh": 10.5}
        )
        await settle(app, pilot)
        await pilot.press("x")
        await settle(app, pilot)
        screen = app.screen
        assert screen.name == "explore"
        explorer = screen.explorer
        assert explorer is not None and explorer.machine.name == "cycloid_drawing_machine"
        table = screen.query_one("#pois", DataTable)
        assert table.row_count == len(explorer.pois) > 0
        canvas = screen.query_one("#canvas", ExploreCanvas)
        assert len(canvas.markers) == len(explorer.pois)
        # Base parameters as sliders before any invariant.
        assert [w.label for w in screen.query(InvariantSlider)] == list(explorer.names)

        # Select the first curvature maximum with the keyboard and freeze its curvature.
        first = next(p.id for p in explorer.pois if p.kind == CURVATURE)
        table.focus()
        table.move_cursor(row=first)
        await pilot.press("enter")
        await settle(app, pilot)
        assert screen.selected == [first]
        await pilot.press("2")
        await settle(app, pilot)
        assert [inv.label for inv in explorer.invariants] == [f"curvature:{first}"]
        sliders = list(screen.query(InvariantSlider))
        assert [w.label for w in sliders] == [s.name for s in explorer.sliders]
        assert sliders[0].label == "axis 1" and len(sliders) < len(explorer.names)
        screen.action_cycle_poi(1)  # move the highlight away: the frozen PoI shows as ◆
        assert sum(m.char == "◆" for m in canvas.markers) == 1

        # Move the first slider: live preview (two curves drawn), then release: re-projection.
        before = explorer.base_design
        sliders[0].focus()
        await pilot.press("right", "right")
        await settle(app, pilot)
        assert len(canvas.polylines) == 2
        assert explorer.values[0] != 0
        await pilot.press("enter")
        await settle(app, pilot)
        assert explorer.base_design != before
        assert "released" in screen.last_message and f"curvature:{first}" in screen.last_message
        assert explorer.invariant_errors()[f"curvature:{first}"] < 0.02
        assert len(canvas.polylines) == 1

        # ctrl+z undoes the release (the design before it), then the kept invariant; then nothing is left.
        released = dict(explorer.design)
        await pilot.press("ctrl+z")
        await settle(app, pilot)
        assert screen.explorer.base_design == before and screen.explorer.design != released
        assert [inv.label for inv in screen.explorer.invariants] == [f"curvature:{first}"]
        await pilot.press("ctrl+z")
        await settle(app, pilot)
        assert screen.explorer.invariants == [] and screen.explorer.base_design == before
        assert [w.label for w in screen.query(InvariantSlider)] == list(screen.explorer.names)
        await pilot.press("ctrl+z")
        await settle(app, pilot)
        assert screen.last_message == "nothing to undo"
        # redo by hand: keep the invariant again and release, as before
        screen.selected = [first]
        await pilot.press("2")
        await settle(app, pilot)
        explorer = screen.explorer
        sliders = list(screen.query(InvariantSlider))
        sliders[0].focus()
        await pilot.press("right", "right", "enter")
        await settle(app, pilot)
        assert explorer.base_design != before

        # Send the explored design back to the Drawing machines screen.
        await pilot.press("o")
        await settle(app, pilot)
        assert app.screen.name == "drawing"
        machine, params = app.screen.current_design()
        assert machine == "cycloid_drawing_machine"
        assert all(np.isclose(params[k], v) for k, v in explorer.design.items())


async def test_over_constrained_is_reported_and_the_screen_stays_usable(tmp_path):
    async with opened(tmp_path, size=(150, 45)) as (app, pilot):
        await pilot.press("x")  # from home: the Drawing screen's current design (a Spirograph: 1 parameter)
        await settle(app, pilot)
        screen = app.screen
        assert screen.name == "explore"
        await pilot.press("1")  # position of the highlighted PoI: over-constrained with one parameter
        await settle(app, pilot)
        assert "over-constrained" in screen.last_message
        assert screen.explorer.invariants == []
        await pilot.press("n", "n")
        await settle(app, pilot)
        assert screen.highlighted == 2


async def test_a_click_on_the_canvas_selects_the_nearest_poi(tmp_path):
    from station.tui.widgets.canvas import world_to_cell

    async with opened(tmp_path, "x", size=(150, 45)) as (app, pilot):
        screen = app.screen
        canvas = screen.query_one("#canvas", ExploreCanvas)
        target = screen.explorer.pois[3]
        bounds = canvas.current_bounds()
        col, row = world_to_cell(target.xy, canvas.size.width, canvas.size.height, bounds)
        world = canvas.cell_to_world(col, row)
        assert world_to_cell(world, canvas.size.width, canvas.size.height, bounds) == (col, row)
        border = canvas.styles.gutter  # the click offset is relative to the widget's outer region
        await pilot.click(ExploreCanvas, offset=(col + border.left, row + border.top))
        await settle(app, pilot)
        picked = screen.explorer.pois[screen.selected[-1]]
        # The PoI nearest to the clicked cell's centre: the target, or one at least as near (sharing its cell).
        assert np.hypot(*np.subtract(picked.xy, world)) <= np.hypot(*np.subtract(target.xy, world)) + 1e-9


async def test_poi_coordinates_at_the_centre_read_zero_not_minus_zero(tmp_path):
    # The spirograph's default design crosses itself at the centre: the table showed -0.000 beside 0.000.
    async with opened(tmp_path, "x", size=(150, 45)) as (app, pilot):
        table = app.screen.query_one("#pois", DataTable)
        cells = [str(cell) for row in range(table.row_count) for cell in table.get_row_at(row)[2:4]]
        assert "0.000" in cells and "-0.000" not in cells


async def test_without_a_drawing_screen_explore_starts_from_a_default_design(tmp_path):
    async with opened(tmp_path, "x", size=(150, 45), without=("drawing",)) as (app, pilot):
        screen = app.screen
        assert screen.name == "explore" and app.current_design() is None
        assert screen.explorer is not None and screen.explorer.machine.name == "cycloid_drawing_machine"
        assert screen.loaded_design[0] == "cycloid_drawing_machine"
