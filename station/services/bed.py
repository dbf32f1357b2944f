"""The laser's bed seen by a camera: its registration to machine coordinates, the stock on it, and a job placed on
the stock.

Registration (``station calibrate bed``): the laser engraves four small filled squares of different sizes (5, 6.5,
8 and 9.5 mm, so that each is told by its size whatever way the camera is turned or mirrored) at known work
positions on a piece of scrap; the camera finds them, and the sixteen corners give the bed's homography, camera
pixels -> machine mm (the marks' work positions plus the work offset the laser had when it engraved them), with
its residual in mm at those corners. It is kept per laser, ``calibration/beds/<laser>.json`` in the station's data
folder (the laser's ``station.toml`` name), with the camera it was measured with. A homography is the whole
mapping for a lens without distortion looking at a flat bed; a camera with a wide-angle lens leaves a larger
residual, which the registration reports.

Placement: the stock (the largest light sheet on the dark bed) is found in a frame and mapped to machine mm; a
job's outline (its laser-on moves) is drawn on the camera's picture at true scale, wherever a
:class:`cam.place.Placement` puts it; :func:`placement_on_stock` puts the job's lower-left corner a
margin inside the stock's lower-left corner, along the stock's edge.

The camera over the bed: the configured camera whose ``options = { laser = "NAME" }`` names the laser; a
simulated laser without one gets a simulated camera over its bed (:data:`SIM_BED_CAMERA`, which sees what that
laser burns).
"""

from __future__ import annotations

import contextlib
import itertools
import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from cam.place import Placement, place_lines
from common.progress import Progress, Reporter
from drivers.gcode import GcodeError, interpret
from station.errors import ServiceError, station_errors

__all__ = ["MARK_SIZES", "SIM_BED_CAMERA", "BedCalibration", "BedCalibrationRequest", "BedRegistration", "bed_camera",
           "bed_file", "bed_picture", "calibrate_bed", "default_mark_area", "find_marks", "find_stock",
           "grab_bed_frame", "job_outline",
           "load_registration", "mark_positions", "marks_job", "placement_on_stock", "register_bed",
           "save_registration", "BedPlacement"]

#: The edge of each registration mark (mm), in the order of the area's corners: lower-left, lower-right,
#: upper-right, upper-left. Their areas differ by a third or more: the camera tells them apart by size.
MARK_SIZES = (5.0, 6.5, 8.0, 9.5)
#: The camera a simulated laser gets when none is configured over its bed: 0.5 mm per pixel over an 800 x 600 mm
#: plane, the 400 mm bed (machine X0 Y0 at plane 200, 200) in the middle, a sheet of plywood lying on it a little
#: turned.
SIM_BED_CAMERA = "sim://camera?size=1600x1200&f=1300&height=650&stock=-120,-90,240,170,6"
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


# ----------------------------------------------------------------------------------------------------------- marks


@station_errors
def default_mark_area(width: float, height: float) -> tuple[float, float, float, float]:
    """The marks' rectangle (work mm) on a ``width`` x ``height`` work area: its middle, 140 x 100 mm."""
    cx, cy = width / 2.0, height / 2.0
    return (cx - 70.0, cy - 50.0, cx + 70.0, cy + 50.0)


@station_errors
def mark_positions(area: Sequence[float]) -> list[tuple[tuple[float, float], float]]:
    """``[(centre, size)]`` of the four marks at the corners of ``area`` ``(x0, y0, x1, y1)`` (work mm)."""
    x0, y0, x1, y1 = (float(v) for v in area)
    if not (x1 - x0 >= 30 and y1 - y0 >= 30):
        raise ServiceError(f"area must be x0,y0,x1,y1 with at least 30 mm between the marks each way, got "
                           f"{','.join(f'{v:g}' for v in area)}", field="area", value=area)
    corners = ((x0, y0), (x1, y0), (x1, y1), (x0, y1))
    return [(corner, size) for corner, size in zip(corners, MARK_SIZES)]


