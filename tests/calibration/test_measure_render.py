"""calibration.measure on frames drawn by the camera twin (drivers/sim/camera_render.py, which shares no code with
the detector): the acceptance's fast version, and the pitfalls of the issue, each shown to matter.

The full acceptance (many frames, tilted cameras, timings) is bench/bench_check_accuracy.py.
"""

from __future__ import annotations

import math
from dataclasses import replace
from functools import cache

import cv2
import numpy as np
import pytest

from calibration.evaluate import (
    acceptance_camera,
    acceptance_options,
    part_scene,
    reference_layout,
    score,
)
from calibration.intrinsics import CameraIntrinsics, to_gray
from calibration.measure import detected_corners, measure
from drivers.sim.camera_render import render
from drivers.sim.camera_scene import ImageItem, Occluder, PlaneScene, TagItem
from vision.detection import detect_tags

HEADINGS = tuple(range(-180, 180, 15))


def intrinsics_of(camera) -> CameraIntrinsics:
    return CameraIntrinsics(camera.camera_matrix, camera.dist_coeffs, camera.image_size, 0.0, "sim")


@cache
def acceptance_frame():
    """24 tags at heights 0-50 mm, headings every 15 degrees all round, under a slightly tilted camera."""
    camera = acceptance_camera(tilt_deg=6.0, roll_deg=2.0)
    scene, parts = part_scene(11, len(HEADINGS), headings=HEADINGS)
    image, truth = render(scene, camera, acceptance_options(seed=11))
    return camera, scene, parts, image, truth


def test_acceptance_fast_version():
    """Found all visible tags, no false ids; position p95 <= 0.25 and max <= 0.5 mm; heading p95 <= 0.5 deg, and
    every 15 degrees all round within 0.5 deg."""
    camera, _scene, parts, image, truth = acceptance_frame()
    result = measure(image, intrinsics_of(camera), reference_layout(), parts)
    assert result.plane is not None and result.plane.residual_mm < 0.2
    assert result.missing_reference_ids == () and result.unknown_ids == () and result.duplicate_ids == ()
    figures = score(result, truth, parts).summary()
    assert figures["visible"] == len(HEADINGS) == figures["found"] and figures["false_ids"] == []
    assert figures["position_p95_mm"] <= 0.25 and figures["position_max_mm"] <= 0.5
    assert figures["heading_p95_deg"] <= 0.5
    by_id = {t.tag_id: t for t in result.tags}
    for tag_id, heading in enumerate(HEADINGS):
        assert abs((by_id[tag_id].heading_deg - heading + 180) % 360 - 180) <= 0.5, heading
        assert by_id[tag_id].fit_residual_mm < 0.3


def test_half_pixel_convention_on_rendered_corners():
    """pupil-apriltags' corners sit 0.5 px right and down of OpenCV's pixel centres: converted, they match the
    renderer's truth to a few hundredths of a pixel; unconverted they would be half a pixel off."""
    camera, _scene, _parts, image, truth = acceptance_frame()
    truth_by_id = {t.tag_id: t for t in truth}
    offsets = np.concatenate([detected_corners(tag) - truth_by_id[tag.tag_id].corners_px
                              for tag in detect_tags(to_gray(image))])
    assert np.abs(offsets.mean(axis=0)).max() < 0.05
    assert np.abs(offsets + 0.5).mean() > 0.4  # the unconverted corners: the offset is real


def test_height_is_needed():
    """A tag 50 mm up, 400 mm off the camera's axis, measured as if on the table is ~20 mm out (50 x 400 / 950)."""
    camera = acceptance_camera()
    tag = TagItem(1, (400.0, 0.0), 30.0, 0.0, 50.0)
    scene = PlaneScene(tags=tuple(TagItem(i, c, s) for i, c, s in reference_layout()) + (tag,))
    image, _truth = render(scene, camera, acceptance_options(seed=2))
    intrinsics = intrinsics_of(camera)
    right = measure(image, intrinsics, reference_layout(), {1: (30.0, 50.0)}).tag(1)
    table = measure(image, intrinsics, reference_layout(), {1: (30.0, 0.0)}).tag(1)
    assert math.dist(right.center_mm, (400.0, 0.0)) < 0.25
    assert table.center_mm[0] - 400.0 == pytest.approx(400.0 * 50.0 / 950.0, abs=0.3)


