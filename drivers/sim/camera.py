"""A simulated camera (``sim://camera``): it renders the guide plane it looks at (:mod:`drivers.sim.camera_render`)
and knows the truth of every tag in it.

URL options (``sim://camera?size=1920x1080&f=1400&height=1000&noise=2&seed=3&projector=bench``)
---------------------------------------------------------------------------------------------
``size`` (``WxH`` pixels, default 1920x1080), ``f`` (focal length in pixels, default 1400), ``height`` (mm above the
plane, default 1000), ``target`` (``u,v``: where the optical axis meets the plane, mm, default 0,0), ``tilt`` (deg:
the camera moved back towards -v, still aiming at the target, default 0), ``roll`` (deg about the optical axis),
``k1`` ``k2`` ``p1`` ``p2`` ``k3`` (OpenCV's lens distortion), ``blur`` (Gaussian sigma, pixels), ``noise`` (sigma,
grey levels), ``vignetting`` (0..1), ``jpeg`` (quality 1..100), ``exposure`` (gain, default 1), ``supersample``
(samples per pixel along each axis, default 3), ``seed`` (of the noise: frame ``n`` uses ``seed + n``), ``name``
(share one camera, its scene and its faults, between the opens of that name, as ``sim://projector?name=`` does) and
``projector`` (the name of a shared simulated projector, ``sim://projector?name=NAME``: each frame shows the light it
throws now; none while no projector of that name is open: it is off) and ``view`` (``top``, the default: the
camera over the table, whose plane is the guide's; ``side``: the camera in front of the table facing the upright
reference board behind the parts, whose plane is the board's, ``height`` then its distance from the board and
``tilt`` how far below the target it stands). The station hands each view its own scene. An unknown option or a bad
value is one :class:`drivers.errors.SimConfigError` line naming it.

Over a laser's bed (:mod:`drivers.sim.camera_bed`): ``laser`` (the name of a shared simulated GRBL,
``sim://grbl?name=NAME``: the camera sees what it burned on the stock), ``bed`` (``u,v,angle``: where the laser's
machine X0 Y0 lies on the plane and how its X axis is turned, default ``200,200,0``: a 400 mm bed homed at the
back-right around the view's middle), ``stock`` (``u,v,w,h,angle``: a sheet's lower-left corner, size and turn on the
plane, mm and degrees) and ``kerf`` (the burn's width, mm, default 0.15). With ``laser`` or ``stock`` the plane is
the bed's dark honeycomb.

Faults (:meth:`SimulatedCamera.inject`)
-----------------------------------------
``"no-frame"`` (grab raises the driver's "no frame" :class:`~drivers.errors.DriverError`), ``"black"`` (frames are
black: a lens cap), ``"frozen"`` (the last frame again: a stalled stream), ``"unplugged"`` (grab and open raise, the
probe says "not available"). ``inject(None)`` clears them.
"""

from __future__ import annotations

import math
import threading
import urllib.parse
from dataclasses import replace
from typing import Any

import numpy as np

from drivers.errors import DriverError, SimConfigError
from drivers.sim.camera_bed import BED_COLOR, BedView, burns_of
from drivers.sim.camera_render import render
from drivers.sim.camera_scene import CameraModel, PlaneScene, RenderOptions, TagTruth
from drivers.sim.shared import SharedTwins, bounded_number

__all__ = ["FAULTS", "SimulatedCamera", "camera_named", "forget_cameras", "parse_camera_options", "sim_camera"]

FAULTS = ("no-frame", "black", "frozen", "unplugged")
_DISTORTION = ("k1", "k2", "p1", "p2", "k3")
_NUMBERS = {  # option: (lowest, highest, what it takes)
    "f": (1.0, 1e6, "a focal length in pixels > 0"), "height": (1e-3, 1e6, "a height in mm > 0"),
    "tilt": (-80.0, 80.0, "an angle in degrees from -80 to 80"), "roll": (-360.0, 360.0, "an angle in degrees"),
    "blur": (0.0, 50.0, "a Gaussian sigma in pixels from 0 to 50"), "noise": (0.0, 255.0, "grey levels from 0 to 255"),
    "vignetting": (0.0, 1.0, "a number from 0 to 1"), "exposure": (1e-3, 100.0, "a gain > 0"),
    **{k: (-10.0, 10.0, "a distortion coefficient from -10 to 10") for k in _DISTORTION},
    "kerf": (0.01, 5.0, "a burn width in mm from 0.01 to 5"),
}
_WHOLE = {"jpeg": (1, 100), "supersample": (1, 8), "seed": (0, 2**32 - 1)}
_OPTIONS = ("size", "target", "name", "projector", "view", "laser", "bed", "stock", *_NUMBERS, *_WHOLE)
#: The planes a simulated camera can look at (module notes).
VIEWS = ("top", "side")

_SHARED: SharedTwins[SimulatedCamera] = SharedTwins("camera")