@station_errors
def marks_job(marks: Sequence[tuple[tuple[float, float], float]], *, power: float, feed: float,
              kerf: float = 0.15) -> list[str]:
    """The G-code that engraves the marks as filled squares: rows ``kerf`` apart both ways, then their outline
    half a kerf inside (a crisp edge for the camera), laser dark on every travel (``M4``, ``G0``)."""
    if not kerf > 0:
        raise ServiceError(f"kerf must be > 0 mm, got {kerf!r}", field="kerf", value=kerf)
    lines = ["; chaos-station laser job: bed registration marks", "G21 G90 G94 G17", "M5 S0", "M4 S0"]
    half = kerf / 2.0
    for (cx, cy), size in marks:
        x0, y0, x1, y1 = cx - size / 2 + half, cy - size / 2 + half, cx + size / 2 - half, cy + size / 2 - half
        rows = max(1, int(math.ceil((y1 - y0) / kerf)))
        for row in range(rows + 1):
            y = y0 + (y1 - y0) * row / rows
            a, b = (x0, x1) if row % 2 == 0 else (x1, x0)
            lines.append(f"G0 X{a:.3f} Y{y:.3f} S0")
            lines.append(f"G1 X{b:.3f} S{power:g} F{feed:g}")
        lines.append(f"G0 X{x0:.3f} Y{y0:.3f} S0")
        for x, y in ((x1, y0), (x1, y1), (x0, y1), (x0, y0)):
            lines.append(f"G1 X{x:.3f} Y{y:.3f} S{power:g} F{feed:g}")
    lines += ["M5 S0", "G0 X0 Y0"]
    return lines


@dataclass(frozen=True)
class FoundMark:
    """A dark square found in a frame: its pixel centroid, area and corners (sub-pixel, in contour order)."""

    centre: np.ndarray
    area: float
    corners: np.ndarray


def _gray(frame: np.ndarray) -> np.ndarray:
    frame = np.asarray(frame)
    if frame.ndim == 3:
        return cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY)
    return frame.astype(np.uint8)


@station_errors
def find_marks(frame: np.ndarray) -> list[FoundMark]:
    """Dark, square blobs enclosed by light stock (the marks and anything like them), largest first."""
    gray = _gray(frame)
    threshold, _ = cv2.threshold(gray, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    dark = (gray < threshold).astype(np.uint8)
    count, labels, stats, centroids = cv2.connectedComponentsWithStats(dark, connectivity=8)
    h, w = gray.shape
    found: list[FoundMark] = []
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 0.01)
    for label in range(1, count):
        x, y, bw, bh, area = stats[label]
        if area < 12 or x <= 1 or y <= 1 or x + bw >= w - 1 or y + bh >= h - 1 or area > 0.01 * h * w:
            continue
        mask = (labels[y:y + bh, x:x + bw] == label).astype(np.uint8)
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        contour = max(contours, key=cv2.contourArea)
        (_, _), (rw, rh), _ = cv2.minAreaRect(contour)
        if min(rw, rh) < 3 or max(rw, rh) / min(rw, rh) > 1.3 or area / max(rw * rh, 1e-9) < 0.8:
            continue
        approx = cv2.approxPolyDP(contour, 0.08 * cv2.arcLength(contour, True), True).reshape(-1, 2)
        if len(approx) != 4:
            continue
        corners = approx.astype(np.float32) + np.array([x, y], dtype=np.float32)
        window = max(2, int(min(rw, rh) / 5))
        corners = cv2.cornerSubPix(gray, corners.reshape(-1, 1, 2).copy(), (window, window), (-1, -1),
                                   criteria).reshape(-1, 2)
        found.append(FoundMark(np.array(centroids[label], dtype=float), float(area), corners.astype(float)))
    return sorted(found, key=lambda m: -m.area)


