"""One small interface per kind of device, and one registry from a device URL to its driver.

Kinds
-----
- ``grbl``: a GRBL 1.1 controller behind a serial port URL (the plotter and the laser);
- ``camera``: a camera: a real one on OpenCV's ``VideoCapture`` (:mod:`drivers.camera.opencv`) or its simulated twin
  (:mod:`drivers.sim.camera`);
- ``projector``: a projector: a full-screen window on a display (:mod:`drivers.projector`) or its simulated twin
  (:mod:`drivers.sim.projector`);
- ``world``: the physical world the contraption is built in; only simulated (:mod:`drivers.sim.world`: hidden
  physics and a maker placing parts with human error), for the station's unattended loop.

The registry (:func:`resolve`) reads a URL and says which kind it names and which driver serves it. A kind whose
driver does not exist would be said so (:attr:`DriverInfo.available` False, :func:`probe` answering
``"no driver yet"``): no device is ever faked as working.

Accepted URLs
-------------
GRBL: ``sim://grbl?profile=NAME`` (the simulated twin), ``/dev/tty*``, ``COMn``, ``socket://HOST:PORT``,
``rfc2217://HOST:PORT``, ``loop://``. Camera: ``sim://camera``, an integer index (``0``), ``/dev/video*``,
``rtsp://...``, ``http(s)://...`` or a video file (``.mp4``, ``.avi``, ``.mkv``, ``.mov``). Projector:
``sim://projector``, ``display:N``. World: ``sim://world``.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

from drivers.errors import DriverError, PortError

__all__ = [
    "ACCEPTED_FORMS",
    "Camera",
    "FORMS",
    "DriverInfo",
    "GrblDevice",
    "KINDS",
    "Projector",
    "UnknownDeviceURL",
    "probe",
    "projector_identity",
    "resolve",
]

KINDS = ("grbl", "camera", "projector", "world")

#: Seconds between status queries while a GRBL probe waits for the answer.
QUERY_INTERVAL = 0.25

VIDEO_SUFFIXES = (".mp4", ".avi", ".mkv", ".mov", ".webm")

#: The URLs :func:`resolve` accepts for each kind, for messages naming what was expected.
FORMS = {
    "grbl": "sim://grbl?profile=NAME, /dev/tty*, COMn, socket://HOST:PORT, rfc2217://HOST:PORT, loop://",
    "camera": "sim://camera, an index such as 0, /dev/video*, rtsp://..., http(s)://..., a video file "
    f"({', '.join(VIDEO_SUFFIXES)})",
    "projector": "sim://projector, display:N",
    "world": "sim://world",
}

#: What :func:`resolve` accepts, for the error message on an URL that matches nothing.
ACCEPTED_FORMS = (f"GRBL: {FORMS['grbl']}; camera: {FORMS['camera']}; projector: {FORMS['projector']}; "
                  f"world: {FORMS['world']}")


class UnknownDeviceURL(DriverError):
    """A device URL that no driver in the registry accepts."""


@runtime_checkable
class GrblDevice(Protocol):
    """A GRBL machine as the station sees it before a job: open the port, ask its state, close.

    :class:`drivers.grbl.connection.GrblConnection` is the full driver (streaming, real-time bytes); this is the
    small part every GRBL device offers.
    """

    url: str

    def open(self) -> None:
        """Open the port (raises :class:`drivers.errors.PortError` when it cannot)."""

    def state(self) -> str:
        """A short state line (``"connected: Grbl 1.1h"``, ``"not connected: no such port"``)."""

    def close(self) -> None:
        """Close the port; closing twice is harmless."""


@runtime_checkable
class Camera(Protocol):
    """A camera: open it, grab images of :attr:`size`, close it.

    :class:`drivers.camera.opencv.OpenCVCamera` (an index, ``/dev/video*``, a stream URL, a video file) and
    :class:`drivers.sim.camera.SimulatedCamera` (``sim://camera``) follow it. A camera that cannot be opened, or that
    gives no frame within its timeout (2 s), raises a :class:`drivers.errors.DriverError` with one line saying why.
    """

    def open(self) -> None:
        """Start the camera (returns once it has given a frame)."""

    def grab(self) -> Any:
        """One image: an ``H x W x 3`` uint8 RGB array, the newest the camera has."""

    @property
    def size(self) -> tuple[int, int]:
        """Image size ``(width, height)`` in pixels."""

    def close(self) -> None:
        """Release the camera; closing twice is harmless."""

    def state(self) -> str:
        """The probe line, opening it: ``"open: 1920x1080"`` or ``"not available: <why>"``."""


@runtime_checkable
class Projector(Protocol):
    """A projector: open it, show frames (fitted to :attr:`size`), blank it, close it.

    :class:`drivers.projector.display.DisplayProjector` (``display:N``) and
    :class:`drivers.sim.projector.SimulatedProjector` (``sim://projector``) follow it. A projector that cannot be
    opened raises a :class:`drivers.errors.DriverError` with one line saying why.
    """

    def open(self) -> None:
        """Open the output (a full-screen window on a display); opening twice is harmless."""

    def show(self, frame: Any) -> str | None:
        """Project one frame: a uint8 array ``H x W`` (grey) or ``H x W x 3`` (RGB), or a PIL image. A frame whose
        size is not :attr:`size` is scaled and letterboxed; the answer says so (None: shown pixel for pixel)."""

    def blank(self) -> None:
        """Show black, staying open."""

    @property
    def size(self) -> tuple[int, int]:
        """Output size ``(width, height)`` in pixels."""

    def close(self) -> None:
        """Blank the output and release it; closing twice is harmless."""


@dataclass(frozen=True)
class DriverInfo:
    """What the registry knows about one device URL.

    Parameters
    ----------
    url : str
        The URL as given.
    kind : str
        One of :data:`KINDS`.
    driver : str
        The driver's name (``"grbl-serial"``) or ``""`` when there is none yet.
    simulated : bool
        True for the ``sim://`` twins.
    factory : callable or None
        ``factory(url, **options)`` makes a device of the kind's protocol; None when no driver exists yet.
    """

    url: str
    kind: str
    driver: str
    simulated: bool
    factory: Callable[..., Any] | None

    @property
    def available(self) -> bool:
        """Whether a driver exists for this URL."""
        return self.factory is not None


class GrblSerialDevice:
    """The :class:`GrblDevice` of a GRBL controller on a serial port URL (real or ``sim://grbl``).

    It opens the port, writes the status query ``?`` (a real-time byte that changes nothing; a soft reset would stop
    a job) until the status report comes, and reads the banner, if any, and the state. The full driver is
    :class:`~drivers.grbl.connection.GrblConnection`.

    Probing is not free on every machine: an Arduino-based controller resets when its USB port is opened (the
    serial adapter's DTR line), so probing one that another program is streaming to stops that job. Probe a real
    machine when nothing else drives it.

    Parameters
    ----------
    url : str
        Port URL.
    baud : int
        Baud rate (GRBL 1.1: 115200).
    timeout : float
        How long :meth:`state` waits for the status report, in seconds (a board that resets on open needs about 2).
    """

    def __init__(self, url: str, baud: int = 115200, timeout: float = 0.5) -> None:
        self.url = url
        self.baud = baud
        self.timeout = timeout
        self._port = None

    def open(self) -> None:
        from drivers.grbl.connection import open_port

        if self._port is None:
            self._port = open_port(self.url, baud=self.baud, timeout=0.05)

    def state(self) -> str:
        try:
            self.open()
        except PortError as error:
            return "not connected: " + _port_problem(str(error))
        port = self._port
        try:
            port.reset_input_buffer()
            received = b""
            deadline = time.monotonic() + self.timeout
            next_query = 0.0
            while (now := time.monotonic()) < deadline:
                # asked again until answered: a board that resets when its port opens (an Arduino) loses what is
                # written while it boots, and prints its banner only after a second or two
                if now >= next_query:
                    port.write(b"?")
                    next_query = now + QUERY_INTERVAL
                received = (received + port.read(256))[-4096:]
                status = re.search(rb"<([A-Za-z]+)[|:>]", received)
                if status:
                    banner = re.search(rb"Grbl (\S+)", received)
                    version = f"Grbl {banner.group(1).decode('ascii', 'replace')}, " if banner else ""
                    return f"connected: {version}{status.group(1).decode('ascii')}"
        except (OSError, ValueError) as error:  # the port vanished while probing
            return f"not connected: {error}"
        return f"not connected: no GRBL banner within {self.timeout:g} s"

    def close(self) -> None:
        if self._port is not None:
            try:
                self._port.close()
            finally:
                self._port = None


def _port_problem(message: str) -> str:
    """A short reason from :func:`~drivers.grbl.connection.open_port`'s message."""
    if "No such file or directory" in message or "Errno 2" in message:
        return "no such port"
    if "Permission denied" in message or "Errno 13" in message:
        return "permission denied (join the dialout group?)"
    return message


_GRBL = "grbl-serial"
_DISPLAY, _SIM_PROJECTOR = "sdl-display", "sim-projector"
_OPENCV, _SIM_CAMERA = "opencv", "sim-camera"
_SIM_WORLD = "sim-world"


def _display_projector(url: str, **options: Any) -> Any:
    """A :class:`drivers.projector.display.DisplayProjector` (imported when asked for: it starts processes)."""
    from drivers.projector.display import DisplayProjector

    return DisplayProjector(url, **options)


def _sim_projector(url: str, **options: Any) -> Any:
    """A :class:`drivers.sim.projector.SimulatedProjector` (the shared one for a ``name=`` URL)."""
    from drivers.sim.projector import sim_projector

    return sim_projector(url, **options)


def _opencv_camera(url: str, **options: Any) -> Any:
    """A :class:`drivers.camera.opencv.OpenCVCamera` (cv2 is imported when a camera is asked for)."""
    from drivers.camera.opencv import opencv_camera

    return opencv_camera(url, **options)


def _sim_camera(url: str, **options: Any) -> Any:
    """A :class:`drivers.sim.camera.SimulatedCamera` (the shared one for a ``name=`` URL)."""
    from drivers.sim.camera import sim_camera

    return sim_camera(url, **options)


def _sim_world(url: str, **options: Any) -> Any:
    """A :class:`drivers.sim.world.SimulatedWorld` (the shared one for a ``name=`` URL)."""
    from drivers.sim.world import sim_world

    return sim_world(url, **options)


#: ``(pattern, kind, driver, simulated, factory)``, tried in order; the first that matches wins.
_RULES: tuple[tuple[re.Pattern, str, str, bool, Callable[..., Any] | None], ...] = (
    (re.compile(r"^sim://grbl(\?.*)?$"), "grbl", _GRBL, True, GrblSerialDevice),
    (re.compile(r"^/dev/tty\S+$"), "grbl", _GRBL, False, GrblSerialDevice),
    (re.compile(r"^COM\d+$", re.IGNORECASE), "grbl", _GRBL, False, GrblSerialDevice),
    (re.compile(r"^(socket|rfc2217)://\S+$"), "grbl", _GRBL, False, GrblSerialDevice),
    (re.compile(r"^loop://\S*$"), "grbl", _GRBL, False, GrblSerialDevice),
    (re.compile(r"^sim://camera(\?.*)?$"), "camera", _SIM_CAMERA, True, _sim_camera),
    (re.compile(r"^\d+$"), "camera", _OPENCV, False, _opencv_camera),
    (re.compile(r"^/dev/video\d+$"), "camera", _OPENCV, False, _opencv_camera),
    (re.compile(r"^(rtsp|https?)://\S+$"), "camera", _OPENCV, False, _opencv_camera),
    (re.compile(r"^\S.*(" + "|".join(re.escape(s) for s in VIDEO_SUFFIXES) + r")$", re.IGNORECASE),
     "camera", _OPENCV, False, _opencv_camera),
    (re.compile(r"^sim://projector(\?.*)?$"), "projector", _SIM_PROJECTOR, True, _sim_projector),
    (re.compile(r"^display:\d+$"), "projector", _DISPLAY, False, _display_projector),
    (re.compile(r"^sim://world(\?.*)?$"), "world", _SIM_WORLD, True, _sim_world),
)


def resolve(url: str) -> DriverInfo:
    """The kind and driver of device ``url``.

    Raises
    ------
    UnknownDeviceURL
        When no rule accepts ``url``; the message names it and lists the accepted forms.
    """
    text = str(url).strip()
    for pattern, kind, driver, simulated, factory in _RULES:
        if pattern.match(text):
            return DriverInfo(text, kind, driver, simulated, factory)
    raise UnknownDeviceURL(f"device URL {str(url)!r} matches no driver; accepted: {ACCEPTED_FORMS}")


def projector_identity(url: str) -> str:
    """Which projector ``url`` drives, as a text that two URLs of the same projector share: ``display:N`` for a
    display (SDL's display N), ``sim://projector?name=NAME`` for a shared simulated twin whatever its other
    options, ``sim://projector`` for an unnamed one. What is measured on a projector (its calibration) is kept
    under it.

    Raises
    ------
    UnknownDeviceURL
        ``url`` matches no driver, or names another kind of device.
    SimConfigError
        A ``sim://projector`` URL with a bad option.
    """
    info = resolve(url)
    if info.kind != "projector":
        raise UnknownDeviceURL(f"device URL {info.url!r} is a {info.kind}, not a projector; projector: "
                               f"{FORMS['projector']}")
    if info.driver == _SIM_PROJECTOR:
        from drivers.sim.projector import twin_identity

        return twin_identity(info.url)
    return info.url


def probe(url: str, timeout: float = 0.5) -> str:
    """A short state line for the device at ``url``, opening it briefly when a driver exists.

    For GRBL the port is opened and asked its status (``"connected: Grbl 1.1h, Idle"``), or the reason it is not
    connected. For a camera: ``"open: 1920x1080"`` once it has given a frame (a real camera gets at least
    :data:`drivers.camera.opencv.FRAME_TIMEOUT` for it; settings it refused are listed) or ``"not available: <why>"``.
    For a projector:
    ``"open: 1280x800"`` (a display adds its number, the display count and SDL's driver; it is asked in a
    short-lived process that makes no window, waiting at least
    :data:`drivers.projector.display.DISPLAY_PROBE_TIMEOUT`) or ``"not available: <why>"``.
    """
    info = resolve(url)
    if not info.available:
        return "no driver yet"
    try:
        device = info.factory(info.url, timeout=timeout)
    except DriverError as error:  # a sim:// URL with a bad option
        return ("not connected: " if info.kind == "grbl" else "not available: ") + str(error)
    try:
        return device.state()
    finally:
        device.close()
