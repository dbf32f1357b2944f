"""The projector panel for the Calibrate screen: map with the simulated pair, progress per pattern, stop, errors."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from textual.app import App, ComposeResult
from textual.widgets import Input

from drivers.sim.projector import sim_projector
from station.services.projector_calibration import projector_map_file
from station.services.projectors import projector_mapping
from station.tui.widgets.progress import ProgressPanel
from station.tui.widgets.projector_calibration import ProjectorCalibrationPanel

CAMERA = "sim://camera?size=320x180&f=220&supersample=1&projector=panel"
PROJECTOR = "sim://projector?name=panel&size=320x200"


class Host(App):
    def compose(self) -> ComposeResult:
        yield ProjectorCalibrationPanel()


@pytest.fixture(autouse=True)
def _sim_pair(fresh_twins):
    projector = sim_projector(PROJECTOR)
    corners = np.float32([[-0.5, -0.5], [319.5, -0.5], [319.5, 199.5], [-0.5, 199.5]])
    projector.place(cv2.getPerspectiveTransform(corners, np.float32([[-140, 90], [150, 95], [140, -85], [-130,
                                                                                                     -80]])))
    return projector


async def settle(app, pilot):
    for _ in range(3):
        await pilot.pause()
        await app.workers.wait_for_complete()
    await pilot.pause()


async def fill(app, pilot, camera=CAMERA, projector=PROJECTOR):
    app.query_one("#projector-camera", Input).value = camera
    app.query_one("#projector-url", Input).value = projector
    await pilot.pause()


async def test_the_panel_maps_the_projector_and_shows_the_landing_error(station_home):
    app = Host()
    async with app.run_test(size=(120, 40)) as pilot:
        await fill(app, pilot)
        await pilot.click("#projector-run")
        await settle(app, pilot)
        panel = app.query_one(ProjectorCalibrationPanel)
        assert "landing error at " in panel.result_text and "saved " in panel.result_text
        assert panel.query_one("#projector-progress", ProgressPanel).message.startswith("done: landing error p95 ")
        # kept under the projector it was measured on (the twin named panel), where the guide and the check look
        assert f"saved {projector_map_file('panel')}" in panel.result_text
        assert not projector_map_file("projector").exists()  # the station's own projector is not calibrated by it
        assert projector_mapping(PROJECTOR, (320, 200)).true_scale
        assert not projector_mapping("sim://projector?size=320x200", (320, 200)).true_scale


async def test_a_wrong_url_is_one_line_in_the_panel(station_home):
    app = Host()
    async with app.run_test(size=(120, 40)) as pilot:
        await fill(app, pilot, camera="sim://projector?size=64x40")
        panel = app.query_one(ProjectorCalibrationPanel)
        panel.query_one("#projector-run").focus()  # the panel's keys work while the focus is in it, off the inputs
        await pilot.pause()
        await pilot.press("m")
        await settle(app, pilot)
        assert panel.result_text == "camera: 'sim://projector?size=64x40' is not a camera the station can drive " \
                                    "(it names a projector)"


async def test_stop_cancels_between_patterns_and_blanks_the_projector(station_home, _sim_pair):
    app = Host()
    async with app.run_test(size=(120, 40)) as pilot:
        await fill(app, pilot, camera=CAMERA.replace("supersample=1", "supersample=4"))
        panel = app.query_one(ProjectorCalibrationPanel)
        panel.start()
        for _ in range(200):
            await pilot.pause(0.02)
            if _sim_pair.frames_shown >= 2:
                break
        panel.stop()
        await settle(app, pilot)
        assert panel.result_text == "stopped; the projector is blank, nothing saved"
        assert _sim_pair.blanked and _sim_pair.frames_shown < 26
        assert not projector_map_file("panel").exists() and not projector_map_file("projector").exists()
