"""The plane and tag geometry of calibration.measure on exact points from cv2.projectPoints (no images).

The detections are made the way pupil-apriltags reports them (pixel edges at integers: OpenCV's pixel + 0.5), so
these tests also pin the half-pixel conversion; tests/calibration/test_measure_render.py checks it on rendered frames.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from calibration.errors import CalibrationError
from calibration.intrinsics import CameraIntrinsics
from calibration.measure import fit_square, measure, square_corners
from vision.detection import FoundTag

SIZE = (1920, 1080)
MATRIX = np.array([[1400.0, 0, 959.5], [0, 1400.0, 539.5], [0, 0, 1]])
DIST = np.array([-0.12, 0.05, 0.0005, -0.0003, -0.01])
INTRINSICS = CameraIntrinsics(MATRIX, DIST, SIZE)
REFERENCES = [(583, (-300.0, -150.0), 40.0), (584, (300.0, -150.0), 40.0), (585, (300.0, 150.0), 40.0),
              (586, (-300.0, 150.0), 40.0)]
BLANK = np.zeros((SIZE[1], SIZE[0]), dtype=np.uint8)


def pose(centre=(10.0, -20.0, 1000.0), tilt_deg=8.0, yaw_deg=5.0):
    """A camera at ``centre`` (u, v, h) looking down, tilted about u and turned about h."""
    down = np.diag([1.0, -1.0, -1.0])  # camera x = +u, y = -v (image down), z = -h (looking down)
    tilt = cv2.Rodrigues(np.array([math.radians(tilt_deg), 0.0, 0.0]))[0]
    yaw = cv2.Rodrigues(np.array([0.0, 0.0, math.radians(yaw_deg)]))[0]
    rotation = tilt @ down @ yaw
    return cv2.Rodrigues(rotation)[0].ravel(), -rotation @ np.asarray(centre, dtype=float)


def seen(tag_id, centre, size, heading=0.0, height=0.0, camera=None, offset=0.5):
    """The tag as pupil-apriltags would report it (corners + ``offset``)."""
    rvec, tvec = camera or pose()
    corners = np.column_stack([square_corners(centre, size, heading), np.full(4, height)])
    pixels = cv2.projectPoints(corners, rvec, tvec, MATRIX, DIST)[0].reshape(-1, 2) + offset
    return FoundTag(tag_id, pixels.mean(axis=0), pixels, 0)


def reference_tags(camera=None):
    return [seen(i, c, s, camera=camera) for i, c, s in REFERENCES]


def test_exact_points_give_exact_positions_at_height_and_heading_all_round():
    parts = {}
    found = reference_tags()
    truth = {}
    for k, heading in enumerate(range(-180, 180, 15)):
        centre = (-330.0 + 28.0 * k, 40.0 * math.sin(k))
        height = 50.0 * (k % 3) / 2
        parts[k] = (30.0, height)
        truth[k] = (centre, heading)
        found.append(seen(k, centre, 30.0, heading, height))
    result = measure(BLANK, INTRINSICS, REFERENCES, parts, found=found)
    assert result.plane is not None and result.plane.residual_mm < 1e-6
    assert result.missing_reference_ids == () and result.unknown_ids == () and result.duplicate_ids == ()
    assert abs(result.plane.camera_centre_mm - [10.0, -20.0, 1000.0]).max() < 1e-4
    assert len(result.tags) == len(parts)
    for tag in result.tags:
        centre, heading = truth[tag.tag_id]
        assert np.hypot(*np.subtract(tag.center_mm, centre)) < 1e-5
        assert abs((tag.heading_deg - heading + 180) % 360 - 180) < 1e-5
        assert tag.fit_residual_mm < 1e-5 and tag.height_mm == parts[tag.tag_id][1]


def test_ignoring_height_costs_height_times_offset_over_camera_height():
    """A tag 50 mm up, 400 mm off the camera's axis, measured as if on the table: ~20 mm out (50 x 400 / 1000)."""
    camera = pose(centre=(0.0, 0.0, 1000.0), tilt_deg=0.0, yaw_deg=0.0)
    found = reference_tags(camera) + [seen(1, (400.0, 0.0), 30.0, 0.0, 50.0, camera)]
    at_height = measure(BLANK, INTRINSICS, REFERENCES, {1: (30.0, 50.0)}, found=found).tag(1)
    on_table = measure(BLANK, INTRINSICS, REFERENCES, {1: (30.0, 0.0)}, found=found).tag(1)
    assert abs(at_height.center_mm[0] - 400.0) < 1e-4
    # the ray through the tag meets the table at 400 * 1000 / (1000 - 50)
    assert on_table.center_mm[0] - 400.0 == pytest.approx(400.0 * 50.0 / 950.0, rel=1e-4)


