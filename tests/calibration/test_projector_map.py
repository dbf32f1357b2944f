"""Projector mapping: Gray code patterns, decoding, the fit and its landing error, the saved map, and the station's
service and CLI hook, on the simulated projector (placed obliquely) seen by the simulated camera."""

from __future__ import annotations

import argparse
import json

import cv2
import numpy as np
import pytest

from calibration.errors import CalibrationError
from calibration.projector_map import (
    GrayCodePlan,
    ProjectorMap,
    apply_homography,
    decode,
    load_projector_map,
    save_projector_map,
)
from common.progress import Cancelled, Reporter
from drivers.sim.camera import sim_camera
from drivers.sim.camera_scene import Occluder, PlaneScene
from drivers.sim.projector import sim_projector
from station.errors import ServiceError
from station.services.projector_calibration import (
    ProjectorCalibrationRequest,
    calibrate_projector,
    projector_map_file,
    projector_summary,
)

PROJECTOR = (1280, 800)
#: An oblique placement: the image lands as a skewed quadrilateral (a projector off to one side and tilted).
LANDS_ON = np.float32([[-290, 200], [330, 215], [300, -190], [-270, -170]])


pytestmark = pytest.mark.usefixtures("fresh_twins")


def oblique(size=PROJECTOR):
    width, height = size
    corners = np.float32([[-0.5, -0.5], [width - 0.5, -0.5], [width - 0.5, height - 0.5], [-0.5, height - 0.5]])
    return cv2.getPerspectiveTransform(corners, LANDS_ON).astype(float)


def table_homography(model):
    """Undistorted camera pixel -> plane (u, v) mm at h = 0 (what calibration.measure's PlaneFix gives)."""
    rotation = model.rotation
    return np.linalg.inv(model.camera_matrix @ np.column_stack([rotation[:, 0], rotation[:, 1], model.tvec]))


def test_gray_code_neighbours_differ_in_one_bit_and_decode_exactly():
    plan = GrayCodePlan((200, 120), 8)
    assert plan.cells == (25, 15) and plan.bits == (5, 4) and len(plan.names) == 2 + 2 * 9
    patterns = dict(plan.patterns())
    x_bits = np.array([patterns[f"x{b}"][0, ::8] > 0 for b in range(5)])
    assert (np.count_nonzero(x_bits[:, 1:] != x_bits[:, :-1], axis=0) == 1).all()
    assert (patterns["x0"] == 255 - patterns["x0~"]).all()
    # the patterns themselves as the camera's images: camera pixel = projector pixel
    found = decode(plan, [pattern for _name, pattern in plan.patterns()])
    assert len(found.cells) == 23 * 13  # every cell but the border ones (and none cut by the image's edge)
    assert np.allclose(found.camera_px, found.projector_px) and (found.pixels == 64).all()


def test_decoding_refuses_what_is_not_the_plan():
    plan = GrayCodePlan((64, 48), 4)
    with pytest.raises(CalibrationError, match=r"expected 18 camera images \(white, black, x3, x3~, \.\.\.\), got 2"):
        decode(plan, [np.zeros((10, 10))] * 2)
    with pytest.raises(CalibrationError, match="the camera saw no projected stripes"):
        decode(plan, [np.zeros((10, 10), np.uint8)] * len(plan.names))
    with pytest.raises(CalibrationError, match="finest_px"):
        GrayCodePlan((64, 48), 20)


