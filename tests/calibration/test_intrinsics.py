"""Camera intrinsics: the JSON file, the ChArUco board PDF (measured as printed), calibration on views drawn by the
camera twin (drivers/sim/camera_render.py), the corner-coverage rule."""

from __future__ import annotations

import json
from functools import cache

import numpy as np
import pytest

from calibration.charuco import BoardSpec, detect_charuco, write_board_pdf
from calibration.errors import CalibrationError
from calibration.evaluate import board_views
from calibration.intrinsics import (
    CameraIntrinsics,
    calibrate_camera,
    corner_coverage,
    load_intrinsics,
    save_intrinsics,
)

SIZE = (640, 480)
MATRIX = np.array([[520.0, 0.0, 322.6], [0.0, 520.0, 237.3], [0.0, 0.0, 1.0]])
DIST = np.array([-0.12, 0.05, 0.0005, -0.0003, -0.01])


@cache
def views(count: int = 12):
    return board_views(count, MATRIX, DIST, SIZE, seed=4)


def test_charuco_recovers_f_within_half_a_percent():
    result = calibrate_camera(views(), name="twin")
    k = result.intrinsics.camera_matrix
    assert abs(k[0, 0] / 520.0 - 1) < 0.005 and abs(k[1, 1] / 520.0 - 1) < 0.005
    assert abs(k[0, 2] - 322.6) < 2.0 and abs(k[1, 2] - 237.3) < 2.0
    assert result.intrinsics.rms_px < 0.2 and len(result.used) == 12
    assert all(v.rms_px is not None and v.rms_px < 0.3 for v in result.views)
    # 12 views: every fourth pushed into a corner in turn (top-left, top-right, bottom-right): bottom-left lacks
    assert result.uncovered_corners == ("bottom-left",) and result.k3_fixed
    assert result.intrinsics.dist_coeffs[4] == 0.0 and "bottom-left" in result.warnings[0]
    assert result.intrinsics.name == "twin"


def test_views_with_too_few_corners_are_skipped_and_said():
    blank = np.full((SIZE[1], SIZE[0]), 200, np.uint8)
    result = calibrate_camera([("blank.png", blank)] + list(views()[:4]))
    assert result.views[0].skipped == "0 board corners found, 8 needed" and len(result.used) == 4
    assert any("blank.png" in w for w in result.warnings)
    with pytest.raises(CalibrationError, match="1 usable views of the board, 3 needed.*blank.png: 0"):
        calibrate_camera([("blank.png", blank), views()[0]])
    with pytest.raises(CalibrationError, match="second.png: 320x240 pixels, but the first view is 640x480"):
        calibrate_camera([views()[0], ("second.png", np.zeros((240, 320), np.uint8))])


def test_coverage_needs_points_in_every_image_corner():
    size = (100, 100)
    corners = np.array([[5, 5], [8, 6], [95, 4], [93, 9], [96, 96], [91, 92], [3, 97], [9, 93]], dtype=float)
    coverage, uncovered = corner_coverage(corners, size)
    assert uncovered == () and 0 < coverage < 0.3
    assert corner_coverage(corners[:6], size)[1] == ("bottom-left",)
    assert corner_coverage(np.array([[50.0, 50.0]]), size)[1] == ("top-left", "top-right", "bottom-right",
                                                                  "bottom-left")


def test_json_round_trip_and_bad_files(tmp_path):
    camera = CameraIntrinsics(MATRIX, DIST, SIZE, 0.12, "desk")
    path = tmp_path / "cameras" / "desk.json"
    save_intrinsics(camera, path)
    data = json.loads(path.read_text())
    assert set(data) >= {"camera_matrix", "dist_coeffs", "image_size"} and data["image_size"] == [640, 480]
    back = load_intrinsics(path)
    assert np.array_equal(back.camera_matrix, MATRIX) and np.array_equal(back.dist_coeffs, DIST)
    assert back.image_size == SIZE and back.rms_px == 0.12 and back.name == "desk"
    for field, value, message in [("camera_matrix", [[1, 0], [0, 1]], "field 'camera_matrix': expected a 3x3"),
                                  ("dist_coeffs", [0.1, "a"], "field 'dist_coeffs': expected a list"),
                                  ("dist_coeffs", [0.1, 0.2, 0.3], "field 'dist_coeffs': expected 4, 5"),
                                  ("image_size", [640.5, 480], "field 'image_size': expected \\[width, height\\]"),
                                  ("rms_px", -1, "field 'rms_px'")]:
        bad = dict(data, **{field: value})
        (tmp_path / "bad.json").write_text(json.dumps(bad))
        with pytest.raises(CalibrationError, match=f"bad.json: {message}"):
            load_intrinsics(tmp_path / "bad.json")
    (tmp_path / "bad.json").write_text(json.dumps({"dist_coeffs": [0, 0, 0, 0, 0]}))
    with pytest.raises(CalibrationError, match="bad.json: field 'camera_matrix' is missing"):
        load_intrinsics(tmp_path / "bad.json")
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(CalibrationError, match="bad.json: not valid JSON"):
        load_intrinsics(tmp_path / "bad.json")
    with pytest.raises(CalibrationError, match="nothere.json: cannot read"):
        load_intrinsics(tmp_path / "nothere.json")


def test_guess_says_it_is_a_guess():
    guess = CameraIntrinsics.guess((1920, 1080))
    assert guess.focal_px == 1920 and guess.rms_px is None and "not calibrated" in guess.notes[0]
    assert guess.camera_matrix[0, 2] == 959.5


def test_board_pdf_is_one_to_one_and_detects(tmp_path):
    """Rasterized at 12 px/mm, every square of the printed board measures 30 mm within 0.2 mm, and the board's
    24 inner corners are found in the rasterized page."""
    import pypdfium2 as pdfium

    spec = BoardSpec()
    path = write_board_pdf(tmp_path / "board.pdf", spec)
    document = pdfium.PdfDocument(str(path))  # kept: a page outlives no document
    page = document[0]
    width_pt, height_pt = page.get_size()
    assert (width_pt / 72 * 25.4, height_pt / 72 * 25.4) == pytest.approx((297.0, 210.0), abs=0.1)
    scale = 12.0  # px per mm
    gray = np.asarray(page.render(scale=scale * 25.4 / 72).to_pil().convert("L"))
    found = detect_charuco(gray, spec)
    assert found is not None and len(found.ids) == (spec.squares_x - 1) * (spec.squares_y - 1)
    # the inner corners' spacing, in mm on the page: the squares' edge as printed
    by_id = dict(zip(found.ids.tolist(), found.corners / scale))
    across = spec.squares_x - 1
    steps = [np.linalg.norm(by_id[i + 1] - by_id[i]) for i in by_id if (i + 1) in by_id and (i + 1) % across]
    steps += [np.linalg.norm(by_id[i + across] - by_id[i]) for i in by_id if (i + across) in by_id]
    assert len(steps) > 30 and np.max(np.abs(np.array(steps) - spec.square_mm)) < 0.2
    # the board's outer edge: the first row of squares spans the board's 210 mm
    row = gray[int(round((gray.shape[0] / scale / 2) * scale))]
    dark = np.flatnonzero(row < 128)
    assert (dark[-1] - dark[0] + 1) / scale == pytest.approx(spec.size_mm[0], abs=0.2)
