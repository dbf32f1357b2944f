"""A simulated GRBL 1.1 controller that speaks the serial protocol byte for byte.

What it models
--------------
- The 128-byte serial RX buffer (a ring buffer: 127 bytes usable; ``Bf`` second field reports 128 minus the bytes in
  it, as GRBL's ``serial_get_rx_buffer_available`` does), with overflow counted (a correct streamer never overflows it)
  and GRBL's line reading (one line at a time, blocked while the planner is full).
- The 15-block planner (``Bf`` first field) and motion that takes time: each block runs at its feed (``G0`` at
  ``$110``-``$112``), limited by acceleration (``$120``-``$122``) so that the machine can always stop within the
  planned blocks, as GRBL's look-ahead does; all motion and dwell times are multiplied by ``time_scale``.
- Real-time commands ``?`` ``!`` ``~`` 0x18 (soft reset) 0x85 (jog cancel) and overrides, handled on arrival.
- ``$$``, ``$x=val``, ``$I`` (``[OPT:V,15,128]``), ``$#``, ``$G``, ``$N``, ``$C`` (check mode), ``$X``, ``$H``,
  ``$J=``, ``$RST=``; G-code errors with GRBL's numbers (error:9 locked, error:20 unsupported, error:22 no feed ...).
- Soft limits as GRBL 1.1 checks them (``system_check_travel_limits``): only with ``$20=1``, which needs homing
  (``$20=1`` with ``$22=0`` answers error:10, and ``$22=0`` also clears ``$20``); every axis in -travel..0, or with
  the build option HOMING_FORCE_SET_ORIGIN (``force_origin=1``, ``Z`` in ``[OPT:]``) an axis whose ``$23`` bit is
  set in 0..+travel. A target outside: ALARM:2, ``[MSG:Reset to continue]``, and the triggering line's ``ok`` only
  after the reset. Without homing there are no machine-space limits at all: machine zero is where the head stood at
  power-up (and G54 starts at zero there, GRBL's default).
- Homing ``$H`` (error:5 with ``$22=0``) ends where GRBL's ``limits_go_home`` sets the position: ``-$27`` (pull-off)
  for an axis homing towards +, ``-travel + $27`` for one whose ``$23`` bit is set, 0 with HOMING_FORCE_SET_ORIGIN.
  As in GRBL 1.1, ``?`` gets no answer while the cycle runs (1.5 simulated seconds): one ``<Home|...>`` report
  follows its end, however many were asked for.
- ``$I`` prints ``[VER:1.1h.20190825:<build info>]`` (report.c's format) with the build info ``$I=`` stored.
- Reset during motion: ALARM:3 and alarm lock; laser mode ``$32=1`` with M3 (constant) and M4 (dynamic) power,
  dark rapids and dark feed hold.
- A record of what it executed (:class:`SimRecord`): every block's end position, laser power and timing, samples of
  position and laser power over time, soft resets, lines received.

URL query parameters (``sim://grbl?profile=laser&time_scale=0.05&seed=3``)
--------------------------------------------------------------------------
``profile`` (``plotter``/``laser``), ``name`` (share one machine between opens), ``time_scale`` (real seconds per
simulated second), ``latency`` (seconds each way), ``wire`` (0 disables the baud-rate transfer time), ``seed``,
``drop`` / ``corrupt`` / ``stray`` / ``delay`` (probabilities per reply line), ``delay_max`` (seconds),
``disconnect_at`` (the N-th G-code line received unplugs the port), ``drop_reply_at`` (the reply to the N-th
G-code line is lost), ``locked`` (power up in alarm), ``homing`` (``0``: ``$22=0``, which also clears soft limits
``$20`` as GRBL does; ``1``: ``$22=1``), ``travel`` (``$130``-``$132`` as ``WxD`` or ``WxDxH`` in mm, e.g.
``travel=400x400``), ``force_origin`` (``1``: built with HOMING_FORCE_SET_ORIGIN), ``record`` (a file the machine
writes its record to as JSON when its port closes: what another process, e.g. a test of ``station send``, can
inspect), and ``s<N>=<value>`` to override
setting ``$N`` (applied last; ``s20=1`` with homing off is refused, as GRBL answers ``$20=1`` with error:10).
"""

from __future__ import annotations

import math
import random
import re
import threading
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

VERSION = "1.1h"
BUILD_DATE = "20190825"
BANNER = f"Grbl {VERSION} ['$' for help]"
PLANNER_BLOCKS = 15
RX_BUFFER_SIZE = 128
LINE_BUFFER_SIZE = 80

#: GRBL 1.1 defaults (defaults.h, generic).
DEFAULT_SETTINGS: dict[int, float] = {
    0: 10, 1: 25, 2: 0, 3: 0, 4: 0, 5: 0, 6: 0, 10: 1, 11: 0.010, 12: 0.002, 13: 0, 20: 0, 21: 0, 22: 0, 23: 0,
    24: 25.0, 25: 500.0, 26: 250, 27: 1.0, 30: 1000, 31: 0, 32: 0, 100: 250.0, 101: 250.0, 102: 250.0,
    110: 500.0, 111: 500.0, 112: 500.0, 120: 10.0, 121: 10.0, 122: 10.0, 130: 200.0, 131: 200.0, 132: 200.0,
}
INTEGER_SETTINGS = {0, 1, 2, 3, 4, 5, 6, 10, 13, 20, 21, 22, 23, 26, 32}
ZERO_DECIMAL_SETTINGS = {30, 31}

#: The station's two simulated machines (their EEPROM as shipped by the station).
SIM_PROFILES: dict[str, dict[int, float]] = {
    "plotter": {
        20: 1, 22: 1, 23: 0, 30: 1000, 32: 0, 100: 80.0, 101: 80.0, 102: 400.0, 110: 8000.0, 111: 8000.0,
        112: 1000.0, 120: 800.0, 121: 800.0, 122: 200.0, 130: 420.0, 131: 297.0, 132: 40.0,
    },
    "laser": {
        20: 1, 22: 1, 23: 0, 30: 1000, 32: 1, 100: 80.0, 101: 80.0, 102: 400.0, 110: 6000.0, 111: 6000.0,
        112: 1000.0, 120: 1000.0, 121: 1000.0, 122: 200.0, 130: 400.0, 131: 400.0, 132: 20.0,
    },
}

