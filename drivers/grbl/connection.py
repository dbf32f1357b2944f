"""A live connection to one GRBL 1.1 controller.

Threads
-------
- a reader thread reads the port, splits lines and dispatches every message (ok/error to the oldest pending line,
  alarms, banners, status reports, push messages) and keeps a rolling log of the traffic;
- a status thread writes ``?`` at most every ``poll_interval`` s (5 Hz by default) and runs the watchdogs: a lost
  ``ok`` (status shows the machine idle with empty planner and RX buffer while lines are still counted as pending)
  and a silent port (see :mod:`drivers.grbl.watchdogs`);
- the calling thread streams lines (:meth:`GrblConnection.stream`) by character counting against GRBL's serial RX
  buffer (size from ``$I``), or send-response for what GRBL's interface rules require (``$`` commands, ``G10``,
  ``G28.1``, ``G30.1``).

Real-time bytes (``?``, ``!``, ``~``, 0x18, 0x85, overrides) are written at once by :meth:`realtime`: G-code waits in
this object's memory, never in the port, and at most one RX buffer of G-code (128 bytes) is ever in flight, so a
real-time byte never waits behind queued G-code.

A port that vanished (USB unplugged, a pty hung up, a socket closed) makes the OS fail a read or a write: that is
reported at once. A port that stays open but goes silent, and a lost ``ok``, are found by the watchdogs of
:mod:`drivers.grbl.watchdogs` (their rules are written there).

After any banner (power-up or reset) or alarm, the character counter is cleared; after an alarm, ``ok`` lines are
ignored until the reset banner (the soft-limit line's ``ok`` arrives only after the reset). An ``ok`` is never
invented: a lost one stops the stream with a clear message.

A hard or soft limit (ALARM:1, ALARM:2) leaves GRBL in its critical-event loop (``protocol_exec_rt_system``): it
answers nothing, not even ``?``, until a soft reset, and a reset that arrives before GRBL has printed
``[MSG:Reset to continue]`` is swallowed by that loop. So the status thread sends the reset itself once GRBL asks for
it (or a moment after the alarm), and again while no banner follows; meanwhile the silence watchdog rests. After the
reset GRBL is still locked: :meth:`GrblConnection.recover` unlocks it (``$X``) only after ALARM:2, whose position GRBL
kept; after ALARM:1 it stays locked for homing.

Status reports come in whatever form ``$10`` asks for (``MPos`` or ``WPos``, with or without ``Bf``): the connection
never changes that setting. Each report is completed with the other position from the work offset GRBL reports
(``WCO``, or ``$#`` and ``$G`` until a report brings one), so callers always find both ``mpos`` and ``wpos``.

Why this module stays over 600 lines: :class:`GrblConnection` is one class on purpose. Its reader thread, its
streamer and its real-time path share one lock, one count of the bytes in GRBL's RX buffer and one fault state, and
the rules that keep a machine safe hold across all three (never more than one RX buffer of G-code in flight, an
``ok`` never invented, no line written after an abort's reset); split over files, one invariant would be read in
pieces. What has state or rules of its own lives apart: the watchdogs (:mod:`drivers.grbl.watchdogs`), what the
settings say about the machine (:mod:`drivers.grbl.machine_settings`), the message grammar
(:mod:`drivers.grbl.protocol`).
"""

from __future__ import annotations

import functools
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import serial

from drivers.errors import DeviceStateError, PortError, ProtocolError
from drivers.gcode import clean_line
from drivers.grbl.machine_settings import MachineSettings
from drivers.grbl.protocol import (
    CRITICAL_ALARMS,
    HOMING_FAIL_ALARMS,
    Alarm,
    Banner,
    Error,
    Feedback,
    Garbled,
    Ok,
    SettingLine,
    StatusReport,
    VersionInfo,
    needs_sync,
    parse_line,
    parse_version,
)
from drivers.grbl.watchdogs import LostOkWatchdog, SilenceWatchdog, dwell_seconds, pauses_reports

__all__ = ["GrblConnection", "LineResult", "StreamStopped", "open_port"]

DEFAULT_RX_SIZE = 128
DEFAULT_PLANNER_SIZE = 15
#: Seconds after ALARM:1/2 before the reset is sent when GRBL has not said ``[MSG:Reset to continue]`` (a lost line).
CRITICAL_RESET_DELAY = 0.5
#: Seconds to wait for the banner after such a reset before sending another (the first may have come too early).
CRITICAL_RESET_RETRY = 1.0
#: Resets sent after ALARM:1/2 without a banner before the controller counts as gone.
CRITICAL_RESET_TRIES = 5


def open_port(url: str, baud: int = 115200, timeout: float = 0.05) -> serial.SerialBase:
    """Open ``url`` with :func:`serial.serial_for_url` (device path, ``socket://``, ``loop://``, ``sim://``)."""
    import drivers.sim

    drivers.sim.register()
    try:
        return serial.serial_for_url(url, baudrate=baud, timeout=timeout, write_timeout=2.0)
    except (serial.SerialException, ValueError, OSError) as error:
        raise PortError(f"cannot open port {url!r}: {error}") from None


