"""A simulated projector (``sim://projector``): it keeps the frames shown, and tells a simulated camera what light
it throws.

URL options (``sim://projector?size=1280x800&folder=frames&name=bench``)
------------------------------------------------------------------------
``size`` (``WxH`` pixels, default 1280x800), ``folder`` (write each frame shown there as ``frame_0001.png``, ...;
made when the projector opens), ``name`` (share one projector, its frames and its placement, between the opens of
that name, as ``sim://grbl?name=`` does), ``keep`` (how many of the latest frames to keep in memory, default 32;
the count of frames shown goes on), ``area`` (``u0,v0,u1,v1``: where the image lands on the guide plane, in mm: its
lower-left corner on (u0, v0) and its upper-right on (u1, v1), a projector square to the plane; default: centred on
the plane's origin at :data:`DEFAULT_MM_PER_PIXEL`, 640 x 400 mm for 1280x800, in the middle of a simulated camera's
default view; see :meth:`SimulatedProjector.place` for any other placement). An unknown option or a bad value is one
:class:`drivers.errors.SimConfigError` line naming it.

What a camera sees: :meth:`SimulatedProjector.light`
------------------------------------------------------
A dict of plain data (builtins and one numpy array; no import of ``design`` or ``projector`` needed to read it)::

    {"size": [w, h],               # the image's size in pixels
     "image": ndarray (h, w, 3),   # uint8 RGB light leaving the lens now (black when blank or nothing shown);
                                   # row 0 is the top of the image, pixel (x, y) has its centre at (x, y)
     "blank": bool,                # True when showing black (blank(), closed, or nothing shown yet)
     "frames_shown": int,          # how many frames show() has been given
     "plane_from_pixel": [[...]],  # 3x3 homography: guide-plane (u, v, 1) mm ~ H @ (x, y, 1)
     "note": str or None}          # how the last frame was fitted to the screen, None when pixel for pixel

A simulated camera that knows its own pose on the guide plane lights each of its pixels with
``image[y, x]`` at ``(x, y) = inverse(plane_from_pixel) @ (u, v, 1)``.
"""

from __future__ import annotations

import threading
import urllib.parse
from pathlib import Path
from typing import Any

import numpy as np

from drivers.errors import DriverError, SimConfigError
from drivers.projector.frame import as_rgb, fit_to_screen
from drivers.sim.shared import SharedTwins

__all__ = ["DEFAULT_SIZE", "SimulatedProjector", "forget_projectors", "projector_named", "sim_projector",
           "twin_identity"]

DEFAULT_SIZE = (1280, 800)
DEFAULT_KEEP = 32
#: The guide plane's millimetres per pixel of an image without ``area=``.
DEFAULT_MM_PER_PIXEL = 0.5
_OPTIONS = ("area", "folder", "keep", "name", "size")

_SHARED: SharedTwins[SimulatedProjector] = SharedTwins("projector")


