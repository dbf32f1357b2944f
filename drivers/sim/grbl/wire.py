"""The simulated GRBL's serial side: the wire in both directions, injected faults, real-time bytes.

Bytes travel with ``latency`` plus their transfer time at the baud rate (``wire=0``: none); a reply or status line
may be dropped, corrupted, split and delayed, or preceded by a stray line (``drop``, ``corrupt``, ``delay``,
``stray``); real-time bytes (``?`` ``!`` ``~`` 0x18 and the extended ones) act on arrival, the rest fill the 128-byte
RX ring buffer (127 usable; overflow is counted and lost, as on GRBL). :class:`Wire` is a mixin of
:class:`drivers.sim.grbl.SimulatedGrbl`; the port object (:mod:`drivers.sim.protocol_sim`) calls its public methods
from the host's threads.

Times on the wire are the machine's clock (:mod:`drivers.sim.clock`). On a virtual clock the host still reads with
wall-clock timeouts: the machine's thread moves the time on and wakes waiting readers when bytes come due. What the
host did last (a read, a write of line bytes) is kept on the wall clock: a virtual clock waits for the host's turn
(see :meth:`Wire._host_had_its_turn`).
"""

from __future__ import annotations

import time

from drivers.sim.grbl.settings import BANNER, RX_BUFFER_SIZE

REALTIME_STATUS = 0x3F  # '?'
REALTIME_HOLD = 0x21  # '!'
REALTIME_START = 0x7E  # '~'
REALTIME_RESET = 0x18
REALTIME_JOG_CANCEL = 0x85
REALTIME_SAFETY_DOOR = 0x84
_REALTIME_ASCII = frozenset((REALTIME_STATUS, REALTIME_HOLD, REALTIME_START, REALTIME_RESET))


