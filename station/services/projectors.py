"""The station's projector: open the configured one (simulated by default) for the guide's steps."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from station.devices import DeviceEntry
from station.errors import StationError

__all__ = ["configured_projector", "open_projector"]


def configured_projector() -> DeviceEntry | None:
    """The first projector of the station's devices (``station.toml``, or the simulated default), or None."""
    from station.config import configured_devices

    return next((device for device in configured_devices() if device.kind == "projector"), None)


@contextmanager
def open_projector(device: DeviceEntry) -> Iterator:
    """The projector ``device`` opened (its driver from :func:`drivers.devices.resolve`), closed (blank) on exit.

    Raises
    ------
    StationError
        The device is not a projector, or its kind has no driver.
    drivers.errors.DriverError
        It cannot be opened (one line saying why: no such display, pygame-ce missing ...).
    """
    from drivers.devices import resolve

    info = resolve(device.url)
    if info.kind != "projector" or not info.available:
        raise StationError(f"device {device.name!r} ({device.url}) is not a projector the station can drive")
    projector = info.factory(info.url)
    projector.open()
    try:
        yield projector
    finally:
        projector.close()


def projector_homography(name: str, size):
    """The guide-plane -> projector-pixel homography of projector ``name`` from its saved map (``station calibrate
    projector``: ``calibration/projectors/NAME.json``), for frames at true scale; None without a map, or with one of
    another screen size (the frames are then fitted to the screen, and say so)."""
    import numpy as np

    from calibration.errors import CalibrationError
    from calibration.projector_map import load_projector_map
    from station.services.projector_calibration import projector_map_file

    path = projector_map_file(name)
    if not path.exists():
        return None
    try:
        mapping = load_projector_map(path)
    except (CalibrationError, OSError):
        return None  # a map that no longer reads: fitted to the screen, as without one
    if tuple(mapping.projector_size) != tuple(size):
        return None
    return np.linalg.inv(np.asarray(mapping.plane_from_pixel, dtype=float))


def saved_homography(size) -> object | None:
    """:func:`projector_homography` of the station's configured projector at ``size`` (None without one or a map)."""
    device = configured_projector()
    return None if device is None else projector_homography(device.name, size)

