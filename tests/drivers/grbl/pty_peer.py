"""A serial device on the master side of a pty, for tests of the driver on a real port (termios, select, hang-ups)
that the ``sim://`` URL handler does not go through."""

from __future__ import annotations

import os
import select
import threading

import pytest


class PtyPeer:
    """The device end of a fresh pty: the driver opens :attr:`path`; a thread hands each chunk the driver writes to
    :meth:`received` and calls :meth:`tick` between reads (every ``poll`` seconds at least)."""

    poll = 0.05

    def __init__(self) -> None:
        if not hasattr(os, "openpty"):
            pytest.skip("needs a pty")
        self.master, self.slave = os.openpty()
        self.path = os.ttyname(self.slave)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)

    def start(self) -> PtyPeer:
        self._thread.start()
        return self

    def tick(self) -> None:
        """Work between reads (replies that are due)."""

    def received(self, data: bytes) -> None:
        raise NotImplementedError

    def write(self, data: bytes) -> None:
        os.write(self.master, data)

    def _serve(self) -> None:
        while not self._stop.is_set():
            self.tick()
            ready, _, _ = select.select([self.master], [], [], self.poll)
            if not ready:
                continue
            try:
                data = os.read(self.master, 1024)
            except OSError:
                return
            self.received(data)

    def hang_up(self) -> None:
        """Close the master side, as a USB-serial adapter that disappears does."""
        self._stop.set()
        self._thread.join(2.0)
        os.close(self.master)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass
