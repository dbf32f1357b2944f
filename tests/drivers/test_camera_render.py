"""The simulated camera's renderer: exact geometry, upstream tags, truth, light, degradations.

Independent checks: the tag cells are compared with the station's own drawing (projector/tags.py), the rendered
geometry with cv2.projectPoints and with the darkness centroid of the picture (no detector), and the tags are decoded
by pupil-apriltags through vision.detection (a detector the renderer shares nothing with).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from drivers.errors import SimConfigError
from drivers.sim.camera_render import TAG_BLACK, TAG_WHITE, render, tag_cells_upstream
from drivers.sim.camera_scene import (
    CameraModel,
    ImageItem,
    Occluder,
    PlaneScene,
    RenderOptions,
    Solid,
    TagItem,
    tag_corners_mm,
)
from drivers.sim.projector import SimulatedProjector, area_homography
from vision.detection import detect_tags
from vision.tags import tag_cells

CAMERA = CameraModel.looking_down(target_mm=(0, 0), height_mm=1000.0)


def grey(image):
    return cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)


def polygon_area_centroid(polygon):
    x, y = polygon[:, 0], polygon[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    area = cross.sum() / 2
    return abs(area), np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6 * area)


def general_tags(count=12, seed=3, size=30.0, heights=(0.0, 50.0)):
    """Tags spread over the view at headings away from the axes (the detector has a bias of about 0.1 px on
    axis-aligned edges, which is its own, not the renderer's) and heights up to 50 mm."""
    rng = np.random.default_rng(seed)
    return tuple(TagItem(n, (-560.0 + (n % 6) * 220 + rng.uniform(-10, 10), -220.0 + (n // 6) * 220),
                         size, heading_deg=float(rng.uniform(15, 75) + 90 * (n % 4)),
                         height_mm=float(rng.uniform(*heights))) for n in range(count))


def test_tags_are_upstream_tag36h11_as_the_station_draws_them():
    for tag_id in (0, 1, 7, 42, 586):
        assert np.array_equal(tag_cells_upstream(tag_id), tag_cells(tag_id))
    with pytest.raises(SimConfigError, match="tag id"):
        tag_cells_upstream(587)


def test_rendered_tags_decode_and_corners_match_truth_with_the_half_pixel_convention():
    tags = general_tags()
    image, truth = render(PlaneScene(tags=tags), CAMERA)
    found = detect_tags(grey(image))
    assert sorted(f.tag_id for f in found) == list(range(len(tags)))  # every id, no false id
    by_id = {t.tag_id: t for t in truth}
    assert all(t.visible for t in truth)
    # pupil-apriltags puts pixel edges at integers: OpenCV (centre) = pupil - 0.5
    offsets = np.array([f.corners - by_id[f.tag_id].corners_px for f in found]).reshape(-1, 2)
    assert np.allclose(offsets.mean(axis=0), 0.5, atol=0.03)
    errors = np.linalg.norm(offsets - 0.5, axis=1)
    wrong_way = np.linalg.norm(offsets + 0.5, axis=1)
    assert np.percentile(errors, 90) <= 0.15 and errors.max() <= 0.3
    assert wrong_way.min() > 0.7
    centres = np.array([f.center - 0.5 - by_id[f.tag_id].center_px for f in found])
    assert np.abs(centres).max() <= 0.15


@pytest.mark.parametrize("dist", [None, (-0.18, 0.06, 0.002, -0.001, 0.0)])
def test_the_picture_is_exact_darkness_centroid_at_the_projected_black_cells(dist):
    # no detector: the centroid of darkness inside the tag equals the projected centroid of its black cells
    camera = CameraModel.looking_down(target_mm=(0, 0), height_mm=1000.0, dist_coeffs=dist, tilt_deg=12.0)
    for tag in (TagItem(5, (-520.3, 240.2), 30.0, heading_deg=23.0, height_mm=40.0),
                TagItem(9, (13.1, -7.7), 30.0, heading_deg=0.0, height_mm=0.0)):
        image, (truth,) = render(PlaneScene(tags=(tag,)), camera, RenderOptions(supersample=3))
        red = image[..., 0].astype(float)
        inner = camera.project(np.column_stack([tag_corners_mm(tag, 9.5 / 8), np.full(4, tag.height_mm)]))
        mask = np.zeros(red.shape, np.uint8)
        cv2.fillPoly(mask, [np.round(inner * 16).astype(np.int32)], 1, cv2.LINE_8, 4)
        ys, xs = np.nonzero(mask)
        dark = (TAG_WHITE[0] - red[ys, xs]) / (TAG_WHITE[0] - TAG_BLACK[0])
        measured = np.array([(dark * xs).sum(), (dark * ys).sum()]) / dark.sum()
        rows, cols = np.nonzero(~tag_cells(tag.tag_id))
        cell, theta = tag.size_mm / 8, np.radians(tag.heading_deg)
        right, up = np.array([np.cos(theta), np.sin(theta)]), np.array([-np.sin(theta), np.cos(theta)])
        # each black cell's image is a quadrilateral (perspective): weight its centroid by its area in the image
        offsets = np.array([(0, 0), (1, 0), (1, 1), (0, 1)])
        total, moment = 0.0, np.zeros(2)
        for row, col in zip(rows, cols, strict=True):
            corners = [np.array(tag.center_mm) + (col + dx - 5) * cell * right + (5 - row - dy) * cell * up
                       for dx, dy in offsets]
            quad = camera.project(np.column_stack([corners, np.full(4, tag.height_mm)]))
            area, centroid = polygon_area_centroid(quad)
            total, moment = total + area, moment + area * centroid
        expected = moment / total
        assert np.linalg.norm(measured - expected) < 0.03
        assert truth.visible


def test_distortion_moves_corners_as_project_points_says():
    tag = TagItem(3, (-480.0, 250.0), 40.0, heading_deg=31.0)
    plain = CameraModel.looking_down(height_mm=1000.0)
    bent = CameraModel(plain.camera_matrix, np.array([-0.2, 0.08, 0.0, 0.0, 0.0]), plain.image_size, plain.rvec,
                       plain.tvec)
    (f_plain,), (f_bent,) = (detect_tags(grey(render(PlaneScene(tags=(tag,)), c)[0])) for c in (plain, bent))
    points = np.column_stack([tag_corners_mm(tag), np.zeros(4)])
    moved = cv2.projectPoints(points, bent.rvec, bent.tvec, bent.camera_matrix, bent.dist_coeffs)[0].reshape(-1, 2) \
        - cv2.projectPoints(points, plain.rvec, plain.tvec, plain.camera_matrix, None)[0].reshape(-1, 2)
    assert np.abs(moved).min() > 10  # the distortion is large here
    assert np.abs((f_bent.corners - f_plain.corners) - moved).max() < 0.3


def test_a_tag_at_height_shows_where_project_points_puts_it():
    tag = TagItem(11, (400.0, -200.0), 30.0, heading_deg=140.0, height_mm=50.0)
    image, (truth,) = render(PlaneScene(tags=(tag,)), CAMERA)
    (found,) = detect_tags(grey(image))
    at_height = cv2.projectPoints(np.array([[400.0, -200.0, 50.0]]), CAMERA.rvec, CAMERA.tvec,
                                  CAMERA.camera_matrix, CAMERA.dist_coeffs)[0].reshape(2)
    on_table = CAMERA.project(np.array([[400.0, -200.0, 0.0]]))[0]
    assert np.linalg.norm(found.center - 0.5 - at_height) < 0.15
    assert np.linalg.norm(at_height - on_table) > 25  # ~ 50 mm x 447 mm off-centre / 1000 mm, in pixels
    assert np.allclose(truth.center_px, at_height)


def test_occluders_and_higher_items_hide_tags_and_truth_says_so():
    tags = (TagItem(1, (0.0, 0.0), 30.0), TagItem(2, (100.0, 0.0), 30.0), TagItem(3, (-100.0, 0.0), 30.0),
            TagItem(4, (1500.0, 0.0), 30.0))
    hand = Occluder(np.array([[80.0, -30.0], [130.0, -30.0], [130.0, 30.0], [80.0, 30.0]]), height_mm=60.0)
    board = ImageItem(np.full((10, 10, 3), 120, np.uint8), np.array([[-120, 10], [-80, 10], [-80, -10], [-120, -10]]),
                      height_mm=20.0)
    image, truth = render(PlaneScene(tags=tags, occluders=(hand,), images=(board,)), CAMERA)
    assert [t.visible for t in truth] == [True, False, False, False]  # 4 is out of view
    assert [f.tag_id for f in detect_tags(grey(image))] == [1]
    u, v = CAMERA.project(np.array([[105.0, 0.0, 60.0]]))[0].round().astype(int)
    assert np.allclose(image[v, u], (90, 70, 60), atol=2)


def box(u0, u1, v0, v1, h0, h1):
    return np.array([[u, v, h] for u in (u0, u1) for v in (v0, v1) for h in (h0, h1)], float)


def test_a_solid_hides_what_the_camera_sees_behind_it_in_perspective():
    # a block 100 mm tall over u 200..260: seen from 1000 mm up, its top hides the plane out to u = 260 * 1000 / 900
    block = Solid((box(200.0, 260.0, -30.0, 30.0, 0.0, 100.0),), color=(40, 160, 90))
    beyond = TagItem(5, (284.0, 0.0), 8.0)   # its white border reaches u = 279..289: clear of the block's footprint
    before = TagItem(6, (190.0, 0.0), 8.0)   # on the camera's side of the block: its walls lean away from it
    on_top = TagItem(7, (230.0, 0.0), 30.0, heading_deg=30.0, height_mm=100.0)  # printed on the block's top face
    image, truth = render(PlaneScene(tags=(beyond, before, on_top), solids=(block,)), CAMERA)
    assert [t.visible for t in truth] == [False, True, True]
    assert sorted(f.tag_id for f in detect_tags(grey(image))) == [6, 7]
    far_edge = CAMERA.project(np.array([[260.0, 0.0, 100.0]]))[0]  # where the top face's far edge shows
    inside, outside = (np.round(far_edge + [dx, 0.0]).astype(int) for dx in (-1.5, 1.5))
    assert np.allclose(image[inside[1], inside[0]], (40, 160, 90), atol=2)
    assert np.allclose(image[outside[1], outside[0]], (200, 200, 195), atol=2)  # the plane's own colour
    # the same block as a flat occluder on the plane hides only its footprint: the tag beyond shows
    flat = Occluder(box(200.0, 260.0, -30.0, 30.0, 0.0, 0.0)[::2][[0, 1, 3, 2], :2], height_mm=0.0)
    _, flat_truth = render(PlaneScene(tags=(beyond,), occluders=(flat,)), CAMERA)
    assert flat_truth[0].visible


def test_a_tag_between_a_solids_depths_is_hidden_only_by_its_nearer_part():
    # a shelf at 50 mm beside a block 0..100 mm: the block's upper half stands between the camera and the shelf's
    # tag, seen from the camera's centre; a lower block (0..40 mm) would be behind the shelf's plane and hide nothing
    tag = TagItem(9, (279.0, 0.0), 10.0, height_mm=50.0)  # border u 272.75..285.25: the upper half reaches 274.4
    tall = Solid((box(200.0, 260.0, -30.0, 30.0, 0.0, 100.0),))
    low = Solid((box(200.0, 272.0, -30.0, 30.0, 0.0, 40.0),))
    _, (hidden,) = render(PlaneScene(tags=(tag,), solids=(tall,)), CAMERA)
    _, (seen,) = render(PlaneScene(tags=(tag,), solids=(low,)), CAMERA)
    assert not hidden.visible and seen.visible


def test_projector_light_lands_where_plane_from_pixel_says():
    projector = SimulatedProjector("sim://projector?size=320x200")
    projector.place(area_homography((-160.0, -100.0, 160.0, 100.0), (320, 200)))
    frame = np.zeros((200, 320, 3), np.uint8)
    frame[50:100, 200:260] = 255  # pixels x 200..259, y 50..99: u 40..100 mm, v 0..50 mm
    projector.open()
    projector.show(frame)
    image, _ = render(PlaneScene(light=projector.light()), CAMERA)
    lit = CAMERA.project(np.array([[70.0, 25.0], [30.0, 25.0], [70.0, -10.0]])).round().astype(int)
    values = [int(image[y, x, 1]) for x, y in lit]
    assert values[0] == 255 and values[1] == 200 and values[2] == 200  # 200 * (1 + 0.6) clips
    dim, _ = render(PlaneScene(light=projector.light()), CAMERA, RenderOptions(exposure=0.5))
    assert int(dim[lit[0][1], lit[0][0], 1]) == 160


def test_degradations_are_seeded_and_bounded():
    scene = PlaneScene(tags=general_tags(4))
    options = RenderOptions(blur_px=1.0, noise=3.0, vignetting=0.3, jpeg_quality=80, seed=7)
    one, _ = render(scene, CAMERA, options)
    two, _ = render(scene, CAMERA, options)
    other, _ = render(scene, CAMERA, RenderOptions(blur_px=1.0, noise=3.0, vignetting=0.3, jpeg_quality=80, seed=8))
    assert np.array_equal(one, two) and not np.array_equal(one, other)
    assert one[540, 960].mean() > one[2, 2].mean() + 40  # vignetting darkens the corners
    assert sorted(f.tag_id for f in detect_tags(grey(one))) == [0, 1, 2, 3]


@pytest.mark.parametrize("options, name", [(RenderOptions(supersample=0), "supersample"),
                                           (RenderOptions(vignetting=2.0), "vignetting"),
                                           (RenderOptions(jpeg_quality=0), "jpeg_quality")])
def test_bad_options_are_one_line_naming_them(options, name):
    with pytest.raises(SimConfigError, match=name):
        render(PlaneScene(), CAMERA, options)


def test_a_tag_on_a_parts_top_face_is_seen_on_it():
    face = Occluder(np.array([[-40.0, -30.0], [40.0, -30.0], [40.0, 30.0], [-40.0, 30.0]]), height_mm=35.0)
    tag = TagItem(21, (0.0, 0.0), 30.0, heading_deg=60.0, height_mm=35.0)
    image, (truth,) = render(PlaneScene(tags=(tag,), occluders=(face,)), CAMERA)
    assert truth.visible and [f.tag_id for f in detect_tags(grey(image))] == [21]
    u, v = CAMERA.project(np.array([[36.0, 0.0, 35.0]]))[0].round().astype(int)
    assert np.allclose(image[v, u], (90, 70, 60), atol=2)  # the face around the tag


def test_a_tag_far_outside_a_barrel_lens_view_is_not_visible_where_project_points_folds_it_in():
    camera = CameraModel.looking_down(height_mm=1000.0, dist_coeffs=(-0.25, 0, 0, 0, 0))
    far = TagItem(2, (1500.0, 0.0), 30.0)  # the polynomial turns back: projectPoints puts it at x ~ 1878
    near = TagItem(3, (500.0, 0.0), 30.0)
    image, (t_far, t_near) = render(PlaneScene(tags=(far, near)), camera)
    assert 0 < t_far.center_px[0] < 1920 and not t_far.visible and t_near.visible
    assert [f.tag_id for f in detect_tags(grey(image))] == [3]
