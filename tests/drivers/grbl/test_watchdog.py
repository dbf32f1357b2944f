"""The silence watchdog: a port that really went silent or vanished is declared lost, our own stalls never are.

The flake these tests pin down: under load (2 cores, load ~4.5) the Textual app's garbage collections held the
interpreter for 0.3-0.7 s; no thread of the process ran, no ``?`` was written, and the watchdog, which measured
silence from the last byte received, declared the simulated port vanished ("position lost") mid-job.
"""

from __future__ import annotations

import sys
import threading
import time

import pytest

from drivers.grbl import GrblConnection

from ..conftest import sim_url
from .pty_peer import PtyPeer


def _hold_the_interpreter(seconds: float) -> None:
    """Run Python for ``seconds`` without letting any other thread of this process run: what a host that
    deschedules the process, or a long garbage collection, does to every thread at once."""
    interval = sys.getswitchinterval()
    sys.setswitchinterval(seconds * 10)  # other threads may ask for the GIL; none gets it before we are done
    try:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            pass
    finally:
        sys.setswitchinterval(interval)


def test_a_stalled_process_is_not_a_silent_port(make_connection):
    # Fails with the old watchdog: after the stall it saw 2 s since the last byte and declared the port lost,
    # though no status request had been written during those 2 s.
    conn = make_connection(sim_url("plotter"))
    stall = 2 * (conn.silence_timeout + conn.silence_grace)
    _hold_the_interpreter(stall)
    assert conn.fresh_status() is not None
    assert not conn.position_lost, conn.fault
    conn.command("$G")  # and the connection still works


def test_a_starved_reader_is_not_a_silent_port(make_connection):
    # The status thread runs on time but the reader does not (here: held in a listener, as a starved thread
    # would be): the replies wait unread in the port, which is not silent. Fails with the old watchdog.
    conn = make_connection(sim_url("plotter"))
    entered, release = threading.Event(), threading.Event()
    armed = [True]

    def hold_the_reader(event, data):
        if event == "status" and armed[0]:
            armed[0] = False
            entered.set()
            release.wait(10.0)

    conn.add_listener(hold_the_reader)
    assert entered.wait(5.0)
    time.sleep(2 * (conn.silence_timeout + conn.silence_grace))  # status requests go on meanwhile
    release.set()
    assert conn.fresh_status() is not None
    assert not conn.position_lost, conn.fault


def test_homing_answers_no_status_and_is_not_a_silent_port(make_connection):
    # GRBL 1.1 serves no '?' during a homing cycle (limits.c: "No time to run protocol_execute_realtime()"); the
    # simulator, like the firmware, stays silent for the cycle's 1.5 s. Fails with the old watchdog.
    conn = make_connection(sim_url("plotter", time_scale=1.0))
    assert conn.homing_enabled
    conn.command("$H")
    assert not conn.position_lost, conn.fault
    assert conn.fresh_status().state == "Idle"


def test_a_muted_port_is_declared_lost_after_a_probe(make_connection):
    conn = make_connection(sim_url("plotter"))
    conn.port.machine.mute()  # open, but no byte comes any more: a hung controller, a dead cable
    assert conn.wait_for(lambda: conn.position_lost, 10.0)
    assert "no byte from the controller" in conn.fault and "after a probe" in conn.fault
    assert any("probing" in text for _, direction, text in conn.log if direction == "info")


def test_a_muted_port_is_declared_lost_even_on_a_loaded_host(make_connection):
    # Late wake-ups still count (at most one poll period each): a silent port is found under load too.
    conn = make_connection(sim_url("plotter"))
    conn.port.machine.mute()
    deadline = time.monotonic() + 30.0
    while not conn.position_lost and time.monotonic() < deadline:
        _hold_the_interpreter(conn.poll_interval * 3)  # every wake-up of the watchdog comes late
        time.sleep(conn.poll_interval / 2)
    assert conn.position_lost and "no byte from the controller" in conn.fault


def test_an_unplugged_port_is_lost_at_once_without_waiting_for_silence(make_connection):
    conn = make_connection(sim_url("plotter"), silence_timeout=60.0, silence_grace=60.0)
    conn.port.machine.unplug()  # the OS fails the reads and writes
    assert conn.wait_for(lambda: conn.position_lost, 10.0)
    assert "port vanished" in conn.fault and "no byte" not in conn.fault


# ------------------------------------------------------------------ a real pty: the OS reports the hang-up

_BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"
_REPLIES = {
    b"$I": b"[VER:1.1h.20190825:]\r\n[OPT:V,15,128]\r\nok\r\n",
    b"$$": b"$10=3\r\n$22=0\r\n$32=0\r\n$130=200.000\r\n$131=200.000\r\n$132=200.000\r\nok\r\n",
    b"$#": b"[G54:0.000,0.000,0.000]\r\n[G92:0.000,0.000,0.000]\r\n[TLO:0.000]\r\nok\r\n",
    b"$G": b"[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]\r\nok\r\n",
}
_STATUS = b"<Idle|MPos:0.000,0.000,0.000|Bf:15,128|FS:0,0>\r\n"


class _PtyGrbl(PtyPeer):
    """A minimal GRBL 1.1 on the master side of a pty: the banner after a soft reset, ``?``, ``$I`` (the
    firmware's exact bytes), ``$$``, ``$#``, ``$G``, ``ok`` to anything else."""

    def __init__(self) -> None:
        super().__init__()
        self._line = b""
        self.start()

    def received(self, data: bytes) -> None:
        for byte in data:
            char = bytes([byte])
            if char == b"\x18":
                self._line = b""
                self.write(_BANNER)
            elif char == b"?":
                self.write(_STATUS)
            elif char == b"\n":
                if self._line.strip():
                    self.write(_REPLIES.get(self._line.strip(), b"ok\r\n"))
                self._line = b""
            elif byte < 0x80:
                self._line += char


