"""Limit alarms as gnea/grbl 1.1h has them: after ALARM:1 (hard limit) or ALARM:2 (soft limit) GRBL answers nothing,
not even ``?``, until a soft reset, and a reset that comes before it printed ``[MSG:Reset to continue]`` is lost in
its critical-event loop (protocol.c). The driver sends the reset itself (again while no banner follows), and a job
stopped by ALARM:2 ends with GRBL unlocked (the position is kept) and the laser off; after ALARM:1 GRBL stays locked
for homing."""

from __future__ import annotations

import threading
import time

import pytest

from drivers.errors import DeviceStateError
from drivers.grbl import GrblConnection, Job, JobRunner

from ..conftest import sim_url
from .pty_peer import PtyPeer

WALK = ["G21", "G90", "M4 S400", "G0 X30 Y30", "G1 X60 Y30 F3000", "G1 X60 Y60", "G1 X5 Y60", "G0 X30 Y30"]


def test_a_soft_limit_mid_job_is_reset_and_unlocked_with_the_laser_off(make_connection):
    conn = make_connection(sim_url("laser"))
    machine = conn.port.machine

    def shrink(progress) -> None:
        # after the pre-flight read the travel: GRBL's soft limits now see a smaller machine (as when the pre-flight
        # misread a job), so the job runs into them
        if progress.stage == "running":
            machine.settings[130] = 380.0  # machine X -380..0: the job's X 30 is machine -370, X 5 is -395

    result = JobRunner(conn, Job("walk", WALK, laser=True), on_progress=shrink).run()
    assert result.state == "stopped" and result.laser_off, result.message
    assert result.message.startswith("job stopped by ALARM:2 (Soft limit alarm.")
    assert "GRBL reset and unlocked ($X" in result.message and "check its extent and the work offset" in result.message
    record = machine.snapshot()
    assert record.alarms == [2] and len(record.resets) == 1
    after = record.received[record.received.index("G1X5Y60") + 1:]
    assert "$X" in after and after.index("$X") < after.index("M5S0")  # unlocked, then the laser switched off
    status = conn.fresh_status()
    assert status.state == "Idle" and conn.alarm is None and not conn.position_lost
    assert any(reply.kind == "G54" for reply in conn.command("$#"))  # it answers again
    assert "G1X5Y60" not in [b.text for b in record.executed]
    assert -380.0 <= status.mpos[0] <= 0.0  # held to a stop on the way, inside the travel


def test_the_connection_resets_a_limit_alarm_by_itself_and_is_not_lost(make_connection):
    conn = make_connection(sim_url("laser"))  # watchdogs at 0.6 s + 0.5 s
    with pytest.raises(DeviceStateError, match=r"ALARM:2 .*unlock \(\$X; the position is kept\)"):
        conn.command("G0 X900")  # machine X 500: outside the travel
    assert conn.wait_for(lambda: not conn.alarm_locked, 5.0)
    time.sleep(1.5)  # longer than the silence watchdog allows: GRBL answered nothing but the reset meanwhile
    assert not conn.position_lost and conn.fault is None
    assert conn.fresh_status().state == "Alarm" and conn.alarm.code == 2  # locked until the user unlocks
    assert len(conn.port.machine.snapshot().resets) == 1


# ------------------------------------------------------------------ a GRBL on a pty with the firmware's timing