def test_half_pixel_convention_is_converted():
    """Corners given in OpenCV's own convention (no +0.5) shift the whole view half a pixel: the plane's pose takes
    the shift (the camera centre moves about 0.5 px x 1000 mm / 1400 px along u and v, part of it taken up by a
    tilt), so the conversion is really applied. (Part tags measured against the reference tags hardly feel it:
    both move alike.)"""
    camera = pose(tilt_deg=0.0, yaw_deg=0.0)
    found_cv = [seen(i, c, s, camera=camera, offset=0.0) for i, c, s in REFERENCES]
    shifted = measure(BLANK, INTRINSICS, REFERENCES, {}, found=found_cv).plane.camera_centre_mm
    right = measure(BLANK, INTRINSICS, REFERENCES, {}, found=reference_tags(camera)).plane.camera_centre_mm
    assert abs(right - [10.0, -20.0, 1000.0]).max() < 1e-4
    assert np.linalg.norm(shifted[:2] - [10.0, -20.0]) > 0.3


def test_unknown_duplicate_and_missing_ids_are_reported_not_measured():
    found = reference_tags()[:3] + [seen(1, (0.0, 0.0), 30.0), seen(1, (100.0, 0.0), 30.0),
                                    seen(7, (50.0, 50.0), 30.0), seen(2, (-50.0, 0.0), 30.0)]
    result = measure(BLANK, INTRINSICS, REFERENCES, {1: (30.0, 0.0), 2: (30.0, 0.0), 3: (30.0, 0.0)}, found=found)
    assert result.missing_reference_ids == (586,)
    assert result.duplicate_ids == (1,) and result.unknown_ids == (7,)
    assert [t.tag_id for t in result.tags] == [2]
    assert result.plane.reference_ids == (583, 584, 585)


def test_one_reference_tag_gives_no_plane_and_no_tags():
    found = reference_tags()[:1] + [seen(1, (0.0, 0.0), 30.0)]
    result = measure(BLANK, INTRINSICS, REFERENCES, {1: (30.0, 0.0)}, found=found)
    assert result.plane is None and result.tags == ()
    assert result.missing_reference_ids == (584, 585, 586)


def test_a_moved_camera_is_reported():
    first = measure(BLANK, INTRINSICS, REFERENCES, {}, found=reference_tags()).plane
    again = measure(BLANK, INTRINSICS, REFERENCES, {}, previous=first, found=reference_tags()).plane
    assert again.moved_mm < 1e-6
    bumped_camera = pose(centre=(13.0, -20.0, 1000.0))
    bumped = measure(BLANK, INTRINSICS, REFERENCES, {}, previous=first, found=reference_tags(bumped_camera)).plane
    assert bumped.moved_mm == pytest.approx(3.0, abs=0.05)


def test_a_misread_reference_corner_is_dropped_by_ransac():
    found = reference_tags()
    bad = found[2].corners.copy()
    bad[1] += [25.0, -10.0]
    found[2] = FoundTag(585, found[2].center, bad, 0)
    result = measure(BLANK, INTRINSICS, REFERENCES, {1: (30.0, 0.0)}, found=found + [seen(1, (5.0, 5.0), 30.0)])
    assert np.hypot(*np.subtract(result.tag(1).center_mm, (5.0, 5.0))) < 1e-4
    assert result.plane.residual_mm > 1.0  # the residual still says a corner is off


def test_fit_square_residual_flags_a_wrong_size():
    corners = square_corners((3.0, 4.0), 33.0, 20.0)
    centre, heading, rms = fit_square(corners, 30.0)
    assert np.allclose(centre, (3.0, 4.0)) and heading == pytest.approx(20.0)
    assert rms == pytest.approx(1.5 * math.sqrt(2), rel=1e-6)


def test_bad_input_is_one_clear_error():
    with pytest.raises(CalibrationError, match="1280x720 pixels.*1920x1080"):
        measure(np.zeros((720, 1280), np.uint8), INTRINSICS, REFERENCES, {})
    with pytest.raises(CalibrationError, match="both as reference and as part"):
        measure(BLANK, INTRINSICS, REFERENCES, {583: (30.0, 0.0)})
    with pytest.raises(CalibrationError, match="8-bit grey or RGB"):
        measure(np.zeros((1080, 1920), np.float32), INTRINSICS, REFERENCES, {})
