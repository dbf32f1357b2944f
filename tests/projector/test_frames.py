"""Projected frames: the drawing lands where the homography says, step k lights part k only, the calibrate frame's
tags decode (pupil-apriltags) where the homography puts them, and an un-calibrated fit stays on the screen and says
that its scale is not true."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from shapely.geometry import Polygon, box

from projector.errors import ProjectorError
from projector.frames import (
    CURRENT_FILL,
    NOT_TRUE,
    WARNING,
    apply_homography,
    fit_homography,
    render_calibrate,
    render_frames,
    render_step,
    tolerance_box,
)
from projector.guide import (
    REFERENCE_TAG_IDS,
    Guide,
    ParameterTolerance,
    PartDrawing,
    PartKind,
    ReferenceTag,
)
from projector.samples import sample_guide, side_plane, top_plane
from vision.detection import TagDetector

SIZE = (1280, 800)
SIDE, TOP = side_plane(), top_plane()


def keystone(guide: Guide, corners=((150, 760), (1180, 700), (1100, 90), (240, 60))) -> np.ndarray:
    """A projector seen at an angle: the guide's extent lands on a skewed quadrilateral."""
    u0, v0, u1, v1 = guide.extent_mm
    source = np.float32([[u0, v0], [u1, v0], [u1, v1], [u0, v1]])
    return cv2.getPerspectiveTransform(source, np.float32(corners))


def interior(frame: np.ndarray, homography: np.ndarray, outline, erode: int = 4) -> np.ndarray:
    """The frame's pixels inside ``outline`` drawn through ``homography`` (a rasterization of our own), eroded."""
    mask = np.zeros(frame.shape[:2], np.uint8)
    polygons = getattr(outline, "geoms", [outline])
    rings = [np.round(apply_homography(homography, np.asarray(p.exterior.coords))).astype(np.int32) for p in polygons]
    cv2.fillPoly(mask, rings, 255)
    mask = cv2.erode(mask, np.ones((2 * erode + 1, 2 * erode + 1), np.uint8))
    return frame[mask > 0]


def one_part_guide(outline, tolerances=(), plane=SIDE) -> Guide:
    part = PartDrawing("block", PartKind.PLACED, 1, outline, tuple(outline.centroid.coords[0]), 0.0,
                       tolerances=tuple(tolerances))
    tags = tuple(ReferenceTag(i, c, 40.0) for i, c in zip(REFERENCE_TAG_IDS, [(0, 0), (400, 0), (400, 300), (0, 300)]))
    return Guide("ONE", "0", plane, (part,), tags, (-30.0, -30.0, 430.0, 330.0))


def test_a_guide_point_lands_where_the_homography_says():
    # a square with a square hole; the frame is found by its own pixels, not by the drawing code
    square = Polygon([(100, 80), (260, 80), (260, 220), (100, 220)], [[(150, 120), (210, 120), (210, 180),
                                                                       (150, 180)]])
    guide = one_part_guide(square)
    homography = keystone(guide)
    frame = render_step(guide, 1, SIZE, homography)
    fill = np.round(np.asarray(CURRENT_FILL) * 0.55)
    lit = np.abs(frame.astype(int) - fill).max(axis=2) <= 2
    # points well inside the ring are filled; points in the hole and beyond the outline are dark
    inside = [(u, v) for u in np.linspace(108, 252, 9) for v in (88, 100, 200, 212)]
    hole = [(u, v) for u in np.linspace(160, 200, 5) for v in np.linspace(130, 170, 5)]
    outside = [(u, v) for u in np.linspace(90, 270, 10) for v in (60, 240)] + [(80, 150), (285, 150)]
    for points, expected in ((inside, True), (hole, False), (outside, False)):
        pixels = np.round(apply_homography(homography, points)).astype(int)
        assert lit[pixels[:, 1], pixels[:, 0]].tolist() == [expected] * len(points)
    # the outline's corners: white edge pixels within 2 px of where the homography puts them
    edge_y, edge_x = np.nonzero(frame.min(axis=2) >= 200)
    edges = np.column_stack([edge_x, edge_y])
    for corner in apply_homography(homography, [(100, 80), (260, 80), (260, 220), (100, 220), (150, 120)]):
        assert np.linalg.norm(edges - corner, axis=1).min() <= 2.0