class SimulatedProjector:
    """The simulated twin of :class:`drivers.projector.display.DisplayProjector`.

    Parameters
    ----------
    url : str
        ``sim://projector`` with its options (see the module docstring).
    timeout : float
        Unused (the probe's signature for every device).

    Attributes
    ----------
    frames : list of ndarray
        The latest frames shown (at most ``keep``), oldest first, each as shown on the screen (fitted to its size).
    notes : list of str or None
        For each kept frame, how it was fitted (None: pixel for pixel).
    frames_shown : int
        Every frame ever shown.
    """

    def __init__(self, url: str = "sim://projector", timeout: float = 0.0) -> None:
        self.url = str(url).strip()
        options = parse_options(self.url)
        self._size: tuple[int, int] = options["size"]
        self.folder: Path | None = options["folder"]
        self.keep: int = options["keep"]
        self.name: str = options["name"]
        # a camera linked to it sees its light where it lands, without being told (``sim://camera?projector=NAME``)
        half_w, half_h = (DEFAULT_MM_PER_PIXEL * n / 2 for n in self._size)
        self.place(area_homography(options["area"] or (-half_w, -half_h, half_w, half_h), self._size))
        self.frames: list[np.ndarray] = []
        self.notes: list[str | None] = []
        self.frames_shown = 0
        self.blanked = True
        self._opens = 0  # a shared twin counts its opens: a probe's open and close leave the guide's open alone
        self._lock = threading.Lock()

    # -- the Projector protocol -------------------------------------------------------------------------------------

    def open(self) -> None:
        """Open it (make the PNG folder if one is asked for: a folder that cannot be made is a DriverError)."""
        if self.folder is not None:
            try:
                self.folder.mkdir(parents=True, exist_ok=True)
            except OSError as error:
                raise DriverError(f"projector {self.url}: cannot make the frame folder {str(self.folder)!r} "
                                  f"({error.strerror or error})") from None
        with self._lock:
            self._opens += 1

    @property
    def is_open(self) -> bool:
        """Whether it is open (a shared twin stays open until every open has been closed)."""
        return self._opens > 0

    @property
    def size(self) -> tuple[int, int]:
        """The screen's ``(width, height)`` in pixels."""
        return self._size

    def show(self, frame: Any) -> str | None:
        """Show ``frame``: kept in memory and written to the folder, if any. Returns None when shown pixel for
        pixel, else the line saying how it was scaled and letterboxed."""
        self._check_open()
        image, note = fit_to_screen(as_rgb(frame), self._size)
        image = image.copy()  # the caller may draw the next frame into the same array
        image.flags.writeable = False
        with self._lock:
            self.frames_shown += 1
            self.frames.append(image)
            self.notes.append(note)
            del self.frames[:-self.keep], self.notes[:-self.keep]
            self.blanked = False
            number = self.frames_shown
        if self.folder is not None:
            self._write(image, number)
        return note

    def blank(self) -> None:
        """Show black."""
        self._check_open()
        self.blanked = True

    def close(self) -> None:
        """Close one open; the last one shows black. The frames stay (a shared twin keeps them for its next open)."""
        with self._lock:
            self._opens = max(0, self._opens - 1)
            if not self._opens:
                self.blanked = True

    # -- what a camera sees --

    def current(self) -> tuple[np.ndarray, tuple[int, int]]:
        """The image on the screen now (black when blank) and its size ``(width, height)``."""
        with self._lock:
            if self.blanked or not self.frames:
                image = np.zeros((self._size[1], self._size[0], 3), dtype=np.uint8)
            else:
                image = self.frames[-1]
        return image, self._size

    def place(self, plane_from_pixel: Any) -> None:
        """Say where the image lands: a 3x3 homography, guide-plane (u, v, 1) mm ~ H @ (x, y, 1) pixels."""
        matrix = np.asarray(plane_from_pixel, dtype=float)
        if matrix.shape != (3, 3) or not np.isfinite(matrix).all() or abs(np.linalg.det(matrix)) < 1e-12:
            raise SimConfigError(f"projector {self.url}: placement: expected an invertible 3x3 homography, got "
                                 f"{np.shape(plane_from_pixel)}")
        self.plane_from_pixel = matrix / matrix[2, 2] if matrix[2, 2] else matrix

    def light(self) -> dict:
        """What a simulated camera needs to see the projection (the module docstring documents the fields)."""
        image, size = self.current()
        with self._lock:
            note = self.notes[-1] if self.notes and not self.blanked else None
            blank = self.blanked or not self.frames
        return {"size": list(size), "image": image, "blank": blank, "frames_shown": self.frames_shown,
                "plane_from_pixel": self.plane_from_pixel.tolist(),
                "note": note}

    def state(self) -> str:
        """The probe line, opening it (the caller closes it): ``"open: 1280x800"`` (``"open: 1280x800 (showing
        frame 3)"`` for a shared twin in use), or ``"not available: ..."`` (a folder that cannot be made)."""
        if self.is_open and self.frames_shown and not self.blanked:
            self.open()
            return f"open: {self._size[0]}x{self._size[1]} (showing frame {self.frames_shown})"
        try:
            self.open()
        except DriverError as error:
            return f"not available: {error}"
        return f"open: {self._size[0]}x{self._size[1]}"

    def __enter__(self) -> SimulatedProjector:
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _check_open(self) -> None:
        if not self.is_open:
            raise DriverError(f"projector {self.url} is not open: open() it first")

    def _write(self, image: np.ndarray, number: int) -> None:
        from PIL import Image

        path = self.folder / f"frame_{number:04d}.png"
        try:
            Image.fromarray(image).save(path)
        except OSError as error:
            raise DriverError(f"projector {self.url}: cannot write {str(path)!r} ({error.strerror or error})") from None


