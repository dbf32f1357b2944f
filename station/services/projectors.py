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