def _choose_marks(found: list[FoundMark]) -> list[FoundMark] | None:
    """The four of ``found`` whose areas go as the marks' sizes squared, in the marks' order (None: no four)."""
    candidates = found[:12]
    if len(candidates) < 4:
        return None
    expected = np.array(MARK_SIZES) ** 2
    best, best_score = None, math.inf
    for four in itertools.combinations(candidates, 4):
        ordered = sorted(four, key=lambda m: m.area)
        areas = np.array([m.area for m in ordered])
        scale = float(np.sum(areas * expected) / np.sum(expected * expected))
        score = float(np.max(np.abs(areas / (scale * expected) - 1.0)))
        if score < best_score:
            best, best_score = ordered, score
    return best if best_score < 0.2 else None


# ---------------------------------------------------------------------------------------------------- registration


@station_errors
@dataclass(frozen=True)
class BedRegistration:
    """The bed's homography (camera pixels -> machine mm) and how well it fits its marks' corners."""

    homography: np.ndarray
    residual_rms_mm: float
    residual_max_mm: float
    image_size: tuple[int, int]
    marks_mm: tuple = ()  # [(machine centre, size)]
    camera: str = ""
    laser: str = ""
    notes: str = ""

    def to_machine(self, pixels) -> np.ndarray:
        """Pixels ``(n, 2)`` -> machine mm ``(n, 2)``."""
        points = np.asarray(pixels, dtype=float).reshape(-1, 1, 2)
        return cv2.perspectiveTransform(points, self.homography).reshape(-1, 2)

    def to_pixels(self, machine) -> np.ndarray:
        """Machine mm ``(n, 2)`` -> pixels ``(n, 2)``."""
        points = np.asarray(machine, dtype=float).reshape(-1, 1, 2)
        return cv2.perspectiveTransform(points, np.linalg.inv(self.homography)).reshape(-1, 2)

    def to_dict(self) -> dict:
        return {"homography": self.homography.tolist(), "residual_rms_mm": self.residual_rms_mm,
                "residual_max_mm": self.residual_max_mm, "image_size": list(self.image_size),
                "marks_mm": [[list(c), s] for c, s in self.marks_mm], "camera": self.camera, "laser": self.laser,
                "notes": self.notes}

    @classmethod
    def from_dict(cls, data: dict, where: str) -> BedRegistration:
        try:
            homography = np.array(data["homography"], dtype=float)
            problem = ("" if homography.shape == (3, 3) and np.isfinite(homography).all()
                       else "homography: expected 3x3 finite numbers")
            if not problem:
                return cls(homography, float(data["residual_rms_mm"]), float(data["residual_max_mm"]),
                           tuple(int(v) for v in data["image_size"]),
                           tuple((tuple(c), float(s)) for c, s in data.get("marks_mm", [])),
                           str(data.get("camera", "")), str(data.get("laser", "")), str(data.get("notes", "")))
        except (KeyError, TypeError, ValueError) as error:
            problem = str(error)
        raise ServiceError(f"{where}: not a bed registration ({problem}); run `station calibrate bed` again",
                           field="bed", value=where)


@station_errors
def register_bed(frame: np.ndarray, marks_mm: Sequence[tuple[tuple[float, float], float]], *,
                 camera: str = "", laser: str = "") -> BedRegistration:
    """The bed's homography from one frame of the engraved marks (their machine centres and sizes).

    Raises
    ------
    ServiceError
        When the four marks are not all seen (naming how many dark squares were found).
    """
    found = find_marks(frame)
    chosen = _choose_marks(found)
    if chosen is None:
        raise ServiceError(f"image: found {len(found)} dark square(s), not the four registration marks (5, 6.5, 8 "
                           "and 9.5 mm): is the scrap under the camera, lit, and were the marks engraved?",
                           field="image")
    by_size = sorted(range(4), key=lambda i: marks_mm[i][1])
    centres_px = np.array([m.centre for m in chosen], dtype=np.float32)
    centres_mm = np.array([marks_mm[i][0] for i in by_size], dtype=np.float32)
    rough = cv2.getPerspectiveTransform(centres_px, centres_mm)
    pixels, machine = [], []
    for mark, index in zip(chosen, by_size):
        (cx, cy), size = marks_mm[index]
        half = size / 2.0
        nominal = np.array([[cx - half, cy - half], [cx + half, cy - half], [cx + half, cy + half],
                            [cx - half, cy + half]])
        seen = cv2.perspectiveTransform(mark.corners.reshape(-1, 1, 2), rough).reshape(-1, 2)
        for corner in nominal:
            nearest = int(np.argmin(np.linalg.norm(seen - corner, axis=1)))
            pixels.append(mark.corners[nearest])
            machine.append(corner)
    pixels_array, machine_array = np.array(pixels), np.array(machine)
    homography, _ = cv2.findHomography(pixels_array, machine_array, 0)
    if homography is None:
        raise ServiceError("image: the marks' corners give no homography (are they in a line?)", field="image")
    errors = np.linalg.norm(cv2.perspectiveTransform(pixels_array.reshape(-1, 1, 2), homography).reshape(-1, 2)
                            - machine_array, axis=1)
    h, w = np.asarray(frame).shape[:2]
    return BedRegistration(homography, float(np.sqrt(np.mean(errors ** 2))), float(errors.max()), (w, h),
                           tuple((tuple(map(float, c)), float(s)) for c, s in marks_mm), camera, laser)


