"""Projector calibration as a service: show Gray code stripes through a projector, grab each with a camera, map
projector pixels to the guide plane (:mod:`calibration.projector_map`) and keep the map per projector.

Used by ``station calibrate projector`` and the Calibrate screen's projector panel. The map is saved under the
projector it was measured on, as ``calibration/projectors/<key>.json`` in the station's data folder
(:func:`station.paths.data_dir`; the key from :func:`station.services.projectors.projector_key`: the projector's
``station.toml`` name, else a simulated twin's ``name=``, else ``display-N``), and records that projector; frames
projected on it then land at true scale, and frames on any other projector do not borrow it.

The camera's view of the plane is needed (undistorted pixel -> plane mm at h = 0, and the intrinsics that
undistort): given as arguments, else the camera's saved plane fix (``calibration/planes/<camera>.json``, written by
``station calibrate plane``) and intrinsics (``calibration/cameras/<camera>.json``), else, for a simulated camera,
its own pose (it knows it exactly; said so in the result).
"""

from __future__ import annotations

import re
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calibration.errors import CalibrationError
from calibration.projector_map import GrayCodePlan, map_projector, save_projector_map
from common.datafiles import load_json
from common.progress import Reporter
from drivers.devices import projector_identity, resolve
from station.config import configured_devices
from station.errors import ServiceError, station_errors
from station.paths import data_dir
from station.services import projectors

__all__ = ["DEFAULT_SETTLE_S", "ProjectorCalibration", "calibrate_projector", "projector_map_file",
           "projector_summary", "run_patterns"]

#: Seconds a real projector and camera are given after each pattern before the frame is grabbed.
DEFAULT_SETTLE_S = 0.3
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


@station_errors
@dataclass(frozen=True)
class ProjectorCalibration:
    """A finished mapping: the map, where it was saved (None: not saved), the key it is kept under, which devices
    (``projector_identity``: the projector as :func:`drivers.devices.projector_identity` names it), and where the
    camera's plane and intrinsics came from."""

    projector_map: object  # calibration.projector_map.ProjectorMap
    path: Path | None
    name: str
    camera_url: str
    projector_url: str
    frames: int
    plane_source: str
    intrinsics_source: str
    projector_identity: str = ""

    def to_dict(self) -> dict:
        path = None if self.path is None else str(self.path)
        return {**self.projector_map.to_json(), "name": self.name, "path": path,
                "camera": self.camera_url, "projector": self.projector_url, "device": self.projector_identity,
                "frames": self.frames, "plane_source": self.plane_source,
                "intrinsics_source": self.intrinsics_source}


@station_errors
def projector_map_file(name: str) -> Path:
    """Where the map kept under ``name`` is (a projector's key: :func:`station.services.projectors.projector_key`)."""
    return projectors.maps_folder() / f"{_check_name(name)}.json"


def _check_name(name: str) -> str:
    if not isinstance(name, str) or not _NAME.match(name):
        raise ServiceError(f"name must be 1-64 letters, digits, '_', '.' or '-' (a file name), got {name!r}",
                           field="name", value=name)
    return name


def _device(url: str, kind: str):
    info = resolve(url)
    if info.kind != kind or not info.available:
        raise ServiceError(f"{kind}: {url!r} is not a {kind} the station can drive (it names a {info.kind})",
                           field=kind, value=url)
    device = info.factory(info.url)
    device.open()
    return device


def _configured(kind: str) -> tuple[str, str]:
    device = next((d for d in configured_devices() if d.kind == kind), None)
    if device is None:
        raise ServiceError(f"{kind}: no {kind} configured (add one to station.toml, or give its URL)", field=kind)
    return device.name, device.url


@station_errors
def run_patterns(camera, projector, patterns, *, settle_s: float = 0.0, report: Reporter | None = None) -> list:
    """Show each ``(name, image)`` of ``patterns`` on the open ``projector`` and grab it with the open ``camera``.

    A real pair waits ``settle_s`` after each pattern and throws the first frame away (it may have been exposed
    before the projector changed). The projector is blanked at the end, also when stopped.
    """
    report = Reporter.of(report)
    images = []
    try:
        for number, (name, pattern) in enumerate(patterns, start=1):
            report("projector patterns", number - 1, len(patterns), f"pattern {number}/{len(patterns)}: {name}")
            projector.show(pattern)
            if settle_s > 0:
                time.sleep(settle_s)
                camera.grab()
            images.append(np.asarray(camera.grab()))
        report("projector patterns", len(patterns), len(patterns), "patterns seen")
    finally:
        projector.blank()
    return images


