"""A real camera on OpenCV's ``VideoCapture``: a camera index (``0``), a device path (``/dev/video2``), a stream URL
(``rtsp://...``, ``http(s)://...`` MJPEG) or a video file.

What it promises
----------------
- :meth:`OpenCVCamera.open` returns once the first frame has come, or raises one :class:`~drivers.errors.DriverError`
  line within ``timeout`` seconds (2 by default): "no such file", "cannot open ...", "no frame within 2 s".
- :meth:`~OpenCVCamera.grab` returns an RGB uint8 image, the newest frame: a live source (a camera, a stream) is read
  continuously by a thread of its own, so a grab never returns a frame that waited in a buffer, and a source that
  stops sending is one "no frame within N s" line, never a hang. A video file is read frame by frame, one per grab,
  starting again at its end (a recorded session replayed as a camera).
- Resolution, exposure and focus are asked for where the camera allows; what it refused is listed in
  :attr:`~OpenCVCamera.refused` and in the probe line (``"open: 1280x720 (refused: exposure, focus)"``).
"""

from __future__ import annotations

import re
import threading
from pathlib import Path

import numpy as np

from drivers.errors import DriverError

__all__ = ["FRAME_TIMEOUT", "OpenCVCamera", "opencv_camera"]

#: Seconds a camera is given for its first frame, and for each frame after.
FRAME_TIMEOUT = 2.0


