"""Small synthetic camera views for the fast tests: a flat picture seen by a pinhole camera with distortion.

Each output pixel (OpenCV's pixel centres) is undistorted to its ideal pixel, sent through the inverse of the
plane-to-image homography to the picture's millimetres, and sampled from the picture (4x supersampled, area
averaged). It shares nothing with calibration's detectors; tests/calibration/test_*_render.py use the camera twin's
renderer (drivers/sim/camera_render.py) instead.
"""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np


def camera_pose(centre_mm, target_mm=(0.0, 0.0), roll_deg=0.0) -> tuple[np.ndarray, np.ndarray]:
    """(rvec, tvec) of a camera at ``centre_mm`` (u, v, h) looking at ``target_mm`` on the plane h = 0."""
    centre = np.asarray(centre_mm, dtype=float)
    forward = np.array([target_mm[0], target_mm[1], 0.0]) - centre
    forward /= np.linalg.norm(forward)
    up_hint = np.array([0.0, 1.0, 0.0]) if abs(forward[1]) < 0.95 else np.array([1.0, 0.0, 0.0])
    right = np.cross(forward, up_hint)
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    rotation = np.vstack([right, down, forward])
    roll = cv2.Rodrigues(np.array([0.0, 0.0, math.radians(roll_deg)]))[0]
    rotation = roll @ rotation
    return cv2.Rodrigues(rotation)[0].ravel(), -rotation @ centre


@functools.lru_cache(maxsize=4)
def _ideal_pixels(matrix_bytes: bytes, dist_bytes: bytes, size: tuple[int, int], s: int) -> np.ndarray:
    """The undistorted (ideal) pixel of every sub-pixel sample point (OpenCV's convention: the centre of output
    pixel (x, y) is at (x, y)); the same for every view of one camera, so kept."""
    matrix = np.frombuffer(matrix_bytes).reshape(3, 3)
    dist = np.frombuffer(dist_bytes)
    width, height = size
    offsets = (np.arange(s) + 0.5) / s - 0.5
    xs = (np.arange(width)[:, None] + offsets[None, :]).ravel()
    ys = (np.arange(height)[:, None] + offsets[None, :]).ravel()
    grid = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 1, 2)
    return cv2.undistortPointsIter(grid, matrix, dist, None, matrix,
                                   (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 20, 1e-6)).reshape(-1, 2)


def render_picture(picture: np.ndarray, corners_mm: np.ndarray, matrix: np.ndarray, dist: np.ndarray,
                   rvec: np.ndarray, tvec: np.ndarray, size: tuple[int, int], *, supersample: int = 3,
                   background: int = 200, blur: float = 0.0, noise: float = 0.0, seed: int = 0) -> np.ndarray:
    """A grey view of ``picture`` (row 0 at its top) lying on the plane with its top-left, top-right,
    bottom-right, bottom-left corners at ``corners_mm``."""
    width, height = size
    s = supersample
    ideal = _ideal_pixels(matrix.tobytes(), np.asarray(dist, dtype=float).tobytes(), size, s)
    rotation = cv2.Rodrigues(np.asarray(rvec, dtype=float))[0]
    to_image = matrix @ np.column_stack([rotation[:, 0], rotation[:, 1], np.asarray(tvec, dtype=float)])
    plane = np.column_stack([ideal, np.ones(len(ideal))]) @ np.linalg.inv(to_image).T
    plane = plane[:, :2] / plane[:, 2:3]
    rows, cols = picture.shape[:2]
    # picture pixel edges at 0..cols: its corner (0, 0) edge is corners_mm[0]
    source = np.array([[-0.5, -0.5], [cols - 0.5, -0.5], [cols - 0.5, rows - 0.5], [-0.5, rows - 0.5]],
                      dtype=np.float32)
    to_picture = cv2.getPerspectiveTransform(np.asarray(corners_mm, dtype=np.float32), source)
    mapped = cv2.perspectiveTransform(plane.reshape(-1, 1, 2).astype(np.float64), to_picture).reshape(-1, 2)
    map_x = mapped[:, 0].reshape(height * s, width * s).astype(np.float32)
    map_y = mapped[:, 1].reshape(height * s, width * s).astype(np.float32)
    big = cv2.remap(picture, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=background)
    image = cv2.resize(big, size, interpolation=cv2.INTER_AREA).astype(float)
    if blur > 0:
        image = cv2.GaussianBlur(image, (0, 0), blur)
    if noise > 0:
        image += np.random.default_rng(seed).normal(0.0, noise, image.shape)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)