def test_oblique_projector_maps_within_half_a_millimetre(station_home):
    """Acceptance: the projector placed obliquely, a camera with distortion, tilt, blur, noise and JPEG, and a box on
    the table in the light: landing error p95 <= 0.5 mm, measured at check points and against the true placement."""
    placement = oblique()
    shared = sim_projector(f"sim://projector?size={PROJECTOR[0]}x{PROJECTOR[1]}&name=wall")
    shared.place(placement)
    camera_url = ("sim://camera?size=960x540&f=700&height=1000&target=10,0&tilt=8&k1=-0.06&k2=0.02&blur=0.8"
                  "&noise=2&jpeg=90&exposure=0.6&supersample=2&name=desk&projector=wall")
    camera = sim_camera(camera_url)
    box = Occluder(np.array([[60.0, -40.0], [140.0, -40.0], [140.0, 30.0], [60.0, 30.0]]), height_mm=40.0,
                   color=(180, 170, 160))
    camera.set_scene(PlaneScene(occluders=(box,)))
    seen = []
    request = ProjectorCalibrationRequest(camera=camera_url, projector="sim://projector?name=wall&size=1280x800",
                                          name="wall", plane=table_homography(camera.camera_model))
    done = calibrate_projector(request, report=Reporter(seen.append))
    result = done.projector_map
    assert done.path == projector_map_file("wall") and done.path.is_file()
    assert result.landing_error_mm["p95"] <= 0.5 and result.landing_error_mm["check_points"] >= 50
    assert result.cells["inliers"] < result.cells["fitted"]  # the box's cells were dropped by RANSAC
    grid = np.stack(np.meshgrid(np.linspace(0, 1279, 17), np.linspace(0, 799, 11)), axis=-1).reshape(-1, 2)
    truth = np.linalg.norm(result.plane_from(grid) - apply_homography(placement, grid), axis=1)
    assert np.percentile(truth, 95) <= 0.5 and truth.max() <= 0.5
    assert shared.blanked  # the projector is left dark
    stages = [p.stage for p in seen]
    assert stages.count("projector patterns") == len(GrayCodePlan(PROJECTOR).names) + 1
    assert np.allclose(load_projector_map(done.path).plane_from_pixel, result.plane_from_pixel)
    lines = projector_summary(done)
    assert lines[0].startswith(f"projector 'wall' (sim://projector?name=wall&size=1280x800, 1280x800): landing "
                               f"error at {result.landing_error_mm['check_points']} check points: p50 ")
    assert lines[1] == f"saved {projector_map_file('wall')}" and "camera plane: given" in lines[3]