@dataclass(frozen=True)
class ProjectorCalibrationRequest:
    """Which projector :func:`calibrate_projector` maps, with which camera, and where the map goes.

    Parameters
    ----------
    camera, projector : str, optional
        URLs; default the station's camera and projector.
    name : str, optional
        The map's name; default the projector's key (:func:`station.services.projectors.projector_key`), where the
        guide and the check look for it (a map kept under another name is still found for that projector, as it
        records it).
    plane : ndarray or path, optional
        The camera's 3x3 undistorted-pixel -> plane homography, or a JSON file holding it as ``"homography"`` (what
        ``station calibrate plane`` keeps); default as the module docstring says.
    intrinsics : path, optional
        A camera file (OpenCV's names); default as the module docstring says.
    finest_px : int
        The finest stripe of the Gray code, in projector pixels.
    settle_s : float, optional
        Wait after each pattern; default :data:`DEFAULT_SETTLE_S` for real devices, 0 for simulated ones.
    save : bool
        Save the map (False: only return it).
    out : path, optional
        Where the map goes; default ``calibration/projectors/<name>.json``.
    """

    camera: str | None = None
    projector: str | None = None
    name: str | None = None
    plane: np.ndarray | str | Path | None = None
    intrinsics: str | Path | None = None
    finest_px: int = 8
    settle_s: float | None = None
    save: bool = True
    out: str | Path | None = None


@station_errors
def calibrate_projector(request: ProjectorCalibrationRequest = ProjectorCalibrationRequest(), *,
                        report: Reporter | None = None) -> ProjectorCalibration:
    """Map the projector ``request`` names with its camera, and save the map (recording the projector).

    Progress goes to ``report`` per pattern; its stop check stops between patterns
    (:class:`common.progress.Cancelled`), the projector blanked.

    Raises
    ------
    ServiceError
        A bad argument, or no plane known for a real camera (field ``plane``); a mapping that fails (field
        ``camera``: no stripes seen, too few cells ...).
    StationError
        A device that cannot be opened or gives no frame.
    """
    camera, projector, name, plane, intrinsics = (request.camera, request.projector, request.name, request.plane,
                                                  request.intrinsics)
    finest_px, settle_s, save, out = request.finest_px, request.settle_s, request.save, request.out
    report = Reporter.of(report)
    camera_name, camera_url = _configured("camera") if camera is None else ("camera", camera)
    projector_url = _configured("projector")[1] if projector is None else str(projector).strip()
    key = projectors.projector_key(projector_url)  # not a projector URL: one line on its field
    name = _check_name(name or key)
    target = Path(out) if out is not None else projector_map_file(name)
    if not isinstance(finest_px, int) or finest_px < 1:
        raise ServiceError(f"finest must be a whole number of projector pixels >= 1, got {finest_px!r}",
                           field="finest", value=finest_px)
    projector_device = _device(projector_url, "projector")
    try:
        camera_device = _device(camera_url, "camera")
        try:
            try:
                plan = GrayCodePlan(projector_device.size, finest_px)
            except CalibrationError as error:
                raise ServiceError(str(error), field="finest") from None
            simulated = camera_url.startswith("sim://") and projector_url.startswith("sim://")
            settle = (0.0 if simulated else DEFAULT_SETTLE_S) if settle_s is None else float(settle_s)
            matrix, plane_source = _plane(plane, camera_device, camera_name)
            camera_matrix, dist, intrinsics_source = _intrinsics(intrinsics, camera_device, camera_name)
            images = run_patterns(camera_device, projector_device, plan.patterns(), settle_s=settle,
                                  report=report)
        finally:
            camera_device.close()
    finally:
        projector_device.close()
    report("projector map", 0, 1, "decoding the stripes and fitting the map")
    try:
        result = map_projector(plan, images, matrix, camera_matrix, dist)
    except CalibrationError as error:
        hint = ""
        if camera_url.startswith("sim://camera") and "projector=" not in camera_url:
            # a simulated camera sees a simulated projector only when it names it (the station's default two do)
            hint = ("; a simulated camera sees a simulated projector only when linked, e.g. --camera "
                    "'sim://camera?projector=wall' --projector 'sim://projector?name=wall&area=-300,-190,300,190'")
        raise ServiceError(f"camera: {error}{hint}", field="camera") from None
    report("projector map", 1, 1, f"landing error p95 {result.landing_error_mm['p95']:.2f} mm")
    identity = projector_identity(projector_url)
    if save:
        save_projector_map(result, target, extra={"device": identity, "projector": projector_url})
    return ProjectorCalibration(result, target if save else None, name, camera_url, projector_url, len(images),
                                plane_source, intrinsics_source, identity)