REALTIME_STATUS = 0x3F  # '?'
REALTIME_HOLD = 0x21  # '!'
REALTIME_START = 0x7E  # '~'
REALTIME_RESET = 0x18
REALTIME_JOG_CANCEL = 0x85
REALTIME_SAFETY_DOOR = 0x84


@dataclass
class SimConfig:
    """Settings of one simulated machine (see the module docstring for the URL query)."""

    profile: str = "plotter"
    name: str = ""
    time_scale: float = 1.0
    latency: float = 0.0
    wire: bool = True
    seed: int = 0
    drop: float = 0.0
    corrupt: float = 0.0
    stray: float = 0.0
    delay: float = 0.0
    delay_max: float = 0.05
    disconnect_at: int = 0
    drop_reply_at: int = 0
    locked: bool = False
    homing: bool | None = None  # None: the profile's $22
    travel: tuple[float, ...] | None = None  # $130, $131 (and $132); None: the profile's
    force_origin: bool = False  # built with HOMING_FORCE_SET_ORIGIN ('Z' in [OPT:])
    record: str = ""  # a JSON file the record is written to when the machine stops
    settings: dict[int, float] = field(default_factory=dict)

    @classmethod
    def from_query(cls, query: dict[str, str]) -> SimConfig:
        config = cls()
        floats = {"time_scale", "latency", "drop", "corrupt", "stray", "delay", "delay_max"}
        for key, value in query.items():
            if key in floats:
                setattr(config, key, float(value))
            elif key in ("seed", "disconnect_at", "drop_reply_at"):
                setattr(config, key, int(value))
            elif key in ("wire", "locked", "homing", "force_origin"):
                setattr(config, key, value.lower() in ("1", "true", "yes", "on"))
            elif key == "travel":
                config.travel = _travel_option(value)
            elif key in ("profile", "name", "record"):
                setattr(config, key, value)
            elif re.fullmatch(r"s\d+", key):
                config.settings[int(key[1:])] = float(value)
            else:
                raise ValueError(f"unknown sim option {key!r}")
        if config.profile not in SIM_PROFILES:
            raise ValueError(f"unknown sim profile {config.profile!r}; known: {sorted(SIM_PROFILES)}")
        if config.time_scale <= 0:
            raise ValueError(f"time_scale must be positive, got {config.time_scale}")
        config.machine_settings()  # a contradiction in the URL is refused when the port opens
        return config

    def machine_settings(self) -> dict[int, float]:
        """The EEPROM settings of this machine: GRBL's defaults, the profile, then ``homing``, ``travel`` and the
        ``sNN`` overrides, with GRBL's own rule that soft limits need homing.

        Raises
        ------
        ValueError
            ``s20=1`` on a machine without homing (GRBL answers ``$20=1`` with error:10 there).
        """
        settings = dict(DEFAULT_SETTINGS)
        settings.update(SIM_PROFILES[self.profile])
        if self.homing is not None:
            settings[22] = float(self.homing)
        if self.travel is not None:
            for index, value in enumerate(self.travel):
                settings[130 + index] = value
        settings.update(self.settings)
        if int(settings[20]) and not int(settings[22]):
            if int(self.settings.get(20, 0)):
                raise ValueError("s20=1 needs homing (s22=1 or homing=1): GRBL refuses soft limits without homing "
                                 "(error:10)")
            settings[20] = 0.0  # $22=0 also switches soft limits off (settings.c)
        return settings


def _travel_option(value: str) -> tuple[float, ...]:
    """``400x300`` or ``400x300x20`` (mm) as ``($130, $131[, $132])``."""
    parts = value.lower().split("x")
    try:
        travel = tuple(float(part) for part in parts)
    except ValueError:
        travel = ()
    if len(travel) not in (2, 3) or not all(math.isfinite(v) and v >= 0 for v in travel):
        raise ValueError(f"travel must be WxD or WxDxH in mm (e.g. travel=400x400), got {value!r}")
    return travel


@dataclass(frozen=True)
class ExecutedBlock:
    """One planner block the machine finished: the G-code line it came from and where it ended (machine mm)."""

    line_no: int
    text: str
    end: tuple[float, float, float]
    power: float
    feed: float
    rapid: bool
    jog: bool
    t_end: float


@dataclass(frozen=True)
class Sample:
    """Machine position (mm) and laser/spindle output from time ``t`` (``time.monotonic``) on."""

    t: float
    x: float
    y: float
    z: float
    power: float
    state: str


@dataclass
class SimRecord:
    """Everything the simulated machine did, for tests and benchmarks."""

    executed: list[ExecutedBlock] = field(default_factory=list)
    samples: list[Sample] = field(default_factory=list)
    resets: list[float] = field(default_factory=list)
    received: list[str] = field(default_factory=list)
    overflow_bytes: int = 0
    planner_fill: list[tuple[float, int, bool]] = field(default_factory=list)
    alarms: list[int] = field(default_factory=list)
    replies_delivered: int = 0

    def write(self, path: str) -> None:
        """Write the record as JSON (``samples`` as ``[t, x, y, z, power, state]`` rows, oldest first)."""
        import json

        document = {
            "samples": [[s.t, s.x, s.y, s.z, s.power, s.state] for s in sorted(self.samples, key=lambda s: s.t)],
            "executed": [[b.line_no, b.text, list(b.end), b.power, b.t_end] for b in self.executed],
            "resets": self.resets, "received": self.received, "alarms": self.alarms,
        }
        with open(path, "w", encoding="utf-8") as stream:
            json.dump(document, stream)

    def power_after(self, t: float) -> float | None:
        """Laser output of the first sample at or after ``t`` (None if there is none)."""
        for sample in sorted(self.samples, key=lambda s: s.t):
            if sample.t >= t:
                return sample.power
        return None

    def mean_planner_fill(self) -> float:
        """Time-weighted mean number of planner blocks while the machine was moving."""
        total = weighted = 0.0
        for (t0, n, moving), (t1, _, _) in zip(self.planner_fill, self.planner_fill[1:]):
            if moving and t1 > t0:
                total += t1 - t0
                weighted += (t1 - t0) * n
        return weighted / total if total else 0.0


