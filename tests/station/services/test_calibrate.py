"""``station calibrate board|camera|plane`` and the calibrate service: files in the station's data folder, captures
from the simulated camera with progress and cancellation, the plane check from a frame, the hooks for more
subcommands."""

from __future__ import annotations

import json
from functools import cache

import cv2
import numpy as np
import pytest

from calibration.evaluate import (
    acceptance_camera,
    acceptance_options,
    board_cameras,
    board_scene,
    board_views,
    part_scene,
    reference_layout,
)
from calibration.intrinsics import CameraIntrinsics, load_intrinsics, save_intrinsics
from common.progress import Cancelled, Reporter
from drivers.sim.camera_render import render
from station.cli import build_parser, main
from station.errors import ServiceError
from station.services import calibrate as service

SIZE = (640, 480)
MATRIX = np.array([[520.0, 0.0, 319.5], [0.0, 520.0, 239.5], [0.0, 0.0, 1.0]])
DIST = np.array([-0.1, 0.04, 0.0, 0.0, 0.0])


@cache
def views():
    return board_views(8, MATRIX, DIST, SIZE, seed=21)


def write_views(folder):
    folder.mkdir()
    for name, image in views():
        cv2.imwrite(str(folder / f"{name}.png"), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    return folder


def test_board_command_writes_the_pdf(tmp_path, capsys):
    assert main(["calibrate", "board", "--pdf", str(tmp_path / "board.pdf")]) == 0
    assert (tmp_path / "board.pdf").read_bytes().startswith(b"%PDF")
    assert "check that a square measures 30 mm" in capsys.readouterr().out
    assert main(["calibrate", "board", "--pdf", str(tmp_path / "board.pdf"), "--paper", "a5"]) == 2
    assert capsys.readouterr().err.strip() == "station: error: --paper: expected one of a4, letter, a3, got 'a5'"


def test_camera_command_from_a_folder_saves_per_camera(tmp_path, capsys, station_home):
    folder = write_views(tmp_path / "shots")
    (folder / "notes.txt").write_text("not an image")
    assert main(["calibrate", "camera", "--images", str(folder), "--name", "desk", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    saved = station_home / "calibration" / "cameras" / "desk.json"
    assert out["saved"] == str(saved) and len(out["views"]) == 8
    camera = load_intrinsics(saved)
    assert abs(camera.focal_px / 520.0 - 1) < 0.005 and camera.name == "desk"
    assert main(["calibrate", "camera", "--images", str(folder), "--out", str(tmp_path / "cam.json")]) == 0
    text = capsys.readouterr().out
    assert "RMS" in text and "view-01.png" in text and f"saved {tmp_path / 'cam.json'}" in text
    assert "corners without views" in text  # 8 views reach two image corners only: said, k3 fixed


def test_camera_command_refusals_are_one_line(tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["calibrate", "camera", "--images", str(empty)]) == 2
    assert capsys.readouterr().err.strip().startswith("station: error: --images: no images in")
    (empty / "bad.png").write_bytes(b"not a png")
    assert main(["calibrate", "camera", "--images", str(empty)]) == 2
    assert "bad.png is not an image OpenCV can read" in capsys.readouterr().err
    blank = tmp_path / "blank"
    blank.mkdir()
    cv2.imwrite(str(blank / "a.png"), np.full((120, 160), 200, np.uint8))
    assert main(["calibrate", "camera", "--images", str(blank)]) == 2
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if line.startswith("station: error:")]
    assert len(errors) == 1 and "0 usable views of the board, 3 needed" in errors[0]
    assert main(["calibrate", "camera", "--images", str(blank), "--camera", "0"]) == 2
    assert "--camera goes with --capture N" in capsys.readouterr().err


def test_capture_from_the_simulated_camera_with_progress_and_stop():
    url = "sim://camera?size=640x480&f=520&k1=-0.1&k2=0.04&blur=0.7&noise=2&name=calibrate-test"
    cameras = board_cameras(8, MATRIX, DIST, SIZE, seed=21)
    scene = board_scene()

    def move_board(camera, index):  # the maker moves the board (here: the twin's camera moves)
        camera.set_scene(scene)
        camera.place(cameras[index])

    seen = []
    request = service.CameraCalibrationRequest(capture=8, camera=url, name="twin", interval_s=0.0)
    done = service.calibrate_camera(request, report=Reporter(seen.append), before=move_board)
    assert abs(done.result.intrinsics.focal_px / 520.0 - 1) < 0.005 and done.path.name == "twin.json"
    assert [p.stage for p in seen][:1] == ["capture"] and "solve" in [p.stage for p in seen]
    asked = []
    with pytest.raises(Cancelled):
        service.calibrate_camera(service.CameraCalibrationRequest(capture=8, camera=url, interval_s=0.05),
                                 before=move_board, report=Reporter(stop=lambda: asked.append(1) or len(asked) > 3))
    with pytest.raises(ServiceError, match="capture must be a whole number of views >= 1"):
        service.calibrate_camera(service.CameraCalibrationRequest(capture=0, camera=url))


def plane_frame(tmp_path, name, target=(0.0, 0.0)):
    camera = acceptance_camera(target_mm=target)
    scene, _parts = part_scene(3, 4)
    image, _truth = render(scene, camera, acceptance_options(seed=3))
    path = tmp_path / name
    cv2.imwrite(str(path), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    return camera, path


def test_plane_command_reports_residual_and_a_moved_camera(tmp_path, capsys):
    camera, first = plane_frame(tmp_path, "first.png")
    _camera, moved = plane_frame(tmp_path, "moved.png", target=(2.0, 0.0))
    intrinsics = tmp_path / "sim.json"
    save_intrinsics(CameraIntrinsics(camera.camera_matrix, camera.dist_coeffs, camera.image_size, 0.0, "sim"),
                    intrinsics)
    guide = tmp_path / "guide.json"
    guide.write_text(json.dumps({"reference_tags": [{"id": i, "center_mm": list(c), "size_mm": s}
                                                    for i, c, s in reference_layout()]}))
    common = ["--guide", str(guide), "--intrinsics", str(intrinsics), "--json"]
    assert main(["calibrate", "plane", "--image", str(first), *common]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["plane"]["residual_mm"] < 0.2 and out["plane"]["moved_mm"] is None
    assert out["plane"]["camera_height_mm"] == pytest.approx(1000.0, abs=2.0) and out["unknown_ids"] == [0, 1, 2, 3]
    assert main(["calibrate", "plane", "--image", str(moved), *common[:-1]]) == 0
    text = capsys.readouterr().out
    assert "moved 2." in text and "the camera or the sheet moved" in text
    # without a guide: which reference tags are seen, no plane
    assert main(["calibrate", "plane", "--image", str(first), "--intrinsics", str(intrinsics)]) == 0
    assert "reference tags seen: [583, 584, 585, 586]; no plane solved" in capsys.readouterr().out
    guide.write_text(json.dumps({"reference_tags": [{"id": 583}]}))
    assert main(["calibrate", "plane", "--image", str(first), *common]) == 2
    assert "guide.json: field 'reference_tags[0]': expected" in capsys.readouterr().err


def test_plane_from_the_guessed_intrinsics_is_said(tmp_path, capsys):
    _camera, first = plane_frame(tmp_path, "first.png")
    assert main(["calibrate", "plane", "--image", str(first)]) == 0
    assert "not calibrated: f guessed" in capsys.readouterr().out
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), np.zeros((100, 100), np.uint8))
    save_intrinsics(CameraIntrinsics(MATRIX, DIST, SIZE), tmp_path / "cam.json")
    assert main(["calibrate", "plane", "--image", str(small), "--intrinsics", str(tmp_path / "cam.json")]) == 2
    assert "cam.json is for 640x480 images, the frame is 100x100" in capsys.readouterr().err


def test_calibrate_projector_is_a_subcommand():
    args = build_parser().parse_args(["calibrate", "projector", "--camera", "sim://camera"])
    assert args.camera == "sim://camera" and callable(args.func)
