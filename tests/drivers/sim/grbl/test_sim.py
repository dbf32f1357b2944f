"""The simulated GRBL 1.1, byte for byte through pyserial's URL interface."""

from __future__ import annotations

import time

import pytest
import serial

import drivers.sim  # noqa: F401 - registers sim://

BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"
UNLOCK = b"[MSG:'$H'|'$X' to unlock]\r\n"


class Raw:
    """A raw port: write bytes, read until an expected ending."""

    def __init__(self, url: str) -> None:
        self.port = serial.serial_for_url(url, timeout=0.02)
        self.machine = self.port.machine

    def read_until(self, ending: bytes, timeout: float = 5.0) -> bytes:
        data = b""
        deadline = time.monotonic() + timeout
        while not data.endswith(ending):
            assert time.monotonic() < deadline, f"no {ending!r} in {data!r}"
            data += self.port.read(4096)
        return data

    def ask(self, text: str, ending: bytes = b"ok\r\n") -> bytes:
        self.port.write(text.encode() + b"\n")
        return self.read_until(ending)

    def status(self) -> str:
        self.port.write(b"?")
        line = self.read_until(b">\r\n").decode()
        return line[line.rindex("<"):].strip()

    def wait_state(self, state: str, timeout: float = 5.0) -> str:
        deadline = time.monotonic() + timeout
        while True:
            report = self.status()
            if report.startswith(f"<{state}"):
                return report
            assert time.monotonic() < deadline, report
            time.sleep(0.01)


@pytest.fixture
def raw():
    opened = []

    def make(query: str = "profile=laser&time_scale=0.02") -> Raw:
        port = Raw(f"sim://grbl?{query}")
        opened.append(port)
        assert port.read_until(UNLOCK if "locked=1" in query else BANNER) in (BANNER, BANNER + UNLOCK)
        return port

    yield make
    for port in opened:
        port.port.close()


def test_banner_info_settings_and_parser_state(raw):
    port = raw()
    assert port.ask("$I") == b"[VER:1.1h.20190830:]\r\n[OPT:V,15,128]\r\nok\r\n"
    settings = port.ask("$$").decode()
    assert settings.startswith("$0=10\r\n$1=25\r\n") and "$10=3\r\n" in settings and "$11=0.010\r\n" in settings
    assert "$30=1000\r\n" in settings and "$32=1\r\n" in settings and "$130=400.000\r\n" in settings
    assert port.ask("$G") == b"[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]\r\nok\r\n"
    offsets = port.ask("$#").decode()
    assert offsets.startswith("[G54:-400.000,-400.000,0.000]\r\n[G55:0.000,0.000,0.000]\r\n")
    assert offsets.endswith("[TLO:0.000]\r\n[PRB:0.000,0.000,0.000:0]\r\nok\r\n")
    assert port.status() == "<Idle|MPos:0.000,0.000,0.000|Bf:15,128|FS:0,0|WCO:-400.000,-400.000,0.000>"
    assert port.ask("$10=0") == b"ok\r\n"  # work position, no buffer state
    assert port.status() == "<Idle|WPos:400.000,400.000,0.000|FS:0,0>"


@pytest.mark.parametrize(
    ("line", "reply"),
    [("G41", b"error:20\r\n"), ("G1 X1", b"error:22\r\n"), ("G0 X1 X2", b"error:25\r\n"), ("G0 G1 X1", b"error:21\r\n"),
     ("$99=1", b"error:3\r\n"), ("X", b"error:2\r\n"), ("5", b"error:1\r\n"), ("G4", b"error:28\r\n"),
     ("G1 F-5", b"error:4\r\n"), ("$H", b"ok\r\n"), ("", b"ok\r\n"), ("G0 X10 (comment) Y10", b"ok\r\n")],
)
def test_replies_and_error_codes(raw, line, reply):
    port = raw()
    port.port.write(line.encode() + b"\n")
    assert port.read_until(b"\r\n").endswith(reply)


def test_locked_after_power_up_then_unlock(raw):
    port = raw("profile=plotter&locked=1")
    assert port.ask("G0 X1", b"error:9\r\n") == b"error:9\r\n"
    assert port.status().startswith("<Alarm|")
    assert port.ask("$X") == b"[MSG:Caution: Unlocked]\r\nok\r\n"
    assert port.ask("G0 X1") == b"ok\r\n"


