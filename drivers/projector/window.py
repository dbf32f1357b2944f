"""The projector's window process: SDL (pygame-ce) in a process of its own, driven over its stdin and stdout.

:class:`drivers.projector.display.DisplayProjector` starts ``python -c "...window import main; main()" MODE INDEX``.
The window lives in its own process because SDL wants one thread to own its window for its whole life (the main
thread, on macOS), pumps the window's events so that the desktop never calls it "not responding", installs its own
signal handlers, and writes to the terminal: none of which the station's TUI, whose workers call the projector from
any thread, can afford. A crash in a video driver then costs the projector, not the station.

Modes: ``probe INDEX`` answers the display's size and exits without making a window; ``open INDEX`` makes a
borderless full-screen window at display INDEX's native resolution and serves requests until ``close`` or the end
of its input (the station quit).

Wire format, both ways: one JSON line, then ``n`` raw bytes when the line has an ``"n"``. Requests: ``{"op": "show",
"w", "h", "n"}`` + RGB bytes (exactly the screen's size: the caller fits it), ``{"op": "blank"}``, ``{"op":
"pixels"}`` (answered with the window surface's RGB bytes), ``{"op": "close"}``. Answers: ``{"ok": true, ...}`` or
``{"error": "one line"}``.
"""

from __future__ import annotations

import json
import os
import queue
import sys
import threading
from typing import BinaryIO

#: SDL's video drivers that draw into memory: a projector only when asked for by name (tests).
HEADLESS_DRIVERS = ("offscreen", "dummy")
#: Seconds between event pumps while no request comes.
PUMP_INTERVAL = 0.05


def write_message(stream: BinaryIO, header: dict, payload: bytes = b"") -> None:
    """Send one message (a JSON line, then ``payload`` whose length the line carries as ``n``)."""
    if payload:
        header = {**header, "n": len(payload)}
    stream.write(json.dumps(header).encode("utf-8") + b"\n")
    if payload:
        stream.write(payload)
    stream.flush()


def read_message(stream: BinaryIO) -> tuple[dict, bytes] | None:
    """One message from ``stream``, or None at its end."""
    line = stream.readline()
    if not line:
        return None
    header = json.loads(line)
    size = int(header.get("n", 0))
    payload = stream.read(size) if size else b""
    if len(payload) != size:
        return None
    return header, payload


def _display(index: int):
    """pygame with its display started, and display ``index``'s native size; raises RuntimeError with one line."""
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    # a full-screen SDL window minimizes itself when it loses focus unless told not to: the maker clicks on the
    # station's terminal on the other screen, and the projection must stay
    os.environ.setdefault("SDL_VIDEO_MINIMIZE_ON_FOCUS_LOSS", "0")
    try:
        import pygame
    except ImportError:
        raise RuntimeError("pygame-ce is not installed (pip install 'chaos-station[projector]')") from None
    try:
        pygame.display.init()
    except pygame.error as error:
        raise RuntimeError(f"no video device (SDL: {error})") from None
    driver = pygame.display.get_driver()
    if driver in HEADLESS_DRIVERS and os.environ.get("SDL_VIDEODRIVER", "").lower() != driver:
        # SDL falls back to a driver that draws into memory when it finds no screen: that is no projector
        pygame.display.quit()
        raise RuntimeError(f"no video device (no screen attached; SDL found only its {driver} driver)")
    count = pygame.display.get_num_displays()
    if not 0 <= index < count:
        listed = f"0 to {count - 1}" if count > 1 else "0"
        raise RuntimeError(f"no display {index}: SDL sees {count} display{'s' if count != 1 else ''} ({listed})")
    width, height = pygame.display.get_desktop_sizes()[index]
    return pygame, (width, height), count


def main(argv: list[str] | None = None) -> int:
    """Run the window process (``argv``: ``[MODE, INDEX]``)."""
    argv = sys.argv[1:] if argv is None else argv
    out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)  # a stray print (a library's banner) must not land in the answers
    mode, index = argv[0], int(argv[1])
    try:
        pygame, size, count = _display(index)
    except RuntimeError as error:
        write_message(out, {"error": str(error)})
        return 1
    driver = pygame.display.get_driver()
    if mode == "probe":
        write_message(out, {"ok": True, "size": size, "displays": count, "driver": driver})
        pygame.display.quit()
        return 0
    try:
        screen = pygame.display.set_mode(size, pygame.FULLSCREEN | pygame.NOFRAME, display=index)
    except pygame.error as error:
        write_message(out, {"error": f"cannot open a window on display {index} (SDL: {error})"})
        return 1
    pygame.display.set_caption("chaos-station projector")
    pygame.mouse.set_visible(False)
    screen.fill((0, 0, 0))
    pygame.display.flip()
    write_message(out, {"ok": True, "size": list(screen.get_size()), "displays": count, "driver": driver})
    return _serve(pygame, screen, out)


def _serve(pygame, screen, out: BinaryIO) -> int:
    """Answer requests until ``close`` or the end of the input, pumping the window's events in between."""
    requests: queue.Queue = queue.Queue()

    def read() -> None:
        while True:
            message = read_message(sys.stdin.buffer)
            requests.put(message)
            if message is None:
                return

    threading.Thread(target=read, name="projector requests", daemon=True).start()
    while True:
        try:
            message = requests.get(timeout=PUMP_INTERVAL)
        except queue.Empty:
            pygame.event.pump()
            continue
        if message is None:
            break
        header, payload = message
        op = header.get("op")
        try:
            if op == "show":
                image = pygame.image.frombytes(payload, (header["w"], header["h"]), "RGB")
                screen.blit(image, (0, 0))
                pygame.display.flip()
                write_message(out, {"ok": True})
            elif op == "blank":
                screen.fill((0, 0, 0))
                pygame.display.flip()
                write_message(out, {"ok": True})
            elif op == "pixels":
                surface = pygame.display.get_surface()
                write_message(out, {"ok": True, "size": list(surface.get_size())},
                              pygame.image.tobytes(surface, "RGB"))
            elif op == "close":
                write_message(out, {"ok": True})
                break
            else:
                write_message(out, {"error": f"unknown request {op!r}"})
        except (pygame.error, ValueError, KeyError) as error:
            write_message(out, {"error": f"{op}: {error}"})
        pygame.event.pump()
    pygame.display.quit()
    return 0


if __name__ == "__main__":
    sys.exit(main())
