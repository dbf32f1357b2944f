"""Measuring tags on the guide plane from one camera frame: the plane from the reference tags, parts at their height.

:func:`measure` finds the tags (:func:`vision.detection.detect_tags`'s detector, never pupil-apriltags directly),
moves their corners into OpenCV's pixel convention (pupil-apriltags puts pixel EDGES at integers: a pixel's centre is
at +0.5; OpenCV puts the centre at the integer, so every corner is 0.5 px less in x and y), removes the lens
distortion, and then:

1. **The plane** from the reference tags' corners (4 per tag, at h = 0, upright as printed): a RANSAC homography
   drops a misread corner, then ``cv2.solvePnP`` (IPPE, refined by Levenberg-Marquardt) gives the camera's pose to the
   plane. Redone at every frame: a bumped camera moves the plane, and ``moved_mm`` says by how much.
2. **Each part tag at its own height**: a tag on a part's top face lies ``h`` above the plane; each corner's ray from
   the camera centre is cut with the plane ``h`` = height (mapping it through the table's plane instead would put it
   about ``h x offset / camera height`` too far out: 10 mm at 400 mm off-centre for a 25 mm high part under a camera
   1 m up). The tag's centre and heading come from a least-squares fit of a square of its known size to the four
   corners; the fit's RMS is its ``fit_residual_mm``.

The tag's own 6-DoF pose (one tag's four corners alone, as AprilTag computes it) is far less accurate than this:
its depth, hence its lateral position, rests on a 30 mm square seen from 1 m; here the depth comes from the plane
(fixed by four tags spread over the sheet) and the known height. Ids are never guessed: a duplicate is reported and
not measured, an unknown id is reported, a missing reference tag is named.
"""

from __future__ import annotations

import math
import threading
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from calibration.errors import CalibrationError
from calibration.intrinsics import CameraIntrinsics, to_gray
from common.opencv import undistort_points

__all__ = ["PlaneFix", "TagPose", "Measurement", "measure", "plane_from_points", "rays_to_height",
           "fit_square", "sort_ids", "square_corners", "detected_corners", "undistort", "MIN_REFERENCE_TAGS",
           "APRILTAG_OFFSET_PX"]

#: pupil-apriltags' pixel centres sit at +0.5 (its pixel edges at integers); OpenCV's at integers.
APRILTAG_OFFSET_PX = 0.5
#: Reference tags needed for a plane (8 corners over the sheet; a single tag's plane tilts freely).
MIN_REFERENCE_TAGS = 2
#: The detector's first pass searches quads on an image this many times smaller; its threads.
FAST_DECIMATE = 2.0
DETECT_THREADS = 2
#: RANSAC threshold of the homography, in plane millimetres.
RANSAC_MM = 3.0
#: Unit corners of a tag's black square, [lower-left, lower-right, upper-right, upper-left], (u, v) as printed.
_UNIT_SQUARE = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])


@dataclass(frozen=True)
class PlaneFix:
    """The guide plane seen through the reference tags.

    Attributes
    ----------
    rvec, tvec : ndarray, shape (3,)
        The camera's pose: plane (u, v, h) mm -> camera, ``x_cam = R @ [u, v, h] + t``.
    homography : ndarray, shape (3, 3)
        Undistorted pixel -> plane (u, v) mm at h = 0.
    residual_mm : float
        RMS distance, on the plane, between the reference corners seen and where they are printed.
    reference_ids : tuple of int
        The reference tags used.
    moved_mm : float or None
        The largest distance by which the previous fix would now misplace a reference corner (a bumped camera);
        None without a previous fix.
    """

    rvec: np.ndarray
    tvec: np.ndarray
    homography: np.ndarray
    residual_mm: float
    reference_ids: tuple[int, ...]
    moved_mm: float | None = None

    @property
    def rotation(self) -> np.ndarray:
        import cv2

        return cv2.Rodrigues(np.asarray(self.rvec, dtype=float))[0]

    @property
    def camera_centre_mm(self) -> np.ndarray:
        """The camera centre in (u, v, h) mm."""
        return -self.rotation.T @ np.asarray(self.tvec, dtype=float).ravel()

    def to_dict(self) -> dict:
        return {"residual_mm": float(self.residual_mm), "reference_ids": list(self.reference_ids),
                "moved_mm": None if self.moved_mm is None else float(self.moved_mm),
                "rvec": np.asarray(self.rvec, dtype=float).ravel().tolist(),
                "tvec": np.asarray(self.tvec, dtype=float).ravel().tolist(),
                "camera_height_mm": float(self.camera_centre_mm[2])}