class SimulatedCamera:
    """The simulated twin of :class:`drivers.camera.opencv.OpenCVCamera`.

    Parameters
    ----------
    url : str
        ``sim://camera`` with its options (module docstring).
    timeout : float
        Seconds a real camera is given for a frame (only quoted in the "no frame" fault's message).

    Attributes
    ----------
    options : RenderOptions
        How frames are degraded (from the URL; replace it to change them).
    frames_grabbed : int
        Frames returned so far.
    """

    def __init__(self, url: str = "sim://camera", timeout: float = 2.0) -> None:
        self.url = str(url).strip()
        parsed = parse_camera_options(self.url)
        self.name: str = parsed["name"]
        self.projector_name: str = parsed["projector"]
        #: The plane it looks at: ``"top"`` (the table) or ``"side"`` (the board behind the parts).
        self.view: str = parsed["view"]
        #: A laser's bed, its stock and burns (None: not over a laser's bed).
        self.bed_view: BedView | None = parsed["bed"]
        #: The simulated GRBL whose burns it sees (set by the station for a twin opened without ``name=``).
        self.laser_machine = None
        self.timeout = float(timeout)
        self.options: RenderOptions = parsed["render"]
        self._model: CameraModel = parsed["model"]
        self._scene = PlaneScene()
        self._truth: tuple[TagTruth, ...] = ()
        self._last: np.ndarray | None = None
        self._faults: set[str] = set()
        self._opens = 0
        self.frames_grabbed = 0
        self._lock = threading.RLock()

    # -- the Camera protocol -------------------------------------------------------------------------------------

    def open(self) -> None:
        """Start it (a shared twin counts its opens); an injected "unplugged" refuses."""
        with self._lock:
            if "unplugged" in self._faults:
                raise DriverError(f"camera {self.url}: not available: unplugged")
            self._opens += 1

    @property
    def is_open(self) -> bool:
        return self._opens > 0

    @property
    def size(self) -> tuple[int, int]:
        """Image ``(width, height)`` in pixels."""
        return self._model.image_size

    def grab(self) -> np.ndarray:
        """Render the scene as the camera sees it now (RGB uint8 ``h x w x 3``); :meth:`truth` then describes it."""
        with self._lock:
            if not self.is_open:
                raise DriverError(f"camera {self.url} is not open: open() it first")
            if "unplugged" in self._faults:
                raise DriverError(f"camera {self.url}: the camera is gone (unplugged)")
            if "no-frame" in self._faults:
                raise DriverError(f"camera {self.url}: no frame within {self.timeout:g} s")
            if "frozen" in self._faults and self._last is not None:
                self.frames_grabbed += 1
                return self._last.copy()
            scene = self._scene
            if self.projector_name:
                scene = replace(scene, light=self._projector_light())
            if self.bed_view is not None:
                from drivers.sim.protocol_sim import machine_named

                laser = self.laser_machine or (machine_named(self.bed_view.laser) if self.bed_view.laser else None)
                burns = burns_of(laser, self.bed_view.since)
                scene = replace(scene, images=scene.images + self.bed_view.items(burns), background=BED_COLOR)
            options = replace(self.options, seed=(self.options.seed + self.frames_grabbed) % 2**32)
            image, truth = render(scene, self._model, options)
            if "black" in self._faults:
                image = np.zeros_like(image)
            self._truth, self._last = truth, image
            self.frames_grabbed += 1
            return image.copy()

    def close(self) -> None:
        """Close one open; closing twice is harmless."""
        with self._lock:
            self._opens = max(0, self._opens - 1)

    def state(self) -> str:
        """The probe line, opening it (the caller closes it): ``"open: 1920x1080"`` or ``"not available: ..."``."""
        try:
            self.open()
        except DriverError:
            return "not available: unplugged (injected fault)"
        return f"open: {self.size[0]}x{self.size[1]}"

    def __enter__(self) -> SimulatedCamera:
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- what the twin adds ----------------------------------------------------------------------------------

    def set_scene(self, scene: PlaneScene) -> None:
        """What lies on the plane from the next frame on."""
        if not isinstance(scene, PlaneScene):
            raise SimConfigError(f"camera {self.url}: set_scene: expected a PlaneScene, got {type(scene).__name__}")
        with self._lock:
            self._scene = scene

    @property
    def scene(self) -> PlaneScene:
        return self._scene

    def truth(self) -> tuple[TagTruth, ...]:
        """The truth of every tag in the last frame grabbed (empty before the first)."""
        return self._truth

    @property
    def camera_model(self) -> CameraModel:
        """The camera's intrinsics and pose."""
        return self._model

    def place(self, model: CameraModel) -> None:
        """Move the camera (a bumped camera, a new lens): the next frame is seen through ``model``."""
        if not isinstance(model, CameraModel):
            raise SimConfigError(f"camera {self.url}: place: expected a CameraModel, got {type(model).__name__}")
        with self._lock:
            self._model = model

    def inject(self, fault: str | None) -> None:
        """Add a fault (one of :data:`FAULTS`), or clear them all with None."""
        if fault is not None and fault not in FAULTS:
            raise SimConfigError(f"camera {self.url}: inject: expected one of {', '.join(FAULTS)} or None, got "
                                 f"{fault!r}")
        with self._lock:
            if fault is None:
                self._faults.clear()
            else:
                self._faults.add(fault)

    @property
    def faults(self) -> frozenset[str]:
        return frozenset(self._faults)

    def _projector_light(self) -> dict | None:
        """The named projector's light; None while no projector of that name is open (it is off: it throws none)."""
        from drivers.sim.projector import projector_named

        projector = projector_named(self.projector_name)
        if projector is None:
            return None
        return projector.light()


