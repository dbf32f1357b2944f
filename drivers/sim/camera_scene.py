"""What a simulated camera looks at: its lens and pose over the guide plane, and a plain description of what lies on
the plane (tags, pictures, occluders, the projector's light). Plain data: no import of ``design`` or ``projector``;
the station hands the twin these objects.

Coordinates
-----------
The guide plane's frame: (u, v) millimetres as the maker sees the plane, ``h`` millimetres above it (towards the
camera); (u, v, h) is right-handed. A camera's pose is OpenCV's ``(rvec, tvec)``: ``x_cam = R @ [u, v, h] + t``.
Pixels follow OpenCV: pixel (x, y) has its centre at integer (x, y), x right, y down.

A tag's size is the edge of its black square (its white border, one cell of the ten across, is drawn around it); its
heading is the direction of its printed "up", counter-clockwise as the maker sees the plane, 0 = +v. Its corners are
listed [lower-left, lower-right, upper-right, upper-left] as printed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from drivers.errors import SimConfigError

__all__ = ["CameraModel", "ImageItem", "Occluder", "PlaneScene", "RenderOptions", "Solid", "TagItem", "TagTruth",
           "tag_corners_mm"]


def _array(value, shape: tuple[int, ...], what: str) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.shape != shape or not np.isfinite(array).all():
        raise SimConfigError(f"camera model: {what}: expected finite numbers of shape {shape}, "
                             f"got {np.shape(value)}")
    array = array.copy()
    array.flags.writeable = False
    return array


@dataclass(frozen=True)
class CameraModel:
    """Intrinsics and pose of a (simulated) camera over the guide plane.

    Parameters
    ----------
    camera_matrix : ndarray
        3x3 OpenCV camera matrix.
    dist_coeffs : ndarray
        ``(5,)`` OpenCV distortion ``k1 k2 p1 p2 k3``.
    image_size : tuple of int
        ``(width, height)`` in pixels.
    rvec, tvec : ndarray
        ``(3,)`` pose, plane mm -> camera (Rodrigues vector, translation in mm).
    """

    camera_matrix: np.ndarray
    dist_coeffs: np.ndarray
    image_size: tuple[int, int]
    rvec: np.ndarray
    tvec: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "camera_matrix", _array(self.camera_matrix, (3, 3), "camera_matrix"))
        dist = np.zeros(5) if self.dist_coeffs is None else np.asarray(self.dist_coeffs, dtype=float).ravel()
        if dist.size < 5:
            dist = np.concatenate([dist, np.zeros(5 - dist.size)])
        object.__setattr__(self, "dist_coeffs", _array(dist[:5], (5,), "dist_coeffs"))
        object.__setattr__(self, "rvec", _array(np.ravel(self.rvec), (3,), "rvec"))
        object.__setattr__(self, "tvec", _array(np.ravel(self.tvec), (3,), "tvec"))
        width, height = (int(v) for v in self.image_size)
        if width < 1 or height < 1:
            raise SimConfigError(f"camera model: image_size: expected (width, height) >= 1, got {self.image_size!r}")
        object.__setattr__(self, "image_size", (width, height))

    @classmethod
    def looking_down(cls, target_mm=(0.0, 0.0), height_mm: float = 1000.0, image_size=(1920, 1080),
                     focal_px: float = 1400.0, dist_coeffs=None, tilt_deg: float = 0.0,
                     roll_deg: float = 0.0) -> CameraModel:
        """A camera ``height_mm`` above the plane whose optical axis goes through ``target_mm`` (on the plane).

        Untilted, it sits straight above the target and the image shows the plane as the maker sees it (image x
        along +u, image y along -v). ``tilt_deg`` moves it back towards -v at the same height, still aiming at the
        target (the view of a camera on a stand in front of the table); ``roll_deg`` turns the image about the optical
        axis. The principal point is the image centre ((w - 1) / 2, (h - 1) / 2).
        """
        if not height_mm > 0 or not focal_px > 0 or not -80.0 <= tilt_deg <= 80.0:
            raise SimConfigError(f"looking_down: expected height_mm > 0, focal_px > 0 and |tilt_deg| <= 80, got "
                             f"{height_mm!r}, {focal_px!r}, {tilt_deg!r}")
        import cv2

        width, height = (int(v) for v in image_size)
        target = np.array([float(target_mm[0]), float(target_mm[1]), 0.0])
        centre = target + np.array([0.0, -height_mm * math.tan(math.radians(tilt_deg)), height_mm])
        z_axis = (target - centre) / np.linalg.norm(target - centre)
        hint = np.array([0.0, -1.0, 0.0])  # image y runs along -v (the far edge of the table at the top)
        y_axis = hint - hint.dot(z_axis) * z_axis
        y_axis /= np.linalg.norm(y_axis)
        x_axis = np.cross(y_axis, z_axis)
        roll = math.radians(roll_deg)
        x_axis, y_axis = (math.cos(roll) * x_axis + math.sin(roll) * y_axis,
                          -math.sin(roll) * x_axis + math.cos(roll) * y_axis)
        rotation = np.stack([x_axis, y_axis, z_axis])
        rvec, _ = cv2.Rodrigues(rotation)
        matrix = np.array([[focal_px, 0.0, (width - 1) / 2.0], [0.0, focal_px, (height - 1) / 2.0],
                           [0.0, 0.0, 1.0]])
        return cls(matrix, np.zeros(5) if dist_coeffs is None else dist_coeffs, (width, height), rvec.ravel(),
                   -rotation @ centre)

    @property
    def rotation(self) -> np.ndarray:
        """The 3x3 rotation matrix of :attr:`rvec`."""
        import cv2

        return cv2.Rodrigues(self.rvec)[0]

    @property
    def centre_mm(self) -> np.ndarray:
        """The camera centre in (u, v, h) mm."""
        return -self.rotation.T @ self.tvec

    def project(self, points_uvh_mm) -> np.ndarray:
        """Pixels ``(n, 2)`` of plane points ``(n, 3)`` (u, v, h) mm, or ``(n, 2)`` (u, v) at h = 0, through the
        lens model (``cv2.projectPoints``)."""
        import cv2

        points = np.asarray(points_uvh_mm, dtype=float).reshape(-1, np.shape(points_uvh_mm)[-1])
        if points.shape[1] == 2:
            points = np.column_stack([points, np.zeros(len(points))])
        if points.shape[1] != 3:
            raise SimConfigError(f"project: expected points of shape (n, 3) or (n, 2), "
                                 f"got {np.shape(points_uvh_mm)}")
        if not len(points):
            return np.zeros((0, 2))
        pixels, _ = cv2.projectPoints(points, self.rvec, self.tvec, self.camera_matrix, self.dist_coeffs)
        return pixels.reshape(-1, 2)

    def depth(self, points_uvh_mm) -> np.ndarray:
        """Each point's depth along the optical axis in mm (> 0: in front of the camera)."""
        points = np.asarray(points_uvh_mm, dtype=float).reshape(-1, 3)
        return points @ self.rotation[2] + self.tvec[2]