class Wire:
    """Bytes in and out of :class:`drivers.sim.grbl.SimulatedGrbl` (a mixin)."""

    def receive(self, data: bytes) -> None:
        """Bytes written by the host; they arrive after the latency and the wire time."""
        if not data:
            return
        with self._cond:
            if not self.connected:
                return
            if any(byte not in _REALTIME_ASCII and byte < 0x80 for byte in data):
                self._host_wrote = True  # line bytes: the host acted on what it read
                self._host_active = time.monotonic()
            now = self.clock.now()
            arrival = max(now + self.config.latency, self._in_last) + len(data) * self.byte_time
            self._in_last = arrival
            self._in_wire.append((arrival, bytes(data)))
            self._cond.notify_all()

    def read_output(self, size: int, timeout: float | None) -> bytes:
        """Up to ``size`` bytes the machine sent, waiting at most ``timeout`` s (wall clock). Raises ConnectionError
        if the port was unplugged (and nothing is left to read)."""
        deadline = None if timeout is None else time.monotonic() + timeout
        with self._out_cond:
            while True:
                self._deliver_output()
                if self._out_ready:
                    data = bytes(self._out_ready[:size])
                    del self._out_ready[:size]
                    self._host_wrote = False
                    self._host_active = time.monotonic()
                    return data
                if not self.connected:
                    raise ConnectionError("simulated port unplugged")
                waits = []
                if self._out_wire and not self.clock.virtual:
                    # on a virtual clock the machine's thread wakes this wait when the time comes
                    waits.append(self._out_wire[0][0] - self.clock.now())
                if deadline is not None:
                    wall = time.monotonic()
                    if wall >= deadline:
                        return b""
                    waits.append(deadline - wall)
                self._out_cond.wait(min(waits) if waits else 0.5)

    def settled(self, timeout: float = 5.0) -> bool:
        """Wait (at most ``timeout`` wall seconds) until every byte the host wrote has arrived and the machine has
        acted on it: its real-time bytes served, its lines in the RX buffer or taken out by the parser. False if
        bytes were still on the wire at the timeout.

        The machine's thread holds the lock for a whole turn (take in bytes, move, parse) and lets go only while it
        waits, so an empty input wire seen under the lock means the turn that took the last bytes in is over. A
        test asserts what the machine did (or did not) answer after this, not after a pause of guessed length.
        """
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._in_wire:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                self._cond.notify_all()
                self._cond.wait(min(remaining, 0.005))
            return True

    def bytes_waiting(self) -> int:
        """How many bytes the host can read now."""
        with self._out_cond:
            self._deliver_output()
            return len(self._out_ready)

    def _deliver_output(self) -> None:
        """Move the bytes whose time has come from the wire to what the host can read (``_out_cond`` held)."""
        now = self.clock.now()
        while self._out_wire and self._out_wire[0][0] <= now:
            self._out_ready += self._out_wire.popleft()[1]

    def clear_output(self) -> None:
        """Forget what the host has not read (``reset_input_buffer``)."""
        with self._out_cond:
            self._out_ready.clear()

    def mute(self) -> None:
        """Simulate a hung controller or a dead cable that raises no error: nothing is sent any more."""
        with self._out_cond:
            self._muted = True
            self._out_wire.clear()

    def unplug(self) -> None:
        """Simulate a vanished port (USB cable pulled): reads and writes fail from now on."""
        with self._cond:
            self.connected = False
            self._in_wire.clear()
        with self._out_cond:
            self._out_wire.clear()
            self._out_cond.notify_all()

    def greet(self) -> None:
        """Send the power-up banner again, as GRBL does after a reset; opening the port of an Arduino resets it
        (DTR), so a reopened shared machine greets its new host (with the unlock hint when in alarm)."""
        with self._cond:
            self._emit_banner()

    # ------------------------------------------------------------------ output with faults

    def _emit(self, line: str, kind: str = "push") -> None:
        """Send one line ``\\r\\n``-terminated; faults apply to replies (``ok``/``error``) and status reports."""
        cfg = self.config
        rng = self.rng
        if kind in ("reply", "status"):
            if cfg.stray and rng.random() < cfg.stray:
                stray = rng.choice(["[MSG:stray]", "\x00\x7fnoise", "[echo:G1X1]", "Grb", "<Idle|garbled"])
                self._push((stray + "\r\n").encode("latin-1"))
            if cfg.drop and rng.random() < cfg.drop:
                return
            if cfg.corrupt and rng.random() < cfg.corrupt and line:
                chars = bytearray(line.encode("latin-1"))
                chars[rng.randrange(len(chars))] = rng.choice([0x9E, 0xFF, ord("#")])
                self._push(bytes(chars) + b"\r\n")
                return
        if kind == "reply":
            self.record.replies_delivered += 1
        data = (line + "\r\n").encode("latin-1")
        if cfg.delay and kind in ("reply", "status") and rng.random() < cfg.delay:
            cut = rng.randrange(1, len(data))
            self._push(data[:cut])
            self._push(data[cut:], extra=rng.uniform(0, cfg.delay_max))
        else:
            self._push(data)

    def _push(self, data: bytes, extra: float = 0.0) -> None:
        with self._out_cond:
            if not self.connected or self._muted:
                return
            now = self.clock.now()
            deliver = max(now + self.config.latency + extra, self._out_last) + len(data) * self.byte_time
            self._out_last = deliver
            self._out_wire.append((deliver, data))
            self._out_cond.notify_all()

    def _emit_banner(self) -> None:
        """The banner (the machine's lock held, or before its thread runs)."""
        self._push(b"\r\n")
        self._emit(BANNER, "banner")
        if self._state == "Alarm":
            self._emit("[MSG:'$H'|'$X' to unlock]")

    def _deliver_input(self, now: float) -> None:
        while self._in_wire and self._in_wire[0][0] <= now:
            _, data = self._in_wire.popleft()
            for byte in data:
                if not self.connected:
                    return
                if byte in _REALTIME_ASCII or byte >= 0x80:
                    self._realtime(byte, now)
                elif len(self._rx) < RX_BUFFER_SIZE - 1:  # a ring buffer: one slot always stays empty
                    self._rx.append(byte)
                else:
                    self.record.overflow_bytes += 1  # a real GRBL silently loses it

    def _wake_readers(self, now: float) -> None:
        """Virtual clock: tell a host waiting in :meth:`read_output` that bytes have come due (time jumped)."""
        with self._out_cond:
            if self._out_wire and self._out_wire[0][0] <= now:
                self._out_cond.notify_all()

    def _next_delivery(self, now: float) -> float | None:
        """When the next bytes still on their way out reach the host, after ``now`` (None: none)."""
        with self._out_cond:
            return next((deliver for deliver, _ in self._out_wire if deliver > now), None)

    def _host_had_its_turn(self) -> bool:
        """Virtual clock: whether the host has acted on everything delivered to it, so that simulated time may go on.

        True when it has read every delivered byte and written line bytes since its last read, or has neither read
        nor written for the clock's ``quiet`` seconds; also, whatever it left unread, after ``patience`` seconds.
        """
        idle = time.monotonic() - self._host_active
        if idle >= self.clock.patience:
            return True
        with self._out_cond:
            unread = bool(self._out_ready) or bool(self._out_wire and self._out_wire[0][0] <= self.clock.now())
        return not unread and (self._host_wrote or idle >= self.clock.quiet)

    # ------------------------------------------------------------------ real-time commands

    def _realtime(self, byte: int, now: float) -> None:
        """A real-time byte, acted on when it arrives (GRBL's ``protocol_execute_realtime``).

        After a hard or soft limit (ALARM:1, ALARM:2) GRBL spins in ``protocol_exec_rt_system``'s critical-event loop,
        which serves nothing but a reset: a status request, a hold or an override only sets a flag that the reset
        then clears, so they are never answered."""
        if self._critical and byte != REALTIME_RESET:
            return
        if byte == REALTIME_STATUS:
            if self._state == "Home":
                # limits_go_home has "no time to run protocol_execute_realtime()": the request waits for the end
                # of the cycle, and any number of them gets one report
                self._report_owed = True
                return
            self._emit(self._status_report(now), "status")
        elif byte == REALTIME_RESET:
            self._soft_reset(now)
        elif byte == REALTIME_HOLD:
            self._feed_hold(now)
        elif byte == REALTIME_START:
            self._cycle_start(now)
        elif byte == REALTIME_JOG_CANCEL:
            self._jog_cancel(now)
        elif byte == 0x90:
            self.overrides[0] = 100
        elif byte in (0x91, 0x92, 0x93, 0x94):
            delta = {0x91: 10, 0x92: -10, 0x93: 1, 0x94: -1}[byte]
            self.overrides[0] = int(min(200, max(10, self.overrides[0] + delta)))
        elif byte in (0x95, 0x96, 0x97):
            self.overrides[1] = {0x95: 100, 0x96: 50, 0x97: 25}[byte]
        elif byte == 0x99:
            self.overrides[2] = 100
        elif byte in (0x9A, 0x9B, 0x9C, 0x9D):
            delta = {0x9A: 10, 0x9B: -10, 0x9C: 1, 0x9D: -1}[byte]
            self.overrides[2] = int(min(200, max(10, self.overrides[2] + delta)))
        # other extended bytes (safety door, coolant toggles, spindle stop) are ignored by this machine
