"""The devices the station knows about, and the default set: every device simulated.

A device entry is a name, a kind and a port URL. Simulated devices use the ``sim://`` family of URLs served by the
simulated twins in :mod:`drivers`; a real device uses its real URL (``/dev/ttyUSB0``, ``socket://...``).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class DeviceEntry:
    """One configured device.

    Parameters
    ----------
    name : str
        The name shown to the user, unique in the station.
    kind : str
        ``"plotter"``, ``"laser"``, ``"camera"`` or ``"projector"``.
    url : str
        Port URL (serial devices), camera index/URL, or display name.
    simulated : bool
        True when the URL points at a simulated twin.
    """

    name: str
    kind: str
    url: str
    simulated: bool

    @property
    def label(self) -> str:
        return f"{self.name} ({self.kind}, {'simulated' if self.simulated else 'real'})"


def default_devices() -> tuple[DeviceEntry, ...]:
    """The station's embedded default: one of each kind, all simulated."""
    return (
        DeviceEntry("plotter", "plotter", "sim://grbl?profile=plotter", True),
        DeviceEntry("laser", "laser", "sim://grbl?profile=laser", True),
        DeviceEntry("camera", "camera", "sim://camera", True),
        DeviceEntry("projector", "projector", "sim://projector", True),
    )