def test_soft_limit_alarm_answers_nothing_but_a_reset(raw):
    # gnea/grbl protocol.c: after ALARM:1/2 protocol_exec_rt_system spins "until user issues reset": a status request
    # only sets a flag that the reset clears, and lines sent meanwhile are dropped with the RX buffer
    port = raw()
    port.port.write(b"G0 X500\n")  # machine X = 500 - 400 = 100 > 0: outside the travel
    assert port.read_until(b"Reset to continue]\r\n") == b"ALARM:2\r\n[MSG:Reset to continue]\r\n"
    port.port.write(b"?$#\n!~\x91?")
    assert port.machine.settled()  # every byte taken in: none of them is answered
    assert port.port.read(4096) == b""
    port.port.write(b"\x18")
    assert port.read_until(UNLOCK) == b"ok\r\n" + BANNER + UNLOCK
    assert port.machine.snapshot().alarms == [2]
    assert port.status().startswith("<Alarm|MPos:0.000,0.000,0.000|")  # no report owed from the lock
    assert port.ask("G0 X1", b"error:9\r\n") == b"error:9\r\n"
    assert port.ask("$X") == b"[MSG:Caution: Unlocked]\r\nok\r\n"
    assert port.status().startswith("<Idle|MPos:0.000,0.000,0.000|")


def test_soft_limit_during_motion_holds_to_a_stop_first(raw):
    # limits_soft_check: while a cycle runs, a feed hold brings it to a controlled stop (Hold in the reports), and
    # only then comes ALARM:2: the position is where the hold stopped, on the path
    port = raw("profile=laser&time_scale=1&s120=50")  # 50 mm/s^2: a hold from 50 mm/s takes 1 s
    assert port.ask("G1 X200 F3000") == b"ok\r\n"  # machine X -200 .. 0 (G54 at -400)
    port.wait_state("Run")
    port.port.write(b"G1 X500\n")
    port.wait_state("Hold:1", timeout=0.5)
    assert port.read_until(b"Reset to continue]\r\n").endswith(b"ALARM:2\r\n[MSG:Reset to continue]\r\n")
    port.port.write(b"\x18")
    assert port.read_until(UNLOCK).endswith(b"ok\r\n" + BANNER + UNLOCK)
    report = port.status()
    x = float(report.split("MPos:")[1].split(",")[0])
    assert report.startswith("<Alarm|") and -200.0 < x < 0.0 and port.machine.snapshot().alarms == [2]


def test_reset_during_motion_is_alarm_3_and_lock(raw):
    port = raw("profile=laser&time_scale=1")
    assert port.ask("G1 X200 F600") == b"ok\r\n"
    port.wait_state("Run")
    port.port.write(b"\x18")
    assert port.read_until(UNLOCK) == b"ALARM:3\r\n" + BANNER + UNLOCK
    assert port.status().startswith("<Alarm|")


def test_planner_and_rx_buffer_in_bf(raw):
    port = raw("profile=laser&time_scale=1")
    port.ask("$10=3")
    lines = [f"G1X{10 + i}F60" for i in range(17)]  # 1 mm at 1 mm/s each: the planner fills
    for line in lines[:15]:
        assert port.ask(line) == b"ok\r\n"
    port.port.write((lines[15] + "\n" + lines[16] + "\n").encode())
    assert port.machine.settled()
    # 15 blocks planned; line 16 is out of the RX buffer but blocked in the parser; line 17 waits in the buffer
    report = port.status()
    assert report.startswith("<Run|") and f"|Bf:0,{128 - len(lines[16]) - 1}|" in report
    port.port.write(b"\x18")


def test_rx_ring_buffer_holds_127_of_128_bytes(raw):
    port = raw("profile=laser&time_scale=1")
    port.ask("$10=3")
    for i in range(15):
        port.ask(f"G1X{10 + i}F60")  # the planner is full
    port.port.write(b"G1X30F60\n")  # taken out of the buffer, blocked in the parser
    assert port.machine.settled()
    port.port.write(b"G1X31F60;" + b"x" * 119)  # 128 bytes of one unfinished line
    assert port.machine.settled()
    assert "|Bf:0,1|" in port.status()  # 127 bytes in: GRBL reports 128 - 127
    assert port.machine.snapshot().overflow_bytes == 1
    port.port.write(b"\x18")


