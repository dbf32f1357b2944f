"""Calibration as a service: the ChArUco board PDF, a camera's intrinsics, the plane check from one frame.

Used by ``station calibrate`` and the Calibrate screen. The work is :mod:`calibration` (pure: images in, numbers
out); this module reads images from a folder or grabs them from a camera, and keeps the results in the station's
data folder (:func:`station.paths.data_dir`):

- ``calibration/cameras/<name>.json``: a camera's intrinsics (OpenCV's names, :mod:`calibration.intrinsics`);
- ``calibration/planes/<name>.json``: the camera's last plane fix, so that the next check says whether the camera
  (or the sheet) moved since.

A camera's name is its device name in the station's config (``station devices``), ``camera`` by default.
"""

from __future__ import annotations

import json
import re
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calibration.charuco import BoardSpec, write_board_pdf
from calibration.errors import CalibrationError
from calibration.intrinsics import CameraIntrinsics, load_intrinsics, save_intrinsics, to_gray
from calibration.intrinsics import calibrate_camera as solve
from calibration.measure import Measurement, PlaneFix, measure, sort_ids
from common.progress import Reporter
from drivers.devices import resolve
from station.config import configured_devices
from station.errors import ServiceError, station_errors
from station.paths import data_dir
from station.services.guide_manifest import read_manifest, reference_tags
from station.services.images import check_frame_size, check_image_file
from vision.detection import detect_tags

__all__ = ["IMAGE_SUFFIXES", "CameraCalibration", "PlaneCheck", "calibrate_camera", "camera_file", "camera_summary",
           "capture_views", "check_name", "grab_frame", "intrinsics_for", "plane_check", "plane_summary",
           "read_views", "reference_tags_from_guide", "write_board"]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
DEFAULT_CAMERA = "camera"
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


@station_errors
def check_name(name: str) -> str:
    """A camera name usable as a file name (letters, digits, ``_ . -``), or a :class:`ServiceError`."""
    if not isinstance(name, str) or not _NAME.match(name):
        raise ServiceError(f"name must be 1-64 letters, digits, '_', '.' or '-' (a file name), got {name!r}",
                           field="name", value=name)
    return name


def _folder(kind: str) -> Path:
    folder = data_dir() / "calibration" / kind
    folder.mkdir(parents=True, exist_ok=True)
    return folder


@station_errors
def camera_file(name: str = DEFAULT_CAMERA) -> Path:
    """Where the intrinsics of camera ``name`` are kept."""
    return _folder("cameras") / f"{check_name(name)}.json"


def _plane_file(name: str) -> Path:
    return _folder("planes") / f"{check_name(name)}.json"


@station_errors
def write_board(path: str | Path, paper: str = "a4"):
    """Write the default ChArUco board (:class:`calibration.charuco.BoardSpec`) as a 1:1 PDF; the spec written."""
    spec = BoardSpec()
    try:
        write_board_pdf(path, spec, paper)
    except CalibrationError as error:
        raise ServiceError(str(error), field="paper" if "paper" in str(error) else "pdf") from None
    return spec


def _read_image(path: Path, field: str = "images") -> np.ndarray:
    import cv2  # heavy: cv2

    if not path.is_file():
        raise ServiceError(f"{field}: no such file: {path}", field=field, value=str(path))
    check_image_file(path, field)  # from the header: a huge image is refused before it is decoded
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise ServiceError(f"{field}: {path} is not an image OpenCV can read (expected {', '.join(IMAGE_SUFFIXES)})",
                           field=field, value=str(path))
    check_frame_size(path, (image.shape[1], image.shape[0]), field)
    return image


@station_errors
def read_views(folder: str | Path) -> list[tuple[str, np.ndarray]]:
    """The images in ``folder`` (by name), grey, as (file name, image) pairs."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ServiceError(f"images: {folder} is not a folder (expected a folder of board images)",
                           field="images", value=str(folder))
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file())
    if not files:
        raise ServiceError(f"images: no images in {folder} (expected files ending in {', '.join(IMAGE_SUFFIXES)})",
                           field="images", value=str(folder))
    return [(p.name, _read_image(p)) for p in files]


@station_errors
def open_camera(url: str):
    info = resolve(url)
    if info.kind != "camera" or not info.available:
        raise ServiceError(f"camera: {url!r} is not a camera the station can drive ({info.kind}"
                           f"{'' if info.available else ', no driver'})", field="camera", value=url)
    camera = info.factory(info.url)
    camera.open()
    return camera


@station_errors
def configured_camera_url() -> tuple[str, str]:
    """(name, url) of the station's first camera (``station devices``; ``sim://camera`` by default)."""
    device = next((d for d in configured_devices() if d.kind == "camera"), None)
    if device is None:
        raise ServiceError("camera: no camera configured (add one to station.toml, or give a camera URL)",
                           field="camera")
    return device.name, device.url