def sim_camera(url: str = "sim://camera", timeout: float = 2.0, **_: Any) -> SimulatedCamera:
    """The registry's factory: a new twin, or the shared one when the URL has ``name=`` (a later open asking for
    another image size than the shared one's is refused)."""
    return _SHARED.share(SimulatedCamera(url, timeout), url)


#: ``camera_named(name)``: the shared twin opened with ``name=...``, if any; ``forget_cameras()``: forget them all.
camera_named, forget_cameras = _SHARED.named, _SHARED.forget


def parse_camera_options(url: str) -> dict:
    """A ``sim://camera?...`` URL's options, checked: ``{"model": CameraModel, "render": RenderOptions, "name": str,
    "projector": str, "view": str}`` (SimConfigError naming a bad option)."""
    parts = urllib.parse.urlsplit(url)
    if parts.scheme != "sim" or (parts.netloc or parts.path.lstrip("/")) != "camera":
        raise SimConfigError(f"expected a sim://camera URL, got {url!r}")
    query = {k: v[-1] for k, v in urllib.parse.parse_qs(parts.query, keep_blank_values=True).items()}
    values: dict[str, Any] = {"size": (1920, 1080), "target": (0.0, 0.0), "name": "", "projector": "", "view": "top",
                              "f": 1400.0,
                              "height": 1000.0, "tilt": 0.0, "roll": 0.0, "blur": 0.0, "noise": 0.0,
                              "vignetting": 0.0, "exposure": 1.0, "jpeg": None, "supersample": 3, "seed": 0,
                              "laser": "", "bed": (200.0, 200.0, 0.0), "stock": None, "kerf": 0.15,
                              **dict.fromkeys(_DISTORTION, 0.0)}
    for key, text in query.items():
        if key not in _OPTIONS:
            raise SimConfigError(f"unknown sim camera option {key!r}; known: {', '.join(sorted(_OPTIONS))}")
        values[key] = _option(key, text)
    model = CameraModel.looking_down(target_mm=values["target"], height_mm=values["height"],
                                     image_size=values["size"], focal_px=values["f"],
                                     dist_coeffs=[values[k] for k in _DISTORTION], tilt_deg=values["tilt"],
                                     roll_deg=values["roll"])
    options = RenderOptions(blur_px=values["blur"], noise=values["noise"], vignetting=values["vignetting"],
                            jpeg_quality=values["jpeg"], exposure=values["exposure"],
                            supersample=values["supersample"], seed=values["seed"])
    bed = None
    if values["laser"] or values["stock"] is not None:
        bed = BedView(values["laser"], values["bed"], values["stock"], values["kerf"])
    return {"model": model, "render": options, "name": values["name"], "projector": values["projector"],
            "view": values["view"], "bed": bed}


def _option(key: str, text: str) -> Any:
    if key == "view":
        if text not in VIEWS:
            raise SimConfigError(f"sim camera option view: expected one of {', '.join(VIEWS)}, got {text!r}")
        return text
    if key in ("bed", "stock"):
        count, form = (3, "u,v,angle (mm, mm, degrees)") if key == "bed" else (5, "u,v,w,h,angle (mm, degrees)")
        try:
            numbers = tuple(float(v) for v in text.split(","))
        except ValueError:
            numbers = ()
        if len(numbers) != count or not all(math.isfinite(v) for v in numbers) or (
                key == "stock" and min(numbers[2:4]) <= 0):
            raise SimConfigError(f"sim camera option {key}: expected {form}"
                                 f"{', w and h > 0' if key == 'stock' else ''}, got {text!r}")
        return numbers
    if key in ("name", "projector", "laser"):
        if not text.strip():
            raise SimConfigError(f"sim camera option {key}: expected a name, got ''")
        return text
    if key == "size":
        parts = text.lower().split("x")
        if len(parts) == 2 and all(p.isdigit() and 16 <= int(p) <= 16384 for p in parts):
            return int(parts[0]), int(parts[1])
        raise SimConfigError(f"sim camera option size: expected WxH in pixels from 16 to 16384 (e.g. "
                             f"size=1920x1080), got {text!r}")
    if key == "target":
        try:
            target = tuple(float(v) for v in text.split(","))
        except ValueError:
            target = ()
        if len(target) != 2 or not all(math.isfinite(v) for v in target):
            raise SimConfigError(f"sim camera option target: expected u,v in mm (e.g. target=100,-50), got {text!r}")
        return target
    if key in _WHOLE:
        low, high = _WHOLE[key]
        if not text.isdigit() or not low <= int(text) <= high:
            raise SimConfigError(f"sim camera option {key}: expected a whole number from {low} to {high}, got "
                                 f"{text!r}")
        return int(text)
    return bounded_number("camera", key, text, *_NUMBERS[key])