@dataclass(frozen=True)
class TagItem:
    """A printed AprilTag lying on the plane, or on a part's face parallel to it at ``height_mm``."""

    tag_id: int
    center_mm: tuple[float, float]
    size_mm: float
    heading_deg: float = 0.0
    height_mm: float = 0.0
    family: str = "tag36h11"


@dataclass(frozen=True)
class ImageItem:
    """A printed picture (a ChArUco board, a guide sheet, a part's top face) lying flat at ``height_mm``.

    ``image`` is uint8 ``H x W`` or ``H x W x 3`` RGB, row 0 the top of the picture; ``corners_mm`` ``(4, 2)`` are
    the plane (u, v) of its top-left, top-right, bottom-right and bottom-left corners (the outer edges of the corner
    pixels).
    """

    image: np.ndarray
    corners_mm: np.ndarray
    height_mm: float = 0.0


@dataclass(frozen=True)
class Occluder:
    """Something opaque (a hand, a part's body): a flat polygon ``(n, 2)`` in plane mm at ``height_mm``, hiding what
    lies under it as seen from the camera. A tag at the same height lies on it (a part's top face with its tag)."""

    polygon_mm: np.ndarray
    height_mm: float = 0.0
    color: tuple[int, int, int] = (90, 70, 60)


@dataclass(frozen=True)
class Solid:
    """Something opaque with depth (a part's body, a jig's plate): convex ``pieces``, each the hull of its points
    ``(n, 3)`` in (u, v, h) mm. The renderer draws what it hides as the camera's own centre sees it, in perspective
    (a body standing 100 mm in front of the plane hides another patch of it than its footprint): a flat item at a
    height inside a piece is hidden by the piece's part nearer the camera and hides the part behind it. What lies
    below the plane (h < 0) is behind it and not drawn."""

    pieces: tuple[np.ndarray, ...]
    color: tuple[int, int, int] = (120, 124, 132)


@dataclass(frozen=True)
class PlaneScene:
    """Everything on the plane. ``light`` is :meth:`drivers.sim.projector.SimulatedProjector.light` (with its
    ``plane_from_pixel`` set) or None; ``background`` the plane's own colour (RGB)."""

    tags: tuple[TagItem, ...] = ()
    images: tuple[ImageItem, ...] = ()
    occluders: tuple[Occluder, ...] = ()
    light: dict | None = field(default=None, compare=False)
    background: tuple[int, int, int] = (200, 200, 195)
    solids: tuple[Solid, ...] = ()


@dataclass(frozen=True)
class RenderOptions:
    """How the picture is degraded after the exact geometry: ``blur_px`` (Gaussian sigma, pixels), ``noise``
    (Gaussian sigma, grey levels), ``vignetting`` (0..1 darkening at the image corners), ``jpeg_quality`` (None: no
    compression), ``exposure`` (a gain on the light), ``supersample`` (samples per pixel along each axis), ``seed``
    (the noise's)."""

    blur_px: float = 0.0
    noise: float = 0.0
    vignetting: float = 0.0
    jpeg_quality: int | None = None
    exposure: float = 1.0
    supersample: int = 3
    seed: int = 0


@dataclass(frozen=True)
class TagTruth:
    """Ground truth of one tag of the scene.

    ``corners_px`` ``(4, 2)`` are its black square's corners in the image (OpenCV pixel centres), [lower-left,
    lower-right, upper-right, upper-left] as printed; ``center_px`` its centre's image; ``visible`` whether the whole
    tag with its white border is inside the image and no part of it is hidden by an occluder or a higher item.
    """

    tag_id: int
    center_mm: tuple[float, float]
    heading_deg: float
    height_mm: float
    size_mm: float
    corners_px: np.ndarray
    center_px: np.ndarray
    visible: bool


def tag_corners_mm(tag: TagItem, scale: float = 1.0) -> np.ndarray:
    """The plane (u, v) ``(4, 2)`` of a tag's black square corners [lower-left, lower-right, upper-right,
    upper-left] as printed (``scale`` 10/8 gives its white border's outer corners)."""
    theta = math.radians(tag.heading_deg)
    right = np.array([math.cos(theta), math.sin(theta)])
    up = np.array([-math.sin(theta), math.cos(theta)])
    half = 0.5 * float(tag.size_mm) * scale
    centre = np.asarray(tag.center_mm, dtype=float)
    return np.array([centre + half * (sx * right + sy * up) for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