class OpenCVCamera:
    """A camera behind ``cv2.VideoCapture``; follows :class:`drivers.devices.Camera`.

    Parameters
    ----------
    url : str
        ``"0"`` (index), ``"/dev/video2"``, ``"rtsp://..."``, ``"http(s)://..."`` or a video file's path.
    timeout : float
        Seconds to wait for a frame (the first and each next one).
    size : tuple of int, optional
        ``(width, height)`` to ask for.
    exposure : float, optional
        Manual exposure in the backend's unit (V4L2: 100 us steps); auto exposure is turned off first.
    focus : float, optional
        Manual focus in the backend's unit; autofocus is turned off first.

    Attributes
    ----------
    refused : tuple of str
        The settings asked for that the camera did not take (``"size (gives 640x480)"``, ``"exposure"``, ``"focus"``).
    """

    def __init__(self, url: str, timeout: float = FRAME_TIMEOUT, *, size: tuple[int, int] | None = None,
                 exposure: float | None = None, focus: float | None = None) -> None:
        self.url = str(url).strip()
        self.timeout = float(timeout)
        self.wanted_size = size
        self.exposure = exposure
        self.focus = focus
        self.refused: tuple[str, ...] = ()
        self._kind = _source_kind(self.url)
        self._capture = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._ready = threading.Condition()
        self._frame: np.ndarray | None = None
        self._sequence = 0  # frames read so far (live sources)
        self._given = 0  # the sequence number of the last frame grab() returned
        self._failure: str | None = None
        self._size: tuple[int, int] | None = None

    # -- the Camera protocol -------------------------------------------------------------------------------------

    def open(self) -> None:
        """Open the source and wait for its first frame (DriverError with one line saying why not)."""
        if self.is_open:
            return
        self._stop.clear()
        self._failure, self._frame, self._sequence, self._given = None, None, 0, 0
        if self._kind == "file":
            self._open_file()
            return
        if self._kind == "device" and not Path(self.url).exists():
            raise DriverError(f"camera {self.url}: no such device (is the camera plugged in? `ls /dev/video*`)")
        self._thread = threading.Thread(target=self._run, name=f"camera {self.url}", daemon=True)
        self._thread.start()
        with self._ready:
            self._ready.wait_for(lambda: self._frame is not None or self._failure is not None, self.timeout)
            failure, got = self._failure, self._frame is not None
        if not got:
            self.close()
            raise DriverError(f"camera {self.url}: {failure or f'no frame within {self.timeout:g} s'}")

    @property
    def is_open(self) -> bool:
        return self._capture is not None if self._kind == "file" else (
            self._thread is not None and self._thread.is_alive() and self._frame is not None)

    @property
    def size(self) -> tuple[int, int]:
        """The frames' ``(width, height)`` as the camera gives them (which may not be what was asked for); ``(0, 0)``
        until it has given its first frame."""
        return self._size or (0, 0)

    def grab(self) -> np.ndarray:
        """The newest frame (RGB uint8 ``h x w x 3``); a file's next frame."""
        if self._kind == "file":
            if self._capture is None:
                raise DriverError(f"camera {self.url} is not open: open() it first")
            return _rgb(self._read_file())
        if self._thread is None:
            raise DriverError(f"camera {self.url} is not open: open() it first")
        with self._ready:
            self._ready.wait_for(lambda: self._sequence > self._given or self._failure is not None, self.timeout)
            if self._sequence > self._given:
                self._given = self._sequence
                return _rgb(self._frame)
            failure = self._failure
        raise DriverError(f"camera {self.url}: {failure or f'no frame within {self.timeout:g} s'}")

    def close(self) -> None:
        """Stop reading and release the camera; closing twice is harmless."""
        self._stop.set()
        thread, self._thread = self._thread, None
        if thread is not None and thread is not threading.current_thread():
            thread.join(1.0)  # a read stuck in the backend ends on its own timeout; the thread releases it then
        if self._kind == "file" and self._capture is not None:
            self._capture.release()
        self._capture = None

    def state(self) -> str:
        """The probe line, opening it (the caller closes it): ``"open: 1920x1080"`` (with ``(refused: ...)``), or
        ``"not available: <why>"``."""
        try:
            self.open()
        except DriverError as error:
            return "not available: " + str(error).removeprefix(f"camera {self.url}: ")
        refused = f" (refused: {', '.join(self.refused)})" if self.refused else ""
        return f"open: {self.size[0]}x{self.size[1]}{refused}"

    def __enter__(self) -> OpenCVCamera:
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- inside --------------------------------------------------------------------------------------------------

    def _new_capture(self):
        """A ``cv2.VideoCapture`` of the source with the settings asked for applied, or a reason string."""
        import cv2

        _quiet_backends()
        milliseconds = max(1, int(self.timeout * 1000))
        if self._kind == "index":
            capture = cv2.VideoCapture(int(self.url))
        elif self._kind == "device":
            capture = cv2.VideoCapture(self.url, cv2.CAP_V4L2)
        else:  # streams and files through FFmpeg, which honours the timeouts
            capture = cv2.VideoCapture(self.url, cv2.CAP_FFMPEG, [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, milliseconds,
                                                                 cv2.CAP_PROP_READ_TIMEOUT_MSEC, milliseconds])
        if not capture.isOpened():
            capture.release()
            return {"index": "cannot open camera index " + self.url + " (no such camera, or in use)",
                    "device": "cannot open the device (no such camera, in use, or no permission: join the video "
                              "group?)",
                    "stream": "cannot open the stream (unreachable, refused, or not a video stream)",
                    "file": "cannot read the video file (not a video, or a codec OpenCV lacks)"}[self._kind]
        self.refused = self._apply_settings(capture)
        return capture

    def _apply_settings(self, capture) -> tuple[str, ...]:
        import cv2

        refused = []
        if self.wanted_size is not None:
            width, height = self.wanted_size
            capture.set(cv2.CAP_PROP_FRAME_WIDTH, width)
            capture.set(cv2.CAP_PROP_FRAME_HEIGHT, height)  # checked on the first frame
        if self.exposure is not None:
            capture.set(cv2.CAP_PROP_AUTO_EXPOSURE, 1)  # V4L2 "manual"; others ignore it
            if not (capture.set(cv2.CAP_PROP_EXPOSURE, float(self.exposure))
                    and abs(capture.get(cv2.CAP_PROP_EXPOSURE) - float(self.exposure)) < 1e-6 + 0.01 * abs(
                        float(self.exposure))):
                refused.append("exposure")
        if self.focus is not None:
            capture.set(cv2.CAP_PROP_AUTOFOCUS, 0)
            if not (capture.set(cv2.CAP_PROP_FOCUS, float(self.focus))
                    and abs(capture.get(cv2.CAP_PROP_FOCUS) - float(self.focus)) < 1e-6 + 0.01 * abs(
                        float(self.focus))):
                refused.append("focus")
        return tuple(refused)

    def _first_frame(self, frame: np.ndarray) -> None:
        self._size = (int(frame.shape[1]), int(frame.shape[0]))
        if self.wanted_size is not None and tuple(self.wanted_size) != self._size:
            self.refused = (f"size (gives {self._size[0]}x{self._size[1]})", *self.refused)

    def _run(self) -> None:
        """The reader thread of a live source: open, then keep the newest frame until stopped."""
        capture = self._new_capture()
        if isinstance(capture, str):
            with self._ready:
                self._failure = capture
                self._ready.notify_all()
            return
        try:
            while not self._stop.is_set():
                ok, frame = capture.read()
                if self._stop.is_set():
                    break
                with self._ready:
                    if not ok or frame is None:
                        # a stream that ended or stalled past the backend's read timeout: grab() says so
                        self._failure = f"no frame within {self.timeout:g} s (the source stopped sending)"
                        self._ready.notify_all()
                        break
                    if self._frame is None:
                        self._first_frame(frame)
                    self._frame = frame
                    self._sequence += 1
                    self._ready.notify_all()
        finally:
            capture.release()

    def _open_file(self) -> None:
        import cv2

        if not Path(self.url).expanduser().is_file():
            raise DriverError(f"camera {self.url}: no such video file")
        capture = self._new_capture()
        if isinstance(capture, str):
            raise DriverError(f"camera {self.url}: {capture}")
        self._capture = capture
        try:
            self._first_frame(self._read_file())
        except DriverError:
            self.close()
            raise
        capture.set(cv2.CAP_PROP_POS_FRAMES, 0)  # the first grab is the first frame

    def _read_file(self) -> np.ndarray:
        import cv2

        ok, frame = self._capture.read()
        if not ok:  # its end: start again
            self._capture.set(cv2.CAP_PROP_POS_FRAMES, 0)
            ok, frame = self._capture.read()
        if not ok or frame is None:
            raise DriverError(f"camera {self.url}: the video file has no frame OpenCV can read")
        return frame


