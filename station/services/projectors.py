"""The station's projectors: open one (the configured one, simulated by default, or any projector URL) for the
guide's steps and the check, and find the calibration measured on it.

A projector's calibration (``station calibrate projector``) is kept under the projector it was measured on: the file
``calibration/projectors/KEY.json`` in the station's data folder, KEY from :func:`projector_key`, and the file
records the projector (:func:`drivers.devices.projector_identity`). A projector is drawn at true scale only through
a map measured on it: a map kept under its key that records no projector (written before maps recorded one), or any
map that records it; never another projector's.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calibration.errors import CalibrationError
from calibration.projector_map import load_projector_map
from drivers.devices import UnknownDeviceURL, projector_identity, resolve
from drivers.errors import DriverError
from drivers.sim.projector import parse_options
from station.config import configured_devices
from station.devices import DeviceEntry
from station.errors import ServiceError, StationError, station_errors
from station.paths import data_dir

__all__ = ["ProjectorMapping", "configured_projector", "mapping_of", "maps_folder", "open_projector",
           "projector_device", "projector_homography", "projector_key", "projector_mapping"]

_KEY = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


@station_errors
def configured_projector() -> DeviceEntry | None:
    """The first projector of the station's devices (``station.toml``, or the simulated default), or None."""
    return next((device for device in configured_devices() if device.kind == "projector"), None)


def _configured_projectors() -> list[DeviceEntry]:
    return [device for device in configured_devices() if device.kind == "projector"]


def _identity(url: str) -> str:
    """:func:`drivers.devices.projector_identity`, its refusal as a ServiceError on field ``projector``."""
    try:
        info = resolve(url)
    except UnknownDeviceURL as error:
        raise ServiceError(f"projector: {error}", field="projector", value=url) from None
    if info.kind != "projector":
        raise ServiceError(f"projector: {info.url!r} is not a projector the station can drive (it names a "
                           f"{info.kind})", field="projector", value=url)
    try:
        return projector_identity(info.url)
    except DriverError as error:
        raise ServiceError(f"projector: {error}", field="projector", value=url) from None


@station_errors
def projector_key(url: str) -> str:
    """The name the calibration of the projector at ``url`` is kept under (``calibration/projectors/KEY.json``).

    The ``station.toml`` name of the configured projector that is the same projector (same display, or the same
    shared simulated twin); else the simulated twin's ``name=`` (``sim://projector?name=wall``: ``wall``),
    ``display-N`` for ``display:N``, ``sim-projector`` for an unnamed twin. A key that another configured device is
    named gets a short hash of the projector, so that it never reads that device's map.
    """
    identity = _identity(url)
    configured = _configured_projectors()
    for device in configured:
        try:
            if _identity(device.url) == identity:
                return device.name
        except ServiceError:
            continue
    if identity.startswith("sim://projector"):
        name = parse_options(identity)["name"]
        key = name or "sim-projector"
    else:
        key = identity.replace(":", "-")
    slug = re.sub(r"[^A-Za-z0-9_.-]+", "-", key).strip("-.")[:56]
    if slug != key or not _KEY.match(slug) or any(device.name == slug for device in configured_devices()):
        slug = f"{slug or 'projector'}-{hashlib.sha1(identity.encode()).hexdigest()[:6]}"
    return slug


@station_errors
def projector_device(url: str | None = None) -> DeviceEntry | None:
    """The projector at ``url`` (opened as given) as a device named by its :func:`projector_key` (the name of the
    configured entry of the same projector); None: the configured projector (None without one).

    Raises
    ------
    ServiceError
        ``url`` is not a projector URL (field ``projector``).
    """
    if url is None:
        return configured_projector()
    url = str(url).strip()
    return DeviceEntry(projector_key(url), "projector", url, resolve(url).simulated)


@contextmanager
@station_errors
def open_projector(device: DeviceEntry) -> Iterator:
    """The projector ``device`` opened (its driver from :func:`drivers.devices.resolve`), closed (blank) on exit.

    Raises
    ------
    StationError
        The device is not a projector, or its kind has no driver.
    drivers.errors.DriverError
        It cannot be opened (one line saying why: no such display, pygame-ce missing ...).
    """
    info = resolve(device.url)
    if info.kind != "projector" or not info.available:
        raise StationError(f"device {device.name!r} ({device.url}) is not a projector the station can drive")
    projector = info.factory(info.url)
    projector.open()
    try:
        yield projector
    finally:
        projector.close()


