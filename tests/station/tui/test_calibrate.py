"""The Calibrate screen: camera intrinsics from a folder (progress, per-view table, result saved), a bad folder said
in one line, the plane checked from a frame file, more panels joining through EXTRA_PANELS."""

from __future__ import annotations

import json

import cv2
from textual.widgets import DataTable, Input, Label, Static

from calibration.evaluate import acceptance_camera, acceptance_options, part_scene, reference_layout
from calibration.intrinsics import CameraIntrinsics, save_intrinsics
from drivers.sim.camera_render import render
from station.tui.screens.calibrate import CalibrateScreen, CameraPanel

from ...conftest import opened, settle
from ..services.test_calibrate import write_views


def text_of(screen, selector: str) -> str:
    return str(screen.query_one(selector, Static).render())


async def test_camera_panel_calibrates_a_folder(tmp_path, station_home):
    folder = write_views(tmp_path / "shots")
    async with opened(tmp_path, "k") as (app, pilot):
        screen = app.screen
        assert isinstance(screen, CalibrateScreen)
        screen.query_one("#camera-folder", Input).value = str(tmp_path / "nothere")
        await pilot.click("#camera-run")
        await settle(app, pilot)
        assert "is not a folder" in text_of(screen, "#camera-result")
        screen.query_one("#camera-folder", Input).value = str(folder)
        await pilot.click("#camera-run")
        await settle(app, pilot)
        result = text_of(screen, "#camera-result")
        assert "RMS" in result and "saved" in result, result
        assert (station_home / "calibration" / "cameras" / "camera.json").exists()
        assert screen.query_one("#camera-views", DataTable).row_count == 8
        assert screen.query_one(CameraPanel).query_one("#camera-stop").disabled


async def test_plane_panel_checks_a_frame(tmp_path, station_home):
    camera = acceptance_camera()
    scene, _parts = part_scene(3, 2)
    image, _truth = render(scene, camera, acceptance_options(seed=3))
    frame = tmp_path / "frame.png"
    cv2.imwrite(str(frame), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    save_intrinsics(CameraIntrinsics(camera.camera_matrix, camera.dist_coeffs, camera.image_size, 0.0, "camera"),
                    station_home / "calibration" / "cameras" / "camera.json")
    guide = tmp_path / "guide.json"
    guide.write_text(json.dumps({"reference_tags": [{"id": i, "center_mm": list(c), "size_mm": s}
                                                    for i, c, s in reference_layout()]}))
    async with opened(tmp_path, "k") as (app, pilot):
        screen = app.screen
        screen.query_one("#plane-guide", Input).value = str(guide)
        screen.query_one("#plane-image", Input).value = str(frame)
        screen.set_focus(None)
        await pilot.press("p")
        await settle(app, pilot)
        result = text_of(screen, "#plane-result")
        assert "residual 0.0" in result and "camera 1000 mm above it" in result, result


async def test_the_projector_panel_stands_beside_them(tmp_path):
    async with opened(tmp_path, "k") as (app, pilot):
        panel = app.screen.query_one("#projector-panel")
        assert "Gray code stripes" in str(panel.query_one(Label).render())


async def test_the_simulator_result_shows_every_value_the_agreement_and_the_brier_score_at_160x50(tmp_path):
    """SIMPLE's every material value (7, domino.angular_damping the last) fitted to the station's log: the whole
    result is in view at 160x50 once the fit ends (every value, every event's agreement, the held-out Brier)."""
    from calibration.sim_fit import FitSettings
    from station.services.trials import build_trial, layout_values, load_trial_scenario, open_store
    from station.tui.widgets.sim_calibration import SimCalibrationPanel

    simple = load_trial_scenario("simple")
    layout = layout_values(simple, simple.layout("success"))
    with open_store() as store:
        for i in range(6):  # the first domino falls half of the time
            store.add(build_trial(simple, layout, {"last_stops": "yes"} if i % 2 else {
                "ball_rolls": "yes", "ball_hits_domino": "yes", "first_topples": "no"}))
    async with opened(tmp_path, "k") as (app, pilot):
        screen = app.screen
        panel = screen.query_one(SimCalibrationPanel)
        panel.simulation_workers = 1
        panel.fit_settings = FitSettings(draws=2, sobol=4, rounds=1, per_round=2, held_out=0.34)
        panel.query_one("#sim-scenarios", Input).value = "simple"
        await pilot.click("#sim-every")
        await pilot.click("#sim-start")
        for _ in range(600):
            await pilot.pause(0.1)
            if not panel.calibrating:
                break
        await settle(app, pilot)
        assert panel.result is not None, text_of(screen, "#sim-status")
        values, events = screen.query_one("#sim-values", DataTable), screen.query_one("#sim-events", DataTable)
        assert values.row_count == 7 and str(values.get_row_at(6)[0]) == "domino.angular_damping"
        assert events.row_count == 5
        assert "held-out Brier" in text_of(screen, "#sim-status")
        for widget in (values, events, screen.query_one("#sim-status")):
            geometry = screen.find_widget(widget)
            assert geometry.visible_region == geometry.region, f"{widget.id} is cut: {geometry}"
        for table in (values, events):  # and no column or row is scrolled out of the table's own view
            assert table.max_scroll_x == 0 and table.max_scroll_y == 0, (table.id, table.virtual_size, table.size)
