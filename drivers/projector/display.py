"""The real projector: a borderless full-screen window on one display (``display:N``), through SDL (pygame-ce).

``display:N`` names SDL's display N, counted from 0 in SDL's order: ``display:0`` is usually the computer's own
screen and ``display:1`` the projector plugged in beside it. The window covers that display at its native (desktop)
resolution, without a frame or a mouse pointer, and stays up when the station's terminal takes the focus.

pygame-ce is an optional extra (``pip install 'chaos-station[projector]'``); without it, opening says so in one
line. The window runs in a process of its own (:mod:`drivers.projector.window` says why); this class drives it and
is safe to call from any one thread at a time. Frames of another size than the screen are scaled and letterboxed
(:func:`drivers.projector.frame.fit_to_screen`); :meth:`DisplayProjector.show` says so.
"""

from __future__ import annotations

import importlib.util
import os
import queue
import re
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import numpy as np

from drivers.errors import DriverError
from drivers.projector.frame import as_rgb, fit_to_screen
from drivers.projector.window import read_message, write_message

__all__ = ["DISPLAY_PROBE_TIMEOUT", "DisplayProjector", "display_index"]

#: Seconds a probe or an open waits at least for the window process (a Python process must start and load SDL).
DISPLAY_PROBE_TIMEOUT = 3.0
#: Seconds a request (show a frame, blank) may take before the window process is given up.
REQUEST_TIMEOUT = 5.0
INSTALL_HINT = "pygame-ce is not installed; install the extra: pip install 'chaos-station[projector]' (pygame-ce)"


def display_index(url: str) -> int:
    """The display number of a ``display:N`` URL (a :class:`DriverError` on anything else)."""
    match = re.fullmatch(r"display:(\d+)", str(url).strip())
    if not match:
        raise DriverError(f"projector URL {url!r}: expected display:N (N = SDL's display number, from 0)")
    return int(match.group(1))