class StreamStopped(DeviceStateError):
    """Streaming stopped before every line was acknowledged (fault, alarm, error, abort). ``.reason`` says why."""

    def __init__(self, message: str, reason: str, first_unconfirmed: int | None = None) -> None:
        super().__init__(message)
        self.reason = reason
        self.first_unconfirmed = first_unconfirmed
        self.results: list[LineResult] = []


@dataclass
class LineResult:
    """What happened to one streamed line (``index`` into the caller's list)."""

    index: int
    text: str
    status: str = "pending"  # pending, ok, error, unconfirmed
    error: int | None = None
    replies: list = field(default_factory=list)


class _Prepared(NamedTuple):
    """A line read ahead by the streamer (see :meth:`GrblConnection._prepare`)."""

    result: LineResult
    data: bytes
    sync: bool
    dwell: float
    busy: float


@dataclass
class _Pending:
    result: LineResult
    nbytes: int
    dwell: float  # G4: GRBL reports Idle with empty buffers meanwhile (the lost-ok watchdog allows for it)
    busy: float = 0.0  # homing: GRBL answers nothing meanwhile (only the wait for the reply allows for it)
    done: threading.Event = field(default_factory=threading.Event)


class GrblConnection(MachineSettings):
    """One GRBL controller behind a port URL.

    Parameters
    ----------
    url : str
        Port URL (``/dev/ttyUSB0``, ``socket://host:port``, ``sim://grbl?profile=laser`` ...).
    baud : int
        Baud rate (115200 for GRBL 1.1).
    poll_interval : float
        Seconds between status requests (``?``); GRBL asks for at most 5 Hz on real machines.
    lost_ok_timeout : float
        Seconds the "idle, buffers empty, lines pending" condition must hold before a lost ``ok`` is declared.
        With the 5 Hz poll the loss is reported within ``lost_ok_timeout + poll_interval`` (2 s by default).
    silence_timeout : float
        Seconds a status request (``?``) may stay without any byte in reply, counted only while this process runs
        (see the module docstring), before a last probe is sent. GRBL answers within milliseconds outside homing
        and EEPROM writes, during which the watchdog rests.
    silence_grace : float
        Seconds after that probe (counted the same way) before the port counts as vanished ("position lost").
        A silent port is declared within about ``silence_timeout + silence_grace + poll_interval`` (1.4 s by
        default) when the host is not overloaded; a port the OS reports gone is declared at once.
    banner_timeout : float
        Seconds to wait for the banner after opening (then a soft reset is tried).
    reply_timeout : float
        Seconds a line may wait for its ``ok``/``error`` (plus its dwell) before the stream stops.
    log_size : int
        Lines of traffic kept in :attr:`log`.
    """

    def __init__(
        self,
        url: str,
        baud: int = 115200,
        *,
        poll_interval: float = 0.2,
        lost_ok_timeout: float = 1.5,
        silence_timeout: float = 0.7,
        silence_grace: float = 0.5,
        banner_timeout: float = 3.0,
        reply_timeout: float = 10.0,
        log_size: int = 4000,
    ) -> None:
        self.url = url
        self.baud = baud
        self.poll_interval = poll_interval
        self.lost_ok_timeout = lost_ok_timeout
        self.silence_timeout = silence_timeout
        self.silence_grace = silence_grace
        self.banner_timeout = banner_timeout
        self.reply_timeout = reply_timeout
        self.log: deque[tuple[float, str, str]] = deque(maxlen=log_size)
        self.port = None
        self.rx_size = DEFAULT_RX_SIZE
        self.planner_size = DEFAULT_PLANNER_SIZE
        self.options = ""
        self.version = ""  # GRBL_VERSION, e.g. "1.1h" (from the banner, then from $I)
        self.firmware = VersionInfo("")  # version, build date and build info from $I's [VER:...] line
        self.settings: dict[int, float] = {}
        self.offsets: dict[str, tuple[float, ...]] = {}
        self.parser_state = ""
        self.status: StatusReport | None = None
        self.status_time = 0.0
        self.wco: tuple[float, ...] | None = None
        self.alarm: Alarm | None = None
        self.position_lost = False
        self.fault: str | None = None
        self.messages: deque[str] = deque(maxlen=200)
        self._lock = threading.RLock()
        self._cond = threading.Condition(self._lock)
        self._write_lock = threading.Lock()
        self._pending: deque[_Pending] = deque()
        self._ignore_oks = 0  # stale replies still to come after an alarm (at most one: GRBL runs one line at a time)
        self._expect_banner = False
        self._owed_banners: deque[float] = deque()  # when each soft reset not answered by a banner yet was sent
        self._reset_sent_at = 0.0  # monotonic time of the last soft reset written
        self._critical_since: float | None = None  # ALARM:1/2 came at this time and no banner since
        self._critical_asked = False  # GRBL said "[MSG:Reset to continue]" since then
        self._critical_resets = 0  # resets sent since then
        self._banner_count = 0
        self._last_rx = 0.0  # monotonic time of the last byte read (reader thread)
        self._reader_beat = 0.0  # monotonic time the reader thread last went round its loop
        self._silence = SilenceWatchdog(silence_timeout, silence_grace, poll_interval,
                                        functools.partial(self._log, "info"))
        self._lost_ok = LostOkWatchdog(lost_ok_timeout)
        self._alarm_count = 0
        self.max_pending_bytes = 0  # the most G-code bytes ever unacknowledged (never above rx_size)
        self.replies_accepted = 0  # ok/error lines matched to a sent line (never more than the controller sent)
        self._fault_count = 0
        self._reset_since_alarm = False
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._listeners: list[Callable[[str, object], None]] = []
        self._line_buffer = bytearray()

    # ------------------------------------------------------------------ life cycle

    def open(self) -> GrblConnection:
        """Open the port, wait for the banner (soft-reset if none comes), read ``$I``, ``$$``, ``$#``, ``$G``.

        Changes no setting: status reports are read in the form ``$10`` gives them (see the module docstring).
        """
        self.port = open_port(self.url, self.baud)
        self._stop.clear()
        self._last_rx = self._reader_beat = time.monotonic()
        self._silence.reset()
        reader = threading.Thread(target=self._read_loop, name="grbl-reader", daemon=True)
        self._threads = [reader]
        banners = self._banner_count
        reader.start()
        if not self._wait_for(lambda: self._banner_count > banners, self.banner_timeout):
            self._log("info", "no banner after opening; sending soft reset")
            with self._lock:
                self._owed_banners.append(time.monotonic())  # a board slow to start may still greet, then reset
            self.soft_reset()
        if self._banner_count == banners:
            self.close()
            raise PortError(f"{self.url}: no GRBL banner (is it a GRBL 1.1 controller at {self.baud} baud?)")
        poller = threading.Thread(target=self._status_loop, name="grbl-status", daemon=True)
        self._threads.append(poller)
        poller.start()  # before the first queries: the lost-reply watchdog needs status reports
        self.refresh()
        self.fresh_status()
        return self

    def fresh_status(self, timeout: float = 2.0) -> StatusReport | None:
        """Ask for a status report now and wait for one newer than this call (None if none came)."""
        asked = time.monotonic()
        try:
            self.realtime(b"?")
        except (PortError, DeviceStateError):
            return None
        self._wait_for(lambda: self.status_time > asked or self.position_lost, timeout)
        return self.status if self.status_time > asked else None

    def refresh(self) -> None:
        """Re-read ``$I`` (RX buffer size, options), ``$$`` (settings), ``$#`` (offsets) and ``$G`` (modal state)."""
        for reply in self.command("$I", retries=2):
            if isinstance(reply, Feedback) and reply.kind == "OPT":
                parts = reply.text.split(",")
                self.options = parts[0]
                if len(parts) >= 3 and parts[2].strip().isdigit():
                    self.rx_size = int(parts[2])
                if len(parts) >= 2 and parts[1].strip().isdigit():
                    self.planner_size = int(parts[1])
            elif isinstance(reply, Feedback) and reply.kind == "VER":
                self.firmware = parse_version(reply.text)
                self.version = self.firmware.version
        self.settings = {r.key: r.value for r in self.command("$$", retries=2) if isinstance(r, SettingLine)}
        offsets = {}
        for reply in self.command("$#", retries=2):
            if isinstance(reply, Feedback):
                values = reply.text.split(":")[0]
                try:
                    offsets[reply.kind] = tuple(float(v) for v in values.split(","))
                except ValueError:
                    continue
        with self._lock:  # one change, so that status reports meanwhile are completed with one set of offsets
            self.offsets = offsets
            self.wco = None  # until a status report brings it again, these offsets are the truth
        for reply in self.command("$G", retries=2):
            if isinstance(reply, Feedback) and reply.kind == "GC":
                self.parser_state = reply.text

    def close(self) -> None:
        self._stop.set()
        with self._cond:
            self._cond.notify_all()
        for thread in self._threads:
            if thread is not threading.current_thread():
                thread.join(timeout=2.0)
        self._threads = []
        if self.port is not None:
            try:
                self.port.close()
            except (OSError, serial.SerialException):
                pass

    def __enter__(self) -> GrblConnection:
        return self.open()

    def __exit__(self, *exc) -> None:
        self.close()

    def add_listener(self, callback: Callable[[str, object], None]) -> None:
        """``callback(event, data)`` from the reader/status threads: events ``status``, ``message``, ``alarm``,
        ``fault``, ``banner``, ``log``. Callbacks must return quickly and never block (some run while the
        connection's lock is held): hand the data to your own thread or queue."""
        self._listeners.append(callback)

    def remove_listener(self, callback: Callable[[str, object], None]) -> None:
        """Stop calling ``callback`` (one added with :meth:`add_listener`; another is ignored)."""
        if callback in self._listeners:
            self._listeners.remove(callback)

    def _notify(self, event: str, data: object) -> None:
        for callback in list(self._listeners):
            try:
                callback(event, data)
            except Exception:  # noqa: BLE001 - a broken listener must not kill the reader
                pass

    # ------------------------------------------------------------------ properties
    # (what the settings say about the machine: homing_enabled, travel, laser_mode ... come from MachineSettings)

    @property
    def pending_count(self) -> int:
        with self._lock:
            return len(self._pending)

    @property
    def pending_bytes(self) -> int:
        with self._lock:
            return sum(p.nbytes for p in self._pending)

    def work_offset(self) -> tuple[float, float, float]:
        """WCO = active G54..G59 offset + G92 (+ TLO on Z), from ``$#``/``$G`` or the last status report."""
        if self.wco is not None:
            return tuple(self.wco)
        wcs = "G54"
        for word in self.parser_state.split():
            if word in ("G54", "G55", "G56", "G57", "G58", "G59"):
                wcs = word
        base = self.offsets.get(wcs, (0.0, 0.0, 0.0))
        g92 = self.offsets.get("G92", (0.0, 0.0, 0.0))
        tlo = self.offsets.get("TLO", (0.0,))[0]
        return (base[0] + g92[0], base[1] + g92[1], base[2] + g92[2] + tlo)

    def _completed(self, status: StatusReport) -> StatusReport:
        """``status`` with both positions: GRBL sends ``MPos`` or ``WPos`` as ``$10`` bit 0 says, and WPos = MPos -
        WCO with the WCO of this report, of the last report that had one, or from ``$#``/``$G`` before any did."""
        if (status.mpos is None) == (status.wpos is None):
            return status
        if self.wco is None and not self.offsets:
            return status  # connecting: no offset known yet
        wco = self.work_offset()
        return replace(status, mpos=status.machine_position(wco), wpos=status.work_position(wco))

    @property
    def alarm_locked(self) -> bool:
        """True from ALARM:1/2 until the reset's banner: GRBL answers nothing meanwhile (see the module docstring)."""
        with self._lock:
            return self._critical_since is not None

    # ------------------------------------------------------------------ writing

    def _write(self, data: bytes, stop: threading.Event | None = None) -> bool:
        """Write bytes; returns False (nothing written) if ``stop`` is set. ``stop`` is checked under the write
        lock, so a line is never written after an abort's soft reset (it would run on the reset machine)."""
        if self.position_lost:
            raise DeviceStateError(f"{self.url}: position lost ({self.fault}); reconnect and home before sending")
        try:
            with self._write_lock:
                if stop is not None and stop.is_set():
                    return False
                self.port.write(data)
        except (serial.SerialException, OSError) as error:
            self._port_lost(f"write failed: {error}")
            raise PortError(f"{self.url}: port vanished ({error}); position lost") from None
        if data[:1] == b"\x18":
            self._log("out", "<soft reset>")
        elif data != b"?":
            for text in data.decode("latin-1").rstrip("\n").split("\n"):  # a streamer's write may hold several lines
                self._log("out", text)
        return True

    def realtime(self, byte: bytes) -> None:
        """Send one real-time byte now: ``?`` status, ``!`` hold, ``~`` start, 0x18 reset, 0x85 jog cancel,
        0x90-0x9D overrides."""
        if len(byte) != 1:
            raise ValueError("a real-time command is one byte")
        if byte == b"\x18":
            with self._lock:
                self._expect_banner = True
                self._reset_sent_at = time.monotonic()
                self._owed_banners.append(self._reset_sent_at)  # a reset sent again may be answered twice
        self._write(byte)

    def feed_hold(self) -> None:
        self.realtime(b"!")

    def cycle_start(self) -> None:
        self.realtime(b"~")

    def jog_cancel(self) -> None:
        self.realtime(b"\x85")

    #: Real-time override bytes of GRBL 1.1.
    OVERRIDES = {
        ("feed", "reset"): b"\x90", ("feed", "+10"): b"\x91", ("feed", "-10"): b"\x92", ("feed", "+1"): b"\x93",
        ("feed", "-1"): b"\x94", ("rapid", "100"): b"\x95", ("rapid", "50"): b"\x96", ("rapid", "25"): b"\x97",
        ("spindle", "reset"): b"\x99", ("spindle", "+10"): b"\x9a", ("spindle", "-10"): b"\x9b",
        ("spindle", "+1"): b"\x9c", ("spindle", "-1"): b"\x9d", ("spindle", "stop"): b"\x9e",
    }

    def override(self, kind: str, action: str) -> None:
        """Feed, rapid or spindle override: ``override("feed", "+10")``, ``override("rapid", "50")``,
        ``override("spindle", "reset")`` ... (see :attr:`OVERRIDES`)."""
        try:
            byte = self.OVERRIDES[(kind, action)]
        except KeyError:
            known = ", ".join(f"{k}:{a}" for k, a in self.OVERRIDES)
            raise ValueError(f"unknown override {kind}:{action}; known: {known}") from None
        self.realtime(byte)

    def soft_reset(self, wait: bool = True, timeout: float | None = None) -> bool:
        """Send 0x18 (stops motion at once, laser off). With ``wait``, wait for the reset banner. The character
        counter is cleared when the banner arrives."""
        banners = self._banner_count
        self.realtime(b"\x18")
        if not wait:
            return True
        return self._wait_for(lambda: self._banner_count > banners or self.position_lost,
                              timeout or self.banner_timeout) and not self.position_lost

    def recover(self) -> str:
        """After a stream stopped (an error, an alarm, a lost ``ok``): reset GRBL (motion stops, the laser goes off)
        and unlock it where that is safe. Returns what was done, for the user.

        After ALARM:1/2 the status thread sends the reset (GRBL asks for it and answers nothing else): this waits for
        its banner. GRBL is then still locked: after ALARM:2 (a soft limit: "Machine position retained. Alarm may be
        safely unlocked") this sends ``$X``; after ALARM:1 (a hard limit, the position likely lost) it stays locked
        for homing. Any other stop gets a soft reset here, and no unlock (ALARM:3 after a reset in motion means the
        position is lost too).
        """
        with self._lock:
            critical = self._critical_since is not None
            alarm = self.alarm
        if critical:
            ok = self._wait_for(lambda: self._critical_since is None or self.position_lost,
                                CRITICAL_RESET_DELAY + CRITICAL_RESET_TRIES * CRITICAL_RESET_RETRY
                                + self.poll_interval * 2) and not self.position_lost
            if not ok:
                return ""
        elif not self.soft_reset(wait=True):
            return ""
        status = self.fresh_status()
        if status is None or status.state != "Alarm":
            return "GRBL reset"
        if alarm is not None and alarm.code == 2 and critical:
            try:
                self.command("$X", timeout=3.0)
            except (ProtocolError, DeviceStateError) as error:
                return f"GRBL reset, still locked ($X failed: {error})"
            self.fresh_status()  # Idle: the alarm is over (see _handle)
            return "GRBL reset and unlocked ($X; a soft limit keeps the position)"
        return "GRBL reset, still locked"

    def command(self, line: str, timeout: float | None = None, retries: int = 0) -> list:
        """Send-response: send ``line`` alone (after every pending line is answered) and return the messages that
        came with its ``ok``.

        ``retries`` re-sends a line whose reply was lost, or that a reset overtook (a board slow to start greets after
        the reset the connection sent): only for read-only queries (``$I``, ``$$``, ``$#``, ``$G``), which change
        nothing if they ran twice.

        Raises
        ------
        ProtocolError
            On ``error:N`` (with the meaning in words).
        DeviceStateError
            On an alarm, a lost reply (timeout) or a lost port.
        """
        for attempt in range(retries + 1):
            try:
                results = self.stream([line], sync_all=True, timeout=timeout)
                break
            except StreamStopped as stopped:
                if attempt < retries and (self.recover_lost_ok() or self._recover_timeout(stopped)
                                          or (stopped.reason == "reset" and not self.position_lost)):
                    self._log("info", f"resending {line!r} after its reply was lost (read-only query)")
                    continue
                raise
        result = results[0]
        if result.status == "error":
            error = Error(result.error)
            raise ProtocolError(f"{self.url}: {line!r} -> {error}")
        return result.replies

    def stream(
        self,
        lines: Sequence[str],
        *,
        sync_all: bool = False,
        on_ack: Callable[[LineResult], None] | None = None,
        on_sent: Callable[[int], None] | None = None,
        stop: threading.Event | None = None,
        stop_on_error: bool = True,
        timeout: float | None = None,
    ) -> list[LineResult]:
        """Stream ``lines`` (raw G-code; comments and whitespace are stripped) and wait for every reply.

        Character counting keeps at most ``rx_size - 1`` bytes unacknowledged (GRBL's ring buffer holds one byte
        less than its size); lines that need it (``$``, ``G10``,
        ``G28.1``, ``G30.1``), or every line with ``sync_all`` (send-response), go alone.

        Raises
        ------
        StreamStopped
            When the stream could not finish: alarm, error (with ``stop_on_error``), lost ``ok``, reset, lost port,
            or ``stop`` set. Lines already sent are never re-sent; their results say ``unconfirmed``.
        """
        results: list[LineResult] = []
        reply_timeout = timeout or self.reply_timeout
        since = (self._alarm_count, self._fault_count)  # only alarms and faults from now on stop this stream
        cursor = [0]  # next result to report through on_ack, in order

        def report() -> None:
            while cursor[0] < len(results) and results[cursor[0]].status in ("ok", "error"):
                result = results[cursor[0]]
                cursor[0] += 1
                if on_ack:
                    on_ack(result)
                if result.status == "error" and stop_on_error and len(lines) > 1:
                    raise StreamStopped(f"line {result.index + 1} ({result.text!r}): {Error(result.error)}",
                                        "error")

        room = self.rx_size - 1  # GRBL's RX ring buffer holds one byte less than its size
        ahead: deque[_Prepared] = deque()  # lines read ahead (their results listed), not written yet
        prepared = [0, 0, 0]  # lines read ahead so far, bytes of them not written, 1 while the first one waits

        def read_ahead() -> None:
            # a buffer's worth of lines, so that as many as fit go in one write; not past a line that goes alone
            while prepared[0] < len(lines) and prepared[1] < room and not (ahead and ahead[-1].sync):
                item = self._prepare(lines[prepared[0]], prepared[0], sync_all)
                results.append(item.result)
                ahead.append(item)
                prepared[0] += 1
                prepared[1] += len(item.data)

        try:
            while True:
                read_ahead()
                if not ahead:
                    break
                first = ahead[0]
                if not first.data:  # an empty line (only a comment): nothing to send
                    ahead.popleft()
                    report()
                    continue
                if len(first.data) > room:
                    raise ProtocolError(f"line {first.result.index + 1} is {len(first.data)} bytes, longer than "
                                        f"GRBL's RX buffer ({self.rx_size}): {first.result.text[:40]!r}...")
                with self._cond:
                    ready = self._no_pending if first.sync else functools.partial(self._has_room, len(first.data))
                    prepared[2] = 1
                    self._wait_locked(ready, stop, reply_timeout, "waiting for buffer space", since, report)
                    prepared[2] = 0
                    batch = [ahead.popleft()]
                    if not first.sync:
                        # every following line that fits now goes in the same write: fewer writes and wake-ups at
                        # both ends of the wire, and the buffer as full as character counting allows
                        free = room - self._pending_bytes() - len(first.data)
                        while ahead and not ahead[0].sync and len(ahead[0].data) <= free:
                            free -= len(ahead[0].data)
                            batch.append(ahead.popleft())
                    entries = [_Pending(item.result, len(item.data), item.dwell, item.busy)
                               for item in batch if item.data]
                    self._pending.extend(entries)
                    self.max_pending_bytes = max(self.max_pending_bytes, self._pending_bytes())
                    self._lost_ok.clear()
                data = b"".join(item.data for item in batch)
                prepared[1] -= len(data)
                try:
                    written = self._write(data, stop)
                except (PortError, DeviceStateError):
                    raise StreamStopped(f"{self.url}: {self.fault or 'port lost'}", "fault") from None
                if not written:
                    with self._cond:
                        for entry in entries:
                            if entry in self._pending:
                                self._pending.remove(entry)
                    raise StreamStopped(f"{self.url}: stopped", "stopped")
                if on_sent:
                    for entry in entries:
                        on_sent(entry.result.index)
                if first.sync:
                    entry = entries[0]
                    with self._cond:
                        self._wait_locked(entry.done.is_set, stop, reply_timeout + entry.dwell + entry.busy,
                                          f"waiting for the reply to {first.result.text!r}", since, report)
                report()
            with self._cond:
                self._wait_locked(lambda: not self._pending, stop,
                                  reply_timeout + sum(p.dwell + p.busy for p in self._pending),
                                  "waiting for the last replies",
                                  since, report)
            report()
            if any(r.status == "unconfirmed" for r in results):
                raise StreamStopped(f"{self.url}: the controller was reset; lines sent were never answered", "reset")
        except StreamStopped as stopped:
            # the lines read ahead and not written are not part of what happened (but one that waited for room is)
            del results[len(results) - (len(ahead) - prepared[2]):]
            stopped.first_unconfirmed = self._first_unconfirmed(results)
            stopped.results = results
            raise
        return results

    def _prepare(self, raw: str, index: int, sync_all: bool) -> _Prepared:
        """A line as the streamer sends it: cleaned (GRBL's own rules), its bytes, whether it goes alone, and the
        time its reply may take beyond the usual (a dwell, homing). An empty line is answered at once."""
        block = clean_line(raw) if not raw.lstrip().startswith("$") else "".join(raw.split())
        result = LineResult(index, block)
        if not block:
            result.status = "ok"
            return _Prepared(result, b"", False, 0.0, 0.0)
        return _Prepared(result, (block + "\n").encode("latin-1"), sync_all or needs_sync(block),
                         dwell_seconds(block), self.homing_seconds() if block.upper().startswith("$H") else 0.0)

    def _no_pending(self) -> bool:
        return not self._pending

    def _has_room(self, size: int) -> bool:
        # GRBL's RX ring buffer holds one byte less than its size (head never catches up with tail)
        return self._pending_bytes() + size <= self.rx_size - 1

    def _pending_bytes(self) -> int:
        return sum(p.nbytes for p in self._pending)

    def _first_unconfirmed(self, results: list[LineResult]) -> int | None:
        for result in results:
            if result.status in ("pending", "unconfirmed"):
                return result.index
        return None

    def _wait_locked(self, ready, stop, timeout, what: str, since: tuple[int, int], tick=None) -> None:
        # called with self._cond held; ``tick`` (progress reporting) runs with the lock released
        deadline = time.monotonic() + timeout
        while True:
            # faults first: an alarm or a reset empties the counter, which must not read as "all answered"
            if self.position_lost or self._fault_count > since[1]:
                raise StreamStopped(f"{self.url}: {self.fault}", "fault")
            if self._alarm_count > since[0]:
                alarm = self.alarm or Alarm(0)
                raise StreamStopped(f"{self.url}: {alarm}; {alarm.recovery}", "alarm")
            if stop is not None and stop.is_set():
                raise StreamStopped(f"{self.url}: stopped", "stopped")
            if self._stop.is_set():
                raise StreamStopped(f"{self.url}: connection closed", "closed")
            if ready():
                return
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise StreamStopped(f"{self.url}: no reply after {timeout:.1f} s {what}", "timeout")
            self._cond.wait(min(remaining, 0.1))
            if tick is not None:
                self._cond.release()
                try:
                    tick()
                finally:
                    self._cond.acquire()

    def wait_for(self, predicate, timeout: float) -> bool:
        """Wait (at most ``timeout`` s) until ``predicate()`` is true; re-checked on every message and every 0.1 s."""
        return self._wait_for(predicate, timeout)

    def _wait_for(self, predicate, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        with self._cond:
            while not predicate():
                remaining = deadline - time.monotonic()
                if remaining <= 0 or self._stop.is_set():
                    return predicate()
                self._cond.wait(min(remaining, 0.1))
        return True

    def expect_reset(self) -> None:
        """Announce a banner caused on purpose by a command (``$C`` leaving check mode resets GRBL)."""
        with self._lock:
            self._expect_banner = True

    def recover_lost_ok(self) -> bool:
        """After a lost-``ok`` fault (the controller was idle with empty buffers throughout), clear the character
        counter and the fault. The lost lines stay ``unconfirmed``; nothing is marked ``ok``. Returns False if the
        fault is something else."""
        with self._cond:
            if self.position_lost or not (self.fault or "").startswith("lost ok"):
                return False
            self._clear_counter("lost ok")
            self.fault = None
            self._lost_ok.clear()
            return True

    def _recover_timeout(self, stopped: StreamStopped) -> bool:
        # a send-response query without a reply (before status polling runs): nothing else is in flight
        if stopped.reason != "timeout" or self.position_lost:
            return False
        with self._cond:
            self._clear_counter("reply timeout")
        return True

    def clear_fault(self) -> None:
        """Forget a lost-``ok`` fault or an alarm record after the user dealt with it (not a lost position)."""
        with self._cond:
            if not self.position_lost:
                self.fault = None
            self._lost_ok.clear()

    # ------------------------------------------------------------------ reading

    def _log(self, direction: str, text: str) -> None:
        entry = (time.monotonic(), direction, text)
        self.log.append(entry)
        self._notify("log", entry)

    def _read_loop(self) -> None:
        while not self._stop.is_set():
            self._reader_beat = time.monotonic()
            try:
                waiting = self.port.in_waiting
                data = self.port.read(max(1, min(waiting, 4096)))
            except (serial.SerialException, OSError, TypeError, AttributeError) as error:
                if not self._stop.is_set():
                    self._port_lost(f"read failed: {error}")
                return
            if not data:
                continue
            self._last_rx = time.monotonic()
            self._line_buffer += data
            while True:
                index = self._line_buffer.find(b"\n")
                if index < 0:
                    break
                raw = bytes(self._line_buffer[:index]).rstrip(b"\r")
                del self._line_buffer[: index + 1]
                self._handle(raw.decode("latin-1"))

    def _handle(self, text: str) -> None:
        if not text:
            return
        message = parse_line(text)
        if not isinstance(message, StatusReport):
            self._log("in", text)
        with self._cond:
            if isinstance(message, (Ok, Error)):
                self._reply(message, text)
            elif isinstance(message, StatusReport):
                if message.wco is not None:
                    self.wco = message.wco
                message = self._completed(message)
                self.status = message
                self.status_time = time.monotonic()
                if self.alarm is not None and self._reset_since_alarm and message.state != "Alarm":
                    self.alarm = None  # unlocked or homed after the alarm's reset
                self._check_lost_ok(message)
            elif isinstance(message, Alarm):
                self.alarm = message
                self._alarm_count += 1
                self._reset_since_alarm = False
                self.messages.append(str(message))
                self._clear_counter("alarm")
                # the line that raised it may still be answered: after the reset (soft limit) or at once (probe)
                self._ignore_oks = 1
                if message.code in CRITICAL_ALARMS:
                    self._critical_since = time.monotonic()
                    self._critical_asked = False
                    self._critical_resets = 0
                elif message.code in HOMING_FAIL_ALARMS:
                    self._expect_banner = True  # GRBL resets itself after a failed homing cycle
            elif isinstance(message, Banner):
                self.version = self.version or message.version
                self.firmware = self.firmware if self.firmware.version else VersionInfo(message.version)
                now = time.monotonic()
                while self._owed_banners and now - self._owed_banners[0] > 2 * max(self.banner_timeout,
                                                                                     CRITICAL_RESET_RETRY):
                    self._owed_banners.popleft()  # that reset never got an answer (lost in GRBL's alarm loop)
                owed = bool(self._owed_banners)
                if owed:
                    self._owed_banners.popleft()
                unexpected = not (self._expect_banner or owed)
                self._expect_banner = False
                self._critical_since = None
                self._ignore_oks = 0
                self._clear_counter("reset")
                self._banner_count += 1
                self._reset_since_alarm = True
                self.wco = None
                if unexpected and self._banner_count > 1 and not self.position_lost:
                    # the controller restarted on its own (power, USB or DTR glitch): its position is gone
                    self.position_lost = True
                    self._fault_count += 1
                    self.fault = "the controller restarted by itself: position lost; reconnect and home"
            elif isinstance(message, (Feedback, SettingLine)):
                if self._pending:
                    self._pending[0].result.replies.append(message)
                if isinstance(message, Feedback) and message.kind == "MSG":
                    self.messages.append(message.text)
                    if message.text == "Reset to continue" and self._critical_since is not None:
                        self._critical_asked = True  # printed just before GRBL starts waiting for the reset
            elif isinstance(message, Garbled):
                self._log("info", f"ignored unrecognized line {text!r}")
            self._cond.notify_all()
        if isinstance(message, StatusReport):
            self._notify("status", message)
        elif isinstance(message, Alarm):
            self._notify("alarm", message)
        elif isinstance(message, Banner):
            self._notify("banner", message)
        elif isinstance(message, Feedback):
            self._notify("message", message)

    def _reply(self, message, text: str) -> None:
        if self._ignore_oks:
            self._ignore_oks -= 1
            self._log("info", f"ignored {text!r} that arrived between an alarm and the reset banner")
            return
        if not self._pending:
            self._log("info", f"ignored {text!r}: no line is waiting for a reply")
            return
        entry = self._pending.popleft()
        self.replies_accepted += 1
        if isinstance(message, Ok):
            entry.result.status = "ok"
        else:
            entry.result.status = "error"
            entry.result.error = message.code
            self.messages.append(f"{entry.result.text}: {message}")
        entry.done.set()
        self._lost_ok.clear()

    def _clear_counter(self, why: str) -> None:
        for entry in self._pending:
            entry.result.status = "unconfirmed"
            entry.done.set()
        if self._pending:
            self._log("info", f"{why}: {len(self._pending)} line(s) never answered; counter cleared")
        self._pending.clear()

    def _check_lost_ok(self, status: StatusReport) -> None:
        fault = self._lost_ok.check(status, self._pending, planner_size=self.planner_size, rx_size=self.rx_size,
                                    fault=self.fault, now=time.monotonic())
        if fault is not None:
            self.fault = fault
            self._fault_count += 1
            self._log("fault", self.fault)
            self._notify("fault", self.fault)

    def _port_lost(self, why: str) -> None:
        with self._cond:
            if self.position_lost:
                return
            self.position_lost = True
            self._fault_count += 1
            self.fault = f"port vanished ({why}): position lost; reconnect and home before running a job"
            self._log("fault", self.fault)
            self._cond.notify_all()
        self._notify("fault", self.fault)

    def _status_loop(self) -> None:
        tick = time.monotonic()
        while not self._stop.wait(self.poll_interval):
            if self.position_lost:
                return
            previous, tick = tick, time.monotonic()
            if self._critical_since is not None:
                # GRBL answers nothing until it is reset: send the reset instead of '?' (the watchdog rests)
                self._silence.reset()
                if not self._reset_critical(tick):
                    return
                continue
            if self._silence.step(previous, tick, last_rx=self._last_rx, reader_beat=self._reader_beat,
                                  paused=self._reports_paused, waiting=self._bytes_waiting):
                self._port_lost(self._silence.describe())
                return
            asked = time.monotonic()
            try:
                self._write(b"?")
            except (PortError, DeviceStateError):
                return
            self._silence.asked(asked)  # taken before the write: a reply can only be read after it

    def _reset_critical(self, now: float) -> bool:
        """One tick of the status thread while GRBL waits for a reset after ALARM:1/2: send it when due. False when the
        port is gone (the thread ends)."""
        with self._lock:
            since = self._critical_since
            if since is None:
                return True
            if self._reset_sent_at > since:
                due = now - self._reset_sent_at >= CRITICAL_RESET_RETRY  # no banner: that reset came too early
            else:
                due = self._critical_asked or now - since >= CRITICAL_RESET_DELAY
            tries = self._critical_resets
            alarm = self.alarm
        if not due:
            return True
        if tries >= CRITICAL_RESET_TRIES:
            self._port_lost(f"no banner after {tries} soft resets following {alarm or 'a limit alarm'}")
            return False
        with self._lock:
            self._critical_resets += 1
        self._log("info", f"{alarm}: GRBL waits for a reset; sending it" + (f" (again, {tries + 1})" if tries else ""))
        try:
            self.realtime(b"\x18")
        except (PortError, DeviceStateError):
            return False
        return True

    def _bytes_waiting(self) -> int:
        try:
            return self.port.in_waiting
        except (serial.SerialException, OSError, TypeError, AttributeError):
            return 0  # the reader meets the same error and reports it

    def _reports_paused(self) -> bool:
        # GRBL answers no status request while it homes or writes its EEPROM: the line in flight then is one of
        # those (send-response: nothing else is in flight), and its reply timeout bounds the wait
        with self._lock:
            return any(pauses_reports(p.result.text) for p in self._pending)