def test_rx_overflow_is_recorded(raw):
    port = raw("profile=laser&time_scale=1")
    port.port.write(b"G1X10F60\n")
    port.port.write(b"G1X11F60\n" * 30)  # 270 bytes at once: a correct streamer never does this
    assert port.machine.settled()
    assert port.machine.snapshot().overflow_bytes > 0


def test_motion_takes_time_at_the_commanded_feed(raw):
    port = raw("profile=laser&time_scale=0.02")
    port.ask("G1 X20 F600")  # from work X400 (machine 0) to X20 (machine -380): 380 mm at 10 mm/s
    port.wait_state("Idle", timeout=10)
    record = port.machine.snapshot()
    block = record.executed[-1]
    start = next(s for s in record.samples if s.state == "Run")
    assert block.end == (-380.0, 0.0, 0.0)
    assert block.t_end - start.t == pytest.approx(380 / 10 * 0.02, rel=1e-6)


def test_laser_mode_power_feed_hold_and_m5(raw):
    port = raw("profile=laser&time_scale=1")
    port.ask("G0 X10 Y10")
    port.ask("M3 S500")
    port.ask("G1 X30 F600")
    port.wait_state("Run")
    port.port.write(b"!")
    port.wait_state("Hold:0")
    record = port.machine.snapshot()
    assert record.samples[-1].power == 0.0  # laser mode: dark while held
    port.port.write(b"~")
    port.wait_state("Idle", timeout=10)
    port.ask("M5")
    record = port.machine.snapshot()
    rapid, cut = record.executed[-2:]
    assert rapid.power == 0.0 and cut.power == 500.0
    assert record.samples[-1].power == 0.0


def test_laser_mode_status_reports_the_power_motion_set(raw):
    # as gnea/grbl 1.1h (grbl-sim) reports it: in laser mode the stepper sets the spindle speed as motion runs,
    # a completed hold switches it off (FS:0,0, DISABLE_LASER_DURING_HOLD) until "~" restores it, and M4's power
    # follows the speed (0 once stopped) where M3 keeps its S
    def fs(report: str) -> str:
        return report.split("FS:")[1].split("|")[0].rstrip(">")

    def spindle(report: str) -> str:
        return fs(report).split(",")[1]

    port = raw("profile=laser&time_scale=1&s120=100")
    port.ask("M3 S500")
    assert fs(port.status()) == "0,0"  # M3 alone sets no power in laser mode
    port.ask("G91 G1 X-10 F600")  # 1 s, inside the machine space (-400..0)
    report = port.wait_state("Run")
    assert spindle(report) == "500"
    port.port.write(b"!")
    assert fs(port.wait_state("Hold:0")) == "0,0"
    port.port.write(b"~")
    assert port.read_until(b"\r\n") == b"[MSG:Restoring spindle]\r\n"
    assert spindle(port.wait_state("Run")) == "500"
    assert fs(port.wait_state("Idle", timeout=10)) == "0,500"  # M3: the last block's power stays set
    port.ask("M4 S400")
    port.ask("G1 X-2")
    assert fs(port.wait_state("Idle", timeout=10)) == "0,0"
    plotter = raw("profile=plotter&time_scale=1")  # spindle mode: the servo's S is set at once, and kept held
    plotter.ask("M3 S30")
    assert fs(plotter.status()) == "0,30"


