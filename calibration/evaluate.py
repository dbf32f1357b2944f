"""Synthetic frames with known answers, and how well :func:`calibration.measure.measure` reads them.

Used by the acceptance tests, ``bench/bench_check_accuracy.py`` and anyone checking a measurement change: a scene of
the four reference tags and part tags at random places, headings and heights (drawn by the camera twin,
:mod:`drivers.sim.camera_render`, which shares no code with the detector), rendered with noise, blur and JPEG, and
scored against the renderer's ground truth (:class:`drivers.sim.camera_scene.TagTruth`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

__all__ = ["Scores", "acceptance_camera", "acceptance_options", "board_cameras", "board_scene", "board_views",
           "camera_pose", "part_scene", "reference_layout", "score"]

#: The acceptance camera: 1080p, f 1400 px, 1 m above the plane, a mild barrel lens.
ACCEPTANCE_DISTORTION = (-0.08, 0.03, 0.0004, -0.0003, 0.0)


def acceptance_camera(tilt_deg: float = 0.0, roll_deg: float = 0.0, target_mm=(0.0, 0.0), focal_px: float = 1400.0,
                      height_mm: float = 1000.0):
    """The acceptance's camera model (:class:`drivers.sim.camera_scene.CameraModel`)."""
    from drivers.sim.camera_scene import CameraModel

    return CameraModel.looking_down(target_mm=target_mm, height_mm=height_mm, image_size=(1920, 1080),
                                    focal_px=focal_px, dist_coeffs=np.array(ACCEPTANCE_DISTORTION),
                                    tilt_deg=tilt_deg, roll_deg=roll_deg)


def acceptance_options(seed: int = 0, jpeg_quality: int | None = 85):
    """Noise, blur and JPEG of the acceptance frames (:class:`drivers.sim.camera_scene.RenderOptions`)."""
    from drivers.sim.camera_scene import RenderOptions

    return RenderOptions(blur_px=0.8, noise=3.0, vignetting=0.2, jpeg_quality=jpeg_quality, supersample=3,
                         seed=seed)


def reference_layout(half_u: float = 540.0, half_v: float = 300.0,
                     size_mm: float = 40.0) -> list[tuple[int, tuple[float, float], float]]:
    """The four reference tags (583-586) at the corners of a 2 half_u x 2 half_v area, as :func:`measure` takes."""
    corners = [(-half_u, -half_v), (half_u, -half_v), (half_u, half_v), (-half_u, half_v)]
    return [(583 + k, corner, size_mm) for k, corner in enumerate(corners)]


def part_scene(seed: int, count: int = 20, *, size_mm: float = 30.0, max_height_mm: float = 50.0,
               area_mm: tuple[float, float] = (460.0, 240.0), headings: Sequence[float] | None = None,
               references=None):
    """A :class:`drivers.sim.camera_scene.PlaneScene` of the reference tags and ``count`` part tags (ids 0..) at
    random centres in +-area_mm, random headings (or ``headings`` in turn) and heights in [0, max_height_mm], at
    least 2.2 tag sizes apart (rotated, with their white borders, they never touch); and the ``part_tags`` mapping
    :func:`measure` takes."""
    from drivers.sim.camera_scene import PlaneScene, TagItem

    rng = np.random.default_rng(seed)
    references = reference_layout() if references is None else references
    tags = [TagItem(tag_id, tuple(centre), size) for tag_id, centre, size in references]
    centres: list[np.ndarray] = []
    parts = {}
    while len(centres) < count:
        centre = rng.uniform(-1.0, 1.0, 2) * area_mm
        if any(np.linalg.norm(centre - c) < 2.2 * size_mm for c in centres):
            continue
        index = len(centres)
        centres.append(centre)
        heading = float(headings[index % len(headings)]) if headings is not None else float(rng.uniform(-180, 180))
        height = float(rng.uniform(0.0, max_height_mm))
        tags.append(TagItem(index, (float(centre[0]), float(centre[1])), size_mm, heading, height))
        parts[index] = (size_mm, height)
    return PlaneScene(tags=tuple(tags)), parts


