"""The clocks a simulated machine runs on: the wall clock, or a virtual clock that skips the waiting.

A simulated machine's thread goes round a loop: take in the bytes that have arrived, advance motion, run the
parser, then wait for the next thing to happen, a host byte (a notify on its condition) or its next *event* (the
end of a block, of a dwell, of a deceleration, of homing, a byte on the simulated wire). The clock decides how
that wait passes:

- :class:`WallClock` (the default): real seconds (``time.monotonic``); the wait is a real wait.
- :class:`VirtualClock`: simulated seconds from 0; instead of waiting for an event, the clock jumps to it, once
  the host has had its turn. A job then runs as fast as the host streams it, with the same simulated timing.

"The host has had its turn" is the heart of the virtual clock. The host (a streamer, a status poll) runs on the
wall clock in other threads; it cannot be told to wait for simulated time. So the machine jumps at once only when
no host byte can change what happens first: the event is a byte already on the wire (its time is fixed), the
planner is full, homing runs or a hold decelerates. Otherwise (motion runs with room in the planner, or a line
waits for the planner to empty or for a dwell: what the host sends meanwhile decides the look-ahead) the jump waits
until the host has read everything delivered to it and written since, or has done nothing for ``quiet`` wall
seconds (the end of a stream, a host that only polls status). The wait for *bytes* is always on the wall clock, on
the machine's condition, so a host write wakes the machine at once: input never waits for simulated time.

What comes of it: the blocks a job executes and their simulated times do not depend on the host's speed (unless
it stalls for longer than ``quiet`` mid-stream); with ``wire=0``, or a host that sends line by line, the whole
record is the same run after run. A ``pace`` makes a virtual clock run no faster than that many simulated seconds
per wall second, for tests that must act while a job runs.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Protocol

from drivers.errors import SimConfigError

__all__ = ["CLOCKS", "Clock", "VirtualClock", "WallClock", "clock_named"]

#: How long (wall seconds) an idle machine waits for a host byte before it looks again.
_IDLE_WAIT = 0.1


class Clock(Protocol):
    """What a simulated machine needs of its clock."""

    virtual: bool

    def now(self) -> float:
        """The machine's time in seconds."""
        ...

    def wait(self, condition: threading.Condition, now: float, event: float | None,
             may_jump: Callable[[], bool]) -> None:
        """Let time pass until ``event`` (the machine's next event, None for none) or a notify on ``condition``
        (held by the caller); ``now`` is the time the machine last acted at. ``may_jump()`` tells whether the
        host has had its turn (used by a virtual clock only)."""
        ...


class WallClock:
    """Real time: ``time.monotonic`` seconds, real waits (at most 0.1 s at a time, to look at the machine again)."""

    virtual = False

    def now(self) -> float:
        return time.monotonic()

    def wait(self, condition: threading.Condition, now: float, event: float | None,
             may_jump: Callable[[], bool]) -> None:
        timeout = _IDLE_WAIT if event is None else max(0.0, min(event - now, _IDLE_WAIT))
        condition.wait(timeout)


class VirtualClock:
    """Simulated time that jumps to the machine's next event instead of waiting for it.

    Parameters
    ----------
    start : float
        The time at power-up (seconds).
    quiet : float
        Wall seconds without a host read or write after which the host counts as done (its stream ended, or it only
        polls status) and simulated time goes on without it. Longer is more deterministic under a loaded host,
        shorter is faster at the end of a stream.
    patience : float
        Wall seconds after which simulated time goes on even though the host has not read what the machine sent
        (a host that never reads).
    pace : float, optional
        At most this many simulated seconds per wall second while the machine is busy (None: no limit). For a test
        that must act while a job runs (press abort mid-job): the timing stays the virtual clock's, only the jumps
        wait for the wall clock. The limit counts from when the machine last had nothing to do.

    Notes
    -----
    The machine's thread is the only one that moves the time, under the machine's lock; host threads read it
    (``receive`` stamps a byte's arrival with it) under the same lock.
    """

    virtual = True

    def __init__(self, start: float = 0.0, quiet: float = 0.02, patience: float = 0.25,
                 pace: float | None = None) -> None:
        if not 0 < quiet <= patience:
            raise SimConfigError(f"VirtualClock needs 0 < quiet <= patience, got quiet={quiet}, patience={patience}")
        if pace is not None and not pace > 0:
            raise SimConfigError(f"VirtualClock pace must be positive (simulated seconds per wall second), got {pace}")
        self._now = float(start)
        self.quiet = quiet
        self.patience = patience
        self.pace = pace
        self._anchor = (time.monotonic(), self._now)  # (wall, simulated) when the machine was last idle

    def now(self) -> float:
        return self._now

    def wait(self, condition: threading.Condition, now: float, event: float | None,
             may_jump: Callable[[], bool]) -> None:
        if event is None:
            self._anchor = (time.monotonic(), self._now)
            condition.wait(_IDLE_WAIT)  # nothing will happen until the host writes
            return
        if event <= self._now:
            condition.wait(0.001)  # due already (work left over from a bounded parser turn): look again
            return
        if may_jump():
            reachable = self._reachable()
            if reachable < event:
                # paced: run on as far as the pace allows (positions in status reports move), then look again
                self._now = max(self._now, reachable)
                condition.wait(min((event - self._now) / self.pace, self.quiet))
                return
            self._now = event
            return
        condition.wait(self.quiet)  # the host's turn: a write wakes the machine at once

    def _reachable(self) -> float:
        """The latest time ``pace`` lets the clock reach now (infinite without a pace)."""
        if self.pace is None:
            return float("inf")
        wall, simulated = self._anchor
        return simulated + (time.monotonic() - wall) * self.pace


#: The clocks by the name the ``clock=`` URL option takes.
CLOCKS: dict[str, type] = {"wall": WallClock, "virtual": VirtualClock}


def clock_named(name: str, pace: float | None = None) -> Clock:
    """A new clock of kind ``name`` (``wall`` or ``virtual``, with its ``pace``).

    Raises
    ------
    SimConfigError
        For another name.
    """
    if name not in CLOCKS:
        raise SimConfigError(f"sim option clock: expected {' or '.join(CLOCKS)}, got {name!r}")
    return VirtualClock(pace=pace) if name == "virtual" else CLOCKS[name]()