def test_opencv_bitmap_unturned_reads_half_a_turn_round():
    """A tag printed from OpenCV's DICT_APRILTAG_36h11 bitmap as it comes (not turned 180 deg) still decodes, but its
    heading reads 180 deg off: the station prints the upstream tag (projector/tags.py turns it)."""
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    cells = np.full((10, 10), 255, np.uint8)
    cells[1:-1, 1:-1] = dictionary.generateImageMarker(1, 8)
    picture = cv2.resize(cells, (400, 400), interpolation=cv2.INTER_NEAREST)
    half = 30.0 * 10 / 8 / 2  # the picture holds the white border: 10 cells for an 8-cell (30 mm) black square
    corners = np.array([[100 - half, half], [100 + half, half], [100 + half, -half], [100 - half, -half]])
    scene = PlaneScene(tags=tuple(TagItem(i, c, s) for i, c, s in reference_layout()),
                       images=(ImageItem(picture, corners),))
    camera = acceptance_camera()
    image, _truth = render(scene, camera, acceptance_options(seed=3))
    tag = measure(image, intrinsics_of(camera), reference_layout(), {1: (30.0, 0.0)}).tag(1)
    assert math.dist(tag.center_mm, (100.0, 0.0)) < 0.25
    assert abs(abs(tag.heading_deg) - 180.0) < 0.5


def test_single_tag_pose_is_far_worse_than_the_plane():
    """AprilTag's own 6-DoF pose (one tag's four corners alone, solvePnP IPPE_SQUARE as the library does) puts the
    tags several times further off than the plane constraint does (its depth rests on a 30 mm square)."""
    camera, _scene, parts, image, truth = acceptance_frame()
    intrinsics = intrinsics_of(camera)
    found = detect_tags(to_gray(image))
    result = measure(image, intrinsics, reference_layout(), parts, found=found)
    plane = result.plane
    rotation = plane.rotation
    half = 15.0
    square = np.array([[-half, half, 0], [half, half, 0], [half, -half, 0], [-half, -half, 0]], dtype=float)
    truth_by_id = {t.tag_id: t for t in truth}
    own, ours, heights = [], [], []
    for tag in found:
        if tag.tag_id not in parts:
            continue
        # IPPE_SQUARE's corner order: (-h, h), (h, h), (h, -h), (-h, -h) in the tag frame, y up = the tag's upper-left
        # first; ours is [lower-left, lower-right, upper-right, upper-left]
        pixels = detected_corners(tag)[[3, 2, 1, 0]]
        ok, _rvec, tvec = cv2.solvePnP(square, pixels, camera.camera_matrix, camera.dist_coeffs,
                                       flags=cv2.SOLVEPNP_IPPE_SQUARE)
        assert ok
        centre_uvh = rotation.T @ (tvec.ravel() - plane.tvec)
        own.append(math.dist(centre_uvh[:2], truth_by_id[tag.tag_id].center_mm))
        heights.append(abs(centre_uvh[2] - truth_by_id[tag.tag_id].height_mm))
        ours.append(math.dist(result.tag(tag.tag_id).center_mm, truth_by_id[tag.tag_id].center_mm))
    print(f"single-tag pose: median {np.median(own):.3f} mm, p95 {np.percentile(own, 95):.3f} mm, height median "
          f"{np.median(heights):.2f} mm; plane: median {np.median(ours):.3f} mm, p95 {np.percentile(ours, 95):.3f}")
    assert np.median(own) > 4 * np.median(ours)
    assert np.percentile(own, 95) > 4 * np.percentile(ours, 95)
    assert np.median(heights) > 0.1  # and the height it gives a tag is off by tenths of a millimetre


def test_covered_reference_tag_is_missing_and_a_moved_camera_is_said():
    camera = acceptance_camera()
    scene, parts = part_scene(5, 6)
    hand = Occluder(np.array([[500.0, 260.0], [600.0, 260.0], [600.0, 350.0], [500.0, 350.0]]), height_mm=20.0)
    covered = replace(scene, occluders=(hand,))
    intrinsics = intrinsics_of(camera)
    first = measure(render(scene, camera, acceptance_options(seed=5))[0], intrinsics, reference_layout(), parts)
    image, truth = render(covered, camera, acceptance_options(seed=6))
    again = measure(image, intrinsics, reference_layout(), parts, previous=first.plane)
    assert again.missing_reference_ids == (585,) and again.plane.reference_ids == (583, 584, 586)
    assert again.plane.moved_mm < 0.2
    assert score(again, truth, parts).summary()["position_max_mm"] <= 0.5
    bumped = acceptance_camera(target_mm=(2.0, 0.0))  # the camera slid 2 mm along u
    image, _truth = render(scene, bumped, acceptance_options(seed=7))
    moved = measure(image, intrinsics, reference_layout(), parts, previous=first.plane)
    assert moved.plane.moved_mm == pytest.approx(2.0, abs=0.3)