@station_errors
def capture_views(url: str, count: int, *, interval_s: float = 1.0, report: Reporter | None = None,
                  sleep: Callable[[float], None] = time.sleep,
                  before: Callable[[object, int], None] | None = None) -> list[tuple[str, np.ndarray]]:
    """Grab ``count`` frames from the camera at ``url``, ``interval_s`` apart (time to move the board).

    ``before(camera, index)`` runs before each grab (a simulated camera's scene may be moved there).
    """
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise ServiceError(f"capture must be a whole number of views >= 1, got {count!r}", field="capture",
                           value=count)
    report = Reporter.of(report)
    camera = open_camera(url)
    views = []
    try:
        for index in range(count):
            report("capture", index, count, f"view {index + 1} of {count}: move the board, hold still")
            if index and interval_s > 0:
                waited = 0.0
                while waited < interval_s:  # short naps, so that a cancel is honoured at once
                    sleep(min(0.1, interval_s - waited))
                    waited += 0.1
                    report.check()
            if before is not None:
                before(camera, index)
            views.append((f"capture-{index + 1:02d}", np.asarray(camera.grab())))
        report("capture", count, count, f"{count} views captured")
    finally:
        camera.close()
    return views


@station_errors
@dataclass(frozen=True)
class CameraCalibration:
    """A camera calibrated: the result (:class:`calibration.intrinsics.CalibrationResult`) and where it was saved."""

    result: object
    path: Path | None

    def to_dict(self) -> dict:
        return {**self.result.to_dict(), "saved": None if self.path is None else str(self.path)}


@dataclass(frozen=True)
class CameraCalibrationRequest:
    """Which views :func:`calibrate_camera` solves, and where the calibration goes: a folder of board ``images``,
    or ``capture`` frames grabbed from ``camera`` (a URL; default the station's camera) every ``interval_s``
    seconds; saved as ``name`` to ``out`` (default ``calibration/cameras/<name>.json``)."""

    images: str | Path | None = None
    capture: int | None = None
    camera: str | None = None
    name: str | None = None
    out: str | Path | None = None
    interval_s: float = 1.0


@station_errors
def calibrate_camera(request: CameraCalibrationRequest, *, report: Reporter | None = None,
                     before: Callable[[object, int], None] | None = None) -> CameraCalibration:
    """Calibrate a camera from the views ``request`` names, and save it.
    ``before(camera, index)`` runs before each grab (a simulated camera's board may be moved there).

    Raises
    ------
    ServiceError
        Neither or both of ``images`` and ``capture``; a bad folder, name or count; too few usable views.
    """
    images, capture, camera, name, out = request.images, request.capture, request.camera, request.name, request.out
    if (images is None) == (capture is None):
        raise ServiceError("images or capture: give exactly one (a folder of board images, or N views to grab)",
                           field="images")
    report = Reporter.of(report)
    if images is not None:
        views = read_views(images)
        name = check_name(name or DEFAULT_CAMERA)
    else:
        default_name, url = configured_camera_url() if camera is None else (DEFAULT_CAMERA, camera)
        name = check_name(name or default_name)
        views = capture_views(url, capture, interval_s=request.interval_s, report=report, before=before)
    try:
        result = solve(views, name=name, report=report)
    except CalibrationError as error:
        raise ServiceError(str(error), field="images" if images is not None else "capture") from None
    path = Path(out) if out is not None else camera_file(name)
    save_intrinsics(result.intrinsics, path)
    return CameraCalibration(result, path)