def _json_file(path: Path, what: str, field: str) -> dict:
    try:
        data = load_json(path, what, error=lambda detail: ServiceError(f"{field}: {path}: {detail}", field=field))
    except OSError as error:
        raise ServiceError(f"{field}: cannot read {path} ({error.strerror or error})", field=field) from None
    if not isinstance(data, dict):
        raise ServiceError(f"{field}: {path}: expected {what}", field=field)
    return data


def _saved(kind: str, camera_name: str) -> Path | None:
    path = data_dir() / "calibration" / kind / f"{camera_name}.json"
    return path if path.is_file() else None


def _plane(plane, camera_device, camera_name: str) -> tuple[np.ndarray, str]:
    """The camera's undistorted-pixel -> plane homography, and where it came from."""
    if isinstance(plane, np.ndarray) or isinstance(plane, (list, tuple)):
        return _homography(plane, "plane"), "given"
    path = Path(plane) if plane is not None else _saved("planes", camera_name)
    if path is not None:
        data = _json_file(path, 'a plane fix with "homography": [[...], [...], [...]]', "plane")
        return _homography(data.get("homography"), f"plane: {path}: homography"), f"plane fix {path}"
    model = getattr(camera_device, "camera_model", None)
    if model is not None:  # a simulated camera knows its pose: the table's homography from it
        rotation = model.rotation
        to_pixels = model.camera_matrix @ np.column_stack([rotation[:, 0], rotation[:, 1], model.tvec])
        return np.linalg.inv(to_pixels), "the simulated camera's own pose"
    raise ServiceError("plane: the camera's view of the plane is unknown: run `station calibrate plane` with the "
                       "guide's reference tags in view first, or give --plane PLANE.json", field="plane")


def _homography(value, what: str) -> np.ndarray:
    try:
        matrix = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        matrix = np.zeros(0)
    if matrix.shape != (3, 3) or not np.isfinite(matrix).all() or abs(np.linalg.det(matrix)) < 1e-15:
        raise ServiceError(f"{what}: expected an invertible 3x3 matrix [[...], [...], [...]]", field="plane")
    return matrix


def _intrinsics(intrinsics, camera_device, camera_name: str) -> tuple[np.ndarray, np.ndarray, str]:
    """(camera_matrix, dist_coeffs, where they came from)."""
    path = Path(intrinsics) if intrinsics is not None else _saved("cameras", camera_name)
    if path is not None:
        data = _json_file(path, 'a camera file with "camera_matrix" and "dist_coeffs" (OpenCV\'s names)',
                          "intrinsics")
        try:
            matrix = np.asarray(data["camera_matrix"], dtype=float).reshape(3, 3)
            dist = np.asarray(data["dist_coeffs"], dtype=float).ravel()
        except (KeyError, TypeError, ValueError):
            raise ServiceError(f"intrinsics: {path}: expected camera_matrix (3x3) and dist_coeffs (numbers)",
                               field="intrinsics") from None
        return matrix, dist, f"camera file {path}"
    model = getattr(camera_device, "camera_model", None)
    if model is not None:
        return model.camera_matrix, model.dist_coeffs, "the simulated camera's own lens"
    width, height = camera_device.size
    focal = float(max(width, height))
    guess = np.array([[focal, 0.0, (width - 1) / 2], [0.0, focal, (height - 1) / 2], [0.0, 0.0, 1.0]])
    return guess, np.zeros(5), f"guessed (f = {focal:g} px, no distortion: run `station calibrate camera`)"


@station_errors
def projector_summary(done: ProjectorCalibration) -> list[str]:
    """The lines the CLI prints and the Calibrate screen shows: how true the map lands and where it is kept first
    (a panel may show only the first few)."""
    landing, cells = done.projector_map.landing_error_mm, done.projector_map.cells
    width, height = done.projector_map.projector_size
    lines = [f"projector {done.name!r} ({done.projector_url}, {width}x{height}): landing error at "
             f"{landing.get('check_points')} check points: p50 {landing['p50']:.2f} mm, p95 {landing['p95']:.2f} mm, "
             f"max {landing['max']:.2f} mm"
             + (f" ({landing['outliers']} check points off the plane left out)" if landing.get("outliers") else "")]
    if done.path is not None:
        lines.append(f"saved {done.path}")
    lines += [f"{done.frames} patterns seen by {done.camera_url}: cells seen {cells.get('seen')}, fitted "
              f"{cells.get('fitted')} ({cells.get('inliers')} inliers)",
              f"camera plane: {done.plane_source}; intrinsics: {done.intrinsics_source}"]
    return lines
