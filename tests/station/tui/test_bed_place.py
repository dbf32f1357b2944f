"""The Machines screen's placement on the bed (b): the camera's picture with the job's outline, moved, turned,
snapped onto the stock, verified on the twin and queued at that placement."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.gcode import interpret
from station.services import bed
from station.tui.screens.bed_place import BedPlacementScreen
from station.tui.widgets.picture import HalfBlockPicture

from .test_machines import _connect_laser, _until, machines_screen

RECTANGLE = "G21\nG90\nM4 S0\nG0 X0 Y0\nG1 X50 Y0 S1000 F900\nG1 X50 Y30\nG1 X0 Y30\nG1 X0 Y0\nM5 S0\n"


async def test_a_job_is_placed_on_the_stock_and_queued_where_it_lies(tmp_path):
    # the bed registered on a twin of the same bed (machine coordinates: any twin of it will do)
    bed.calibrate_bed(bed.BedCalibrationRequest(port="sim://grbl?profile=laser&clock=virtual&wire=0"))
    async with machines_screen(tmp_path) as (app, pilot, screen):
        conn = await _connect_laser(pilot, screen)
        await pilot.press("b")
        await pilot.pause()
        assert app.screen is screen  # nothing queued for the laser yet: the screen says so and stays
        assert "no queued job" in screen.last_message or "no queued job" in str(
            screen.query_one("#message").render())
        screen.queue_job("laser", RECTANGLE, title="rectangle")
        await pilot.press("e")  # the job as it is, on the twin
        await _until(pilot, lambda: screen.last_message.startswith("verify rectangle"), 120)
        assert "laser dark on every travel" in screen.last_message
        await pilot.press("b")
        await _until(pilot, lambda: isinstance(app.screen, BedPlacementScreen))
        placing = app.screen
        status = placing.query_one("#bed-status")
        await _until(pilot, lambda: placing.session is not None and placing.session.frame is not None, 120)
        assert placing.query_one(HalfBlockPicture).image is not None
        await pilot.press("s")
        await pilot.pause()
        snapped = placing.session.placement
        stock = placing.session.stock
        assert stock is not None
        edge = stock[1] - stock[0]
        assert snapped.angle == np.degrees(np.arctan2(edge[1], edge[0]))
        await pilot.press("right", "right", "comma")  # 2 steps of 5 mm to the right, then 1 degree more
        assert placing.session.placement.angle == snapped.angle + 1.0
        await pilot.press("v")
        await _until(pilot, lambda: "verify rectangle" in str(status.render()), 120)
        assert "laser dark on every travel" in str(status.render())
        placement = placing.session.placement
        await pilot.press("enter")
        await _until(pilot, lambda: app.screen is screen)
        entry = screen.next_job()
        assert entry.title.startswith("rectangle @ ")
        placed = interpret(entry.job.lines)
        corners = placed.end[~placed.rapid][:, :2]
        assert np.allclose(corners[-1], placement.apply(0.0, 0.0), atol=1e-3)
        assert conn is screen.connections["laser"]


@pytest.mark.slow
async def test_the_bed_is_registered_from_the_placement_screen(tmp_path):
    async with machines_screen(tmp_path) as (app, pilot, screen):
        await _connect_laser(pilot, screen)
        screen.queue_job("laser", RECTANGLE, title="rectangle")
        await pilot.press("b")
        await _until(pilot, lambda: isinstance(app.screen, BedPlacementScreen))
        placing = app.screen
        # no registration yet: k engraves the marks with this laser and registers the bed
        assert "not registered" in str(placing.query_one("#bed-status").render())
        await pilot.press("k")
        await _until(pilot, lambda: placing.session is not None and placing.session.frame is not None, 180)
        assert bed.load_registration("laser").residual_max_mm < 0.3
        assert placing.query_one(HalfBlockPicture).image is not None
