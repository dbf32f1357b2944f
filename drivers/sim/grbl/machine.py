"""The simulated GRBL 1.1 machine: its loop, line parser, soft reset and status report; the other parts are
its mixins (see :mod:`drivers.sim.grbl`)."""

from __future__ import annotations

import random
import threading
import time
from collections import deque

import numpy as np

from drivers.sim.clock import Clock, clock_named
from drivers.sim.grbl.gcode import GcodeInterpreter, clean_block
from drivers.sim.grbl.motion import Block, Planner
from drivers.sim.grbl.record import SimRecord
from drivers.sim.grbl.settings import (
    LINE_BUFFER_SIZE,
    PLANNER_BLOCKS,
    RX_BUFFER_SIZE,
    Halt,
    SimConfig,
    SystemCommands,
    xyz,
)
from drivers.sim.grbl.wire import (
    Wire,
)

__all__ = ["SimulatedGrbl"]


class SimulatedGrbl(Wire, SystemCommands, GcodeInterpreter, Planner):
    """The machine behind a ``sim://grbl`` port. Thread-safe; runs its own thread.

    The port object calls :meth:`receive` with host bytes and :meth:`read_output` for the machine's bytes.

    Parameters
    ----------
    config : SimConfig
    baudrate : int
        Of the port (the wire's transfer time per byte, unless ``config.wire`` is off).
    clock : Clock, optional
        What the machine's time is (:mod:`drivers.sim.clock`); by default the one ``config.clock`` names.
    """

    def __init__(self, config: SimConfig, baudrate: int = 115200, clock: Clock | None = None) -> None:
        self.config = config
        self.clock = clock if clock is not None else clock_named(config.clock, config.pace or None)
        self.rng = random.Random(config.seed)
        self.byte_time = 10.0 / baudrate if config.wire else 0.0
        self.settings = config.machine_settings()
        self.record = SimRecord()
        self.connected = True
        self._cond = threading.Condition()
        self._out_cond = threading.Condition()
        self._in_wire: deque[tuple[float, bytes]] = deque()
        self._out_wire: deque[tuple[float, bytes]] = deque()
        self._out_ready = bytearray()
        self._in_last = 0.0
        self._out_last = 0.0
        self._muted = False
        self._running = True
        self._gcode_lines = 0
        self._host_wrote = False  # line bytes written since the host last read (virtual clock: its turn is over)
        self._host_active = time.monotonic()  # wall time of the host's last read or line write
        self._wire_event_next = False  # the next event is a byte on the wire (see _next_event)
        # EEPROM: work coordinate systems G54..G59 (machine mm), G28/G30 positions
        self.coords = {n: np.zeros(3) for n in range(54, 60)}
        homing = bool(int(self.settings[22]))
        if homing and config.homed:
            # a machine its maker set up: work zero (kept in EEPROM) at the front-left corner of the homed machine
            # space (the lowest X and Y)
            self.coords[54] = np.array([self._machine_bounds()[0][0], self._machine_bounds()[0][1], 0.0])
        self.g28 = np.zeros(3)
        self.g30 = np.zeros(3)
        self.startup_lines = ["", ""]
        self.build_info = ""  # what $I= stored (EEPROM), printed after the build date by $I
        self.mpos = np.zeros(3)
        # HOMING_INIT_LOCK (main.c): with homing enabled GRBL powers up in alarm until $H (or $X)
        self._power_on_state = "Alarm" if config.locked or (homing and not config.homed) else "Idle"
        self._init_runtime(self._power_on_state)
        self._emit_banner()
        self._thread = threading.Thread(target=self._loop, name=f"sim-grbl-{config.profile}", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop the machine thread (the port was closed); with ``record=PATH``, write the record there."""
        with self._cond:
            self._running = False
            self._cond.notify_all()
        self._thread.join(timeout=2.0)
        if self.config.record:
            self.snapshot().write(self.config.record)

    def snapshot(self) -> SimRecord:
        """A consistent copy of the record."""
        with self._cond:
            r = self.record
            samples = sorted(r.samples, key=lambda s: s.t)
            return SimRecord(list(r.executed), samples, list(r.resets), list(r.received), r.overflow_bytes,
                             list(r.planner_fill), list(r.alarms), r.replies_delivered)

    @property
    def state(self) -> str:
        with self._cond:
            return self._state

    def _init_runtime(self, state: str) -> None:
        self._state = state
        self._rx = bytearray()
        self._planner: deque[Block] = deque()
        self._gen = None
        self._wait = None
        self._line_no: int | None = None
        self._halted = False
        self._owed_ok = False
        self._parse_time = self.clock.now()  # the time of the parser's current wake-up (see _step_parser)
        self._check_mode = False
        self._hold = False
        self._hold_remaining = 0.0
        self._decel: tuple[float, float, np.ndarray, np.ndarray, float] | None = None  # Hold:1 (decelerating)
        self._motion_t = 0.0
        self._gc_pos = self.mpos.copy()
        self.g92 = np.zeros(3)
        self.tlo = 0.0
        self.modal = {"motion": 0, "wcs": 54, "plane": 17, "units": 21, "distance": 90, "feedmode": 94,
                      "spindle": 5, "coolant": 9}
        self.feed = 0.0
        self.spindle_speed = 0.0
        self.tool = 0
        self._spindle_out = 0.0
        self._laser_fs = 0.0  # laser mode: the spindle speed status reports show (set by motion, see Planner)
        self.probe_position = np.zeros(3)  # the last probe cycle's ($# PRB:); a reset clears it
        self.probe_succeeded = False
        self._wco_counter = 0
        self._ovr_counter = 0
        self.overrides = [100, 100, 100]
        self._home_until = 0.0
        self._report_owed = False  # a status request that came while homing
        self._critical = False  # ALARM:1/2: GRBL serves nothing but a reset (protocol_exec_rt_system's alarm loop)
        self._fill_changed(self.clock.now())

    def _wco(self) -> np.ndarray:
        wco = self.coords[self.modal["wcs"]] + self.g92
        wco = wco.copy()
        wco[2] += self.tlo
        return wco

    # ------------------------------------------------------------------ main loop

    def _loop(self) -> None:
        with self._cond:
            while self._running:
                now = self.clock.now()
                self._deliver_input(now)
                self._advance(now)
                self._step_parser(now)
                self._advance(now)
                if self.clock.virtual:
                    self._wake_readers(now)
                self.clock.wait(self._cond, now, self._next_event(now), self._may_jump)

    def _next_event(self, now: float) -> float | None:
        """When the machine next has something to do without a new host byte (None: nothing). Sets
        ``_wire_event_next`` when that is a byte on the wire (virtual clock)."""
        times = []
        block = self._current_block()
        if block is not None and not self._hold:
            times.append(block.t0 + block.duration)
        if self._decel is not None:
            times.append(self._decel[1])
        if self._wait is not None and self._wait[0] == "time":
            times.append(self._wait[1])
        if self._state == "Home":
            times.append(self._home_until)
        wire = []
        if self._in_wire:
            wire.append(self._in_wire[0][0])
        if self.clock.virtual:
            delivery = self._next_delivery(now)  # the host's reads wait for it, and the time only moves here
            if delivery is not None:
                wire.append(delivery)
        self._wire_event_next = bool(wire) and (not times or min(wire) <= min(times))
        times.extend(wire)
        return min(times) if times else None

    def _may_jump(self) -> bool:
        """Virtual clock: whether time may skip to the next event now.

        At once when the event is a byte already on the wire (its time is fixed), or when no host byte could change
        what happens first: the planner is full (a line waiting for space, or none), homing runs, a hold
        decelerates. Otherwise once the host has had its turn: while motion runs with room in the planner, or a
        line waits for the planner to empty or for a dwell, the host may be about to send lines, and what it has
        sent by the time motion starts decides the planner's look-ahead.
        """
        if self._wire_event_next or self._planner_full() or self._state == "Home" or self._decel is not None:
            return True
        return self._host_had_its_turn()

    # ------------------------------------------------------------------ line processing

    def _step_parser(self, now: float) -> None:
        # Everything the parser does in this wake-up happens at ``now``, the time motion is planned from. Reading the
        # clock again here put a spindle change after the start of the block it precedes (seen under CPU load).
        self._parse_time = now
        for _ in range(64):  # bounded work per wake-up keeps real-time bytes prompt
            if self._halted or self._state == "Home":
                return
            if self._gen is not None:
                if not self._wait_satisfied(now):
                    return
                self._resume_gen()
                continue
            index = -1
            for i, byte in enumerate(self._rx):
                if byte in (0x0A, 0x0D):
                    index = i
                    break
            if index < 0:
                if len(self._rx) >= RX_BUFFER_SIZE - 1:  # a line longer than the buffer: GRBL's line overflow
                    self._rx.clear()
                    self._emit("error:11", "reply")
                return
            raw = bytes(self._rx[:index]).decode("latin-1")
            del self._rx[: index + 1]
            self._start_line(raw)

    def _wait_satisfied(self, now: float) -> bool:
        kind = self._wait[0] if self._wait else None
        if kind is None:
            return True
        if kind == "space":
            return len(self._planner) < PLANNER_BLOCKS
        if kind == "sync":
            return not self._planner and not self._hold and self._state not in ("Run", "Jog")
        if kind == "time":
            return now >= self._wait[1]
        if kind == "stopped":
            return self._decel is None
        return False

    def _resume_gen(self) -> None:
        try:
            wait = self._gen.send(None)
            self._wait = (wait,) if isinstance(wait, str) else wait
        except StopIteration as stop:
            self._gen = None
            self._wait = None
            status = stop.value or 0
            if self.config.drop_reply_at and self._line_no == self.config.drop_reply_at:
                self._line_no = None  # fault injection: this one reply never leaves the machine
                return
            self._emit("ok" if status == 0 else f"error:{status}", "reply")
        except Halt:
            self._gen = None
            self._wait = None

    def _start_line(self, raw: str) -> None:
        text = clean_block(raw)
        if not text:
            self._emit("ok", "reply")  # GRBL answers an empty line with ok
            return
        if len(text) >= LINE_BUFFER_SIZE:
            self._emit("error:11", "reply")
            return
        if not text.startswith("$"):
            self._gcode_lines += 1
            if self.config.disconnect_at and self._gcode_lines >= self.config.disconnect_at:
                self.record.received.append("<unplugged>")
                self.connected = False
                self._in_wire.clear()
                with self._out_cond:
                    self._out_wire.clear()
                    self._out_cond.notify_all()
                return
        self.record.received.append(text)
        self._line_no = None if text.startswith("$") else self._gcode_lines
        if text.startswith("$"):
            self._gen = self._system_command(text)
        else:
            if self._state == "Alarm":
                self._emit("error:9", "reply")
                return
            if self._state == "Jog":
                self._emit("error:9", "reply")  # G-code locked out during jog
                return
            self._gen = self._gcode(text)
        self._wait = None
        self._resume_gen()

    def _soft_reset(self, now: float) -> None:
        alarm = 0
        # a completed hold is not motion: resetting then keeps the position (no alarm)
        moving = (self._current_block() is not None and self._state != "Hold:0") or self._state in (
            "Run", "Jog", "Home", "Hold:1")
        if self._state == "Home":
            alarm = 6
        elif moving and not self._halted:
            alarm = 3
        self.mpos = np.round(self._position(now), 3)
        self.record.resets.append(now)
        was_locked = self._state == "Alarm" or alarm != 0 or self._halted
        if alarm:
            self.record.alarms.append(alarm)
            self._emit(f"ALARM:{alarm}", "alarm")
        if self._owed_ok:
            self._emit("ok", "reply")  # the soft-limit line finishes only now
        self._planner.clear()
        self._init_runtime("Alarm" if was_locked else "Idle")
        self._sample(now, 0.0)
        self._emit_banner()

    # ------------------------------------------------------------------ status

    def _status_report(self, now: float) -> str:
        state = self._state
        pos = self._position(now)
        wco = self._wco()
        if int(self.settings[10]) & 1:
            fields = [state, f"MPos:{xyz(pos)}"]
        else:
            fields = [state, f"WPos:{xyz(pos - wco)}"]
        if int(self.settings[10]) & 2:
            fields.append(f"Bf:{PLANNER_BLOCKS - len(self._planner)},{RX_BUFFER_SIZE - len(self._rx)}")
        block = self._current_block()
        rate = 0.0
        if block is not None and not self._hold and block.duration > 0:
            rate = block.length / block.duration * self.config.time_scale * 60.0
        if self._laser_mode():
            spindle = self._laser_fs
        else:
            spindle = self.spindle_speed if self.modal["spindle"] in (3, 4) else 0.0
        fields.append(f"FS:{rate:.0f},{spindle:.0f}")
        if self._probe_pin(pos):
            fields.append("Pn:P")  # REPORT_FIELD_PIN_STATE: the probe touches
        busy = state not in ("Idle", "Alarm", "Check")
        if self._wco_counter > 0:
            self._wco_counter -= 1
        else:
            self._wco_counter = 29 if busy else 9
            if self._ovr_counter == 0:
                self._ovr_counter = 1
            fields.append(f"WCO:{xyz(wco)}")
            return "<" + "|".join(fields) + ">"
        if self._ovr_counter > 0:
            self._ovr_counter -= 1
        else:
            self._ovr_counter = 19 if busy else 9
            fields.append(f"Ov:{self.overrides[0]},{self.overrides[1]},{self.overrides[2]}")
            accessory = ""
            if self.modal["spindle"] == 3:
                accessory += "S"
            elif self.modal["spindle"] == 4:
                accessory += "C"
            if self.modal["coolant"] == 8:
                accessory += "F"
            if accessory:
                fields.append(f"A:{accessory}")
        return "<" + "|".join(fields) + ">"