def test_step_k_lights_part_k_only():
    guide = sample_guide()
    homography = keystone(guide)
    frames = render_frames(guide, SIZE, homography)
    assert len(frames.frames) == len(guide.parts) and frames.true_scale
    assert frames.captions[2] == "Step 3 of 7: place top_track (care: tight)"
    for k, frame in enumerate(frames.frames, start=1):
        for part in guide.parts:
            median = np.median(interior(frame, homography, part.outline), axis=0)
            if part.step == k:
                assert median[2] > 120 and median[0] < 40, (k, part.name, median)  # the bright fill
            elif part.step < k:
                assert 20 <= median.max() <= 60, (k, part.name, median)  # dimmed
            else:
                assert median.max() == 0, (k, part.name, median)  # not yet
    assert (render_step(guide, 4, SIZE, homography) == frames.frames[3]).all()


def test_the_calibrate_frames_tags_decode_where_the_homography_puts_them():
    guide = sample_guide()
    detector = TagDetector()
    for homography in (keystone(guide), None):
        frames = render_frames(guide, SIZE, homography)
        grey = cv2.cvtColor(frames.calibrate, cv2.COLOR_RGB2GRAY)
        found = {d.tag_id: d for d in detector.detect(grey)}
        assert sorted(found) == list(REFERENCE_TAG_IDS)
        for tag in guide.reference_tags:
            half = tag.size_mm / 2  # the black square's corners, lower-left first, counter-clockwise as printed
            square = np.asarray(tag.center_mm) + half * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]])
            expected = apply_homography(frames.homography, np.vstack([tag.center_mm, square]))
            assert np.linalg.norm(found[tag.id].center - expected[0]) <= 2.0
            assert np.linalg.norm(found[tag.id].corners - expected[1:], axis=1).max() <= 2.0
    # the step frames carry the tags only when asked
    with_tags = render_frames(guide, SIZE, keystone(guide), reference_tags=True).frames[0]
    assert len(detector.detect(cv2.cvtColor(with_tags, cv2.COLOR_RGB2GRAY))) == 4
    assert len(detector.detect(cv2.cvtColor(frames.frames[0], cv2.COLOR_RGB2GRAY))) == 0


@pytest.mark.parametrize("size", [(1280, 800), (800, 1280), (1920, 1080), (640, 480)])
def test_the_uncalibrated_fit_stays_on_the_screen_and_says_the_scale_is_not_true(size):
    guide = sample_guide()
    frames = render_frames(guide, size)
    assert not frames.true_scale and frames.size == size
    u0, v0, u1, v1 = guide.extent_mm
    corners = apply_homography(frames.homography, [(u0, v0), (u1, v0), (u1, v1), (u0, v1)])
    assert corners.min() >= 0 and (corners.max(axis=0) <= np.array(size) - 1).all()
    assert frames.homography[0, 0] == pytest.approx(-frames.homography[1, 1])  # one scale: shapes stay true
    assert frames.homography[0, 1] == frames.homography[1, 0] == 0
    warning = lambda image: int((np.abs(image.astype(int) - WARNING).max(axis=2) <= 30).sum())  # noqa: E731
    assert warning(frames.frames[0]) > 100 and warning(frames.calibrate) > 100  # the orange line on every frame
    calibrated = render_frames(guide, size, frames.homography)
    assert calibrated.true_scale and warning(calibrated.frames[0]) == 0
    assert NOT_TRUE.startswith("SCALE IS NOT TRUE")
    # below the caption band: the top of the drawing leaves room for the three lines
    assert corners[:, 1].min() >= 3 * 0.9 * 32 * max(0.45, size[1] / 1100)