@station_errors
def intrinsics_for(image_size: tuple[int, int], *, intrinsics: str | Path | None = None,
                   name: str = DEFAULT_CAMERA):
    """The camera's intrinsics: ``intrinsics`` (a file), else the saved ``calibration/cameras/<name>.json``, else a
    guess (:meth:`CameraIntrinsics.guess`, whose ``notes`` say so). A file for another image size is refused."""
    path = Path(intrinsics) if intrinsics is not None else camera_file(name)
    if intrinsics is None and not path.exists():
        return CameraIntrinsics.guess(image_size)
    loaded = load_intrinsics(path)
    if tuple(loaded.image_size) != tuple(image_size):
        raise ServiceError(f"intrinsics: {path} is for {loaded.image_size[0]}x{loaded.image_size[1]} images, the "
                           f"frame is {image_size[0]}x{image_size[1]}; calibrate the camera at this resolution",
                           field="intrinsics", value=str(path))
    return loaded


@station_errors
def reference_tags_from_guide(path: str | Path) -> list[tuple[int, tuple[float, float], float]]:
    """The reference tags of a guide manifest (what ``station guide --json`` prints) as (id, (u, v), size), read by
    :func:`station.services.guide_manifest.read_manifest` (the check's reader too)."""
    return reference_tags(read_manifest(path, parts=False))


@station_errors
@dataclass(frozen=True)
class PlaneCheck:
    """One frame's plane check: the measurement, the intrinsics used, where the frame came from."""

    measurement: object
    intrinsics: object
    source: str
    camera: str
    reference_ids: tuple[int, ...]
    guide: str | None = None

    def to_dict(self) -> dict:
        m = self.measurement
        return {"source": self.source, "camera": self.camera, "guide": self.guide,
                "intrinsics": {"name": self.intrinsics.name, "rms_px": self.intrinsics.rms_px,
                               "notes": list(self.intrinsics.notes)},
                "plane": None if m.plane is None else m.plane.to_dict(),
                "reference_ids": list(self.reference_ids),
                "missing_reference_ids": list(m.missing_reference_ids), "unknown_ids": list(m.unknown_ids),
                "duplicate_ids": list(m.duplicate_ids)}


@station_errors
def grab_frame(url: str) -> np.ndarray:
    """One frame from the camera at ``url``."""
    camera = open_camera(url)
    try:
        return np.asarray(camera.grab())
    finally:
        camera.close()


@station_errors
def plane_check(*, image: str | Path | np.ndarray | None = None, camera: str | None = None,
                guide: str | Path | None = None, intrinsics: str | Path | None = None, name: str | None = None,
                remember: bool = True) -> PlaneCheck:
    """Find the plane in one frame (a file or array ``image``, or grabbed from ``camera``; default the station's
    camera) through the reference tags of ``guide`` (a manifest). Without a guide the tags' positions are unknown:
    only which reference tags (ids 583-586) the camera sees is checked, and no plane is solved.

    The fix is remembered per camera; the next check reports how far the plane moved (``moved_mm``).
    """
    from projector.guide import REFERENCE_TAG_IDS  # heavy: shapely

    if image is not None and camera is not None:
        raise ServiceError("image or camera: give one, not both", field="image")
    if image is None:
        default_name, url = configured_camera_url() if camera is None else (DEFAULT_CAMERA, camera)
        name = check_name(name or default_name)
        frame, source = grab_frame(url), url
    elif isinstance(image, np.ndarray):
        frame, source, name = image, "<frame>", check_name(name or DEFAULT_CAMERA)
    else:
        frame, source, name = _read_image(Path(image), "image"), str(image), check_name(name or DEFAULT_CAMERA)
    size = (frame.shape[1], frame.shape[0])
    camera_model = intrinsics_for(size, intrinsics=intrinsics, name=name)
    references = reference_tags_from_guide(guide) if guide is not None else None
    previous = load_plane(name) if references is not None else None
    try:
        if references is None:
            result = _references_seen(frame, camera_model)
        else:
            result = measure(frame, camera_model, references, {}, previous)
    except CalibrationError as error:
        raise ServiceError(str(error), field="image") from None
    if remember and result.plane is not None:
        save_plane(name, result.plane)
    ids = tuple(i for i, _c, _s in references) if references is not None else REFERENCE_TAG_IDS
    return PlaneCheck(result, camera_model, source, name, tuple(ids), None if guide is None else str(guide))