def _check_name(name: str) -> str:
    if not isinstance(name, str) or not _NAME.match(name):
        raise ServiceError(f"laser must be 1-64 letters, digits, '_', '.' or '-' (a file name), got {name!r}",
                           field="laser", value=name)
    return name


@station_errors
def bed_file(laser: str) -> Path:
    """Where the registration of laser ``laser`` (its ``station.toml`` name) is kept."""
    from station.paths import data_dir

    folder = data_dir() / "calibration" / "beds"
    folder.mkdir(parents=True, exist_ok=True)
    return folder / f"{_check_name(laser)}.json"


@station_errors
def save_registration(registration: BedRegistration, laser: str) -> Path:
    path = bed_file(laser)
    path.write_text(json.dumps(registration.to_dict(), indent=1), encoding="utf-8")
    return path


@station_errors
def load_registration(laser: str) -> BedRegistration | None:
    """The saved registration of ``laser``, None when there is none."""
    path = bed_file(laser)
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise ServiceError(f"{path}: not readable JSON ({error}); run `station calibrate bed` again", field="bed",
                           value=str(path)) from None
    return BedRegistration.from_dict(data, str(path))


# ----------------------------------------------------------------------------------------------------------- devices


@station_errors
def laser_device(laser: str | None = None):
    """The configured laser named ``laser`` (default: the first laser)."""
    from station.config import configured_devices

    lasers = [d for d in configured_devices() if d.kind == "laser"]
    if not lasers:
        raise ServiceError("laser: no laser configured (add one to station.toml)", field="laser")
    if laser is None:
        return lasers[0]
    chosen = next((d for d in lasers if d.name == laser), None)
    if chosen is None:
        raise ServiceError(f"laser must name a configured laser ({', '.join(d.name for d in lasers)}), got "
                           f"{laser!r}", field="laser", value=laser)
    return chosen


@station_errors
def bed_camera(laser_name: str, laser_simulated: bool) -> tuple[str, str]:
    """``(name, url)`` of the camera over ``laser_name``'s bed (module docstring)."""
    from station.config import configured_devices

    camera = next((d for d in configured_devices() if d.kind == "camera" and d.options.get("laser") == laser_name),
                  None)
    if camera is not None:
        return camera.name, camera.url
    if laser_simulated:
        return f"{laser_name}-bed (simulated)", SIM_BED_CAMERA
    raise ServiceError(f"camera: no camera over the bed of {laser_name!r}: add one to station.toml with "
                       f"options = {{ laser = \"{laser_name}\" }}, or give --camera URL", field="camera")


@station_errors
def open_bed_camera(url: str, laser_connection=None):
    """The camera at ``url``, open; a simulated one sees what the simulated laser behind ``laser_connection``
    burns."""
    from station.services.calibrate import open_camera

    camera = open_camera(url)
    machine = getattr(getattr(laser_connection, "port", None), "machine", None)
    if machine is not None and hasattr(camera, "laser_machine") and getattr(camera, "bed_view", None) is not None:
        camera.laser_machine = machine
    return camera