def sim_projector(url: str = "sim://projector", timeout: float = 0.0) -> SimulatedProjector:
    """The registry's factory: a new twin, or the shared one when the URL has ``name=`` (a later open with another
    size than the shared one's is refused)."""
    return _SHARED.share(SimulatedProjector(url, timeout), url)


def twin_identity(url: str) -> str:
    """Which twin ``url`` opens, for what is measured on it: ``sim://projector?name=NAME`` for a shared twin (every
    open of that name is the same projector, whatever its other options), ``sim://projector`` for an unnamed one
    (a new twin at each open, placed by its URL). A bad option is a :class:`SimConfigError`."""
    name = parse_options(url)["name"]
    return f"sim://projector?name={urllib.parse.quote(name, safe='')}" if name else "sim://projector"


def projector_named(name: str) -> SimulatedProjector | None:
    """The shared twin opened with ``name=...``, if any (the simulated camera finds it this way)."""
    return _SHARED.named(name)


def forget_projectors() -> None:
    """Forget every shared twin (tests)."""
    _SHARED.forget()


def parse_options(url: str) -> dict:
    """The options of a ``sim://projector?...`` URL, checked (SimConfigError naming the option)."""
    parts = urllib.parse.urlsplit(url)
    if parts.scheme != "sim" or (parts.netloc or parts.path.lstrip("/")) != "projector":
        raise SimConfigError(f"expected a sim://projector URL, got {url!r}")
    query = {k: v[-1] for k, v in urllib.parse.parse_qs(parts.query, keep_blank_values=True).items()}
    options: dict[str, Any] = {"size": DEFAULT_SIZE, "folder": None, "keep": DEFAULT_KEEP, "name": "", "area": None}
    for key, value in query.items():
        if key not in _OPTIONS:
            raise SimConfigError(f"unknown sim projector option {key!r}; known: {', '.join(_OPTIONS)}")
        if key == "size":
            options["size"] = _size_option(value)
        elif key == "folder":
            if not value.strip():
                raise SimConfigError("sim projector option folder: expected a folder path, got ''")
            options["folder"] = Path(value).expanduser()
        elif key == "keep":
            if not value.isdigit() or int(value) < 1:
                raise SimConfigError(f"sim projector option keep: expected a whole number >= 1, got {value!r}")
            options["keep"] = int(value)
        elif key == "area":
            options["area"] = _area_option(value)
        else:
            options["name"] = value
    return options


def _size_option(text: str) -> tuple[int, int]:
    parts = text.lower().split("x")
    if len(parts) == 2 and all(p.isdigit() for p in parts) and all(1 <= int(p) <= 16384 for p in parts):
        return int(parts[0]), int(parts[1])
    raise SimConfigError(f"sim projector option size: expected WxH in pixels from 1 to 16384 (e.g. size=1280x800), "
                         f"got {text!r}")


def _area_option(text: str) -> tuple[float, float, float, float]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 4 or not np.isfinite(values).all() or values[2] <= values[0] or values[3] <= values[1]:
        raise SimConfigError(f"sim projector option area: expected u0,v0,u1,v1 in mm with u1 > u0 and v1 > v0 "
                             f"(e.g. area=0,0,640,400), got {text!r}")
    return values


def area_homography(area: tuple[float, float, float, float], size: tuple[int, int]) -> np.ndarray:
    """Guide-plane mm from pixels for an image of ``size`` landing square on ``area`` (u0, v0, u1, v1): the
    image's top-left pixel corner (-0.5, -0.5) on (u0, v1), its bottom-right (w - 0.5, h - 0.5) on (u1, v0)."""
    u0, v0, u1, v1 = area
    width, height = size
    su, sv = (u1 - u0) / width, (v1 - v0) / height
    return np.array([[su, 0.0, u0 + 0.5 * su], [0.0, -sv, v1 - 0.5 * sv], [0.0, 0.0, 1.0]])
