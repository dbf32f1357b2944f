"""A camera's intrinsics (OpenCV's pinhole model with distortion) and how to get them from ChArUco views.

The JSON file of a camera keeps OpenCV's names, so any OpenCV program can read it::

    {"format": "chaos-station camera", "version": 1, "name": "desk",
     "camera_matrix": [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], "dist_coeffs": [k1, k2, p1, p2, k3],
     "image_size": [width, height], "rms_px": 0.31, ...}

Pixels follow OpenCV's convention: pixel (x, y) has its centre at integer (x, y). :func:`calibrate_camera` takes the
views of a printed ChArUco board (:mod:`calibration.charuco`), finds the board's corners in each, and solves
``cv2.calibrateCameraExtended``. Views whose corners all lie near the image centre say nothing about the distortion
at the image corners, where k3 (the sixth-power radial term) would then extrapolate wildly: unless every image
corner is covered by some view, k3 is fixed at 0 and the result says which corners lacked views.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from calibration.errors import CalibrationError
from common.datafiles import load_json
from common.progress import Reporter

__all__ = ["CameraIntrinsics", "CalibrationResult", "ViewResult", "calibrate_camera", "load_intrinsics",
           "save_intrinsics", "to_gray", "corner_coverage", "FORMAT"]

FORMAT = "chaos-station camera"
#: A view must show this many board corners to be used (fewer pin the pose badly and mislead the solver).
MIN_CORNERS = 8
#: Views needed to solve the intrinsics at all.
MIN_VIEWS = 3
#: An image corner counts as covered when this many board corners were seen within this fraction of the image's
#: width and height from it.
CORNER_REGION = 0.2
CORNER_POINTS = 2
CORNER_NAMES = ("top-left", "top-right", "bottom-right", "bottom-left")


@dataclass(frozen=True)
class CameraIntrinsics:
    """A camera's pinhole model: matrix, distortion and the image size they hold for.

    Parameters
    ----------
    camera_matrix : ndarray, shape (3, 3)
        ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` in pixels.
    dist_coeffs : ndarray, shape (5,) (or 4, 8, 12, 14: OpenCV's lengths)
        ``k1 k2 p1 p2 k3 ...``.
    image_size : tuple of int
        ``(width, height)`` of the images they were solved for.
    rms_px : float or None
        Reprojection RMS of the calibration (None: not calibrated, e.g. :meth:`guess`).
    name : str or None
        The camera's name (the file's stem when saved per camera).
    """

    camera_matrix: np.ndarray
    dist_coeffs: np.ndarray
    image_size: tuple[int, int]
    rms_px: float | None = None
    name: str | None = None
    notes: tuple[str, ...] = field(default=())

    @property
    def focal_px(self) -> float:
        """The mean of fx and fy."""
        return float(0.5 * (self.camera_matrix[0, 0] + self.camera_matrix[1, 1]))

    def to_json(self) -> dict:
        """The camera as JSON values (OpenCV's names; see the module notes)."""
        return {"format": FORMAT, "version": 1, "name": self.name,
                "camera_matrix": np.asarray(self.camera_matrix, dtype=float).tolist(),
                "dist_coeffs": np.asarray(self.dist_coeffs, dtype=float).ravel().tolist(),
                "image_size": [int(self.image_size[0]), int(self.image_size[1])],
                "rms_px": None if self.rms_px is None else float(self.rms_px), "notes": list(self.notes)}

    @classmethod
    def from_json(cls, data: Any, *, file: str = "<data>") -> CameraIntrinsics:
        """A camera from its JSON values.

        Raises
        ------
        CalibrationError
            ``FILE: field 'camera_matrix': expected ...``: a field missing, of the wrong shape, or not finite.
        """
        if not isinstance(data, Mapping):
            raise CalibrationError(f"{file}: expected a JSON object with camera_matrix, dist_coeffs and image_size "
                                   f"(a camera file of `station calibrate camera`), got {type(data).__name__}")
        matrix = _numbers(data, "camera_matrix", file, "a 3x3 matrix of numbers [[fx, 0, cx], [0, fy, cy], "
                          "[0, 0, 1]]")
        if matrix.shape != (3, 3) or matrix[0, 0] <= 0 or matrix[1, 1] <= 0 or \
                not np.allclose(matrix[2], [0, 0, 1]):
            raise CalibrationError(f"{file}: field 'camera_matrix': expected a 3x3 matrix [[fx, 0, cx], [0, fy, "
                                   f"cy], [0, 0, 1]] with fx, fy > 0, got {matrix.tolist()!r:.120}")
        dist = _numbers(data, "dist_coeffs", file, "a list of 4, 5, 8, 12 or 14 numbers (k1 k2 p1 p2 [k3 ...])")
        dist = dist.ravel()
        if dist.size not in (4, 5, 8, 12, 14):
            raise CalibrationError(f"{file}: field 'dist_coeffs': expected 4, 5, 8, 12 or 14 numbers (k1 k2 p1 p2 "
                                   f"[k3 ...]), got {dist.size}")
        size = data.get("image_size")
        if not (isinstance(size, (list, tuple)) and len(size) == 2
                and all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in size)):
            raise CalibrationError(f"{file}: field 'image_size': expected [width, height] in whole pixels > 0, "
                                   f"got {size!r:.80}")
        rms = data.get("rms_px")
        if rms is not None and (isinstance(rms, bool) or not isinstance(rms, (int, float)) or not rms >= 0):
            raise CalibrationError(f"{file}: field 'rms_px': expected a number >= 0 or null, got {rms!r:.40}")
        name = data.get("name")
        if name is not None and not isinstance(name, str):
            raise CalibrationError(f"{file}: field 'name': expected a string or null, got {name!r:.40}")
        notes = data.get("notes") or []
        if not isinstance(notes, list) or not all(isinstance(n, str) for n in notes):
            raise CalibrationError(f"{file}: field 'notes': expected a list of strings, got {notes!r:.60}")
        return cls(matrix, dist, (int(size[0]), int(size[1])), None if rms is None else float(rms), name,
                   tuple(notes))

    @classmethod
    def guess(cls, image_size: Sequence[int]) -> CameraIntrinsics:
        """Uncalibrated intrinsics: f = the image's larger side (a ~53 degree view), centred, no distortion.

        Good enough to find tags; positions measured with it are off by the lens's true focal length and
        distortion, which the result's ``notes`` say.
        """
        width, height = (int(image_size[0]), int(image_size[1]))
        if width <= 0 or height <= 0:
            raise CalibrationError(f"image_size: expected (width, height) > 0, got {tuple(image_size)!r}")
        focal = float(max(width, height))
        matrix = np.array([[focal, 0.0, (width - 1) / 2.0], [0.0, focal, (height - 1) / 2.0], [0.0, 0.0, 1.0]])
        return cls(matrix, np.zeros(5), (width, height), None, None,
                   (f"not calibrated: f guessed as the image's larger side ({focal:g} px), no lens distortion; "
                    "run `station calibrate camera` for true measurements",))

    def check_image(self, image: np.ndarray, what: str = "image") -> None:
        """Refuse an image of another size than the intrinsics were solved for."""
        height, width = np.asarray(image).shape[:2]
        if (width, height) != tuple(self.image_size):
            raise CalibrationError(f"{what}: {width}x{height} pixels, but the camera intrinsics"
                                   f"{' ' + repr(self.name) if self.name else ''} are for {self.image_size[0]}x"
                                   f"{self.image_size[1]}; calibrate at this resolution or set the camera to it")


def _numbers(data: Mapping, key: str, file: str, expected: str) -> np.ndarray:
    if key not in data:
        raise CalibrationError(f"{file}: field {key!r} is missing; expected {expected}")
    try:
        values = np.array(data[key], dtype=float)
    except (TypeError, ValueError):
        raise CalibrationError(f"{file}: field {key!r}: expected {expected}, got {data[key]!r:.80}") from None
    if not np.all(np.isfinite(values)):
        raise CalibrationError(f"{file}: field {key!r}: expected finite numbers, got {data[key]!r:.80}")
    return values


def load_intrinsics(path: str | Path) -> CameraIntrinsics:
    """The camera file ``path`` (see the module notes); a bad or missing file is one :class:`CalibrationError`."""
    path = Path(path)
    expected = "a camera file of `station calibrate camera` (camera_matrix, dist_coeffs, image_size)"
    try:
        data = load_json(path, expected, error=lambda detail: CalibrationError(f"{path}: {detail}"))
    except OSError as error:
        raise CalibrationError(f"{path}: cannot read the camera file ({error.strerror or error})") from None
    intrinsics = CameraIntrinsics.from_json(data, file=str(path))
    return intrinsics if intrinsics.name else _renamed(intrinsics, path.stem)


def _renamed(intrinsics: CameraIntrinsics, name: str) -> CameraIntrinsics:
    from dataclasses import replace

    return replace(intrinsics, name=name)


def save_intrinsics(intrinsics: CameraIntrinsics, path: str | Path) -> None:
    """Write the camera file (the folder is made), through a temporary file so a failed write loses no old one."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + ".partial")
    partial.write_text(json.dumps(intrinsics.to_json(), indent=1) + "\n")
    partial.replace(path)


def to_gray(image: np.ndarray, what: str = "image") -> np.ndarray:
    """A uint8 grey image from a grey or RGB(A) uint8 array (RGB: the camera twin's and PIL's order)."""
    import cv2

    array = np.asarray(image)
    if array.dtype != np.uint8 or array.ndim not in (2, 3) or (array.ndim == 3 and array.shape[2] not in (1, 3, 4)):
        raise CalibrationError(f"{what}: expected an 8-bit grey or RGB image, got {array.dtype} {array.shape}")
    if array.ndim == 2:
        return array
    if array.shape[2] == 1:
        return array[:, :, 0]
    return cv2.cvtColor(array, cv2.COLOR_RGB2GRAY if array.shape[2] == 3 else cv2.COLOR_RGBA2GRAY)


@dataclass(frozen=True)
class ViewResult:
    """One view of the board: used (with its reprojection RMS) or skipped (and why)."""

    name: str
    corners: int
    rms_px: float | None = None
    skipped: str | None = None


@dataclass(frozen=True)
class CalibrationResult:
    """What :func:`calibrate_camera` found.

    Attributes
    ----------
    intrinsics : CameraIntrinsics
    views : tuple of ViewResult
        Every view given, in order.
    coverage : float
        The fraction of an 8 x 6 grid over the image in which some board corner was seen.
    uncovered_corners : tuple of str
        The image corners (``"top-left"``...) no view reached; k3 was fixed at 0 when any.
    k3_fixed : bool
    warnings : tuple of str
    """

    intrinsics: CameraIntrinsics
    views: tuple[ViewResult, ...]
    coverage: float
    uncovered_corners: tuple[str, ...]
    k3_fixed: bool
    warnings: tuple[str, ...]

    @property
    def used(self) -> tuple[ViewResult, ...]:
        return tuple(v for v in self.views if v.skipped is None)

    def to_dict(self) -> dict:
        """JSON values: the camera, the views, the coverage and the warnings."""
        return {"camera": self.intrinsics.to_json(), "rms_px": self.intrinsics.rms_px,
                "views": [{"name": v.name, "corners": v.corners, "rms_px": v.rms_px, "skipped": v.skipped}
                          for v in self.views],
                "coverage": self.coverage, "uncovered_corners": list(self.uncovered_corners),
                "k3_fixed": self.k3_fixed, "warnings": list(self.warnings)}


def corner_coverage(points: np.ndarray, image_size: Sequence[int]) -> tuple[float, tuple[str, ...]]:
    """The fraction of an 8 x 6 grid over the image holding a point, and the image corners holding too few."""
    width, height = image_size
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(points) == 0:
        return 0.0, CORNER_NAMES
    cells = np.zeros((6, 8), dtype=bool)
    col = np.clip((points[:, 0] / width * 8).astype(int), 0, 7)
    row = np.clip((points[:, 1] / height * 6).astype(int), 0, 5)
    cells[row, col] = True
    near_left = points[:, 0] < CORNER_REGION * width
    near_right = points[:, 0] > (1 - CORNER_REGION) * width
    near_top = points[:, 1] < CORNER_REGION * height
    near_bottom = points[:, 1] > (1 - CORNER_REGION) * height
    regions = (near_top & near_left, near_top & near_right, near_bottom & near_right, near_bottom & near_left)
    uncovered = tuple(name for name, inside in zip(CORNER_NAMES, regions) if int(inside.sum()) < CORNER_POINTS)
    return float(cells.mean()), uncovered


def calibrate_camera(views: Iterable[tuple[str, np.ndarray]], board=None, *, name: str | None = None,
                     min_corners: int = MIN_CORNERS, report: Reporter | None = None) -> CalibrationResult:
    """Solve a camera's intrinsics from views of a ChArUco board.

    Parameters
    ----------
    views : iterable of (str, ndarray)
        (name, image) pairs: grey or RGB uint8 images of one size (a file name or a capture number as the name).
    board : calibration.charuco.BoardSpec, optional
        The printed board (default: :class:`~calibration.charuco.BoardSpec`'s A4 board).
    name : str, optional
        The camera's name, kept in the result.
    min_corners : int
        Views with fewer board corners found are skipped (and said).
    report : Reporter, optional
        Progress per view (stage ``"detect"``), then ``"solve"``; asked between views whether to stop.

    Raises
    ------
    CalibrationError
        Views of different sizes, or fewer than :data:`MIN_VIEWS` usable views (naming how many corners each had).
    common.progress.Cancelled
        When a stop was asked for.
    """
    import cv2

    from calibration.charuco import BoardSpec, detect_charuco

    board = board or BoardSpec()
    report = Reporter.of(report)
    views = list(views)
    results: list[ViewResult] = []
    object_points, image_points, seen = [], [], []
    image_size: tuple[int, int] | None = None
    for index, (view_name, image) in enumerate(views):
        report("detect", index, len(views), f"board corners in {view_name}")
        gray = to_gray(image, str(view_name))
        size = (gray.shape[1], gray.shape[0])
        if image_size is None:
            image_size = size
        elif size != image_size:
            raise CalibrationError(f"{view_name}: {size[0]}x{size[1]} pixels, but the first view is "
                                   f"{image_size[0]}x{image_size[1]}; every view must come from the camera at one "
                                   "resolution")
        found = detect_charuco(gray, board)
        count = 0 if found is None else len(found.ids)
        if count < min_corners:
            results.append(ViewResult(str(view_name), count, skipped=f"{count} board corners found, "
                                      f"{min_corners} needed"))
            continue
        results.append(ViewResult(str(view_name), count))
        object_points.append(found.object_points.astype(np.float32))
        image_points.append(found.corners.astype(np.float32))
        seen.append(found.corners)
    report("detect", len(views), len(views), "board corners found")
    used = [i for i, r in enumerate(results) if r.skipped is None]
    if len(used) < MIN_VIEWS:
        counts = ", ".join(f"{r.name}: {r.corners}" for r in results) or "no views"
        raise CalibrationError(f"camera calibration: {len(used)} usable views of the board, {MIN_VIEWS} needed "
                               f"(each with >= {min_corners} corners; found {counts})")
    coverage, uncovered = corner_coverage(np.concatenate(seen), image_size)
    warnings = []
    flags = 0
    if uncovered:
        flags |= cv2.CALIB_FIX_K3
        warnings.append(f"no view reached the image's {', '.join(uncovered)} corner(s): the distortion there is "
                        "extrapolated, so k3 was fixed at 0; add views with the board in those corners")
    skipped = [r for r in results if r.skipped]
    if skipped:
        warnings.append(f"{len(skipped)} view(s) skipped: " + "; ".join(f"{r.name} ({r.skipped})" for r in skipped))
    report("solve", 0, 1, f"solving with {len(used)} views")
    rms, matrix, dist, _rvecs, _tvecs, _std_in, _std_ex, per_view = cv2.calibrateCameraExtended(
        object_points, image_points, image_size, None, None, flags=flags,
        criteria=(cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-10))
    report("solve", 1, 1, f"RMS {rms:.3f} px")
    per_view = np.asarray(per_view, dtype=float).ravel()
    for slot, index in enumerate(used):
        results[index] = ViewResult(results[index].name, results[index].corners, float(per_view[slot]))
    worst = max(results[i].rms_px for i in used)
    if worst > 3 * max(rms, 0.1):
        bad = [results[i].name for i in used if results[i].rms_px > 3 * max(rms, 0.1)]
        warnings.append(f"view(s) {', '.join(bad)} fit far worse than the rest (a blurred or moved board?): "
                        "consider removing them")
    notes = tuple(warnings)
    intrinsics = CameraIntrinsics(np.asarray(matrix, dtype=float), np.asarray(dist, dtype=float).ravel(),
                                  image_size, float(rms), name, notes)
    if not math.isfinite(rms):
        raise CalibrationError("camera calibration: the solver did not converge; take views at more angles")
    return CalibrationResult(intrinsics, tuple(results), coverage, uncovered, bool(uncovered), notes)