def test_probing_touches_the_plate_or_fails_with_grbls_alarms(raw):
    # mc_probe_cycle: G38.2 moves until the probe touches ([PRB:...:1], the machine stops just past contact), a
    # probe that touches before it starts is ALARM:4, one that never touches ALARM:5; G38.3 fails without the alarm
    port = raw("profile=plotter&homing=0&probe_z=-10&time_scale=0.01")
    assert port.ask("G38.2 Z-20", b"\r\n") == b"error:22\r\n"  # no feed rate
    assert port.ask("G38.2 F100", b"\r\n") == b"error:26\r\n"  # no axis words
    assert port.ask("G38.2 Z0 F100", b"\r\n") == b"error:33\r\n"  # the target is where the head is
    assert port.ask("G38.2 Z-20 F100") == b"[PRB:0.000,0.000,-10.000:1]\r\nok\r\n"
    assert port.status().startswith("<Idle|MPos:0.000,0.000,-10.0")
    assert "|Pn:P" in port.status()
    assert "[PRB:0.000,0.000,-10.000:1]" in port.ask("$#").decode()
    assert port.ask("$G").startswith(b"[GC:G38.2 G54 ")
    assert port.ask("G38.2 Z-15") == b"ALARM:4\r\nok\r\n"  # already touching: no motion
    assert port.status().startswith("<Alarm|") and port.ask("G0 Z0", b"error:9\r\n") == b"error:9\r\n"
    assert port.ask("$X").endswith(b"ok\r\n") and port.ask("G0 Z0") == b"ok\r\n"
    assert port.ask("G38.4 Z5 F100") == b"ALARM:4\r\nok\r\n"  # away: must start touching
    port.ask("$X")
    assert port.ask("G38.3 X10 F100") == b"[PRB:10.000,0.000,0.000:0]\r\nok\r\n"  # no contact, no alarm
    assert port.ask("G38.2 X20") == b"ALARM:5\r\n[PRB:10.000,0.000,0.000:0]\r\nok\r\n"  # G38.2 is modal now
    assert port.status().startswith("<Alarm|MPos:20.000,0.000,0.000")
    port.port.write(b"\x18")
    port.read_until(UNLOCK)
    assert "[PRB:0.000,0.000,0.000:0]" in port.ask("$#").decode()  # a reset forgets the probe
    plain = raw("profile=plotter&homing=0&time_scale=0.01")  # no plate: a probe never touches
    assert plain.ask("G38.2 Z-5 F300") == b"ALARM:5\r\n[PRB:0.000,0.000,0.000:0]\r\nok\r\n"
    assert 4 not in plain.machine.snapshot().alarms and port.machine.snapshot().alarms == [4, 4, 5]


def test_spindle_mode_servo_holds_its_value(raw):
    port = raw("profile=plotter&time_scale=0.01")
    port.ask("M3 S30")
    assert port.machine.snapshot().samples[-1].power == 30.0  # the pen servo keeps its position while idle


def test_check_mode_moves_nothing_and_leaves_by_reset(raw):
    port = raw()
    assert port.ask("$C") == b"[MSG:Enabled]\r\nok\r\n"
    assert port.status().startswith("<Check|")
    assert port.ask("G1 X10 Y10 F100") == b"ok\r\n"
    assert port.ask("G41", b"error:20\r\n").endswith(b"error:20\r\n")
    port.port.write(b"$C\n")
    assert port.read_until(BANNER) == b"[MSG:Disabled]\r\nok\r\n" + BANNER
    assert port.machine.snapshot().executed == []


def test_jog_cancel_and_jog_limits(raw):
    port = raw("profile=laser&time_scale=1")
    assert port.ask("$J=G91 X-50 F600") == b"ok\r\n"
    port.wait_state("Jog")
    port.port.write(b"\x85")
    port.wait_state("Idle")
    assert port.ask("$J=G91 X1000 F600", b"error:15\r\n").endswith(b"error:15\r\n")
    assert port.ask("$J=G91 X1 M3 F600", b"error:16\r\n").endswith(b"error:16\r\n")
    assert port.ask("$J=G91 X1", b"error:22\r\n").endswith(b"error:22\r\n")


def test_homing_and_disabled_homing(raw):
    port = raw("profile=laser&time_scale=0.05")
    assert port.ask("$H") == b"ok\r\n"
    assert port.status().startswith("<Idle|MPos:-1.000,-1.000,-1.000")
    plain = raw("profile=laser&s22=0&s20=0")
    assert plain.ask("$H", b"error:5\r\n").endswith(b"error:5\r\n")


def test_homing_answers_no_status_request_until_the_cycle_ends(raw):
    # GRBL 1.1's limits_go_home never runs protocol_execute_realtime(): '?' waits for the end of the cycle, and
    # however many came, one report follows, still in the Home state (gnea/grbl#1061)
    port = raw("profile=laser&time_scale=2")
    port.port.write(b"$H\n")
    deadline = time.monotonic() + 5.0
    while port.machine.state != "Home":
        assert time.monotonic() < deadline
        time.sleep(0.005)
    port.port.write(b"???")
    reply = port.read_until(b"ok\r\n", timeout=10.0).decode()
    assert reply.count("<") == 1 and reply.startswith("<Home|") and reply.endswith(">\r\nok\r\n")
    assert port.status().startswith("<Idle|")