@dataclass(frozen=True)
class Scores:
    """A measurement against the truth: counts and per-tag errors (position mm, heading degrees)."""

    visible: int
    found: int
    false_ids: tuple[int, ...]
    position_errors_mm: np.ndarray
    heading_errors_deg: np.ndarray

    @staticmethod
    def merge(scores: Sequence[Scores]) -> Scores:
        return Scores(sum(s.visible for s in scores), sum(s.found for s in scores),
                      tuple(i for s in scores for i in s.false_ids),
                      np.concatenate([s.position_errors_mm for s in scores] or [np.zeros(0)]),
                      np.concatenate([s.heading_errors_deg for s in scores] or [np.zeros(0)]))

    def summary(self) -> dict:
        pos, head = self.position_errors_mm, np.abs(self.heading_errors_deg)

        def stat(values, q):
            return float(np.percentile(values, q)) if len(values) else math.nan

        return {"visible": self.visible, "found": self.found,
                "found_fraction": self.found / self.visible if self.visible else math.nan,
                "false_ids": list(self.false_ids), "position_p95_mm": stat(pos, 95),
                "position_max_mm": float(pos.max()) if len(pos) else math.nan,
                "heading_p95_deg": stat(head, 95), "heading_max_deg": float(head.max()) if len(head) else math.nan}


def score(measurement, truths, part_tags) -> Scores:
    """Compare a :class:`calibration.measure.Measurement` with the renderer's truth of the part tags.

    A found tag is one measured with its true id; an id that is not in the scene (or a tag measured that the truth
    says is hidden) is a false id.
    """
    truth_by_id = {t.tag_id: t for t in truths if t.tag_id in part_tags}
    visible = [t for t in truth_by_id.values() if t.visible]
    positions, headings, false_ids = [], [], list(measurement.unknown_ids)
    found = 0
    for tag in measurement.tags:
        truth = truth_by_id.get(tag.tag_id)
        if truth is None:
            false_ids.append(tag.tag_id)
            continue
        found += 1
        positions.append(math.dist(tag.center_mm, truth.center_mm))
        headings.append((tag.heading_deg - truth.heading_deg + 180.0) % 360.0 - 180.0)
    return Scores(len(visible), min(found, len(visible)), tuple(false_ids), np.array(positions), np.array(headings))