# ----------------------------------------------------------------------------------------------------------- calibrate


@station_errors
@dataclass(frozen=True)
class BedCalibration:
    """A finished ``station calibrate bed``."""

    registration: BedRegistration
    path: Path
    laser: str
    camera: str
    engraved: bool
    work_offset: tuple[float, float, float]
    frame: np.ndarray | None = field(default=None, compare=False)

    def to_dict(self) -> dict:
        return {**self.registration.to_dict(), "path": str(self.path), "engraved": self.engraved,
                "work_offset": list(self.work_offset)}


@station_errors
def grab_bed_frame(laser_name: str, laser_simulated: bool, laser_connection=None) -> np.ndarray:
    """One picture of ``laser_name``'s bed from its camera (:func:`bed_camera`, :func:`open_bed_camera`)."""
    _, url = bed_camera(laser_name, laser_simulated)
    camera = open_bed_camera(url, laser_connection)
    try:
        return camera.grab()
    finally:
        camera.close()


@dataclass(frozen=True)
class BedCalibrationRequest:
    """The bed registration :func:`calibrate_bed` makes: which laser, which picture, and how the marks are engraved.

    The laser's open connection, when there is one, is handed beside it to :func:`calibrate_bed`, as ``report=`` is:
    a live object its opener closes, not part of what the calibration is.

    Parameters
    ----------
    laser : str, optional
        A configured laser's name (default the first).
    port : str, optional
        Another URL for the laser.
    camera : str, optional
        The camera's URL (default the laser's bed camera).
    image : path or ndarray, optional
        A frame of the engraved marks (a file, or the frame itself) instead of grabbing one.
    area : sequence of float, optional
        Where the marks go (default :func:`default_mark_area` of the laser's bed).
    engrave : bool
        Engrave the marks (False: they are there already).
    power : float
        A fraction of the laser's maximum, in (0, 1].
    feed : float, optional
        mm/min (default the profile's engrave feed of its first material, else 3000).
    """

    laser: str | None = None
    port: str | None = None
    camera: str | None = None
    image: str | Path | np.ndarray | None = None
    area: Sequence[float] | None = None
    engrave: bool = True
    power: float = 0.3
    feed: float | None = None