def _references_seen(frame: np.ndarray, camera_model):
    """A measurement without a plane: which of the reference ids 583-586 are seen (once, twice, not at all)."""
    from projector.guide import REFERENCE_TAG_IDS  # heavy: shapely

    camera_model.check_image(frame)
    _unique, unknown, duplicates, missing = sort_ids(detect_tags(to_gray(frame)), REFERENCE_TAG_IDS, ())
    return Measurement(None, (), unknown, duplicates, missing)


@station_errors
def save_plane(name: str, plane) -> None:
    data = {**plane.to_dict(), "homography": np.asarray(plane.homography, dtype=float).tolist()}
    path = _plane_file(name)
    partial = path.with_name(path.name + ".partial")
    partial.write_text(json.dumps(data) + "\n")
    partial.replace(path)


@station_errors
def load_plane(name: str):
    """The last plane fix of camera ``name``, or None (none yet, or a file that no longer reads: start afresh)."""
    path = _plane_file(name)
    try:
        data = json.loads(path.read_text())
        return PlaneFix(np.array(data["rvec"], dtype=float), np.array(data["tvec"], dtype=float),
                        np.array(data["homography"], dtype=float).reshape(3, 3), float(data["residual_mm"]),
                        tuple(int(i) for i in data["reference_ids"]))
    except (OSError, ValueError, KeyError, TypeError):
        return None


@station_errors
def camera_summary(result, views: bool = True) -> list[str]:
    """A calibration result in lines: the camera, each view (unless ``views`` is False), the coverage and the
    warnings."""
    cam = result.intrinsics
    k = cam.camera_matrix
    lines = [f"{cam.name or 'camera'}: {cam.image_size[0]}x{cam.image_size[1]}, fx {k[0, 0]:.1f} fy {k[1, 1]:.1f} px, "
             f"centre ({k[0, 2]:.1f}, {k[1, 2]:.1f}), RMS {cam.rms_px:.3f} px over {len(result.used)} views",
             "  distortion k1 k2 p1 p2 k3: " + " ".join(f"{v:+.4f}" for v in cam.dist_coeffs[:5]),
             f"  coverage {result.coverage:.0%} of the image"
             + (f"; corners without views: {', '.join(result.uncovered_corners)} (k3 fixed at 0)"
                if result.uncovered_corners else "; all four corners covered")]
    for view in result.views if views else ():
        state = f"RMS {view.rms_px:.3f} px" if view.skipped is None else f"skipped: {view.skipped}"
        lines.append(f"  {view.name:28s} {view.corners:3d} corners  {state}")
    lines += [f"  warning: {w}" for w in result.warnings]
    return lines


@station_errors
def plane_summary(check) -> list[str]:
    """A plane check in lines."""
    m = check.measurement
    lines = [f"frame from {check.source}; intrinsics: "
             + (f"{check.intrinsics.name} (RMS {check.intrinsics.rms_px:.3f} px)" if check.intrinsics.rms_px
                is not None else "; ".join(check.intrinsics.notes) or "given")]
    if m.plane is None:
        seen = [i for i in check.reference_ids if i not in m.missing_reference_ids and i not in m.duplicate_ids]
        if check.guide is None:
            lines.append(f"reference tags seen: {seen or 'none'}; no plane solved: give --guide GUIDE.json (the "
                         "manifest of `station guide --json`) for their positions")
        else:
            lines.append(f"no plane: {len(seen)} reference tag(s) seen once, at least 2 needed")
    else:
        plane = m.plane
        moved = ("" if plane.moved_mm is None else f"; moved {plane.moved_mm:.2f} mm since the last check"
                 + (" (the camera or the sheet moved)" if plane.moved_mm > 1.0 else ""))
        lines.append(f"plane from reference tags {list(plane.reference_ids)}: residual {plane.residual_mm:.3f} mm, "
                     f"camera {plane.camera_centre_mm[2]:.0f} mm above it{moved}")
    if m.missing_reference_ids:
        lines.append(f"missing reference tags: {list(m.missing_reference_ids)}")
    if m.duplicate_ids:
        lines.append(f"tags seen twice (not used): {list(m.duplicate_ids)}")
    if m.unknown_ids:
        lines.append(f"other tags seen: {list(m.unknown_ids)}")
    return lines