def camera_pose(centre_mm, target_mm=(0.0, 0.0), roll_deg: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(rvec, tvec) of a camera at ``centre_mm`` (u, v, h) looking at ``target_mm`` on the plane h = 0, turned by
    ``roll_deg`` about its optical axis."""
    import cv2

    centre = np.asarray(centre_mm, dtype=float)
    forward = np.array([target_mm[0], target_mm[1], 0.0]) - centre
    forward /= np.linalg.norm(forward)
    hint = np.array([0.0, 1.0, 0.0]) if abs(forward[1]) < 0.95 else np.array([1.0, 0.0, 0.0])
    right = np.cross(forward, hint)
    right /= np.linalg.norm(right)
    rotation = np.vstack([right, np.cross(forward, right), forward])
    rotation = cv2.Rodrigues(np.array([0.0, 0.0, math.radians(roll_deg)]))[0] @ rotation
    return cv2.Rodrigues(rotation)[0].ravel(), -rotation @ centre


def board_scene(board=None, px_per_mm: float = 6.0):
    """A :class:`drivers.sim.camera_scene.PlaneScene` of the ChArUco board (with an 8 mm white margin) lying on the
    plane, centred at the origin, its top towards +v."""
    from calibration.charuco import BoardSpec, board_image
    from drivers.sim.camera_scene import ImageItem, PlaneScene

    board = board or BoardSpec()
    margin = 8.0
    picture = board_image(board, px_per_mm, margin)
    half_w, half_h = board.size_mm[0] / 2 + margin, board.size_mm[1] / 2 + margin
    item = ImageItem(picture, np.array([[-half_w, half_h], [half_w, half_h], [half_w, -half_h], [-half_w, -half_h]]))
    return PlaneScene(images=(item,))


def board_views(count: int, camera_matrix, dist_coeffs, image_size=(1920, 1080), *, seed: int = 0, options=None,
                board=None, px_per_mm: float = 6.0):
    """``count`` views of :func:`board_scene` from :func:`board_cameras`, rendered by the camera twin with a
    little blur and noise: [(name, RGB image)], what :func:`calibration.intrinsics.calibrate_camera` takes."""
    from drivers.sim.camera_render import render
    from drivers.sim.camera_scene import RenderOptions

    scene = board_scene(board, px_per_mm)
    options = options or RenderOptions(blur_px=0.7, noise=2.0, seed=seed)
    cameras = board_cameras(count, camera_matrix, dist_coeffs, image_size, seed=seed, board=board)
    return [(f"view-{k + 1:02d}", render(scene, camera, replace(options, seed=options.seed + k))[0])
            for k, camera in enumerate(cameras)]


def board_cameras(count: int, camera_matrix, dist_coeffs, image_size=(1920, 1080), *, seed: int = 0, board=None):
    """``count`` camera models (:class:`drivers.sim.camera_scene.CameraModel`) looking at :func:`board_scene` from
    random poses: up to 50 degrees of tilt, the board wholly in view; every fourth view smaller, pushed into an image
    corner (in turn), so that the corners can be covered."""
    from calibration.charuco import BoardSpec

    board = board or BoardSpec()
    outline = np.column_stack([board_scene(board, 1.0).images[0].corners_mm, np.zeros(4)])
    rng = np.random.default_rng(seed)
    matrix = np.asarray(camera_matrix, dtype=float)
    focal = float(matrix[0, 0])
    width, height = image_size
    image_corners = np.array([[0.0, 0.0], [width - 1.0, 0.0], [width - 1.0, height - 1.0], [0.0, height - 1.0]])
    views = []
    while len(views) < count:
        # every fourth view is aimed so the board reaches into an image corner (in turn), smaller and less tilted
        wanted = image_corners[(len(views) // 4) % 4] if len(views) % 4 == 3 else None
        tilt = math.radians(rng.uniform(0.0, 50.0 if wanted is None else 25.0))
        azimuth = rng.uniform(0.0, 2 * math.pi)
        fill = rng.uniform(1.3, 2.2) if wanted is None else rng.uniform(2.6, 3.2)  # the board fills 30-75% across
        distance = focal * board.size_mm[0] / width * fill
        centre = distance * np.array([math.sin(tilt) * math.cos(azimuth), math.sin(tilt) * math.sin(azimuth),
                                      math.cos(tilt)])
        # a corner view's board runs roughly along the image's edges (a board turned 45 degrees keeps its corners
        # away from the image's)
        roll = rng.uniform(-180.0, 180.0) if wanted is None else 90.0 * rng.integers(4) + rng.uniform(-8.0, 8.0)
        # a corner view is aimed (Newton steps on the aim point) so that the board corner nearest the wanted image
        # corner lands 2% of the width inside it
        target = rng.uniform(-1.0, 1.0, 2) * 0.1 * distance * width / focal
        best = _camera(matrix, dist_coeffs, image_size, centre, target, roll)
        if wanted is not None:
            goal = wanted + 0.02 * width * np.sign(np.array([width, height]) / 2 - wanted)
            which = int(np.argmin(np.linalg.norm(best.project(outline) - goal, axis=1)))
            for _ in range(8):
                here = best.project(outline)[which]
                step = 1e-3 * distance
                jacobian = np.column_stack([
                    (_camera(matrix, dist_coeffs, image_size, centre, target + d, roll).project(outline)[which]
                     - here) / step for d in (np.array([step, 0.0]), np.array([0.0, step]))])
                target = target + np.linalg.lstsq(jacobian, goal - here, rcond=None)[0]
                best = _camera(matrix, dist_coeffs, image_size, centre, target, roll)
        corners = best.project(outline)
        if not (np.all(best.depth(outline) > 0) and np.all(corners >= 0) and np.all(corners[:, 0] < width - 1)
                and np.all(corners[:, 1] < height - 1)):
            continue
        views.append(best)
    return views


def _camera(matrix, dist_coeffs, image_size, centre, target, roll):
    from drivers.sim.camera_scene import CameraModel

    rvec, tvec = camera_pose(centre, target, roll)
    return CameraModel(matrix, np.asarray(dist_coeffs, dtype=float), tuple(image_size), rvec, tvec)