@station_errors
def calibrate_bed(request: BedCalibrationRequest = BedCalibrationRequest(), *, report: Reporter | None = None,
                  connection=None) -> BedCalibration:
    """Engrave the marks (unless ``request.engrave`` is False: they are there already), grab a frame (or read
    ``request.image``), register the bed and save it under the laser's name.

    ``connection``: the laser's open :class:`drivers.grbl.GrblConnection` (the Machines screen's), else one is
    opened; beside the request, as a live object its opener closes. ``report`` hears of each step and of the marks
    job's lines; a stop asked for is honoured between the steps (a running laser job stops with the machine's own
    hold or abort, not half-way through a line).

    Raises
    ------
    ServiceError
        A ``power`` outside (0, 1] (named), a marks job that does not finish (``laser``).
    """
    from drivers.grbl import GrblConnection, Job, JobRunner
    from station.devices import machine_profile
    from station.services.calibrate import _read_image

    laser, port, camera, image, area = request.laser, request.port, request.camera, request.image, request.area
    engrave, power, feed = request.engrave, request.power, request.feed
    report = Reporter.of(report)

    def say(stage: str, message: str, done: float = 0.0, total: float = 1.0) -> None:
        report.emit(Progress(stage, done, total, message))

    device = laser_device(laser)
    profile = machine_profile(device)
    url = port or device.url
    if not 0 < power <= 1:
        raise ServiceError(f"power must be a fraction of the laser's maximum in (0, 1], got {power:g}", field="power",
                           value=power)
    if area is None:
        area = default_mark_area(profile.width, profile.height)
    marks_work = mark_positions(area)
    materials = list(getattr(profile, "materials", {}).values())
    engrave_feed = feed or (materials[0].engrave.feed if materials else 3000.0)
    kerf = materials[0].kerf if materials and getattr(materials[0], "kerf", None) else 0.15
    max_power = profile.laser.max_power if profile.laser else 1000.0
    opened = contextlib.nullcontext(connection) if connection is not None else GrblConnection(
        url, profile.baud or 115200)
    with opened as conn:
        if engrave:
            lines = marks_job(marks_work, power=power * max_power, feed=engrave_feed, kerf=kerf)
            say("engrave", f"engraving the four marks on {device.name}")

            def lines_done(job_progress) -> None:  # on the job's thread: told, never stopped there
                report.tell(Progress("engrave", job_progress.lines_acked, max(job_progress.lines_total, 1),
                                     "engraving the marks"))

            result = JobRunner(conn, Job("bed registration marks", lines, laser=True), on_progress=lines_done).run()
            if not result.ok:
                raise ServiceError(f"laser: the marks job did not finish: {result.message}", field="laser",
                                   value=device.name)
        wco = tuple(float(v) for v in conn.work_offset())
        camera_name, camera_url = (("image", str(image)) if image is not None and not isinstance(image, np.ndarray)
                                   else ("frame", "") if image is not None
                                   else (camera, camera) if camera else bed_camera(device.name, device.simulated))
        if image is None:
            say("grab", f"grabbing a frame from {camera_name}")
            device_camera = open_bed_camera(camera_url, conn)
            try:
                frame = device_camera.grab()
            finally:
                device_camera.close()
        else:
            frame = image if isinstance(image, np.ndarray) else _read_image(Path(image), "image")
    marks_machine = [((c[0] + wco[0], c[1] + wco[1]), s) for c, s in marks_work]
    registration = register_bed(frame, marks_machine, camera=camera_url, laser=device.name)
    path = save_registration(registration, device.name)
    return BedCalibration(registration, path, device.name, camera_url, engrave, wco, frame)


@station_errors
def bed_summary(done: BedCalibration) -> list[str]:
    registration = done.registration
    return [f"bed of {done.laser}: registered from the four marks' 16 corners"
            f"{' (engraved now)' if done.engraved else ''}; residual {registration.residual_rms_mm:.3f} mm RMS, "
            f"{registration.residual_max_mm:.3f} mm at most",
            f"camera {done.camera}, {registration.image_size[0]}x{registration.image_size[1]}; "
            f"work offset {', '.join(f'{v:.2f}' for v in done.work_offset)}",
            f"saved {done.path}"]


# ----------------------------------------------------------------------------------------------------------- stock