@dataclass(frozen=True)
class TagPose:
    """A part tag measured on the plane at its height (``heading_deg`` counter-clockwise, 0 = its up along +v)."""

    tag_id: int
    center_mm: tuple[float, float]
    heading_deg: float
    height_mm: float
    corners_mm: np.ndarray
    fit_residual_mm: float


@dataclass(frozen=True)
class Measurement:
    """What one frame shows: the plane (None with too few reference tags) and the part tags found, once each."""

    plane: PlaneFix | None
    tags: tuple[TagPose, ...]
    unknown_ids: tuple[int, ...]
    duplicate_ids: tuple[int, ...]
    missing_reference_ids: tuple[int, ...]

    def tag(self, tag_id: int) -> TagPose | None:
        """The measured tag ``tag_id``, or None."""
        return next((t for t in self.tags if t.tag_id == tag_id), None)


def detected_corners(found) -> np.ndarray:
    """A :class:`vision.detection.FoundTag`'s corners in OpenCV's pixel convention (see the module notes)."""
    return np.asarray(found.corners, dtype=float) - APRILTAG_OFFSET_PX


def undistort(points_px: np.ndarray, intrinsics: CameraIntrinsics) -> np.ndarray:
    """Pixels (n, 2) with the lens distortion removed, still in pixels of the same camera matrix."""
    import cv2

    points = np.asarray(points_px, dtype=np.float64).reshape(-1, 1, 2)
    if len(points) == 0:
        return np.zeros((0, 2))
    matrix = np.asarray(intrinsics.camera_matrix, dtype=np.float64)
    # the iterative solver's default (5 steps) leaves ~0.05 px at the corners of a wide lens: ask for more
    out = undistort_points(points, matrix, np.asarray(intrinsics.dist_coeffs, dtype=np.float64), None,
                           matrix, (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-9))
    return out.reshape(-1, 2)


def square_corners(center: Sequence[float], size_mm: float, heading_deg: float = 0.0) -> np.ndarray:
    """A tag's four corners (u, v) mm, [lower-left, lower-right, upper-right, upper-left] as printed, turned by
    ``heading_deg`` counter-clockwise about its centre."""
    angle = math.radians(heading_deg)
    turn = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    return np.asarray(center, dtype=float) + (size_mm * _UNIT_SQUARE) @ turn.T


def fit_square(corners_mm: np.ndarray, size_mm: float) -> tuple[np.ndarray, float, float]:
    """The square of edge ``size_mm`` nearest the four corners (least squares): centre, heading (deg), RMS (mm).

    With the corners' order fixed the fit is closed-form: the centre is their mean (the model's corners sum to
    zero), the angle the one that best turns the model's corners onto the measured ones (2-D Procrustes).
    """
    corners = np.asarray(corners_mm, dtype=float)
    centre = corners.mean(axis=0)
    model = size_mm * _UNIT_SQUARE
    offsets = corners - centre
    cross = float(np.sum(model[:, 0] * offsets[:, 1] - model[:, 1] * offsets[:, 0]))
    dot = float(np.sum(model * offsets))
    angle = math.atan2(cross, dot)
    fitted = square_corners(centre, size_mm, math.degrees(angle))
    rms = float(np.sqrt(np.mean(np.sum((fitted - corners) ** 2, axis=1))))
    heading = (math.degrees(angle) + 180.0) % 360.0 - 180.0
    return centre, (180.0 if heading == -180.0 else heading), rms


