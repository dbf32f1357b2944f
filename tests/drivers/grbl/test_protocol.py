"""Parsing of every GRBL 1.1 message kind, and the codes in words."""

from __future__ import annotations

import pytest

from drivers.grbl.protocol import (
    ALARM_CODES,
    ERROR_CODES,
    Alarm,
    Banner,
    Error,
    Feedback,
    Garbled,
    Ok,
    ReplyParseError,
    SettingLine,
    StatusReport,
    VersionInfo,
    needs_sync,
    parse_line,
    parse_version,
)


@pytest.mark.parametrize(
    ("line", "expected"),
    [
        ("ok", Ok()),
        ("error:20", Error(20)),
        ("ALARM:2", Alarm(2)),
        ("Grbl 1.1h ['$' for help]", Banner("1.1h")),
        ("[MSG:'$H'|'$X' to unlock]", Feedback("MSG", "'$H'|'$X' to unlock")),
        ("[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]", Feedback("GC", "G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0")),
        ("[OPT:V,15,128]", Feedback("OPT", "V,15,128")),
        ("[G54:-400.000,-400.000,0.000]", Feedback("G54", "-400.000,-400.000,0.000")),
        ("$130=400.000", SettingLine(130, 400.0)),
        ("o\x9ek", Garbled("o\x9ek")),
        ("error:", Garbled("error:")),
        ("<Idle|garbled", Garbled("<Idle|garbled")),
    ],
)
def test_parse_line(line, expected):
    assert parse_line(line) == expected


def test_status_report_fields():
    report = parse_line(
        "<Hold:0|MPos:-10.000,-20.500,0.000|Bf:12,100|Ln:7|FS:1500,300|Pn:XZ|WCO:-400.000,-400.000,0.000>"
    )
    assert isinstance(report, StatusReport)
    assert report.state == "Hold" and report.substate == 0 and report.label == "Hold:0"
    assert report.mpos == (-10.0, -20.5, 0.0) and report.wco == (-400.0, -400.0, 0.0)
    assert (report.planner_free, report.rx_free, report.line_number) == (12, 100, 7)
    assert (report.feed, report.spindle, report.pins) == (1500.0, 300.0, "XZ")
    assert report.work_position(report.wco) == (390.0, 379.5, 0.0)
    ov = parse_line("<Run|WPos:1.000,2.000,3.000|FS:100,0|Ov:100,50,120|A:SF>")
    assert ov.overrides == (100, 50, 120) and ov.accessories == "SF"
    assert ov.machine_position((1.0, 1.0, 1.0)) == (2.0, 3.0, 4.0)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("Idle|MPos:0,0,0", "not a status report: 'Idle|MPos:0,0,0'"),
        ("<Dance|MPos:0,0,0>", "unknown state 'Dance' in '<Dance|MPos:0,0,0>'"),
        ("<Hold:x>", "malformed state 'Hold:x' in '<Hold:x>'"),
        ("<Idle|MPos>", "malformed field 'MPos' in '<Idle|MPos>'"),
        ("<Idle|MPos:0,zero,0>", "malformed field 'MPos:0,zero,0' in '<Idle|MPos:0,zero,0>'"),
        ("<Idle|Bf:15>", "malformed field 'Bf:15' in '<Idle|Bf:15>'"),
        ("<Idle|Zz:1>", "unknown field 'Zz' in '<Idle|Zz:1>'"),
        ("<Idle|WCO:0,0>", "short wco in '<Idle|WCO:0,0>'"),
    ],
)
def test_a_malformed_status_report_is_a_reply_parse_error_of_the_drivers_tree(text, message):
    from drivers.errors import DriverError, ProtocolError

    with pytest.raises(ReplyParseError) as caught:
        StatusReport.parse(text)
    assert str(caught.value) == message
    assert isinstance(caught.value, ProtocolError) and isinstance(caught.value, DriverError)
    assert isinstance(caught.value, OSError) and isinstance(caught.value, ValueError)  # old callers still catch it
    if text.startswith("<"):
        assert parse_line(text) == Garbled(text)  # the reader keeps it as a garbled line


def test_codes_have_meanings():
    assert Error(9).meaning.startswith("G-code commands are locked out")
    assert "soft limit" in Alarm(2).meaning.lower() and "$X" in Alarm(2).recovery
    assert "home" in Alarm(3).recovery.lower()
    assert set(range(1, 39)) - {18, 19} == set(ERROR_CODES)
    assert set(range(1, 11)) == set(ALARM_CODES)
    assert "unknown" in Error(99).meaning.lower()


@pytest.mark.parametrize(
    ("block", "sync"),
    [("$$", True), ("$10=3", True), ("$J=G91X1F100", False), ("G10L20P1X0Y0", True), ("G28.1", True),
     ("G30.1", True), ("G1X10Y10", False), ("G1X100Y10", False), ("G28", False), ("M3S100", False)],
)
def test_send_response_rules(block, sync):
    assert needs_sync(block) is sync


@pytest.mark.parametrize(
    "line, expected, shown",
    [
        # report.c: "[VER:" GRBL_VERSION "." GRBL_VERSION_BUILD ":" <build info> "]"; a stock GRBL has no info
        (b"[VER:1.1h.20190830:]\r\n", VersionInfo("1.1h", "20190830", ""), "GRBL 1.1h (build 20190830)"),
        (b"[VER:1.1f.20170801:MYLASER]\r\n", VersionInfo("1.1f", "20170801", "MYLASER"),
         "GRBL 1.1f (build 20170801, info 'MYLASER')"),
        (b"[VER:1.1h.20190830:A:B]\r\n", VersionInfo("1.1h", "20190830", "A:B"),
         "GRBL 1.1h (build 20190830, info 'A:B')"),
        (b"[VER:1.1-fork:]\r\n", VersionInfo("1.1-fork", "", ""), "GRBL 1.1-fork"),
    ],
)
def test_version_line_splits_version_build_date_and_build_info(line, expected, shown):
    # The TUI showed 'GRBL 1.1h.20190830:' (the whole body of the line as the version)
    message = parse_line(line.decode("latin-1").rstrip("\r\n"))
    assert message == Feedback("VER", message.text)
    assert parse_version(message.text) == expected
    assert str(parse_version(message.text)) == shown