@station_errors
def find_stock(frame: np.ndarray, registration: BedRegistration) -> np.ndarray | None:
    """The stock's corners in machine mm ``(4, 2)`` (lower-left first, counter-clockwise), the largest light
    four-sided sheet in the frame; None when there is none."""
    gray = _gray(frame)
    threshold, _ = cv2.threshold(gray, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    light = (gray >= threshold).astype(np.uint8)
    contours, _ = cv2.findContours(light, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return None
    contour = max(contours, key=cv2.contourArea)
    if cv2.contourArea(contour) < 400:
        return None
    hull = cv2.convexHull(contour)
    approx = cv2.approxPolyDP(hull, 0.02 * cv2.arcLength(hull, True), True).reshape(-1, 2).astype(float)
    if len(approx) != 4:
        return None
    points = contour.reshape(-1, 2).astype(float)
    centre = points.mean(axis=0)
    lines = []
    for a, b in zip(approx, np.roll(approx, -1, axis=0)):
        direction = (b - a) / np.linalg.norm(b - a)
        normal = np.array([-direction[1], direction[0]])
        along = (points - a) @ direction
        across = (points - a) @ normal
        length = np.linalg.norm(b - a)
        near = (np.abs(across) < 3.0) & (along > 0.1 * length) & (along < 0.9 * length)
        if near.sum() < 5:
            return None
        vx, vy, x0, y0 = cv2.fitLine(points[near].astype(np.float32), cv2.DIST_HUBER, 0, 0.01, 0.01).ravel()
        point, unit = np.array([x0, y0], float), np.array([vx, vy], float)
        # the contour runs through the sheet's outermost pixels' centres: its edge lies half a pixel further out
        outward = np.array([-unit[1], unit[0]])
        if (point - centre) @ outward < 0:
            outward = -outward
        lines.append((point + 0.5 * outward, unit))
    corners = []
    for (p1, u1), (p2, u2) in zip(lines, lines[-1:] + lines[:-1]):
        matrix = np.array([u1, -u2]).T
        if abs(np.linalg.det(matrix)) < 1e-9:
            return None
        t = np.linalg.solve(matrix, p2 - p1)
        corners.append(p1 + t[0] * u1)
    machine = registration.to_machine(np.array(corners))
    return _counter_clockwise(machine)


def _counter_clockwise(corners: np.ndarray) -> np.ndarray:
    """Four corners counter-clockwise (machine axes, y up), the lower-left one (least x + y) first."""
    centre = corners.mean(axis=0)
    order = np.argsort(np.arctan2(corners[:, 1] - centre[1], corners[:, 0] - centre[0]))
    ordered = corners[order]
    first = int(np.argmin(ordered.sum(axis=1)))
    return np.roll(ordered, -first, axis=0)


@station_errors
def placement_on_stock(stock_mm: np.ndarray, work_offset: Sequence[float], job_lower_left: Sequence[float],
                       margin: float = 5.0) -> Placement:
    """The placement that puts a job's lower-left corner (``job_lower_left``, its own work mm) ``margin`` mm inside
    the stock's lower-left corner, turned with the stock's lower edge. ``stock_mm`` is machine mm (as
    :func:`find_stock` gives it), ``work_offset`` the machine's (machine = work + offset)."""
    stock = np.asarray(stock_mm, dtype=float)
    edge = stock[1] - stock[0]
    angle = math.degrees(math.atan2(edge[1], edge[0]))
    c, s = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    rotation = np.array([[c, -s], [s, c]])
    target = stock[0] + rotation @ np.array([margin, margin]) - np.asarray(work_offset[:2], dtype=float)
    offset = target - rotation @ np.asarray(job_lower_left[:2], dtype=float)
    return Placement(float(offset[0]), float(offset[1]), angle)


# ----------------------------------------------------------------------------------------------------------- picture


@station_errors
def job_outline(lines: Sequence[str], placement: Placement | None = None) -> list[np.ndarray]:
    """The job's laser-on (or drawing) moves as polylines in work mm, placed (a :class:`GcodeError` for a job that
    cannot be placed)."""
    placed = place_lines(lines, placement) if placement is not None else list(lines)
    toolpath = interpret(placed)
    paths: list[np.ndarray] = []
    current: list[np.ndarray] = []
    for start, end, rapid, power in zip(toolpath.start, toolpath.end, toolpath.rapid, toolpath.power):
        if rapid or power <= 0:
            if len(current) > 1:
                paths.append(np.array(current))
            current = []
            continue
        if not current or np.linalg.norm(current[-1] - start[:2]) > 1e-6:
            if len(current) > 1:
                paths.append(np.array(current))
            current = [start[:2].copy()]
        current.append(end[:2].copy())
    if len(current) > 1:
        paths.append(np.array(current))
    return paths


@station_errors
def bed_picture(frame: np.ndarray, registration: BedRegistration, outline_mm: Sequence[np.ndarray] = (), *,
                stock_mm: np.ndarray | None = None, travel_mm: tuple | None = None) -> np.ndarray:
    """The camera's frame with, at true scale through the registration: the job's outline (machine mm polylines,
    red), the stock found (green) and the machine's travel (``(lo, hi)`` machine XY, yellow)."""
    picture = np.ascontiguousarray(np.asarray(frame)[..., :3]).copy()
    shift = 4

    def draw(points_mm, colour, closed=False, thickness=2):
        pixels = registration.to_pixels(points_mm)
        if not np.isfinite(pixels).all():
            return
        fixed = np.round(pixels * (1 << shift)).astype(np.int32).reshape(-1, 1, 2)
        cv2.polylines(picture, [fixed], closed, colour, thickness, cv2.LINE_AA, shift)

    if travel_mm is not None:
        (x0, y0), (x1, y1) = travel_mm
        draw(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]), (240, 210, 40), closed=True)
    if stock_mm is not None:
        draw(stock_mm, (60, 220, 90), closed=True)
    for path in outline_mm:
        draw(path, (255, 40, 40))
    return picture