@dataclass
class _Block:
    start: np.ndarray
    end: np.ndarray
    length: float
    feed: float  # mm/min
    rapid: bool
    power: float
    spindle: int
    line_no: int
    text: str
    jog: bool = False
    t0: float = 0.0
    duration: float = 0.0
    seg_start: np.ndarray | None = None


class _Halt(Exception):
    """Raised inside a line generator to abandon it (critical alarm)."""


class SimulatedGrbl:
    """The machine behind a ``sim://grbl`` port. Thread-safe; runs its own thread.

    The port object calls :meth:`receive` with host bytes and :meth:`read_output` for the machine's bytes.
    """

    def __init__(self, config: SimConfig, baudrate: int = 115200) -> None:
        self.config = config
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
        # EEPROM: work coordinate systems G54..G59 (machine mm), G28/G30 positions
        self.coords = {n: np.zeros(3) for n in range(54, 60)}
        if int(self.settings[22]):
            # homed machine space: the work origin at the front-left corner (the lowest X and Y)
            self.coords[54] = np.array([self._machine_bounds()[0][0], self._machine_bounds()[0][1], 0.0])
        self.g28 = np.zeros(3)
        self.g30 = np.zeros(3)
        self.startup_lines = ["", ""]
        self.build_info = ""  # what $I= stored (EEPROM), printed after the build date by $I
        self.mpos = np.zeros(3)
        self._power_on_state = "Alarm" if config.locked else "Idle"
        self._init_runtime(self._power_on_state)
        self._emit_banner()
        self._thread = threading.Thread(target=self._loop, name=f"sim-grbl-{config.profile}", daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ host side (called by the port object)

    def receive(self, data: bytes) -> None:
        """Bytes written by the host; they arrive after the latency and the wire time."""
        if not data:
            return
        with self._cond:
            if not self.connected:
                return
            now = time.monotonic()
            arrival = max(now + self.config.latency, self._in_last) + len(data) * self.byte_time
            self._in_last = arrival
            self._in_wire.append((arrival, bytes(data)))
            self._cond.notify_all()

    def read_output(self, size: int, timeout: float | None) -> bytes:
        """Up to ``size`` bytes the machine sent, waiting at most ``timeout`` s. Raises ConnectionError if the
        port was unplugged (and nothing is left to read)."""
        deadline = None if timeout is None else time.monotonic() + timeout
        with self._out_cond:
            while True:
                now = time.monotonic()
                while self._out_wire and self._out_wire[0][0] <= now:
                    self._out_ready += self._out_wire.popleft()[1]
                if self._out_ready:
                    data = bytes(self._out_ready[:size])
                    del self._out_ready[:size]
                    return data
                if not self.connected:
                    raise ConnectionError("simulated port unplugged")
                waits = []
                if self._out_wire:
                    waits.append(self._out_wire[0][0] - now)
                if deadline is not None:
                    if now >= deadline:
                        return b""
                    waits.append(deadline - now)
                self._out_cond.wait(min(waits) if waits else 0.5)

    def bytes_waiting(self) -> int:
        with self._out_cond:
            now = time.monotonic()
            while self._out_wire and self._out_wire[0][0] <= now:
                self._out_ready += self._out_wire.popleft()[1]
            return len(self._out_ready)

    def clear_output(self) -> None:
        with self._out_cond:
            self._out_ready.clear()

    def stop(self) -> None:
        """Stop the machine thread (the port was closed); with ``record=PATH``, write the record there."""
        with self._cond:
            self._running = False
            self._cond.notify_all()
        self._thread.join(timeout=2.0)
        if self.config.record:
            self.snapshot().write(self.config.record)

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
            now = time.monotonic()
            deliver = max(now + self.config.latency + extra, self._out_last) + len(data) * self.byte_time
            self._out_last = deliver
            self._out_wire.append((deliver, data))
            self._out_cond.notify_all()

    def _emit_banner(self) -> None:
        self._push(b"\r\n")
        self._emit(BANNER, "banner")
        if self._state == "Alarm":
            self._emit("[MSG:'$H'|'$X' to unlock]")

    # ------------------------------------------------------------------ state

    def _travel(self) -> np.ndarray:
        return np.array([self.settings[130], self.settings[131], self.settings[132]], dtype=float)

    def _machine_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Machine space ``(lo, hi)`` per axis as GRBL's ``system_check_travel_limits`` sees it: -travel..0, or
        0..+travel for an axis whose ``$23`` bit is set when built with HOMING_FORCE_SET_ORIGIN."""
        travel = self._travel()
        mask = int(self.settings[23])
        positive = np.array([self.config.force_origin and bool(mask & (1 << i)) for i in range(3)])
        return np.where(positive, 0.0, -travel), np.where(positive, travel, 0.0)

    def _init_runtime(self, state: str) -> None:
        self._state = state
        self._rx = bytearray()
        self._planner: deque[_Block] = deque()
        self._gen = None
        self._wait = None
        self._line_no: int | None = None
        self._halted = False
        self._owed_ok = False
        self._parse_time = time.monotonic()  # the time of the parser's current wake-up (see _step_parser)
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
        self._wco_counter = 0
        self._ovr_counter = 0
        self.overrides = [100, 100, 100]
        self._home_until = 0.0
        self._report_owed = False  # a status request that came while homing
        self._fill_changed(time.monotonic())

    def _laser_mode(self) -> bool:
        return int(self.settings[32]) == 1

    def _wco(self) -> np.ndarray:
        wco = self.coords[self.modal["wcs"]] + self.g92
        wco = wco.copy()
        wco[2] += self.tlo
        return wco

    def _current_block(self) -> _Block | None:
        if self._planner and self._planner[0].seg_start is not None:
            return self._planner[0]
        return None

    def _position(self, now: float) -> np.ndarray:
        if self._decel is not None:
            t0, t1, p0, p1, _ = self._decel
            tau = min(1.0, max(0.0, (now - t0) / (t1 - t0))) if t1 > t0 else 1.0
            return p0 + (p1 - p0) * (1.0 - (1.0 - tau) ** 2)  # constant deceleration
        block = self._current_block()
        if block is None or self._hold:
            return self.mpos.copy()
        frac = min(1.0, max(0.0, (now - block.t0) / block.duration)) if block.duration > 0 else 1.0
        return block.seg_start + (block.end - block.seg_start) * frac

    def _block_power(self, block: _Block | None) -> float:
        if not self._laser_mode():
            return self._spindle_out
        if block is None or block.rapid or block.jog or (self._hold and self._decel is None) or block.spindle == 5:
            return 0.0
        return min(block.power, self.settings[30])

    def _sample(self, t: float, power: float | None = None) -> None:
        pos = self._position(t)
        if power is None:
            power = self._block_power(self._current_block())
        self.record.samples.append(Sample(t, float(pos[0]), float(pos[1]), float(pos[2]), float(power), self._state))

    def _fill_changed(self, t: float) -> None:
        moving = self._current_block() is not None and not self._hold
        self.record.planner_fill.append((t, len(self._planner), moving))

    # ------------------------------------------------------------------ main loop

    def _loop(self) -> None:
        with self._cond:
            while self._running:
                now = time.monotonic()
                self._deliver_input(now)
                self._advance(now)
                self._step_parser(now)
                self._advance(now)
                wake = self._next_wake(now)
                self._cond.wait(max(0.0, min(wake - now, 0.1)))

    def _next_wake(self, now: float) -> float:
        times = [now + 0.1]
        if self._in_wire:
            times.append(self._in_wire[0][0])
        block = self._current_block()
        if block is not None and not self._hold:
            times.append(block.t0 + block.duration)
        if self._decel is not None:
            times.append(self._decel[1])
        if self._wait is not None and self._wait[0] == "time":
            times.append(self._wait[1])
        if self._state == "Home":
            times.append(self._home_until)
        return min(times)

    def _deliver_input(self, now: float) -> None:
        while self._in_wire and self._in_wire[0][0] <= now:
            _, data = self._in_wire.popleft()
            for byte in data:
                if not self.connected:
                    return
                if byte in (REALTIME_STATUS, REALTIME_HOLD, REALTIME_START, REALTIME_RESET) or byte >= 0x80:
                    self._realtime(byte, now)
                elif len(self._rx) < RX_BUFFER_SIZE - 1:  # a ring buffer: one slot always stays empty
                    self._rx.append(byte)
                else:
                    self.record.overflow_bytes += 1  # a real GRBL silently loses it

    # ------------------------------------------------------------------ real-time commands

    def _realtime(self, byte: int, now: float) -> None:
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
            if self._state == "Jog":
                self.mpos = self._position(now)
                self._planner.clear()
                self._gc_pos = self.mpos.copy()
                self._state = "Idle"
                self._sample(now, 0.0 if self._laser_mode() else None)
                self._fill_changed(now)
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

    def _feed_hold(self, now: float) -> None:
        if self._state in ("Run", "Idle") and not self._halted:
            block = self._current_block()
            if block is not None and block.duration > 0:
                # decelerate along the block at the axes' acceleration (Hold:1), then stop (Hold:0)
                position = self._position(now)
                direction = (block.end - block.seg_start) / max(np.linalg.norm(block.end - block.seg_start), 1e-12)
                speed = np.linalg.norm(block.end - block.seg_start) / (block.duration / self.config.time_scale)
                accel = np.array([self.settings[120], self.settings[121], self.settings[122]])
                moving = np.abs(direction) > 1e-12
                a = float(np.min(accel[moving] / np.abs(direction[moving]))) if moving.any() else 1.0
                remaining = float(np.linalg.norm(block.end - position))
                stop = min(speed * speed / (2 * a), remaining)
                decel_time = (2 * stop / speed if speed > 0 else 0.0) * self.config.time_scale
                left = max(0.0, (remaining - stop) / speed * self.config.time_scale) if speed > 0 else 0.0
                self._decel = (now, now + decel_time, position, position + direction * stop, left)
                self._hold = True
                self._state = "Hold:1"
                self._sample(now)
            else:
                self._hold = True
                self._state = "Hold:0"
                self._sample(now, 0.0 if self._laser_mode() else None)
            self._fill_changed(now)
        elif self._state == "Jog":
            self._realtime(REALTIME_JOG_CANCEL, now)

    def _cycle_start(self, now: float) -> None:
        if self._state == "Hold:0":  # GRBL ignores cycle start until the hold is complete
            self._hold = False
            block = self._current_block()
            if block is not None:
                block.seg_start = self.mpos.copy()
                block.t0 = now
                block.duration = self._hold_remaining
                self._state = "Run"
            else:
                self._state = "Idle"
            self._sample(now)
            self._fill_changed(now)

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

    # ------------------------------------------------------------------ motion

    def _advance(self, now: float) -> None:
        if self._decel is not None and now >= self._decel[1]:
            self.mpos = self._decel[3].copy()
            self._hold_remaining = self._decel[4]
            self._decel = None
            self._state = "Hold:0"
            self._sample(now, 0.0 if self._laser_mode() else None)
        if self._state == "Home" and now >= self._home_until:
            # where limits_go_home sets each axis: pulled off the switch, inside the machine space
            pulloff = self.settings[27]
            towards_minus = np.array([bool(int(self.settings[23]) & (1 << i)) for i in range(3)])
            if self.config.force_origin:
                self.mpos = np.zeros(3)
            else:
                self.mpos = np.where(towards_minus, -self._travel() + pulloff, -pulloff)
            self._gc_pos = self.mpos.copy()
            if self._report_owed:
                self._report_owed = False
                self._emit(self._status_report(now), "status")  # still in Home: mc_homing_cycle serves it
            self._state = "Idle"
            self._sample(now, 0.0)
            return
        if self._hold or self._halted:
            return
        while self._planner:
            block = self._planner[0]
            if block.seg_start is None:
                self._start_block(block, now)
                continue
            t_end = block.t0 + block.duration
            if t_end > now:
                return
            self.mpos = block.end.copy()
            self._planner.popleft()
            self.record.executed.append(ExecutedBlock(
                block.line_no, block.text, tuple(float(v) for v in block.end), self._block_power(block), block.feed,
                block.rapid, block.jog, t_end))
            self._motion_t = t_end
            if self._planner:
                self._start_block(self._planner[0], t_end)
            else:
                if self._state in ("Run", "Jog"):
                    self._state = "Idle"
                self.record.samples.append(Sample(t_end, *map(float, self.mpos), 0.0 if self._laser_mode()
                                                  else self._spindle_out, self._state))
            self._fill_changed(t_end)

    def _start_block(self, block: _Block, t: float) -> None:
        delta = np.abs(block.end - block.start)
        unit = delta / block.length
        moving = unit > 1e-12
        max_rate = np.array([self.settings[110], self.settings[111], self.settings[112]])
        accel = np.array([self.settings[120], self.settings[121], self.settings[122]])
        rate_limit = float(np.min(max_rate[moving] / unit[moving]))
        accel_limit = float(np.min(accel[moving] / unit[moving]))
        feed = rate_limit if block.rapid else min(block.feed * self.overrides[0] / 100.0, rate_limit)
        if block.rapid:
            feed = rate_limit * self.overrides[1] / 100.0
        lookahead = sum(b.length for b in self._planner)  # GRBL must be able to stop at the end of the plan
        speed = min(feed / 60.0, math.sqrt(2.0 * accel_limit * lookahead))
        block.seg_start = block.start.copy()
        block.t0 = t
        block.duration = block.length / max(speed, 1e-6) * self.config.time_scale
        if self._state in ("Idle", "Run", "Jog"):
            self._state = "Jog" if block.jog else "Run"
        self._sample(t, self._block_power(block))

    def _plan(self, target: np.ndarray, rapid: bool, feed: float, text: str, jog: bool = False) -> None:
        length = float(np.linalg.norm(target - self._gc_pos))
        if length < 1e-6:
            return  # GRBL drops zero-length blocks
        power = self.spindle_speed if self.modal["spindle"] in (3, 4) else 0.0
        self._planner.append(_Block(self._gc_pos.copy(), target.copy(), length, feed, rapid, power,
                                    self.modal["spindle"], self._gcode_lines, text, jog))
        self._gc_pos = target.copy()
        self._fill_changed(self._parse_time)

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
        except _Halt:
            self._gen = None
            self._wait = None

    def _start_line(self, raw: str) -> None:
        # GRBL drops whitespace and control characters, strips comments, upper-cases
        text = re.sub(r"\([^)]*\)|;.*$", "", raw)
        text = "".join(ch for ch in text if ch > " " and ch != "\x7f").upper()
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

    # ------------------------------------------------------------------ $ commands

    def _format_setting(self, key: int) -> str:
        value = self.settings[key]
        if key in INTEGER_SETTINGS or key in ZERO_DECIMAL_SETTINGS:
            return f"${key}={int(round(value))}"
        return f"${key}={value:.3f}"

    def _system_command(self, text: str):
        idle_or_alarm = self._state in ("Idle", "Alarm", "Check") or self._check_mode
        if text == "$":
            self._emit("[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H ~ ! ? ctrl-x]")
            return 0
        if text == "$$":
            if not idle_or_alarm:
                return 8
            for key in sorted(self.settings):
                self._emit(self._format_setting(key))
            return 0
        if text == "$#":
            if not idle_or_alarm:
                return 8
            for n in range(54, 60):
                self._emit(f"[G{n}:{self._xyz(self.coords[n])}]")
            self._emit(f"[G28:{self._xyz(self.g28)}]")
            self._emit(f"[G30:{self._xyz(self.g30)}]")
            self._emit(f"[G92:{self._xyz(self.g92)}]")
            self._emit(f"[TLO:{self.tlo:.3f}]")
            self._emit("[PRB:0.000,0.000,0.000:0]")
            return 0
        if text == "$G":
            m = self.modal
            spindle = f"M{m['spindle']}"
            self._emit(f"[GC:G{m['motion']} G{m['wcs']} G{m['plane']} G{m['units']} G{m['distance']} "
                       f"G{m['feedmode']} {spindle} M{m['coolant']} T{self.tool} F{self.feed:.0f} "
                       f"S{self.spindle_speed:.0f}]")
            return 0
        if text == "$I":
            if not idle_or_alarm:
                return 8
            self._emit(f"[VER:{VERSION}.{BUILD_DATE}:{self.build_info}]")
            self._emit(f"[OPT:V{'Z' if self.config.force_origin else ''},{PLANNER_BLOCKS},{RX_BUFFER_SIZE}]")
            return 0
        if text.startswith("$I="):
            if not idle_or_alarm:
                return 8
            self.build_info = text[3:]  # the line as GRBL keeps it: upper case, without spaces
            yield "sync"  # EEPROM write
            return 0
        if text == "$N":
            for i, line in enumerate(self.startup_lines):
                self._emit(f"$N{i}={line}")
            return 0
        if text == "$C":
            if self._check_mode:
                self._emit("[MSG:Disabled]")
                self._emit("ok", "reply")
                self._soft_reset(self._parse_time)
                raise _Halt
            if self._state != "Idle":
                return 8
            self._check_mode = True
            self._state = "Check"
            self._emit("[MSG:Enabled]")
            return 0
        if text == "$X":
            if self._state == "Alarm":
                self._state = "Idle"
                self._emit("[MSG:Caution: Unlocked]")
                return 0
            return 0 if idle_or_alarm else 8
        if text == "$H":
            if not int(self.settings[22]):
                return 5
            if not idle_or_alarm or self._check_mode:
                return 8
            self._state = "Home"
            self._home_until = self._parse_time + 1.5 * self.config.time_scale
            self._wait = ("time", self._home_until)
            yield ("time", self._home_until)
            return 0
        if text.startswith("$J="):
            return (yield from self._jog(text[3:]))
        if text.startswith("$RST="):
            what = text[5:]
            if what not in ("$", "#", "*"):
                return 3
            if what in ("$", "*"):
                self.settings = self.config.machine_settings()  # this machine's EEPROM as shipped
            if what in ("#", "*"):
                for n in self.coords:
                    self.coords[n] = np.zeros(3)
                self.g28 = np.zeros(3)
                self.g30 = np.zeros(3)
            return 0
        match = re.fullmatch(r"\$N([01])=(.*)", text)
        if match:
            self.startup_lines[int(match.group(1))] = match.group(2)
            return 0
        match = re.fullmatch(r"\$(\d+)=(.*)", text)
        if match:
            if not idle_or_alarm:
                return 8
            key = int(match.group(1))
            try:
                value = float(match.group(2))
            except ValueError:
                return 2
            if key not in self.settings:
                return 3
            if value < 0:
                return 4
            if key == 0 and value < 3:
                return 6
            if key == 20 and value and not int(self.settings[22]):
                return 10
            self.settings[key] = float(int(value)) if key in INTEGER_SETTINGS else value
            if key == 22 and not int(value):
                self.settings[20] = 0.0  # GRBL force-disables soft limits with homing
            yield "sync"  # EEPROM write
            return 0
        return 3

    def _xyz(self, v) -> str:
        return ",".join(f"{float(x):.3f}" for x in v)

    def _jog(self, body: str):
        if self._state not in ("Idle", "Jog"):
            return 8
        try:
            words = _grbl_words(body)
        except _GrblError as error:
            return error.code
        absolute = self.modal["distance"] == 90
        unit = 1.0 if self.modal["units"] == 21 else 25.4
        machine = False
        axes: dict[int, float] = {}
        feed = None
        for letter, value in words:
            if letter == "G":
                if value in (90.0, 91.0):
                    absolute = value == 90.0
                elif value in (20.0, 21.0):
                    unit = 1.0 if value == 21.0 else 25.4
                elif value == 53.0:
                    machine = True
                else:
                    return 16
            elif letter in "XYZ":
                axes["XYZ".index(letter)] = value
            elif letter == "F":
                feed = value
            elif letter == "N":
                continue
            else:
                return 16
        if feed is None:
            return 22
        if not axes:
            return 26
        target = self._gc_pos.copy()
        wco = self._wco()
        for i, v in axes.items():
            if machine:
                target[i] = v * unit
            elif absolute:
                target[i] = v * unit + wco[i]
            else:
                target[i] += v * unit
        if int(self.settings[20]) and not self._within_travel(target):
            return 15
        if self._check_mode:
            return 0
        while len(self._planner) >= PLANNER_BLOCKS:
            yield "space"
        self._plan(target, False, feed * unit, "$J=" + body, jog=True)
        return 0

    def _within_travel(self, target: np.ndarray) -> bool:
        lo, hi = self._machine_bounds()
        return bool(np.all((target <= hi + 1e-4) & (target >= lo - 1e-4)))

    # ------------------------------------------------------------------ G-code

    def _gcode(self, text: str):
        try:
            words = _grbl_words(text)
            block = _classify(words)
        except _GrblError as error:
            return error.code
        m = dict(self.modal)
        unit = 1.0
        if "units" in block.groups:
            m["units"] = block.groups["units"]
        unit = 1.0 if m["units"] == 21 else 25.4
        values = block.values
        for letter in ("F", "S", "T", "N", "P"):
            if letter in values and values[letter] < 0:
                return 4
        if "T" in values and values["T"] > 255:
            return 38
        if "N" in values and values["N"] > 9999999:
            return 27
        if "feedmode" in block.groups:
            m["feedmode"] = block.groups["feedmode"]
        feed = self.feed
        if "F" in values:
            feed = values["F"] * unit
        elif m["feedmode"] == 93:
            feed = 0.0
        motion = block.groups.get("motion", m["motion"])
        nonmodal = block.groups.get("nonmodal")
        axis_words = {i: values[a] for i, a in enumerate("XYZ") if a in values}
        axis_user = nonmodal in (10.0, 28.0, 30.0, 92.0)
        if axis_words and not axis_user and motion == 80:
            return 31
        uses_motion = bool(axis_words) and not axis_user and motion in (0, 1, 2, 3)
        if "motion" in block.groups and motion in (1, 2, 3) and not axis_words and not axis_user:
            uses_motion = False
        if uses_motion and motion in (1, 2, 3) and feed <= 0:
            return 22
        if motion in (2, 3) and uses_motion:
            if not ({"I", "J", "K", "R"} & values.keys()):
                return 35
        unused = set(values) & {"I", "J", "K", "R"}
        if unused and not (uses_motion and motion in (2, 3)):
            return 36
        if "L" in values and nonmodal != 10.0:
            return 36
        if "P" in values and nonmodal not in (4.0, 10.0):
            return 36
        if nonmodal == 53.0 and motion not in (0, 1):
            return 30
        if nonmodal == 4.0 and "P" not in values:
            return 28
        if nonmodal == 10.0 and ("L" not in values or "P" not in values):
            return 28
        if nonmodal == 10.0 and (values["L"] not in (2.0, 20.0) or values["P"] not in range(0, 7)):
            return 20

        # -- execute in GRBL's order
        self.modal["feedmode"] = m["feedmode"]
        self.feed = feed
        new_speed = values.get("S", self.spindle_speed)
        new_spindle = block.groups.get("spindle", self.modal["spindle"])
        spindle_changed = new_spindle != self.modal["spindle"]
        speed_changed = new_speed != self.spindle_speed
        if "T" in values:
            self.tool = int(values["T"])
        if spindle_changed or (speed_changed and new_spindle in (3, 4) and not self._laser_mode()):
            if not self._check_mode:
                yield "sync"
            self.modal["spindle"] = new_spindle
            self.spindle_speed = new_speed
            self._spindle_changed()
        else:
            self.spindle_speed = new_speed
        if "coolant" in block.groups:
            self.modal["coolant"] = block.groups["coolant"]
        if nonmodal == 4.0:
            if not self._check_mode:
                yield "sync"
                yield ("time", self._parse_time + values["P"] * self.config.time_scale)
        for key in ("plane", "units", "distance", "wcs"):
            if key in block.groups:
                self.modal[key] = block.groups[key]
        if block.groups.get("arcdistance", 91.1) != 91.1:
            return 20
        if "tlo" in block.groups:
            self.tlo = values.get("Z", 0.0) * unit if block.groups["tlo"] == 43.1 else 0.0
            axis_words.pop(2, None)
        wco = self._wco()
        absolute = self.modal["distance"] == 90

        def work_target(base_machine: np.ndarray, machine_coords: bool = False) -> np.ndarray:
            target = base_machine.copy()
            for i, v in axis_words.items():
                if machine_coords:
                    target[i] = v * unit
                elif absolute:
                    target[i] = v * unit + wco[i]
                else:
                    target[i] = target[i] + v * unit
            return target

        if nonmodal == 10.0:
            index = int(values["P"]) or self.modal["wcs"] - 53
            n = 53 + index
            data = self.coords[n].copy()
            for i, v in axis_words.items():
                if values["L"] == 2.0:
                    data[i] = v * unit
                else:  # L20: current position becomes the given work value
                    data[i] = self._gc_pos[i] - self.g92[i] - v * unit - (self.tlo if i == 2 else 0.0)
            if not self._check_mode:
                yield "sync"  # EEPROM write
            self.coords[n] = data
            self._wco_counter = 0  # GRBL reports the new offset in the next status report
            return 0
        if nonmodal == 92.0:
            for i, v in axis_words.items():
                self.g92[i] = self._gc_pos[i] - self.coords[self.modal["wcs"]][i] - v * unit
            self._wco_counter = 0
            return 0
        if nonmodal == 92.1:
            self.g92 = np.zeros(3)
            self._wco_counter = 0
            return 0
        if nonmodal in (28.1, 30.1):
            if not self._check_mode:
                yield "sync"
            if nonmodal == 28.1:
                self.g28 = self._gc_pos.copy()
            else:
                self.g30 = self._gc_pos.copy()
            return 0
        if nonmodal in (28.0, 30.0):
            stored = self.g28 if nonmodal == 28.0 else self.g30
            if axis_words:
                yield from self._move(work_target(self._gc_pos), True, feed, text)
            yield from self._move(stored.copy(), True, feed, text)
            return 0
        if "motion" in block.groups:
            self.modal["motion"] = block.groups["motion"]
        if uses_motion:
            target = work_target(self._gc_pos, nonmodal == 53.0)
            if motion in (0, 1):
                yield from self._move(target, motion == 0, feed, text)
            else:
                points = self._arc(target, motion == 2, values, unit)
                if points is None:
                    return 33
                for point in points:
                    yield from self._move(point, False, feed, text)
        stop = block.groups.get("stop")
        if stop == 0:  # M0 program pause (M1 optional stop is off on GRBL)
            if not self._check_mode:
                yield "sync"
                self._hold = True
                self._state = "Hold:0"
        elif stop in (2, 30):
            if not self._check_mode:
                yield "sync"
            self.modal.update(motion=1, wcs=54, plane=17, distance=90, feedmode=94, spindle=5, coolant=9)
            self.g92 = np.zeros(3)
            self._spindle_changed()
        return 0

    def _spindle_changed(self) -> None:
        on = self.modal["spindle"] in (3, 4)
        speed = min(max(self.spindle_speed, self.settings[31]), self.settings[30]) if on else 0.0
        self._spindle_out = speed if on else 0.0
        if not self._check_mode:
            self._sample(self._parse_time)

    def _move(self, target: np.ndarray, rapid: bool, feed: float, text: str):
        if int(self.settings[20]) and not self._within_travel(target):
            self._soft_limit_alarm()
            raise _Halt
        if self._check_mode:
            self._gc_pos = target.copy()
            return
        while len(self._planner) >= PLANNER_BLOCKS:
            yield "space"
        if self.modal["feedmode"] == 93 and not rapid:
            length = float(np.linalg.norm(target - self._gc_pos))
            feed = length * feed if feed > 0 else feed
        self._plan(target, rapid, feed, text)

    def _soft_limit_alarm(self) -> None:
        now = self._parse_time
        # GRBL feed-holds to a stop, then resets and waits for the user's reset: position is kept.
        self.mpos = self._position(now)
        self._planner.clear()
        self._hold = False
        self._state = "Alarm"
        self._halted = True
        self._owed_ok = True
        self._spindle_out = 0.0
        self._sample(now, 0.0)
        self._fill_changed(now)
        self.record.alarms.append(2)
        self._emit("ALARM:2", "alarm")
        self._emit("[MSG:Reset to continue]")

    def _arc(self, target: np.ndarray, clockwise: bool, values: dict, unit: float) -> list[np.ndarray] | None:
        a, b = {17: (0, 1), 18: (2, 0), 19: (1, 2)}[self.modal["plane"]]
        start = self._gc_pos
        if "R" in values:
            r = values["R"] * unit
            dx, dy = target[a] - start[a], target[b] - start[b]
            d = math.hypot(dx, dy)
            if d == 0 or 4 * r * r - d * d < -1e-9:
                return None
            h = math.sqrt(max(r * r - d * d / 4, 0.0))
            sign = -1 if clockwise ^ (r < 0) else 1
            centre = (start[a] + dx / 2 - sign * h * dy / d, start[b] + dy / 2 + sign * h * dx / d)
        else:
            names = "IJK"
            centre = (start[a] + values.get(names[a], 0.0) * unit, start[b] + values.get(names[b], 0.0) * unit)
        r0 = math.hypot(start[a] - centre[0], start[b] - centre[1])
        r1 = math.hypot(target[a] - centre[0], target[b] - centre[1])
        if abs(r0 - r1) > 0.5 and abs(r0 - r1) > 0.001 * r0:  # GRBL error:33 (invalid target)
            return None
        t0 = math.atan2(start[b] - centre[1], start[a] - centre[0])
        t1 = math.atan2(target[b] - centre[1], target[a] - centre[0])
        sweep = t1 - t0
        if clockwise and sweep >= -1e-9:
            sweep -= 2 * math.pi
        elif not clockwise and sweep <= 1e-9:
            sweep += 2 * math.pi
        tol = self.settings[12]
        n = max(1, int(math.floor(abs(0.5 * sweep * r0) / math.sqrt(max(tol * (2 * r0 - tol), 1e-12)))))
        points = []
        for k in range(1, n + 1):
            p = start.copy()
            ang = t0 + sweep * k / n
            p[a] = centre[0] + r0 * math.cos(ang)
            p[b] = centre[1] + r0 * math.sin(ang)
            p[3 - a - b] = start[3 - a - b] + (target[3 - a - b] - start[3 - a - b]) * k / n
            points.append(p)
        points[-1] = target.copy()
        return points

    # ------------------------------------------------------------------ status

    def _status_report(self, now: float) -> str:
        state = self._state
        pos = self._position(now)
        wco = self._wco()
        if int(self.settings[10]) & 1:
            fields = [state, f"MPos:{self._xyz(pos)}"]
        else:
            fields = [state, f"WPos:{self._xyz(pos - wco)}"]
        if int(self.settings[10]) & 2:
            fields.append(f"Bf:{PLANNER_BLOCKS - len(self._planner)},{RX_BUFFER_SIZE - len(self._rx)}")
        block = self._current_block()
        rate = 0.0
        if block is not None and not self._hold and block.duration > 0:
            rate = block.length / block.duration * self.config.time_scale * 60.0
        spindle = self.spindle_speed if self.modal["spindle"] in (3, 4) else 0.0
        fields.append(f"FS:{rate:.0f},{spindle:.0f}")
        busy = state not in ("Idle", "Alarm", "Check")
        if self._wco_counter > 0:
            self._wco_counter -= 1
        else:
            self._wco_counter = 29 if busy else 9
            if self._ovr_counter == 0:
                self._ovr_counter = 1
            fields.append(f"WCO:{self._xyz(wco)}")
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


class _GrblError(Exception):
    def __init__(self, code: int) -> None:
        super().__init__(code)
        self.code = code


_SUPPORTED_LETTERS = set("FGIJKLMNPRSTXYZ")
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)")


def _grbl_words(text: str) -> list[tuple[str, float]]:
    words = []
    i = 0
    while i < len(text):
        letter = text[i]
        if not ("A" <= letter <= "Z"):
            raise _GrblError(1)
        match = _NUMBER.match(text, i + 1)
        if match is None:
            raise _GrblError(2)
        if letter not in _SUPPORTED_LETTERS:
            raise _GrblError(20)
        words.append((letter, float(match.group(0))))
        i = match.end()
    return words


@dataclass
class _Classified:
    groups: dict
    values: dict


_G_GROUPS = {
    0.0: ("motion", 0), 1.0: ("motion", 1), 2.0: ("motion", 2), 3.0: ("motion", 3), 80.0: ("motion", 80),
    4.0: ("nonmodal", 4.0), 10.0: ("nonmodal", 10.0), 28.0: ("nonmodal", 28.0), 28.1: ("nonmodal", 28.1),
    30.0: ("nonmodal", 30.0), 30.1: ("nonmodal", 30.1), 53.0: ("nonmodal", 53.0), 92.0: ("nonmodal", 92.0),
    92.1: ("nonmodal", 92.1), 17.0: ("plane", 17), 18.0: ("plane", 18), 19.0: ("plane", 19),
    90.0: ("distance", 90), 91.0: ("distance", 91), 91.1: ("arcdistance", 91.1), 93.0: ("feedmode", 93),
    94.0: ("feedmode", 94), 20.0: ("units", 20), 21.0: ("units", 21), 40.0: ("cutter", 40),
    43.1: ("tlo", 43.1), 49.0: ("tlo", 49), 54.0: ("wcs", 54), 55.0: ("wcs", 55), 56.0: ("wcs", 56),
    57.0: ("wcs", 57), 58.0: ("wcs", 58), 59.0: ("wcs", 59), 61.0: ("control", 61),
}
_M_GROUPS = {0.0: ("stop", 0), 1.0: ("stop", 1), 2.0: ("stop", 2), 30.0: ("stop", 30), 3.0: ("spindle", 3),
             4.0: ("spindle", 4), 5.0: ("spindle", 5), 8.0: ("coolant", 8), 9.0: ("coolant", 9)}


def _classify(words: list[tuple[str, float]]) -> _Classified:
    groups: dict = {}
    values: dict = {}
    for letter, value in words:
        if letter in "GM":
            table = _G_GROUPS if letter == "G" else _M_GROUPS
            key = round(value, 1)
            if key not in table:
                raise _GrblError(20 if letter == "G" or value == int(value) else 23)
            group, code = table[key]
            if group in groups:
                raise _GrblError(21)
            groups[group] = code
        else:
            if letter in values:
                raise _GrblError(25)
            values[letter] = value
    return _Classified(groups, values)
