"""The two watchdogs of a GRBL connection: a silent port, and a lost ``ok``.

Silence
-------
A port that vanished (USB unplugged, a pty hung up, a socket closed) makes the OS fail a read or a write: the
connection reports that at once. A port that stays open but goes silent (a hung controller, a dead cable) is found
by :class:`SilenceWatchdog`. GRBL answers ``?`` within one pass of its main loop (milliseconds: the serial interrupt
sets a flag that ``protocol_execute_realtime`` serves), except while it homes (``limits_go_home`` has "no time to
run protocol_execute_realtime()": not a byte until the cycle ends, then one ``<Home|...>`` report) or writes its
EEPROM (``$x=``, ``$N``, ``$I=``, ``$RST=``, ``G10``, ``G28.1``, ``G30.1``, see :func:`pauses_reports`); the watchdog
rests while such a line is in flight (its reply timeout still bounds it). Silence counts only from a ``?`` actually
written, and only for the time this process was running: the watchdog's thread wakes every ``poll_interval`` s, and
a wake-up that came late (the host was loaded or descheduled, or a garbage collection held the interpreter: 0.3 s
pauses are common in a busy Textual app) counts for at most one poll period, and not at all when the reader thread
did not run since the last one (the reply may sit unread in the OS buffer). After ``timeout`` s of such silence one
more ``?`` is sent as a probe; only if ``grace`` more seconds of it pass, still without a byte and with nothing
waiting in the port, does the port count as vanished.

Lost ``ok``
-----------
:class:`LostOkWatchdog` declares a reply lost when status reports show the controller idle with empty planner and
RX buffer while lines are still counted as pending, for ``timeout`` s plus the dwells (``G4``) of those lines. An
``ok`` is never invented: the connection stops the stream with the message this watchdog writes. A machine whose
``$10`` leaves the buffer state (``Bf``) out of its reports is judged by its state alone: while GRBL is Idle its main
loop reads and runs every line in its RX buffer within milliseconds (motion would make it Run, a hold Hold), so
Idle held for the timeout with lines pending means the same.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from typing import Protocol

from drivers.gcode import GcodeError, tokenize
from drivers.grbl.protocol import StatusReport

__all__ = ["LostOkWatchdog", "SilenceWatchdog", "dwell_seconds", "pauses_reports"]

_PAUSES_REPORTS = re.compile(r"^\$(H|RST=|I=|N\d|\d+=)|G0*10(?![\d.])|G0*28\.1|G0*30\.1", re.IGNORECASE)


def pauses_reports(block: str) -> bool:
    """True for a cleaned line during which GRBL serves no real-time status request: a homing cycle (``$H``,
    ``$HX``...) or an EEPROM write (``$x=``, ``$Nx=``, ``$I=``, ``$RST=``, ``G10``, ``G28.1``, ``G30.1``)."""
    return bool(_PAUSES_REPORTS.search(block))


def dwell_seconds(block: str) -> float:
    """The dwell of a cleaned ``G4 P<seconds>`` line (GRBL reports Idle with empty buffers meanwhile); else 0."""
    if "G4" not in block:
        return 0.0
    try:
        words = tokenize(block)
    except GcodeError:
        return 0.0
    if ("G", 4.0) in words:
        return next((v for letter, v in words if letter == "P"), 0.0)
    return 0.0


class SilenceWatchdog:
    """Whether a port that stays open went silent (see the module docstring for the rules).

    Parameters
    ----------
    timeout : float
        Seconds of silence after a ``?`` before the last probe is sent.
    grace : float
        Seconds of silence after that probe before the port counts as vanished.
    poll_interval : float
        Seconds between the status thread's wake-ups: the most one late wake-up counts for.
    log : callable
        ``log(text)``: a line for the connection's log (the probe is announced there).
    """

    def __init__(self, timeout: float, grace: float, poll_interval: float, log: Callable[[str], None]) -> None:
        self.timeout = timeout
        self.grace = grace
        self.poll_interval = poll_interval
        self.log = log
        self.reset()

    def reset(self) -> None:
        """No request outstanding, no silence counted."""
        self.asked_at: float | None = None  # when the first ``?`` since the last byte read was written
        self.silent = 0.0  # seconds of silence since then, counted only while this process ran
        self.probe_at: float | None = None  # ``silent`` when the last probe before declaring loss was sent

    def asked(self, when: float) -> None:
        """A ``?`` was written; ``when`` is taken before the write (a reply can only be read after it)."""
        if self.asked_at is None:
            self.asked_at = when

    def step(self, previous: float, now: float, *, last_rx: float, reader_beat: float,
             paused: Callable[[], bool], waiting: Callable[[], int]) -> bool:
        """One wake-up of the status thread at ``now`` after the one at ``previous``: True when the port counts as
        vanished.

        ``last_rx`` is when the last byte was read and ``reader_beat`` when the reader thread last went round its
        loop; ``paused()`` says a line that pauses GRBL's reports is in flight; ``waiting()`` counts the bytes
        waiting unread in the port.
        """
        if self.asked_at is not None and last_rx >= self.asked_at:
            self.asked_at = None  # answered (any byte counts: GRBL sends nothing while it is dead)
        if self.asked_at is None or paused():
            self.reset()
            return False
        if reader_beat >= previous:
            # the reader ran since the last wake-up; a late wake-up (the process was not running) counts for at
            # most one poll period, so a stall of the host is never taken for silence of the port
            self.silent += min(now - max(previous, self.asked_at), self.poll_interval)
        if self.probe_at is None:
            if self.silent >= self.timeout:
                self.probe_at = self.silent  # the ``?`` written after this call is the probe
                self.log(f"no reply to status requests for {self.silent:.1f} s: probing with '?' "
                         f"({self.grace:.1f} s grace)")
            return False
        if self.silent - self.probe_at < self.grace:
            return False
        return not waiting()  # bytes waiting: the reader is behind, the port is alive

    def describe(self) -> str:
        """Why the port counts as vanished, for the fault message."""
        return (f"no byte from the controller for {self.silent:.1f} s of status requests "
                f"(the last {self.silent - (self.probe_at or 0.0):.1f} s after a probe)")


class _PendingLine(Protocol):
    """What the lost-``ok`` watchdog reads of a line waiting for its reply."""

    dwell: float

    @property
    def result(self): ...  # a LineResult: ``index`` and ``text``


class LostOkWatchdog:
    """Whether a reply was lost (see the module docstring).

    Parameters
    ----------
    timeout : float
        Seconds the "idle, buffers empty, lines pending" condition must hold (plus the pending lines' dwells).
    """

    def __init__(self, timeout: float) -> None:
        self.timeout = timeout
        self.since: float | None = None  # when the condition was first seen, None while it does not hold
        self.entry: object | None = None  # the first pending line when the last loss was declared

    def clear(self) -> None:
        """A reply arrived, a line was sent or the fault was dealt with: the condition starts over."""
        self.since = None

    def check(self, status: StatusReport, pending: Sequence[_PendingLine], *, planner_size: int, rx_size: int,
              fault: str | None, now: float) -> str | None:
        """One status report: the fault message when a lost ``ok`` is declared now, else None."""
        if status.planner_free is None or status.rx_free is None:
            empty = True  # no buffer state ($10 without bit 1): Idle says it (see the module docstring)
        else:
            empty = status.planner_free == planner_size and status.rx_free == rx_size
        quiet = bool(pending) and status.state in ("Idle", "Check") and empty  # Check: nothing ever moves
        if not quiet:
            self.since = None
            return None
        if self.since is None:
            self.since = now
            return None
        allowance = sum(p.dwell for p in pending)
        fresh = fault is None or (fault.startswith("lost ok") and self.entry is not pending[0])
        if now - self.since < self.timeout + allowance or not fresh:
            return None
        self.entry = pending[0]
        first = pending[0].result
        return (f"lost ok: the controller is idle with empty buffers but {len(pending)} line(s) from line "
                f"{first.index + 1} ({first.text!r}) were never acknowledged; stream stopped")