def rays_to_height(points_px: np.ndarray, matrix: np.ndarray, rvec: np.ndarray, tvec: np.ndarray,
                   height_mm: float) -> np.ndarray:
    """Undistorted pixels (n, 2) -> (u, v) mm where their rays from the camera centre meet the plane h = height."""
    import cv2

    rotation = cv2.Rodrigues(np.asarray(rvec, dtype=float))[0]
    t = np.asarray(tvec, dtype=float).ravel()
    pixels = np.column_stack([np.asarray(points_px, dtype=float).reshape(-1, 2), np.ones(len(points_px))])
    rays = pixels @ np.linalg.inv(matrix).T                # camera frame directions
    normal = rotation[:, 2]                                # the plane's h axis in the camera frame
    anchor = rotation @ np.array([0.0, 0.0, height_mm]) + t
    scale = (anchor @ normal) / (rays @ normal)
    plane = (rays * scale[:, None] - t) @ rotation         # R^T (x - t), row-wise
    return plane[:, :2]


def plane_from_points(pixels: np.ndarray, plane_uv: np.ndarray, intrinsics: CameraIntrinsics,
                      reference_ids: Sequence[int], previous: PlaneFix | None = None) -> PlaneFix:
    """The plane's pose from undistorted pixels of points at h = 0 and their (u, v) mm (see the module notes).

    Raises
    ------
    CalibrationError
        Fewer than 4 points, or points the homography cannot fit (all on a line).
    """
    import cv2

    pixels = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    plane_uv = np.asarray(plane_uv, dtype=np.float64).reshape(-1, 2)
    if len(pixels) < 4:
        raise CalibrationError(f"plane: {len(pixels)} reference corners seen, at least 4 needed")
    _, inliers = cv2.findHomography(pixels, plane_uv, cv2.RANSAC, RANSAC_MM)
    if inliers is None or int(inliers.sum()) < 4:
        raise CalibrationError("plane: the reference corners fit no plane (tags misread or in a line)")
    keep = inliers.ravel().astype(bool)
    objects = np.column_stack([plane_uv[keep], np.zeros(int(keep.sum()))])
    matrix = np.asarray(intrinsics.camera_matrix, dtype=np.float64)
    no_distortion = np.zeros(5)  # the pixels are undistorted already
    ok, rvec, tvec = cv2.solvePnP(objects, pixels[keep], matrix, no_distortion, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        raise CalibrationError("plane: no camera pose fits the reference corners")
    rvec, tvec = cv2.solvePnPRefineLM(objects, pixels[keep], matrix, no_distortion, rvec, tvec)
    rvec, tvec = rvec.ravel(), tvec.ravel()
    rotation = cv2.Rodrigues(rvec)[0]
    to_image = matrix @ np.column_stack([rotation[:, 0], rotation[:, 1], tvec])
    homography = np.linalg.inv(to_image)
    homography /= homography[2, 2]
    seen = _apply(homography, pixels)
    residual = float(np.sqrt(np.mean(np.sum((seen - plane_uv) ** 2, axis=1))))
    moved = None
    if previous is not None:
        before = _apply(np.asarray(previous.homography, dtype=float), pixels)
        moved = float(np.max(np.linalg.norm(before - plane_uv, axis=1)))
    return PlaneFix(rvec, tvec, homography, residual, tuple(int(i) for i in reference_ids), moved)


def _apply(homography: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    points = np.column_stack([pixels, np.ones(len(pixels))]) @ homography.T
    return points[:, :2] / points[:, 2:3]


def _detect(gray: np.ndarray, wanted: set[int]) -> list:
    """The tags in a frame: quads searched on a half-size image first (faster, corners still refined on
    the full image), again at full size only when a wanted tag is not found (a small or far tag, ~20 px or less)."""
    found = _detector(FAST_DECIMATE).detect(gray)
    if wanted <= {tag.tag_id for tag in found}:
        return found
    return _detector(1.0).detect(gray)


_DETECTORS = threading.local()


def _detector(decimate: float):
    """This thread's detector for ``decimate`` (making one builds the family's decode table: ~0.1 s; a detector is
    not safe to share between threads)."""
    from vision.detection import TagDetector

    detectors = _DETECTORS.__dict__.setdefault("by_decimate", {})
    if decimate not in detectors:
        detectors[decimate] = TagDetector(decimate, DETECT_THREADS)
    return detectors[decimate]


def sort_ids(found, reference_ids, part_ids):
    """Sort detections by id: (the tags seen once, by id; unknown ids; duplicate ids; reference ids not seen).

    A duplicate is never measured (which one is the part's?); a reference id seen twice is neither missing nor used.
    """
    counts = Counter(tag.tag_id for tag in found)
    duplicates = tuple(sorted(i for i, n in counts.items() if n > 1))
    unique = {tag.tag_id: tag for tag in found if counts[tag.tag_id] == 1}
    unknown = tuple(sorted(i for i in counts if i not in reference_ids and i not in part_ids))
    missing = tuple(sorted(i for i in reference_ids if i not in counts))
    return unique, unknown, duplicates, missing


def measure(image: np.ndarray, intrinsics: CameraIntrinsics,
            reference_tags: Sequence[tuple[int, tuple[float, float], float]],
            part_tags: Mapping[int, tuple[float, float]], previous: PlaneFix | None = None, *,
            detector=None, found=None) -> Measurement:
    """Find the plane and the part tags in one camera frame.

    Parameters
    ----------
    image : ndarray
        The frame, grey or RGB uint8, of the size the intrinsics are for.
    intrinsics : CameraIntrinsics
    reference_tags : sequence of (id, (u, v) mm, size mm)
        The guide's reference tags (printed upright, on the plane).
    part_tags : mapping of id to (size mm, height mm)
        The tags on the parts and the height of the face each lies on.
    previous : PlaneFix, optional
        The last fix, to say how far the plane moved since.
    detector : vision.detection.TagDetector, optional
        A detector to use (its ``quad_decimate`` sets speed); default: quads searched at half size, then at full
        size only if a wanted tag was not found.
    found : list of vision.detection.FoundTag, optional
        Detections already made on this frame (then ``image`` is only checked for its size).

    Raises
    ------
    CalibrationError
        An image that is not 8-bit grey or RGB, or not of the intrinsics' size; a reference id also a part id.
    """
    references = {int(tag_id): (tuple(map(float, centre)), float(size)) for tag_id, centre, size in reference_tags}
    parts = {int(tag_id): (float(size), float(height)) for tag_id, (size, height) in part_tags.items()}
    both = sorted(set(references) & set(parts))
    if both:
        raise CalibrationError(f"tag ids {both} are given both as reference and as part tags")
    intrinsics.check_image(image)
    if found is None:
        gray = to_gray(image)
        found = detector.detect(gray) if detector is not None else _detect(gray, set(references) | set(parts))
    unique, unknown, duplicates, missing = sort_ids(found, references, parts)

    pixels = {i: undistort(detected_corners(tag), intrinsics) for i, tag in unique.items()
              if i in references or i in parts}
    seen_refs = sorted(i for i in references if i in pixels)
    plane = None
    if len(seen_refs) >= MIN_REFERENCE_TAGS:
        points = np.concatenate([pixels[i] for i in seen_refs])
        printed = np.concatenate([square_corners(*references[i]) for i in seen_refs])
        plane = plane_from_points(points, printed, intrinsics, seen_refs, previous)
    tags = []
    if plane is not None:
        matrix = np.asarray(intrinsics.camera_matrix, dtype=float)
        for tag_id in sorted(i for i in parts if i in pixels):
            size, height = parts[tag_id]
            corners = rays_to_height(pixels[tag_id], matrix, plane.rvec, plane.tvec, height)
            centre, heading, rms = fit_square(corners, size)
            tags.append(TagPose(tag_id, (float(centre[0]), float(centre[1])), heading, height, corners, rms))
    return Measurement(plane, tuple(tags), unknown, duplicates, missing)
