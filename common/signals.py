"""Ctrl-C (SIGINT) and SIGTERM handled by the work they would stop, for as long as a ``with`` block runs.

A subclass says what a signal does (:meth:`HandledSignals._handle`); this installs it for both signals on entry, even
when the process started with SIGINT ignored (a script's background job), and puts the previous handlers back on
exit. Off the main thread (a TUI worker), where Python sets no handler, nothing is installed.
"""

from __future__ import annotations

import signal
import threading
from typing import Any

__all__ = ["HandledSignals"]


class HandledSignals:
    """A context manager installing :meth:`_handle` for SIGINT and SIGTERM (see the module notes)."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self._previous: dict[int, Any] = {}

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():  # handlers can be set there only
            for signum in self.SIGNALS:
                self._previous[signum] = signal.signal(signum, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)
        self._previous.clear()

    def _handle(self, signum, frame) -> None:
        raise NotImplementedError