def test_fit_homography_centres_and_scales_uniformly():
    homography = fit_homography((0, 0, 200, 100), (1000, 600), top=100, margin=0.0)
    # 200 x 100 mm into 1000 x 500 pixels: 5 px/mm, v up, centred below the band
    assert np.allclose(apply_homography(homography, [(0, 0), (200, 100)]), [(-0.5, 599.5), (999.5, 99.5)])


def test_the_tolerance_box_sweeps_the_outline_along_the_planes_axes():
    block = box(0, 0, 40, 20)
    part = PartDrawing("b", PartKind.PLACED, 1, block, (20.0, 10.0), 0.0,
                       tolerances=(ParameterTolerance("b.x", 5.0, "mm"), ParameterTolerance("b.z", 2.0, "mm"),
                                   ParameterTolerance("b.roll", 3.0, "deg")))
    # on the backboard u = -x and v = z: x's delta widens u, z's widens v
    assert tolerance_box(part, SIDE.u_axis, SIDE.v_axis).bounds == pytest.approx((-5, -2, 45, 22))
    # on the table the same parameters move u (x) only; z is out of the plane
    assert tolerance_box(part, TOP.u_axis, TOP.v_axis).bounds == pytest.approx((-5, 0, 45, 20))
    concave = Polygon([(0, 0), (30, 0), (30, 30), (20, 30), (20, 10), (10, 10), (10, 30), (0, 30)])  # a U
    swept = tolerance_box(PartDrawing("u", PartKind.PLACED, 1, concave, (15.0, 15.0), 0.0,
                                      tolerances=(ParameterTolerance("u.x", 2.0, "mm"),)), TOP.u_axis, TOP.v_axis)
    assert swept.area == pytest.approx(concave.area + 2 * 2 * 30 + 2 * 2 * 20)  # the U's gap narrows by 2 x 2 mm
    assert tolerance_box(PartDrawing("n", PartKind.PLACED, 1, block, (0.0, 0.0), 0.0), TOP.u_axis, TOP.v_axis) is None


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"size": (10, 10)}, r"^size: expected \(width, height\) in whole pixels >= 64, got \(10, 10\)$"),
    ({"size": "1280x800"}, r"^size: expected \(width, height\) in whole pixels >= 64, got '1280x800'$"),
    ({"homography": np.eye(2)}, r"^homography: expected an invertible 3 x 3 matrix .*got \(2, 2\)$"),
    ({"homography": np.zeros((3, 3))}, r"^homography: expected an invertible 3 x 3 matrix"),
    ({"homography": [[1, 0, 0], [0, 1, 0], [0.01, 0, -1]]}, r"^homography: part of the guide's extent maps behind"),
])
def test_bad_arguments_are_one_line(kwargs, message):
    with pytest.raises(ProjectorError, match=message):
        render_frames(one_part_guide(box(0, 0, 10, 10)), **kwargs)


@pytest.mark.parametrize("step", [0, 2, 1.0, True])
def test_a_step_out_of_the_guide_is_one_line(step):
    with pytest.raises(ProjectorError, match=r"^step: expected a whole number from 1 to 1, got"):
        render_step(one_part_guide(box(0, 0, 10, 10)), step)


def test_the_calibrate_frame_alone_is_the_one_render_frames_makes():
    guide = sample_guide()
    assert (render_calibrate(guide, SIZE) == render_frames(guide, SIZE).calibrate).all()


def test_a_part_without_an_outline_still_gets_its_step():
    from shapely.geometry import GeometryCollection

    guide = one_part_guide(box(0, 0, 10, 10))
    empty = PartDrawing("ghost", PartKind.PLACED, 1, GeometryCollection(), (50.0, 50.0), 0.0)
    frame = render_step(Guide("G", "0", SIDE, (empty,), guide.reference_tags, guide.extent_mm), 1, SIZE)
    assert frame[100:].max() > 0  # its arrow and label are drawn