def test_build_info_stored_with_dollar_i_follows_the_build_date(raw):
    port = raw()
    assert port.ask("$I=my laser 2") == b"ok\r\n"  # stored as GRBL keeps the line: upper case, no spaces
    assert port.ask("$I").startswith(b"[VER:1.1h.20190830:MYLASER2]\r\n[OPT:V,15,128]")


def test_unplug_makes_reads_and_writes_fail(raw):
    port = raw()
    port.machine.unplug()
    with pytest.raises(serial.SerialException):
        port.port.read(10)
    with pytest.raises(serial.SerialException):
        port.port.write(b"?")


def test_bad_urls():
    with pytest.raises(serial.SerialException, match="unknown simulated device"):
        serial.serial_for_url("sim://mill")
    with pytest.raises(serial.SerialException, match="unknown sim option 'bogus'"):
        serial.serial_for_url("sim://grbl?bogus=1")
    with pytest.raises(serial.SerialException, match="unknown sim profile"):
        serial.serial_for_url("sim://grbl?profile=router")


def test_feed_hold_decelerates_then_reset_keeps_the_position(raw):
    port = raw("profile=laser&time_scale=1")
    port.ask("M3 S200")
    port.ask("G1 X100 F6000")  # 100 mm/s: stopping takes 5 mm at 1000 mm/s^2
    port.wait_state("Run")
    port.port.write(b"!")
    port.wait_state("Hold:0")
    states = [s.state for s in port.machine.snapshot().samples]
    assert "Hold:1" in states and states[-1] == "Hold:0"
    before = port.status()
    port.port.write(b"\x18")  # reset after a completed hold: no ALARM:3, position kept
    assert port.read_until(BANNER) == BANNER
    after = port.status()
    assert after.startswith("<Idle|") and after.split("|")[1] == before.split("|")[1]


# ------------------------------------------------------------------ homing, soft limits and machine space (GRBL 1.1)


def test_without_homing_there_are_no_soft_limits_and_no_machine_space(raw):
    port = raw("profile=laser&homing=0&travel=200x200&time_scale=0.001")
    settings = port.ask("$$").decode()
    assert "$20=0\r\n" in settings and "$22=0\r\n" in settings and "$130=200.000\r\n" in settings
    assert port.ask("$20=1", b"error:10\r\n").endswith(b"error:10\r\n")  # soft limits need homing (settings.c)
    assert port.ask("$#").startswith(b"[G54:0.000,0.000,0.000]\r\n")  # GRBL's default: work zero = power-up spot
    assert port.ask("G0 X-500 Y900") == b"ok\r\n"  # no limits: machine zero means nothing without homing
    port.wait_state("Idle")
    assert port.machine.snapshot().alarms == []
    assert port.machine.snapshot().executed[-1].end == (-500.0, 900.0, 0.0)


def test_homing_off_clears_soft_limits_as_grbl_does(raw):
    port = raw("profile=plotter&time_scale=0.001")
    assert "$20=1\r\n" in port.ask("$$").decode()
    assert port.ask("$22=0") == b"ok\r\n"
    settings = port.ask("$$").decode()
    assert "$22=0\r\n" in settings and "$20=0\r\n" in settings
    assert port.ask("G0 X500") == b"ok\r\n"  # outside -420..0, but nothing checks it any more
    port.wait_state("Idle")
    assert port.machine.snapshot().alarms == []
    assert port.ask("$22=1") == b"ok\r\n"
    assert "$20=0\r\n" in port.ask("$$").decode()  # homing back on does not switch soft limits on
    assert port.ask("$20=1") == b"ok\r\n"