def _quiet_backends() -> None:
    """Silence OpenCV's and FFmpeg's own log lines ("Connection refused", "can't capture by name"): the driver says
    why in one line of its own. Process-wide: OpenCV keeps one log level."""
    import os

    import cv2

    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET, read when FFmpeg opens a source
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)


def _source_kind(url: str) -> str:
    if re.fullmatch(r"\d+", url):
        return "index"
    if re.fullmatch(r"/dev/video\d+", url):
        return "device"
    if re.match(r"(rtsp|https?)://", url, re.IGNORECASE):
        return "stream"
    return "file"


def _rgb(frame: np.ndarray) -> np.ndarray:
    import cv2

    if frame.ndim == 2:
        return cv2.cvtColor(frame, cv2.COLOR_GRAY2RGB)
    if frame.shape[2] == 4:
        return cv2.cvtColor(frame, cv2.COLOR_BGRA2RGB)
    return cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)


def opencv_camera(url: str, timeout: float = FRAME_TIMEOUT, **options) -> OpenCVCamera:
    """The registry's factory (``size``, ``exposure``, ``focus`` as keywords). A camera gets at least
    :data:`FRAME_TIMEOUT` for its first frame (a USB camera takes about a second to start), whatever a probe's
    shorter timeout for serial ports says."""
    return OpenCVCamera(url, max(float(timeout or 0.0), FRAME_TIMEOUT), **options)
