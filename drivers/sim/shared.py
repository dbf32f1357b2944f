"""Simulated devices shared by name between opens (``sim://projector?name=wall``, ``sim://camera?name=desk``): the
station, a guide and a test opening the same name get the same twin, with its frames, scene and placement."""

from __future__ import annotations

import math
import threading
from typing import Generic, TypeVar

from drivers.errors import SimConfigError

__all__ = ["SharedTwins", "bounded_number"]

Twin = TypeVar("Twin")


class SharedTwins(Generic[Twin]):
    """The twins of one kind (``"projector"``, ``"camera"``) opened with a ``name``; each has ``.name`` and
    ``.size``."""

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self._twins: dict[str, Twin] = {}
        self._lock = threading.Lock()

    def share(self, twin: Twin, url: str) -> Twin:
        """``twin`` itself when it has no name, else the first twin opened with its name (a later open asking for
        another size than the shared one's is a SimConfigError)."""
        name = twin.name
        if not name:
            return twin
        with self._lock:
            shared = self._twins.setdefault(name, twin)
        if shared is not twin and shared.size != twin.size:
            raise SimConfigError(f"{self.kind} {url}: the shared {self.kind} {name!r} is {shared.size[0]}x"
                                 f"{shared.size[1]}, not {twin.size[0]}x{twin.size[1]}")
        return shared

    def named(self, name: str) -> Twin | None:
        """The shared twin opened with ``name``, if any."""
        with self._lock:
            return self._twins.get(name)

    def forget(self) -> None:
        """Forget every shared twin (tests)."""
        with self._lock:
            self._twins.clear()


def bounded_number(kind: str, key: str, text: str, low: float, high: float, what: str) -> float:
    """URL option ``key`` of a ``sim://KIND`` twin as a number from ``low`` to ``high`` (``what`` says so in the
    SimConfigError otherwise)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not low <= value <= high:
        raise SimConfigError(f"sim {kind} option {key}: expected {what}, got {text!r}")
    return value
