"""The Calibrate screen: camera intrinsics from a folder (progress, per-view table, result saved), a bad folder said
in one line, the plane checked from a frame file, more panels joining through EXTRA_PANELS."""

from __future__ import annotations

import json

import cv2
from textual.widgets import DataTable, Input, Static

from calibration.evaluate import acceptance_camera, acceptance_options, part_scene, reference_layout
from calibration.intrinsics import CameraIntrinsics, save_intrinsics
from drivers.sim.camera_render import render
from station.tui.screens import calibrate as screen_module
from station.tui.screens.calibrate import CalibrateScreen, CameraPanel

from ..conftest import opened, settle
from .test_calibrate_station import write_views


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


async def test_more_panels_join(tmp_path, monkeypatch):
    monkeypatch.setattr(screen_module, "EXTRA_PANELS", [lambda: Static("projector mapping", id="projector-panel")])
    async with opened(tmp_path, "k") as (app, pilot):
        assert "projector mapping" in text_of(app.screen, "#projector-panel")