class _LimitGrbl(PtyPeer):
    """GRBL 1.1 on the master side of a pty, as far as these tests need it: the banner, ``?``, ``$I``, ``$$``,
    ``$#``, ``$G``, ``$X``, ``ok`` to other lines; the line ``trigger`` raises ALARM:``alarm`` with GRBL's critical
    event: ``[MSG:Reset to continue]`` follows after ``msg_delay`` s, a reset before it (or within ``clear_delay``
    s after it, the time GRBL takes to clear a pending reset) is lost, and the banner follows that reset after
    ``banner_delay`` s."""

    REPLIES = {
        b"$I": b"[VER:1.1h.20190830:]\r\n[OPT:V,15,128]\r\nok\r\n",
        b"$$": b"$10=1\r\n$22=0\r\n$32=0\r\n$130=200.000\r\n$131=200.000\r\n$132=200.000\r\nok\r\n",
        b"$#": b"[G54:0.000,0.000,0.000]\r\n[G92:0.000,0.000,0.000]\r\n[TLO:0.000]\r\nok\r\n",
        b"$G": b"[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]\r\nok\r\n",
    }

    def __init__(self, alarm: int = 2, msg_delay: float = 0.0, clear_delay: float = 0.0,
                 banner_delay: float = 0.0, trigger: bytes = b"G0X999") -> None:
        self.alarm, self.msg_delay, self.clear_delay, self.banner_delay = alarm, msg_delay, clear_delay, banner_delay
        self.trigger = trigger
        self.state = "Idle"
        self.critical = False
        self.listening_since: float | None = None  # when a reset starts counting (critical loop entered)
        self.resets = 0  # resets received while critical
        self.banners = 0
        self.lines: list[bytes] = []
        self._line = b""
        self._later: list[tuple[float, bytes]] = []
        self._lock = threading.Lock()
        super().__init__()
        self.poll = 0.01
        self._send(b"\r\nGrbl 1.1h ['$' for help]\r\n")  # power-up
        self.start()

    def _send(self, data: bytes, delay: float = 0.0) -> None:
        with self._lock:
            self._later.append((time.monotonic() + delay, data))

    def tick(self) -> None:
        with self._lock:
            due = [item for item in self._later if item[0] <= time.monotonic()]
            self._later = [item for item in self._later if item[0] > time.monotonic()]
        for _, data in due:
            self.write(data)

    def received(self, data: bytes) -> None:
        for byte in data:
            self._line = self._byte(byte, self._line)

    def _byte(self, byte: int, line: bytes) -> bytes:
        char = bytes([byte])
        if self.critical:
            if char == b"\x18":
                self.resets += 1
                if self.listening_since is not None and time.monotonic() >= self.listening_since:
                    self.critical = False
                    self.banners += 1
                    self._send(b"ok\r\n\r\nGrbl 1.1h ['$' for help]\r\n[MSG:'$H'|'$X' to unlock]\r\n",
                               self.banner_delay)
            return b""  # everything else waits in a buffer the reset clears
        if char == b"\x18":
            self.banners += 1
            self._send(b"\r\nGrbl 1.1h ['$' for help]\r\n" + (b"[MSG:'$H'|'$X' to unlock]\r\n"
                                                             if self.state == "Alarm" else b""))
            return b""
        if char == b"?":
            self._send(f"<{self.state}|MPos:0.000,0.000,0.000|FS:0,0>\r\n".encode())
            return line
        if char != b"\n":
            return line + char if byte < 0x80 else line
        block = line.strip().upper().replace(b" ", b"")
        self.lines.append(block)
        if block == self.trigger:
            self.state, self.critical = "Alarm", True
            self.listening_since = time.monotonic() + self.msg_delay + self.clear_delay
            self._send(f"ALARM:{self.alarm}\r\n".encode())
            self._send(b"[MSG:Reset to continue]\r\n", self.msg_delay)
        elif block == b"$H":  # no switch found: GRBL resets itself (limits_go_home calls mc_reset)
            self.state = "Alarm"
            self._send(b"ALARM:9\r\nok\r\n\r\nGrbl 1.1h ['$' for help]\r\n[MSG:'$H'|'$X' to unlock]\r\n", 0.2)
        elif block == b"$X":
            self.state = "Idle"
            self._send(b"[MSG:Caution: Unlocked]\r\nok\r\n")
        elif block and self.state == "Alarm" and not block.startswith(b"$"):
            self._send(b"error:9\r\n")
        elif block:
            self._send(self.REPLIES.get(block, b"ok\r\n"))
        return b""


@pytest.fixture
def limit_grbl():
    made = []

    def make(**options) -> tuple[_LimitGrbl, GrblConnection]:
        grbl = _LimitGrbl(**options)
        made.append(grbl)
        conn = GrblConnection(grbl.path, poll_interval=0.05, silence_timeout=0.6, banner_timeout=0.3).open()
        made.append(conn)
        return grbl, conn

    yield make
    for thing in reversed(made):
        thing.close()


def test_a_reset_lost_in_grbls_alarm_loop_is_sent_again(limit_grbl):
    # grbl-sim showed it: a reset sent at once on ALARM:2 came before GRBL had cleared its pending reset, and was lost
    grbl, conn = limit_grbl(msg_delay=0.1, clear_delay=0.3)
    with pytest.raises(DeviceStateError, match="ALARM:2"):
        conn.command("G0 X999")
    assert conn.wait_for(lambda: not conn.alarm_locked, 5.0)
    assert grbl.resets == 2 and not conn.position_lost  # the first reset was lost, the second one was not


def test_a_late_banner_after_two_resets_is_not_a_restart(limit_grbl):
    # the second reset went out while the first one's banner was on its way: two banners, both expected
    grbl, conn = limit_grbl(banner_delay=1.3)
    before = grbl.banners
    read: list[object] = []
    conn.add_listener(lambda event, data: read.append(data) if event == "banner" else None)
    with pytest.raises(DeviceStateError, match="ALARM:2"):
        conn.command("G0 X999")
    assert conn.wait_for(lambda: not conn.alarm_locked, 5.0)
    assert conn.wait_for(lambda: len(read) == 2, 10.0), read  # the connection has read both banners
    assert grbl.banners - before == 2 and not conn.position_lost, conn.fault


def test_a_hard_limit_stops_the_job_and_grbl_stays_locked_for_homing(limit_grbl):
    grbl, conn = limit_grbl(alarm=1, trigger=b"G1X15")
    result = JobRunner(conn, Job("walk", ["G21", "G90", "G1 X10 F1000", "G1 X15", "G1 X20"])).run()
    assert result.state == "stopped", result.message
    assert result.message.startswith("job stopped by ALARM:1 (Hard limit triggered.")
    assert "GRBL reset, still locked" in result.message and "then home ($H)" in result.message
    assert b"$X" not in grbl.lines and grbl.resets == 1 and not conn.position_lost
    assert conn.fresh_status().state == "Alarm"


def test_a_failed_homing_cycle_resets_grbl_and_that_is_no_restart(limit_grbl):
    grbl, conn = limit_grbl()
    read: list[object] = []
    conn.add_listener(lambda event, data: read.append(data) if event == "banner" else None)
    with pytest.raises(DeviceStateError, match="ALARM:9"):
        conn.command("$H")
    assert conn.wait_for(lambda: conn.status is not None and conn.status.state == "Alarm", 5.0)
    assert conn.wait_for(lambda: len(read) == 1, 5.0), read  # the connection has read the banner of GRBL's reset
    assert not conn.position_lost, conn.fault