@station_errors
def placed_outline_machine(lines: Sequence[str], placement: Placement, work_offset: Sequence[float]) \
        -> list[np.ndarray]:
    """The placed job's outline in machine mm (for :func:`bed_picture`)."""
    try:
        paths = job_outline(lines, placement)
    except GcodeError as error:
        raise ServiceError(f"job: {error}", field="job") from None
    offset = np.asarray(work_offset[:2], dtype=float)
    return [p + offset for p in paths]


# ----------------------------------------------------------------------------------------------------------- session


@station_errors
@dataclass
class BedPlacement:
    """A job being placed on the bed by camera (the Machines screen's placement): the registration, the last frame,
    the job's lines, the machine's work offset and the placement so far."""

    registration: BedRegistration
    lines: list[str]
    work_offset: tuple[float, float, float]
    travel: tuple | None = None  # ((x0, y0), (x1, y1)) machine mm
    placement: Placement = field(default_factory=Placement)
    frame: np.ndarray | None = None
    stock: np.ndarray | None = None

    def __post_init__(self) -> None:
        outline = job_outline(self.lines)
        points = np.concatenate(outline) if outline else np.zeros((1, 2))
        #: The job's own lower-left corner and centre (work mm, unplaced).
        self.lower_left = points.min(axis=0)
        self.centre = (points.min(axis=0) + points.max(axis=0)) / 2.0

    def see(self, frame: np.ndarray) -> None:
        """A new frame: the stock is looked for in it."""
        self.frame = frame
        self.stock = find_stock(frame, self.registration)

    def move(self, dx: float, dy: float) -> None:
        p = self.placement
        self.placement = Placement(p.x + dx, p.y + dy, p.angle)

    def turn(self, degrees: float) -> None:
        """Turn the job about its own centre (where it lies stays where it is)."""
        p = self.placement
        centre = np.array(p.apply(*self.centre))
        turned = Placement(0.0, 0.0, p.angle + degrees)
        offset = centre - np.array(turned.apply(*self.centre))
        self.placement = Placement(float(offset[0]), float(offset[1]), (p.angle + degrees) % 360.0)

    def snap(self, margin: float = 5.0) -> bool:
        """Put the job on the stock found (its lower-left corner ``margin`` inside the stock's); False: no stock."""
        if self.stock is None:
            return False
        self.placement = placement_on_stock(self.stock, self.work_offset, self.lower_left, margin)
        return True

    def placed_lines(self) -> list[str]:
        return place_lines(self.lines, self.placement)

    def picture(self) -> np.ndarray:
        """The frame with the placed outline, the stock and the travel drawn, cropped to the travel (or the frame)."""
        outline = placed_outline_machine(self.lines, self.placement, self.work_offset)
        picture = bed_picture(self.frame, self.registration, outline, stock_mm=self.stock, travel_mm=self.travel)
        if self.travel is None:
            return picture
        (x0, y0), (x1, y1) = self.travel
        corners = self.registration.to_pixels(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]))
        h, w = picture.shape[:2]
        left, top = (max(0, int(v) - 10) for v in corners.min(axis=0))
        right, bottom = int(min(w, corners[:, 0].max() + 10)), int(min(h, corners[:, 1].max() + 10))
        return picture[top:bottom, left:right] if right - left > 10 and bottom - top > 10 else picture

    def describe(self) -> str:
        p = self.placement
        stock = "stock found" if self.stock is not None else "no stock found"
        return (f"placed at X {p.x:.1f} Y {p.y:.1f} mm, turned {p.angle:.1f} deg; {stock}; bed residual "
                f"{self.registration.residual_rms_mm:.2f} mm")
