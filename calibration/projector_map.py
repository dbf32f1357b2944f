"""Projector mapping: where each projector pixel lands on the guide plane, from camera images of Gray code stripes.

Why Gray code stripes (not a grid of AprilTags)
-----------------------------------------------
- Every camera pixel the projector lights gets its projector cell, so there are thousands of correspondences
  spread over the whole image (a tag grid gives a few dozen corners), and RANSAC can drop the cells that fell on
  something lying on the table.
- Each bit is read by comparing a pattern with its inverse, pixel by pixel: no global threshold, indifferent to
  the surface's colour, the room light, vignetting and a projector out of focus (its blur is symmetric, so a
  stripe's edge stays where it is). A tag must be projected sharp enough to decode, and the detector's corners
  carry its own biases (about 0.1 px on axis-aligned edges).
- In a Gray code two neighbouring cells differ in exactly one bit, so a pixel on a cell's edge is either
  ambiguous in that one bit (and dropped) or read as one of the two cells: never as a cell far away.

Stripes finer than the camera can resolve carry nothing; the finest stripe used is ``finest_px`` projector pixels
(8 by default: a cell of 8 x 8 projector pixels). Each cell seen whole gives one correspondence: the centroid of the
camera pixels read as that cell <-> the projector pixel at the cell's centre.

Coordinates
-----------
Pixels follow OpenCV (pixel (x, y) has its centre at (x, y)). The camera's plane is given as a 3x3 homography from
*undistorted* camera pixels (``cv2.undistortPoints`` with ``P = camera_matrix``) to guide-plane (u, v) mm at h = 0
(:class:`calibration.measure.PlaneFix.homography`). The result, ``plane_from_pixel``, maps projector pixels to
(u, v) mm: ``(u, v, 1) ~ H @ (x, y, 1)``, the convention of :meth:`drivers.sim.projector.SimulatedProjector.place`.

The saved file (one per projector)::

    {"plane_from_pixel": [[...], [...], [...]], "projector_size": [w, h],
     "landing_error_mm": {"p50": ..., "p95": ..., "max": ..., "check_points": n, "outliers": m},
     "cells": {"seen": n, "fitted": n, "inliers": n}, "finest_px": 8}
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calibration.errors import CalibrationError
from common.opencv import undistort_points

__all__ = ["CHECK_BLOCK", "CHECK_EVERY", "Correspondences", "GrayCodePlan", "ProjectorMap", "apply_homography",
           "camera_to_plane",
           "decode", "fit_projector_map", "load_projector_map", "map_projector", "save_projector_map"]

#: One block of cells in this many (along the blocks' diagonals) is a check point, kept out of the fit.
CHECK_EVERY = 5
#: A check point is a block of CHECK_BLOCK x CHECK_BLOCK cells seen whole: its pixels together locate it far better
#: than one cell's few, so the landing error measured there is the map's, not one cell's reading noise.
CHECK_BLOCK = 4


@dataclass(frozen=True)
class GrayCodePlan:
    """The patterns to project for a projector of ``projector_size`` (w, h), stripes down to ``finest_px``."""

    projector_size: tuple[int, int]
    finest_px: int = 8

    def __post_init__(self) -> None:
        width, height = (int(v) for v in self.projector_size)
        if width < 16 or height < 16 or not isinstance(self.finest_px, (int, np.integer)) or self.finest_px < 1 \
                or self.finest_px * 4 > min(width, height):
            raise CalibrationError(f"projector mapping: expected a projector of at least 16x16 pixels and finest_px "
                                   f"from 1 to a quarter of its height, got {self.projector_size!r} and "
                                   f"{self.finest_px!r}")
        object.__setattr__(self, "projector_size", (width, height))

    @property
    def cells(self) -> tuple[int, int]:
        """Cells across and down (the last ones may be cut by the image's edge)."""
        return tuple(math.ceil(n / self.finest_px) for n in self.projector_size)

    @property
    def bits(self) -> tuple[int, int]:
        """Gray code bits in x and in y."""
        return tuple(max(1, math.ceil(math.log2(n))) for n in self.cells)

    @property
    def names(self) -> list[str]:
        """The frames in order: ``white``, ``black``, then ``x7``, ``x7~`` (its inverse) ... ``y0~``."""
        names = ["white", "black"]
        for axis, count in zip("xy", self.bits, strict=True):
            for bit in range(count - 1, -1, -1):
                names += [f"{axis}{bit}", f"{axis}{bit}~"]
        return names

    def pattern(self, name: str) -> np.ndarray:
        """The frame ``name`` (one of :attr:`names`): a grey uint8 image of the projector's size."""
        width, height = self.projector_size
        if name in ("white", "black"):
            return np.full((height, width), 255 if name == "white" else 0, dtype=np.uint8)
        axis, bit, inverse = name[0], int(name[1:].rstrip("~")), name.endswith("~")
        length = width if axis == "x" else height
        cell = np.arange(length) // self.finest_px
        stripe = (((cell ^ (cell >> 1)) >> bit) & 1).astype(bool) ^ inverse
        line = np.where(stripe, 255, 0).astype(np.uint8)
        return np.broadcast_to(line[None, :] if axis == "x" else line[:, None], (height, width)).copy()

    def patterns(self) -> list[tuple[str, np.ndarray]]:
        """Every frame to project, in order, with its name."""
        return [(name, self.pattern(name)) for name in self.names]


@dataclass(frozen=True)
class Correspondences:
    """Cells seen whole: ``projector_px`` (n, 2) cell centres, ``camera_px`` (n, 2) the centroids of the camera
    pixels read as them (as seen, with the lens' distortion), ``cells`` (n, 2) their (column, row) and ``pixels``
    (n,) how many camera pixels each had."""

    projector_px: np.ndarray
    camera_px: np.ndarray
    cells: np.ndarray
    pixels: np.ndarray


def _grey(image: np.ndarray) -> np.ndarray:
    array = np.asarray(image)
    if array.ndim == 3 and array.shape[2] in (3, 4):
        array = array[..., :3].astype(np.float32).mean(axis=2)
    if array.ndim != 2:
        raise CalibrationError(f"projector mapping: expected camera images H x W or H x W x 3, got {array.shape}")
    return array.astype(np.float32)


def decode(plan: GrayCodePlan, images: Sequence[np.ndarray], *, min_contrast: float = 12.0,
           bit_margin: float = 0.25) -> Correspondences:
    """Correspondences from the camera's images of :meth:`GrayCodePlan.patterns` (same order).

    A pixel counts when the projector's white lights it ``min_contrast`` grey levels above its black, and every
    bit's pattern and inverse differ by at least ``bit_margin`` of that (else it sits on a stripe's edge). A cell
    counts when it is whole: enough pixels (half the median cell's), its four neighbours seen too (not cut by the
    edge of the light or by something on the table) and its pixels together (not scattered by misreadings).
    """
    names = plan.names
    if len(images) != len(names):
        raise CalibrationError(f"projector mapping: expected {len(names)} camera images ({', '.join(names[:4])}, "
                               f"...), got {len(images)}")
    white, black = _grey(images[0]), _grey(images[1])
    contrast = white - black
    valid = contrast >= min_contrast
    codes = []
    position = 2
    for count in plan.bits:
        gray = np.zeros(white.shape, dtype=np.int32)
        for _ in range(count):
            pattern, inverse = _grey(images[position]), _grey(images[position + 1])
            if pattern.shape != white.shape or inverse.shape != white.shape:
                raise CalibrationError(f"projector mapping: image {position + 1} ({names[position]}) is "
                                       f"{pattern.shape[1]}x{pattern.shape[0]}, not {white.shape[1]}x{white.shape[0]}")
            difference = pattern - inverse
            valid &= np.abs(difference) >= bit_margin * contrast
            gray = (gray << 1) | (difference > 0)
            position += 2
        codes.append(_binary(gray))
    columns, rows = plan.cells
    valid &= (codes[0] < columns) & (codes[1] < rows)
    ys, xs = np.nonzero(valid)
    cell_x, cell_y = codes[0][ys, xs], codes[1][ys, xs]
    index = cell_y * columns + cell_x
    size = columns * rows
    count = np.bincount(index, minlength=size).astype(float)
    sums = [np.bincount(index, weights=w, minlength=size) for w in (xs, ys, xs * xs.astype(float),
                                                                     ys * ys.astype(float))]
    seen = count > 0
    if not seen.any():
        raise CalibrationError("projector mapping: the camera saw no projected stripes (is the projector on and in "
                               "view, the room dark enough, the camera not over-exposed?)")
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_x, mean_y = sums[0] / count, sums[1] / count
        spread = sums[2] / count - mean_x ** 2 + sums[3] / count - mean_y ** 2
    typical = float(np.median(count[seen]))
    grid = (count >= 0.5 * typical).reshape(rows, columns)
    whole = grid.copy()
    whole[1:, :] &= grid[:-1, :]
    whole[:-1, :] &= grid[1:, :]
    whole[:, 1:] &= grid[:, :-1]
    whole[:, :-1] &= grid[:, 1:]
    whole[[0, -1], :] = False
    whole[:, [0, -1]] = False
    # a compact cell of n pixels has var_x + var_y ~ n / 6 (a square); scattered misreadings make it larger
    whole &= (spread <= count / 3.0 + 2.0).reshape(rows, columns)
    width, height = plan.projector_size
    edge = plan.finest_px
    cut = (np.arange(columns) + 1) * edge > width, (np.arange(rows) + 1) * edge > height
    whole[:, cut[0]] = False
    whole[cut[1], :] = False
    cell_rows, cell_columns = np.nonzero(whole)
    flat = cell_rows * columns + cell_columns
    projector = np.column_stack([(cell_columns + 0.5) * edge - 0.5, (cell_rows + 0.5) * edge - 0.5])
    return Correspondences(projector, np.column_stack([mean_x[flat], mean_y[flat]]),
                           np.column_stack([cell_columns, cell_rows]), count[flat].astype(int))


def _binary(gray: np.ndarray) -> np.ndarray:
    """Gray code to binary (up to 32 bits)."""
    value = gray.copy()
    for shift in (1, 2, 4, 8, 16):
        value ^= value >> shift
    return value


def apply_homography(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``matrix`` (3x3) applied to points (n, 2)."""
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    mapped = np.column_stack([points, np.ones(len(points))]) @ np.asarray(matrix, dtype=float).T
    return mapped[:, :2] / mapped[:, 2:3]


def camera_to_plane(camera_px: np.ndarray, plane_from_undistorted: np.ndarray, camera_matrix: np.ndarray,
                    dist_coeffs: np.ndarray | None) -> np.ndarray:
    """Plane (u, v) mm at h = 0 of camera pixels (n, 2) as seen: undistorted with the intrinsics, then through the
    plane homography."""
    import cv2

    matrix = _matrix(plane_from_undistorted, "plane_from_undistorted")
    camera_matrix = _matrix(camera_matrix, "camera_matrix")
    points = np.asarray(camera_px, dtype=np.float64).reshape(-1, 1, 2)
    if len(points) and dist_coeffs is not None and np.any(dist_coeffs):
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-9)
        points = undistort_points(points, camera_matrix, np.asarray(dist_coeffs, dtype=np.float64), None,
                                  camera_matrix, criteria)
    return apply_homography(matrix, points.reshape(-1, 2))


def _matrix(value, what: str) -> np.ndarray:
    matrix = np.asarray(value, dtype=float)
    if matrix.shape != (3, 3) or not np.isfinite(matrix).all() or abs(np.linalg.det(matrix)) < 1e-15:
        raise CalibrationError(f"projector mapping: {what}: expected an invertible 3x3 matrix, got shape "
                               f"{np.shape(value)}")
    return matrix


@dataclass(frozen=True)
class ProjectorMap:
    """Where a projector's pixels land: ``plane_from_pixel`` (3x3, projector pixel -> plane mm), the projector's
    ``projector_size`` (w, h), ``landing_error_mm`` at the check points (``p50``, ``p95``, ``max``,
    ``check_points``, ``outliers``: check points further than 3 x the RANSAC threshold, left out of the figures),
    ``cells`` (``seen``, ``fitted``, ``inliers``) and the pattern's ``finest_px``."""

    plane_from_pixel: np.ndarray
    projector_size: tuple[int, int]
    landing_error_mm: dict
    cells: dict
    finest_px: int = 8

    def plane_from(self, projector_px: np.ndarray) -> np.ndarray:
        """Plane (u, v) mm where projector pixels (n, 2) land."""
        return apply_homography(self.plane_from_pixel, projector_px)

    def pixel_from(self, plane_mm: np.ndarray) -> np.ndarray:
        """Projector pixels (n, 2) that land on plane points (n, 2) mm."""
        return apply_homography(np.linalg.inv(self.plane_from_pixel), plane_mm)

    def to_json(self) -> dict:
        return {"plane_from_pixel": np.asarray(self.plane_from_pixel, dtype=float).tolist(),
                "projector_size": list(self.projector_size), "landing_error_mm": dict(self.landing_error_mm),
                "cells": dict(self.cells), "finest_px": int(self.finest_px)}

    @classmethod
    def from_json(cls, data, *, file: str = "<data>") -> ProjectorMap:
        """From :meth:`to_json`'s dict; a :class:`CalibrationError` naming ``file`` and the field."""
        if not isinstance(data, dict):
            raise CalibrationError(f"{file}: expected a JSON object with plane_from_pixel, projector_size and "
                                   f"landing_error_mm, got {type(data).__name__}")
        try:
            matrix = _matrix(data["plane_from_pixel"], "plane_from_pixel")
        except (KeyError, TypeError, ValueError):
            raise CalibrationError(f"{file}: plane_from_pixel: expected an invertible 3x3 matrix of numbers "
                                   "[[...], [...], [...]]") from None
        size = data.get("projector_size")
        if not (isinstance(size, list) and len(size) == 2 and all(isinstance(v, int) and v > 0 for v in size)):
            raise CalibrationError(f"{file}: projector_size: expected [width, height] in pixels, got {size!r}")
        error = data.get("landing_error_mm")
        if not (isinstance(error, dict) and all(isinstance(error.get(k), (int, float)) for k in ("p50", "p95",
                                                                                                  "max"))):
            raise CalibrationError(f"{file}: landing_error_mm: expected {{\"p50\": mm, \"p95\": mm, \"max\": mm}}, "
                                   f"got {error!r}")
        finest = data.get("finest_px", 8)
        return cls(matrix, (size[0], size[1]), dict(error), dict(data.get("cells") or {}),
                   int(finest) if isinstance(finest, int) else 8)


def fit_projector_map(correspondences: Correspondences, plane_mm: np.ndarray, projector_size: tuple[int, int], *,
                      ransac_mm: float = 1.0, finest_px: int = 8) -> ProjectorMap:
    """Fit ``plane_from_pixel`` (``cv2.findHomography``, RANSAC at ``ransac_mm``, then least squares on the
    inliers) to the cells' projector pixels and their plane points (n, 2) mm.

    The cells are grouped in blocks of :data:`CHECK_BLOCK` x :data:`CHECK_BLOCK`; one block in :data:`CHECK_EVERY`
    (on diagonals, so spread over the whole image) stays out of the fit. Each such block seen whole is a check
    point: its cells' pixel-weighted mean plane point against the fit at their pixel-weighted mean projector pixel
    (the two means correspond to first order, the weights being the same pixels).
    """
    import cv2

    projector = np.asarray(correspondences.projector_px, dtype=float)
    plane = np.asarray(plane_mm, dtype=float).reshape(-1, 2)
    blocks = np.asarray(correspondences.cells) // CHECK_BLOCK
    check = (blocks.sum(axis=1) % CHECK_EVERY) == 0
    block_ids, block_index = np.unique(blocks[check], axis=0, return_inverse=True)
    block_index = block_index.ravel()
    weights = np.asarray(correspondences.pixels, dtype=float)[check]
    whole = np.bincount(block_index, minlength=len(block_ids)) == CHECK_BLOCK ** 2
    if (~check).sum() < 8 or whole.sum() < 4:
        raise CalibrationError(f"projector mapping: only {len(projector)} whole projector cells were seen, too few "
                               "to fit and check (is the projector's light in the camera's view, and its stripes "
                               "no finer than the camera can see?)")
    matrix, mask = cv2.findHomography(projector[~check], plane[~check], cv2.RANSAC, float(ransac_mm),
                                      maxIters=5000, confidence=0.9999)
    if matrix is None or mask is None or int(mask.sum()) < 8:
        raise CalibrationError("projector mapping: no projector-to-plane homography fits the cells seen (the "
                               "stripes were misread, or the light fell on something that is not flat)")
    inliers = mask.ravel().astype(bool)
    matrix, _ = cv2.findHomography(projector[~check][inliers], plane[~check][inliers], 0)  # least squares

    def weighted_mean(points: np.ndarray) -> np.ndarray:
        total = np.bincount(block_index, weights=weights)
        return np.column_stack([np.bincount(block_index, weights=weights * points[:, i]) / total for i in (0, 1)])

    at_pixel, seen_at = weighted_mean(projector[check])[whole], weighted_mean(plane[check])[whole]
    errors = np.linalg.norm(apply_homography(matrix, at_pixel) - seen_at, axis=1)
    kept = errors <= 3.0 * ransac_mm
    figures = errors[kept] if kept.any() else errors
    landing = {"p50": round(float(np.percentile(figures, 50)), 4), "p95": round(float(np.percentile(figures, 95)), 4),
               "max": round(float(figures.max()), 4), "check_points": int(whole.sum()),
               "outliers": int((~kept).sum())}
    return ProjectorMap(matrix / matrix[2, 2], tuple(int(v) for v in projector_size), landing,
                        {"seen": int(len(projector)), "fitted": int((~check).sum()), "inliers": int(inliers.sum())},
                        int(finest_px))


def map_projector(plan: GrayCodePlan, images: Sequence[np.ndarray], plane_from_undistorted: np.ndarray,
                  camera_matrix: np.ndarray, dist_coeffs: np.ndarray | None, *, ransac_mm: float = 1.0,
                  min_contrast: float = 12.0) -> ProjectorMap:
    """The whole mapping from the camera's images of ``plan``'s patterns: decode, camera to plane, fit."""
    found = decode(plan, images, min_contrast=min_contrast)
    plane = camera_to_plane(found.camera_px, plane_from_undistorted, camera_matrix, dist_coeffs)
    return fit_projector_map(found, plane, plan.projector_size, ransac_mm=ransac_mm, finest_px=plan.finest_px)


def save_projector_map(projector_map: ProjectorMap, path: str | Path, *, extra: dict | None = None) -> None:
    """Write the map as JSON (via a ``.partial`` file, so a crash never leaves half a file), with the fields of
    ``extra`` beside it (what it was measured on; :meth:`ProjectorMap.from_json` reads past them)."""
    path = Path(path)
    partial = path.with_name(path.name + ".partial")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        partial.write_text(json.dumps({**(extra or {}), **projector_map.to_json()}, indent=1) + "\n",
                           encoding="utf-8")
        partial.replace(path)
    except OSError as error:
        raise CalibrationError(f"{path}: cannot write the projector map ({error.strerror or error})") from None


def load_projector_map(path: str | Path) -> ProjectorMap:
    """Read a map :func:`save_projector_map` wrote (CalibrationError naming the file and the field)."""
    from common.datafiles import load_json

    path = Path(path)
    try:
        data = load_json(path, "a projector map (`station calibrate projector` writes it)", error=CalibrationError)
    except OSError as error:
        raise CalibrationError(f"{path}: cannot read the projector map ({error.strerror or error})") from None
    return ProjectorMap.from_json(data, file=str(path))