def test_soft_limit_checks_both_ends_of_every_axis(raw):
    port = raw("profile=laser&time_scale=0.001")  # homed machine space: -400..0, -400..0, -20..0
    for target in ("X-401", "X1", "Y-401", "Y1", "Z-21", "Z1"):
        port.port.write(f"G53 G0 {target}\n".encode())
        assert port.read_until(b"Reset to continue]\r\n").endswith(b"ALARM:2\r\n[MSG:Reset to continue]\r\n")
        port.port.write(b"\x18")
        port.read_until(UNLOCK)
        assert port.ask("$X") == b"[MSG:Caution: Unlocked]\r\nok\r\n"
    for target in ("X-399", "Y-399", "Z-19"):
        assert port.ask(f"G53 G0 {target}") == b"ok\r\n"
    assert port.machine.snapshot().alarms == [2] * 6


def test_force_origin_build_puts_axes_with_a_homing_dir_bit_in_positive_space(raw):
    # HOMING_FORCE_SET_ORIGIN: X and Y ($23 bits 0 and 1) live in 0..+travel, Z (bit clear) in -travel..0
    port = raw("profile=laser&force_origin=1&s23=3&time_scale=0.001")
    assert port.ask("$I").startswith(b"[VER:1.1h.20190830:]\r\n[OPT:VZ,15,128]")
    assert port.ask("$#").startswith(b"[G54:0.000,0.000,0.000]\r\n")
    assert port.ask("G53 G0 X399 Y399 Z-19") == b"ok\r\n"
    for target in ("X-1", "Z1"):
        port.port.write(f"G53 G0 {target}\n".encode())
        assert port.read_until(b"Reset to continue]\r\n").endswith(b"ALARM:2\r\n[MSG:Reset to continue]\r\n")
        port.port.write(b"\x18")
        port.read_until(UNLOCK)
        port.ask("$X")
    assert port.ask("$H") == b"ok\r\n"
    assert port.wait_state("Idle").startswith("<Idle|MPos:0.000,0.000,0.000")  # homing sets the origin


def test_homing_ends_pulled_off_the_switch_per_homing_direction(raw):
    port = raw("profile=laser&s23=1&time_scale=0.02")  # X homes towards -: X = -travel + pull-off
    assert port.ask("$H") == b"ok\r\n"
    assert port.wait_state("Idle").startswith("<Idle|MPos:-399.000,-1.000,-1.000")


def test_sim_url_options_for_homing_and_travel_are_checked():
    with pytest.raises(serial.SerialException, match=r"s20=1 needs homing .*error:10"):
        serial.serial_for_url("sim://grbl?profile=laser&homing=0&s20=1")
    with pytest.raises(serial.SerialException, match="travel must be WxD or WxDxH"):
        serial.serial_for_url("sim://grbl?profile=laser&travel=400")
    with pytest.raises(serial.SerialException, match="travel must be WxD or WxDxH"):
        serial.serial_for_url("sim://grbl?profile=laser&travel=axb")
    port = serial.serial_for_url("sim://grbl?profile=plotter&homing=0&travel=300x200x10")
    try:
        settings = port.machine.settings
        assert (settings[20], settings[22], settings[130], settings[131], settings[132]) == (0, 0, 300, 200, 10)
    finally:
        port.close()


def test_shipped_machines_follow_grbls_settings_rules():
    """Every simulated profile and every machine profile (examples/profiles, drivers/profiles.py) describes a
    machine GRBL would accept: soft limits only with homing, and a work area equal to the simulated travel."""
    from pathlib import Path

    from drivers.profiles import builtin_profile, builtin_profile_names, load_profile
    from drivers.sim.grbl import SIM_PROFILES, SimConfig

    for name in SIM_PROFILES:
        settings = SimConfig(profile=name).machine_settings()
        assert not (settings[20] and not settings[22]), name
        assert SimConfig(profile=name, homing=False).machine_settings()[20] == 0, name
    examples = sorted((Path(__file__).resolve().parents[4] / "examples" / "profiles").glob("*.toml"))
    profiles = [load_profile(path) for path in examples] + [builtin_profile(n) for n in builtin_profile_names()]
    assert len(profiles) >= 3  # plotter, laser (built in) and the no-homing laser example
    for profile in profiles:
        query = dict(part.split("=", 1) for part in profile.port.split("?", 1)[1].split("&"))
        settings = SimConfig.from_query(query).machine_settings()
        assert (settings[130], settings[131]) == (profile.width, profile.height), profile.source
        assert bool(settings[32]) == (profile.kind == "laser"), profile.source