@pytest.fixture
def pty_grbl():
    grbl = _PtyGrbl()
    yield grbl
    grbl.close()


def test_a_pty_that_hangs_up_is_lost_at_once(pty_grbl):
    conn = GrblConnection(pty_grbl.path, banner_timeout=0.3, silence_timeout=60.0, silence_grace=60.0).open()
    try:
        assert conn.status is not None and not conn.position_lost
        assert (conn.version, conn.firmware.build, conn.firmware.info) == ("1.1h", "20190825", "")
        pty_grbl.hang_up()
        assert conn.wait_for(lambda: conn.position_lost, 10.0)
        assert "port vanished" in conn.fault and "no byte" not in conn.fault  # the OS said so, not the watchdog
    finally:
        conn.close()


def test_the_wait_for_homing_covers_the_cycle_the_settings_allow():
    # With GRBL's default settings ($25=500 mm/min seek, $24=25 mm/min feed, $27=1 mm, 200 mm travel) one axis
    # searches 300 mm for 36 s and locates 5 mm for 12 s; the fixed 60 s wait for '$H' ran out on such a machine.
    from drivers.sim.grbl import DEFAULT_SETTINGS

    conn = GrblConnection("loop://")  # never opened: only the settings matter
    conn.settings = dict(DEFAULT_SETTINGS)
    cycle = sum(1.5 * conn.settings[130 + axis] / (500 / 60) + 5 * 1.0 / (25 / 60) for axis in range(3))
    assert conn.homing_seconds() > cycle


# ------------------------------------------------------------------ the watchdogs alone, on a clock of our own


def _silence(timeout=0.7, grace=0.5, poll=0.2):
    from drivers.grbl.watchdogs import SilenceWatchdog

    logged: list[str] = []
    return SilenceWatchdog(timeout, grace, poll, logged.append), logged


def _wake_ups(watchdog, start, end, *, poll=0.2, reader_runs=True, paused=False, waiting=0):
    """Step ``watchdog`` at every poll from ``start`` to ``end`` (no byte read since before ``start``); the time of
    the first step that declared the port lost, or None."""
    previous, now = start, start + poll
    while now <= end + 1e-9:
        if watchdog.step(previous, now, last_rx=-1.0, reader_beat=now if reader_runs else -1.0,
                         paused=lambda: paused, waiting=lambda: waiting):
            return now
        previous, now = now, now + poll
    return None


def test_silence_probes_after_the_timeout_and_declares_the_port_lost_after_the_grace():
    watchdog, logged = _silence()
    watchdog.asked(0.0)
    lost = _wake_ups(watchdog, 0.0, 3.0)
    assert lost is not None and 1.2 - 1e-9 <= lost <= 1.4 + 1e-9  # timeout 0.7 + grace 0.5, to a poll
    assert len(logged) == 1 and "probing with '?'" in logged[0]
    assert "no byte from the controller for 1." in watchdog.describe() and "after a probe" in watchdog.describe()


def test_no_port_is_lost_while_the_reader_stood_still_reports_are_paused_or_bytes_wait_unread():
    for options in ({"reader_runs": False}, {"paused": True}, {"waiting": 12}):
        watchdog, _ = _silence()
        watchdog.asked(0.0)
        assert _wake_ups(watchdog, 0.0, 10.0, **options) is None, options


def test_a_late_wake_up_counts_for_one_poll_period_and_any_byte_answers():
    watchdog, _ = _silence()
    watchdog.asked(0.0)
    assert not watchdog.step(0.0, 5.0, last_rx=-1.0, reader_beat=5.0, paused=lambda: False, waiting=lambda: 0)
    assert watchdog.silent == pytest.approx(0.2)  # the process slept 5 s: not the port's silence
    assert not watchdog.step(5.0, 5.2, last_rx=5.1, reader_beat=5.2, paused=lambda: False, waiting=lambda: 0)
    assert (watchdog.asked_at, watchdog.silent) == (None, 0.0)


class _Line:
    def __init__(self, index, text, dwell=0.0):
        from drivers.grbl.connection import LineResult

        self.result, self.dwell = LineResult(index, text), dwell


def test_a_lost_ok_is_declared_once_idle_and_empty_for_the_timeout_plus_dwells():
    from drivers.grbl.protocol import StatusReport
    from drivers.grbl.watchdogs import LostOkWatchdog

    idle = StatusReport("Idle", planner_free=15, rx_free=128)
    pending = [_Line(6, "G4P1", dwell=1.0), _Line(7, "G0X1")]
    watchdog = LostOkWatchdog(1.5)
    check = dict(planner_size=15, rx_size=128, fault=None)
    assert watchdog.check(idle, pending, now=0.0, **check) is None  # the condition starts
    assert watchdog.check(idle, pending, now=2.4, **check) is None  # 1.5 s + the 1 s dwell not yet over
    fault = watchdog.check(idle, pending, now=2.6, **check)
    assert fault.startswith("lost ok: the controller is idle with empty buffers but 2 line(s) from line 7 ('G4P1')")
    assert watchdog.check(idle, pending, now=9.0, planner_size=15, rx_size=128, fault=fault) is None  # said once
    running = StatusReport("Run", planner_free=10, rx_free=100)
    assert watchdog.check(running, pending, now=10.0, **check) is None and watchdog.since is None