@station_errors
@dataclass(frozen=True)
class ProjectorMapping:
    """How the guide lands through one projector at one screen size: its calibration, if one measured on it fits.

    ``homography`` (guide-plane mm -> projector pixels) is None when the frames must be fitted to the screen;
    ``reason`` then says why (no calibration of its own, a map of another screen size, a map that does not read).
    """

    key: str
    url: str
    identity: str
    path: Path | None
    projector_map: object | None  # calibration.projector_map.ProjectorMap
    homography: np.ndarray | None
    reason: str = ""

    @property
    def true_scale(self) -> bool:
        return self.homography is not None

    def scale_text(self) -> str:
        """``at true scale (its map PATH, landing error p95 0.31 mm)`` or ``fitted to the screen, NOT at true
        scale: WHY``."""
        if self.homography is not None:
            p95 = self.projector_map.landing_error_mm.get("p95")
            error = f", landing error p95 {p95:.2f} mm" if isinstance(p95, (int, float)) else ""
            return f"at true scale (its map {self.path}{error})"
        return f"fitted to the screen, NOT at true scale: {self.reason}"


@station_errors
def projector_mapping(url: str, size) -> ProjectorMapping:
    """The calibration of the projector at ``url`` for frames of ``size`` ``(width, height)`` (see the module
    docstring for which maps count as its own).

    Raises
    ------
    ServiceError
        ``url`` is not a projector URL (field ``projector``).
    """
    url = str(url).strip()
    identity, key = _identity(url), projector_key(url)
    size = tuple(int(v) for v in size)
    path, elsewhere = _own_map(identity, key)
    if path is None:
        configured = configured_projector()
        command = ("station calibrate projector" if configured is not None and configured.name == key
                   else f"station calibrate projector --projector '{url}'")
        reason = f"{key} has no calibration of its own (`{command}`)"
        if elsewhere:
            reason += f"; {elsewhere}"
        return ProjectorMapping(key, url, identity, None, None, None, reason)
    try:
        mapping = load_projector_map(path)
    except (CalibrationError, OSError) as error:
        return ProjectorMapping(key, url, identity, path, None, None, f"its map does not read ({error})")
    if tuple(mapping.projector_size) != size:
        width, height = mapping.projector_size
        return ProjectorMapping(key, url, identity, path, mapping, None,
                                f"its map {path} is of a {width}x{height} screen, this one is {size[0]}x{size[1]}: "
                                "calibrate it again")
    homography = np.linalg.inv(np.asarray(mapping.plane_from_pixel, dtype=float))
    return ProjectorMapping(key, url, identity, path, mapping, homography)


@station_errors
def mapping_of(projector) -> ProjectorMapping | None:
    """:func:`projector_mapping` of the open ``projector`` (a driver: its ``url`` and ``size``); a driver without a
    ``url`` is taken for the configured projector (None without one)."""
    url = getattr(projector, "url", None)
    if url is None:
        device = configured_projector()
        if device is None:
            return None
        url = device.url
    return projector_mapping(url, tuple(projector.size))


@station_errors
def projector_homography(projector) -> np.ndarray | None:
    """Guide-plane mm -> pixels of the open ``projector`` from the calibration measured on it (:func:`mapping_of`);
    None without one of its size (the frames are then fitted to the screen, and say so)."""
    mapping = mapping_of(projector)
    return None if mapping is None else mapping.homography


@station_errors
def maps_folder() -> Path:
    """Where the projectors' maps are kept: ``calibration/projectors`` in the station's data folder."""
    return data_dir() / "calibration" / "projectors"


def _recorded_projector(path: Path) -> str | None:
    """The projector a map file records (None: it records none, or does not read as JSON)."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    device = data.get("device") if isinstance(data, dict) else None
    return device if isinstance(device, str) else None


def _own_map(identity: str, key: str) -> tuple[Path | None, str]:
    """The map measured on projector ``identity``: its key's file unless that records another projector, else the
    newest file that records it; and, when none, a note on a key file that belongs to another projector."""
    folder = maps_folder()
    own = folder / f"{key}.json"
    note = ""
    if own.is_file():
        recorded = _recorded_projector(own)
        if recorded is None or recorded == identity:
            return own, ""
        note = f"{own} was measured on {recorded}"
    if folder.is_dir():
        others = [path for path in folder.glob("*.json") if path != own and _recorded_projector(path) == identity]
        if others:
            return max(others, key=lambda path: path.stat().st_mtime), ""
    return None, note