class DisplayProjector:
    """A projector on display N (the :class:`drivers.devices.Projector` protocol).

    Parameters
    ----------
    url : str
        ``display:N``.
    timeout : float
        Seconds to wait for the window process to answer an open or a probe (at least
        :data:`DISPLAY_PROBE_TIMEOUT`).
    """

    def __init__(self, url: str, timeout: float = DISPLAY_PROBE_TIMEOUT) -> None:
        self.url = str(url).strip()
        self.index = display_index(self.url)
        self.timeout = max(float(timeout), DISPLAY_PROBE_TIMEOUT)
        self._process: subprocess.Popen | None = None
        self._answers: queue.Queue = queue.Queue()
        self._size: tuple[int, int] | None = None
        self.driver = ""  # SDL's video driver once open (x11, wayland, windows, cocoa, offscreen...)

    # -- the Projector protocol -------------------------------------------------------------------------------------

    def open(self) -> None:
        """Make the full-screen window (raises :class:`DriverError` with one line when it cannot)."""
        if self._process is not None:
            return
        answer = self._start("open")
        self._size = tuple(answer["size"])
        self.driver = answer.get("driver", "")

    @property
    def size(self) -> tuple[int, int]:
        """The screen's ``(width, height)`` in pixels (the display's native resolution); ``(0, 0)`` until open."""
        return self._size or (0, 0)

    def show(self, frame: Any) -> str | None:
        """Project ``frame`` (see :mod:`drivers.projector.frame`); None when shown pixel for pixel, else the line
        saying how it was scaled and letterboxed to the screen."""
        self._check_open()
        image, note = fit_to_screen(as_rgb(frame), self.size)
        self._request({"op": "show", "w": image.shape[1], "h": image.shape[0]}, image.tobytes())
        return note

    def blank(self) -> None:
        """Show black (the projector stays open)."""
        self._check_open()
        self._request({"op": "blank"})

    def close(self) -> None:
        """Close the window; closing twice is harmless."""
        process, self._process = self._process, None
        self._size = None
        if process is None:
            return
        try:
            write_message(process.stdin, {"op": "close"})
        except (OSError, ValueError):  # it has gone already
            pass
        _stop(process)

    # -- beyond the protocol --

    def screen_pixels(self) -> np.ndarray:
        """What the window's surface holds now, ``H x W x 3`` RGB (read back from SDL: tests, diagnostics)."""
        self._check_open()
        header, payload = self._request({"op": "pixels"})
        width, height = header["size"]
        return np.frombuffer(payload, dtype=np.uint8).reshape(height, width, 3).copy()

    def state(self) -> str:
        """The probe line: ``"open: 1920x1080 (display 1 of 2, x11)"`` or ``"not available: <why>"``.

        It asks SDL for the display's desktop size in a short-lived process and makes no window, so probing never
        flashes the projector or disturbs a guide being shown.
        """
        if self._size is not None:
            return f"open: {self._size[0]}x{self._size[1]} (showing, {self.driver})"
        try:
            answer = self._start("probe")
        except DriverError as error:
            return "not available: " + str(error).removeprefix(f"projector {self.url}: ")
        width, height = answer["size"]
        return f"open: {width}x{height} (display {self.index} of {answer['displays']}, {answer['driver']})"

    def __enter__(self) -> DisplayProjector:
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _check_open(self) -> None:
        if self._process is None:
            raise DriverError(f"projector {self.url} is not open: open() it first")

    # -- the window process --

    def _start(self, mode: str) -> dict:
        """Start the window process in ``mode`` and return its first answer (DriverError with its one line)."""
        if importlib.util.find_spec("pygame") is None:
            raise DriverError(f"projector {self.url}: {INSTALL_HINT}")
        root = str(Path(__file__).resolve().parents[2])  # the folder holding the drivers package
        env = {**os.environ, "PYGAME_HIDE_SUPPORT_PROMPT": "1",
               "PYTHONPATH": os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH", "")) if p)}
        try:
            process = subprocess.Popen(
                [sys.executable, "-c", "from drivers.projector.window import main; main()", mode, str(self.index)],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env)
        except OSError as error:
            raise DriverError(f"projector {self.url}: cannot start the window process ({error})") from None
        answers: queue.Queue = queue.Queue()
        threading.Thread(target=_read_answers, args=(process.stdout, answers), name=f"projector {self.url}",
                         daemon=True).start()
        try:
            message = answers.get(timeout=self.timeout)
        except queue.Empty:
            message = ({"error": f"no answer from the window process within {self.timeout:g} s"}, b"")
        answer = message[0] if message is not None else {"error": "the window process ended without a word"}
        if "error" in answer or mode == "probe":
            _stop(process)
            if "error" in answer:
                raise DriverError(f"projector {self.url}: {answer['error']}")
            return answer
        self._process, self._answers = process, answers
        return answer

    def _request(self, header: dict, payload: bytes = b"") -> tuple[dict, bytes]:
        """Send one request and wait for its answer (DriverError when the window process is gone or silent)."""
        process = self._process
        if process is None:
            raise DriverError(f"projector {self.url} is not open: open() it first")
        try:
            write_message(process.stdin, header, payload)
            message = self._answers.get(timeout=REQUEST_TIMEOUT)
        except (OSError, ValueError):
            message = None
        except queue.Empty:
            self.close()
            raise DriverError(f"projector {self.url}: the window did not answer within {REQUEST_TIMEOUT:g} s; "
                              "closed it") from None
        if message is None:
            self.close()
            raise DriverError(f"projector {self.url}: the window process has gone (its window was closed?)")
        answer, data = message
        if "error" in answer:
            raise DriverError(f"projector {self.url}: {answer['error']}")
        return answer, data


def _stop(process: subprocess.Popen) -> None:
    """Let the window process end (it does after ``close``, a probe or an error), or end it; close its pipes.

    Its input is closed first: its reader thread then sees the end at once instead of holding stdin's lock while the
    interpreter shuts down."""
    try:
        process.stdin.close()
    except OSError:
        pass
    try:
        process.wait(timeout=2.0)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
    process.stdout.close()


def _read_answers(stream, answers: queue.Queue) -> None:
    """Move the window process's answers into ``answers`` (None at its end)."""
    try:
        while (message := read_message(stream)) is not None:
            answers.put(message)
    except (OSError, ValueError):
        pass
    answers.put(None)
