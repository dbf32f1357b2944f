"""The devices the station knows about, the default set (every device simulated), and their state from a probe.

A device entry is a name, a kind, a URL and, for a GRBL machine, its machine profile. Simulated devices use the
``sim://`` family of URLs served by the simulated twins in :mod:`drivers`; a real device uses its real URL
(``/dev/ttyUSB0``, ``socket://...``). The entries come from the station's config file
(:func:`station.config.configured_devices`); without one, from :func:`default_devices`.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

#: The kinds of device a station has, and the registry kind (:data:`drivers.devices.KINDS`) of each.
REGISTRY_KIND = MappingProxyType({"plotter": "grbl", "laser": "grbl", "camera": "camera", "projector": "projector"})

#: Kinds that are GRBL machines (they have a machine profile).
GRBL_KINDS = ("plotter", "laser")

#: Seconds a GRBL probe waits for the status report unless the device's ``timeout`` option says otherwise.
PROBE_TIMEOUT = 0.5

#: Seconds :func:`probe_devices` waits beyond the longest probe timeout (opening a ``socket://`` port can take
#: pyserial's own 5 s connect timeout; the answer does not wait for it).
PROBE_GRACE = 1.0


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
        Port URL (serial devices), camera index/URL, or display name (see :mod:`drivers.devices`).
    simulated : bool
        True when the URL points at a simulated twin.
    profile : str
        A GRBL machine's profile: a built-in profile name (``"plotter"``) or a profile file's path; "" for a camera
        or projector. "" on a plotter or laser means the built-in profile named as its kind.
    options : mapping
        Driver options from the config file's ``options`` table (GRBL: ``timeout``, the probe's wait in seconds).
    """

    name: str
    kind: str
    url: str
    simulated: bool
    profile: str = ""
    options: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}), hash=False)

    @property
    def label(self) -> str:
        return f"{self.name} ({self.kind}, {'simulated' if self.simulated else 'real'})"

    @property
    def machine_profile_name(self) -> str:
        """The profile to load for a GRBL machine (:func:`drivers.profiles.load_profile` takes a name or a path)."""
        return self.profile or (self.kind if self.kind in GRBL_KINDS else "")


def default_devices() -> tuple[DeviceEntry, ...]:
    """The station's embedded default: one of each kind, all simulated."""
    return (
        DeviceEntry("plotter", "plotter", "sim://grbl?profile=plotter", True, "plotter"),
        DeviceEntry("laser", "laser", "sim://grbl?profile=laser", True, "laser"),
        # linked: the camera sees what the projector throws (640 x 400 mm in the middle of its view), so that the
        # projector can be calibrated, and the check sees the guide's light, as on a real table
        DeviceEntry("camera", "camera", "sim://camera?projector=projector", True),
        DeviceEntry("projector", "projector", "sim://projector?name=projector", True),
    )


def machine_profile(device: DeviceEntry):
    """The :class:`drivers.profiles.MachineProfile` of a plotter or laser (its built-in profile, or its file).

    Raises
    ------
    drivers.profiles.ProfileError
        When the profile file has gone or changed into a bad one since the config was read.
    """
    from drivers.profiles import builtin_profile, builtin_profile_names, load_profile

    name = device.machine_profile_name
    return builtin_profile(name) if name in builtin_profile_names() else load_profile(name)


def driver_name(device: DeviceEntry) -> str | None:
    """The registry's driver for ``device`` (``"grbl-serial"``), None when its kind has no driver yet."""
    from drivers.devices import resolve

    return resolve(device.url).driver or None


def probe_wait(device: DeviceEntry) -> float:
    """Seconds a probe of ``device`` may wait: its ``timeout`` option, else :data:`PROBE_TIMEOUT`; a real projector
    at least :data:`drivers.projector.display.DISPLAY_PROBE_TIMEOUT` (its probe starts a short-lived process), a
    real camera at least :data:`drivers.camera.opencv.FRAME_TIMEOUT` (it must give a frame)."""
    wait = float(device.options.get("timeout", PROBE_TIMEOUT))
    if device.kind == "projector" and not device.simulated:
        from drivers.projector.display import DISPLAY_PROBE_TIMEOUT

        wait = max(wait, DISPLAY_PROBE_TIMEOUT)
    if device.kind == "camera" and not device.simulated:
        from drivers.camera.opencv import FRAME_TIMEOUT

        wait = max(wait, FRAME_TIMEOUT)
    return wait


def probe_device(device: DeviceEntry) -> str:
    """A short state line for ``device`` from :func:`drivers.devices.probe` (``"connected: Grbl 1.1h, Idle"``,
    ``"not connected: no such port"``, ``"open: 1280x800"``, ``"not available: no display 2: ..."``); it opens a
    GRBL port for at most its timeout (and the time the port takes to open); a display is asked its size without
    making a window; a camera must give a frame."""
    from drivers.devices import probe

    return probe(device.url, timeout=probe_wait(device))


def probe_devices(devices: Sequence[DeviceEntry]) -> list[str]:
    """:func:`probe_device` of every device, probed side by side and answered within the longest timeout plus
    :data:`PROBE_GRACE` seconds; a device still opening by then is ``"not connected: no answer within N s"``.

    The probes run on daemon threads: one stuck in a slow connect neither delays the answer nor the program's exit.
    """
    states: list[str | None] = [None] * len(devices)

    def run(index: int, device: DeviceEntry) -> None:
        states[index] = probe_device(device)

    threads = [threading.Thread(target=run, args=(i, d), name=f"probe {d.name}", daemon=True)
               for i, d in enumerate(devices)]
    for thread in threads:
        thread.start()
    limit = max((probe_wait(d) for d in devices), default=0.0) + PROBE_GRACE
    deadline = time.monotonic() + limit
    for thread in threads:
        thread.join(max(0.0, deadline - time.monotonic()))
    return [state if state is not None else f"not connected: no answer within {limit:g} s" for state in states]