def test_the_default_camera_sees_what_the_default_projector_throws(station_home):
    # the station's default twins are linked: `station calibrate projector` works out of the box on them
    from drivers.devices import resolve
    from station.config import configured_devices

    urls = {device.kind: device.url for device in configured_devices()}
    projector = resolve(urls["projector"]).factory(urls["projector"])
    camera = resolve(urls["camera"]).factory(urls["camera"])
    projector.open()
    camera.open()
    try:
        width, height = projector.size
        lit = np.zeros((height, width, 3), np.uint8)
        lit[:, : width // 2] = 255  # the left half of the projector's image white
        projector.show(lit)
        shown = np.asarray(camera.grab(), dtype=float).mean(axis=2)
        projector.blank()
        dark = np.asarray(camera.grab(), dtype=float).mean(axis=2)
    finally:
        camera.close()
        projector.close()
    # where the light lands: the left half of the projector's area, around the middle of the camera's view
    table = table_homography(camera.camera_model)
    left, right = (cv2.perspectiveTransform(np.float64([[[u, 0.0]]]), np.linalg.inv(table))[0, 0] for u in (-160, 160))

    def at(frame, point):  # the mean of 10 x 10 pixels around ``point``
        column, row = int(point[0]), int(point[1])
        return frame[row - 5:row + 5, column - 5:column + 5].mean()

    assert at(shown, left) > at(dark, left) + 30  # lighter where the white half lands (the table is light grey)
    assert abs(at(shown, right) - at(dark, right)) < 5  # and unchanged where the black half does


@pytest.mark.slow  # the full-size pair: 32 frames of 1920x1080 rendered at 3x3 samples (10-30 s on two cores)
def test_the_default_devices_calibrate_the_projector_with_no_options(station_home):
    done = calibrate_projector(ProjectorCalibrationRequest())
    assert done.name == "projector" and done.path == projector_map_file("projector") and done.path.is_file()
    assert done.projector_map.landing_error_mm["p95"] <= 0.5
    # the map is the default projector's own placement (640 x 400 mm centred on the origin: 0.5 mm a pixel)
    grid = np.float64([[0, 0], [1279, 0], [1279, 799], [0, 799], [640, 400]])
    expected = np.column_stack([-320 + 0.5 * (grid[:, 0] + 0.5), 200 - 0.5 * (grid[:, 1] + 0.5)])
    assert np.abs(done.projector_map.plane_from(grid) - expected).max() <= 0.5


def small_devices(name="bench", target="0,0"):
    projector = sim_projector(f"sim://projector?size=320x200&name={name}")
    projector.place(oblique((320, 200)))
    url = f"sim://camera?size=320x180&f=220&target={target}&supersample=1&projector={name}"
    return projector, url, f"sim://projector?name={name}&size=320x200"


def test_stopping_between_patterns_blanks_the_projector(station_home):
    projector, camera_url, projector_url = small_devices()
    calls = []

    def stop():
        calls.append(1)
        return len(calls) > 3

    with pytest.raises(Cancelled):
        calibrate_projector(ProjectorCalibrationRequest(camera=camera_url, projector=projector_url, finest_px=16),
                            report=Reporter(stop=stop))
    assert projector.blanked and projector.frames_shown <= 3 and not projector_map_file("projector").exists()


def test_a_camera_that_does_not_see_the_light_is_one_line(station_home):
    _projector, camera_url, projector_url = small_devices(target="3000,0")
    with pytest.raises(ServiceError, match=r"^camera: projector mapping: the camera saw no projected stripes") as e:
        calibrate_projector(ProjectorCalibrationRequest(camera=camera_url, projector=projector_url, finest_px=16))
    assert e.value.field == "camera"
    with pytest.raises(ServiceError, match="^plane: expected an invertible 3x3 matrix"):
        calibrate_projector(ProjectorCalibrationRequest(camera=camera_url, projector=projector_url,
                                                        plane=np.zeros((3, 3))))


def test_the_cli_hook_maps_and_prints_json(station_home, tmp_path, capsys):
    from station.commands._calibrate_projector import add_projector_parser

    _projector, camera_url, projector_url = small_devices()
    parser = argparse.ArgumentParser()
    add_projector_parser(parser.add_subparsers())
    out = tmp_path / "map.json"
    args = parser.parse_args(["projector", "--camera", camera_url, "--projector", projector_url, "--finest", "8",
                              "--out", str(out), "--json"])
    assert args.func(args) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["projector_size"] == [320, 200] and printed["path"] == str(out)
    assert printed["plane_source"] == "the simulated camera's own pose"
    assert printed["landing_error_mm"]["p95"] < 1.0
    assert load_projector_map(out).projector_size == (320, 200)


def test_the_saved_map_reads_back_and_bad_files_name_the_field(tmp_path):
    good = ProjectorMap(oblique(), PROJECTOR, {"p50": 0.1, "p95": 0.2, "max": 0.3, "check_points": 9, "outliers": 0},
                        {"seen": 100, "fitted": 80, "inliers": 79})
    path = tmp_path / "p.json"
    save_projector_map(good, path)
    data = json.loads(path.read_text())
    assert set(data) >= {"plane_from_pixel", "projector_size", "landing_error_mm"}
    back = load_projector_map(path)
    assert np.allclose(back.plane_from_pixel, good.plane_from_pixel) and back.projector_size == PROJECTOR
    assert np.allclose(back.pixel_from(back.plane_from(np.array([[10.0, 20.0]]))), [[10.0, 20.0]])
    for broken, field in (({**data, "plane_from_pixel": [[1, 2], [3, 4]]}, "plane_from_pixel"),
                          ({**data, "projector_size": [0, 5]}, "projector_size"),
                          ({**data, "landing_error_mm": {"p50": 1}}, "landing_error_mm")):
        path.write_text(json.dumps(broken))
        with pytest.raises(CalibrationError, match=f"^{path}: {field}: expected"):
            load_projector_map(path)
    path.write_text("{")
    with pytest.raises(CalibrationError, match="not valid JSON"):
        load_projector_map(path)
