"""``station send`` and ``station ports`` as a maker meets them: machines without homing, progress that tells the
truth, plain progress lines in logs, the frame offered before a laser job, warnings for a job written for the other
kind of machine, bad baud rates, and Ctrl-C / SIGTERM leaving the laser off."""

from __future__ import annotations

import io
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from drivers.grbl import JobProgress
from drivers.grbl.job import job_kind
from drivers.sim import protocol_sim
from station.cli import build_parser, main
from station.commands import machines_io

FAST = "time_scale=0.002&wire=0"


def laser_job(width: float, depth: float, rows: int = 6) -> str:
    """A laser job of ``width`` x ``depth`` mm at positive coordinates from work zero: an outline and a hatch."""
    lines = ["G21 G90 G94", "M4 S400", "G0 X0 Y0", f"G1 X{width:g} Y0 F6000", f"G1 X{width:g} Y{depth:g}",
             f"G1 X0 Y{depth:g}", "G1 X0 Y0"]
    for row in range(1, rows):
        y = depth * row / rows
        lines += [f"G0 X0 Y{y:g}", f"G1 X{width:g} Y{y:g}"]
    return "\n".join(lines + ["M5 S0", "G0 X0 Y0"]) + "\n"


@pytest.fixture
def shared():
    """Named simulated machines that outlive the command's port, so a test can read what they did."""
    names: list[str] = []

    def make(name: str, query: str) -> str:
        names.append(name)
        return f"sim://grbl?{query}&name={name}"

    yield make
    for name in names:
        machine = protocol_sim.machine_named(name)
        if machine is not None:
            machine.stop()
            with protocol_sim._SHARED_LOCK:
                protocol_sim._SHARED.pop(name, None)


def last_json(out: str) -> dict:
    return json.loads(out.strip().splitlines()[-1])


# ------------------------------------------------------------------ machines without homing (the acceptance)


def test_a_300_by_100_job_runs_to_the_end_on_a_machine_without_homing_with_400_mm_of_travel(tmp_path, capsys, shared):
    job = tmp_path / "panel.gcode"
    job.write_text(laser_job(300, 100))
    url = shared("nohome400", f"profile=laser&homing=0&travel=400x400&{FAST}")
    assert main(["send", str(job), "--laser", "--port", url, "--json"]) == 0
    result = last_json(capsys.readouterr().out)
    assert result["state"] == "done" and result["lines_acked"] == result["lines_total"] and result["laser_off"]
    record = protocol_sim.machine_named("nohome400").snapshot()
    assert record.alarms == []
    ends = [b.end[:2] for b in record.executed]
    assert (300.0, 100.0) in ends and ends[-1] == (0.0, 0.0)
    assert record.samples[-1].power == 0.0


def test_the_same_job_on_200_mm_of_travel_is_refused_with_its_size_before_any_motion(tmp_path, capsys, shared):
    job = tmp_path / "panel.gcode"
    job.write_text(laser_job(300, 100))
    url = shared("nohome200", f"profile=laser&homing=0&travel=200x200&{FAST}")
    assert main(["send", str(job), "--laser", "--port", url]) == 2
    err = capsys.readouterr().err
    assert "this job is 300.0 mm wide; your machine travels 200.0 mm in X ($130)" in err
    assert "Scale the job down" in err and "Traceback" not in err
    assert err.count("\n") == 1, err  # one line
    record = protocol_sim.machine_named("nohome200").snapshot()
    assert record.executed == [] and all(line.startswith("$") for line in record.received)


def test_without_homing_a_laser_job_run_from_a_script_gets_the_frame_tip(tmp_path, capsys):
    job = tmp_path / "small.gcode"
    job.write_text(laser_job(40, 20, rows=2))
    assert main(["send", str(job), "--laser", "--port", f"sim://grbl?profile=laser&homing=0&{FAST}"]) == 0
    err = capsys.readouterr().err
    assert "no homing ($22=0)" in err and f"station send {job} --frame" in err


def _answer(monkeypatch, *answers: str) -> None:
    monkeypatch.setattr(machines_io, "_interactive", lambda: True)
    monkeypatch.setattr(sys, "stdin", io.StringIO("".join(a + "\n" for a in answers)))


def test_without_homing_a_laser_job_is_offered_its_frame_first(tmp_path, capsys, monkeypatch, shared):
    job = tmp_path / "small.gcode"
    job.write_text(laser_job(40, 20, rows=2))
    url = shared("offer", f"profile=laser&homing=0&{FAST}")
    _answer(monkeypatch, "", "y")  # Enter: yes, trace the frame; then yes, start
    assert main(["send", str(job), "--laser", "--port", url]) == 0
    err = capsys.readouterr().err
    assert "trace the job's frame first" in err and "[Y/n]" in err and "Start the laser job small.gcode? [y/N]" in err
    record = protocol_sim.machine_named("offer").snapshot()
    frame_power = 0.01 * 1000  # the profile-less frame is at S10
    burns = [b for b in record.executed if b.power > 0]
    assert [b.power for b in burns[:4]] == [frame_power] * 4  # the four sides of the frame, at low power
    assert {b.power for b in burns[4:]} == {400.0}  # then the job itself
    assert main(["jobs", "--json"]) == 0
    jobs = json.loads(capsys.readouterr().out)["jobs"]
    assert [(j["kind"], j["status"]) for j in jobs] == [("run", "done"), ("frame", "done")]


def test_after_the_frame_the_job_starts_only_when_asked(tmp_path, capsys, monkeypatch, shared):
    job = tmp_path / "small.gcode"
    job.write_text(laser_job(40, 20, rows=2))
    url = shared("decline", f"profile=laser&homing=0&{FAST}")
    _answer(monkeypatch, "y", "")  # frame yes; Enter at "start?" is no
    assert main(["send", str(job), "--laser", "--port", url]) == 0
    assert "small.gcode not started" in capsys.readouterr().err
    burns = [b for b in protocol_sim.machine_named("decline").snapshot().executed if b.power > 0]
    assert len(burns) == 4 and {b.power for b in burns} == {10.0}


# ------------------------------------------------------------------ words: empty jobs, progress, warnings


def test_an_empty_job_says_it_has_no_gcode_lines(tmp_path, capsys):
    for name, text in (("empty.gcode", ""), ("comments.gcode", "(only a comment)\n; and another\n\n")):
        job = tmp_path / name
        job.write_text(text)
        assert main(["send", str(job), "--port", f"sim://grbl?profile=plotter&{FAST}"]) == 2
        err = capsys.readouterr().err
        assert f"job {str(job)!r}: the file has no G-code lines" in err and "--from-line" not in err


def test_a_job_stopped_at_2_of_3_lines_does_not_show_100_percent(tmp_path, capsys):
    job = tmp_path / "stop.gcode"
    job.write_text("G21\nG0 X10 Y10\nG41\n")
    assert main(["send", str(job), "--port", f"sim://grbl?profile=plotter&{FAST}"]) == 1
    err = capsys.readouterr().err
    assert "send:  66.7% 2/3 lines  stopped\n" in err  # the G41 line was answered with an error: not confirmed
    assert "100.0%" not in err and "ETA" not in err.splitlines()[-2]
    assert main(["send", str(job), "--port", f"sim://grbl?profile=plotter&{FAST}", "--json"]) == 1
    assert last_json(capsys.readouterr().out)["lines_acked"] == 2


def test_a_refused_job_prints_one_line_and_no_eta(tmp_path, capsys):
    job = tmp_path / "far.gcode"
    job.write_text("G0 X900\n")
    assert main(["send", str(job), "--port", f"sim://grbl?profile=plotter&{FAST}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "leaves the machine's travel" in err and "ETA" not in err


def test_progress_in_a_log_is_plain_lines_and_on_a_terminal_a_bar():
    def at(fraction, state="running", eta=5.0):
        return JobProgress(state=state, lines_total=100, lines_acked=int(fraction * 100), fraction=fraction, eta=eta)

    log = io.StringIO()
    bar = machines_io.SendProgress(log)  # not a terminal
    for step in range(101):
        bar(at(step / 100))
    bar(at(1.0, "done", 0.0))
    bar.close()
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue()
    assert lines[0] == "send:   0.0% 0/100 lines  ETA 0:05  running" and lines[-1] == "send: 100.0% 100/100 lines  done"
    assert len(lines) == 12  # one per tenth, and the end
    screen = io.StringIO()
    bar = machines_io.SendProgress(screen, tty=True)  # a terminal: one rich bar for the job, redrawn in place
    bar(at(0.5))
    bar(at(1.0, "done", 0.0))
    bar.close()
    drawn = screen.getvalue()
    frames = drawn.split("\r")
    assert "━" in drawn and len(frames) > 2
    assert "50.0% 50/100 lines  ETA 0:05  running" in drawn
    assert "100.0% 100/100 lines  done" in frames[-1] and "ETA" not in frames[-1] and "\n" in frames[-1]
    assert frames[-1].count("lines") == 1  # a change of state redraws the job's bar, it adds no second one
    assert machines_io.format_duration(5974) == "1:39:34" and machines_io.format_duration(59) == "0:59"


def test_a_pen_plot_sent_to_a_laser_and_a_laser_job_sent_to_a_plotter_are_warned(tmp_path, capsys):
    pen = tmp_path / "pen.gcode"
    assert main(["plot", "spirograph", "--size", "40", "--points", "64", "--out", str(pen)]) == 0
    capsys.readouterr()
    assert main(["send", str(pen), "--dry-run", "--port", f"sim://grbl?profile=laser&{FAST}"]) == 0
    err = capsys.readouterr().err
    assert "warning: job 'pen.gcode' looks like a pen-plotter job, but the machine is in laser mode ($32=1)" in err
    assert "fire the laser" in err
    zpen = tmp_path / "zpen.gcode"
    zpen.write_text("G21 G90\nG0 Z-2\nG0 X10 Y10\nG1 Z-4 F500\nG1 X20 F3000\nG0 Z-2\n")
    assert main(["send", str(zpen), "--dry-run", "--port", f"sim://grbl?profile=laser&{FAST}"]) == 0
    assert "it will mark nothing" in capsys.readouterr().err
    burn = tmp_path / "burn.gcode"
    burn.write_text("G21 G90\nM4 S300\nG1 X10 Y10 F1000\nM5 S0\n")
    assert main(["send", str(burn), "--dry-run", "--port", f"sim://grbl?profile=plotter&{FAST}"]) == 0
    assert "looks like a laser job (M4, or a laser job's header), but the machine is not in laser mode" in (
        capsys.readouterr().err)
    assert main(["send", str(burn), "--dry-run", "--port", f"sim://grbl?profile=laser&{FAST}"]) == 0
    assert "warning" not in capsys.readouterr().err


def test_job_kind_reads_the_writers_marks():
    import numpy as np

    from drivers.profiles import builtin_profile

    t = np.linspace(0, 2 * np.pi, 50)
    circle = [np.column_stack([np.cos(t), np.sin(t)])]
    plot = machines_io.plot_job(circle, builtin_profile("plotter"), 50.0, 0.1)[0].splitlines()
    burn = machines_io.plot_job(circle, builtin_profile("laser"), 50.0, 0.1)[0].splitlines()
    assert job_kind(plot) == "pen" and job_kind(burn) == "laser"
    assert job_kind(["; chaos-station laser job: sheet: 1", "M3 S500", "G1 X1 F100"]) == "laser"
    assert job_kind(["M3 S500", "G1 X1 F100", "M5"]) == ""  # a constant-power laser or a servo: cannot tell


# ------------------------------------------------------------------ ports and options


@pytest.mark.parametrize("baud", ["-1", "0", "12345", "fast"])
def test_a_bad_baud_rate_is_one_line(capsys, tmp_path, baud):
    for argv in (["ports", "--no-probe", "--baud", baud], ["send", "x.gcode", "--baud", baud]):
        with pytest.raises(SystemExit) as exit_:
            main(argv)  # argparse's errors leave by SystemExit(2)
        assert exit_.value.code == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "--baud" in err and "standard baud rate such as 115200" in err


def test_every_option_of_ports_and_send_has_help():
    parser = build_parser()
    commands = next(a for a in parser._actions if a.dest == "command").choices
    for name in ("ports", "send"):
        for action in commands[name]._actions:
            if action.option_strings and action.dest != "help":
                assert action.help, f"station {name} {action.option_strings[0]} has no help"


# ------------------------------------------------------------------ Ctrl-C / SIGTERM


def test_sigterm_mid_job_aborts_with_the_laser_off(tmp_path):
    """``kill`` of a running ``station send`` (a separate process) ends with exit 130, a soft reset and the laser
    off: read from the simulated machine's record, which it writes when the command closes its port."""
    job = tmp_path / "long.gcode"
    # Long enough (about a minute of burning) that the signal surely lands mid-job, however late the first
    # progress line is read: a job that had already ended needs no reset, and the check below would mean nothing.
    lines = ["G21 G90", "G0 X10 Y10", "M4 S700"] + [f"G1 X{10 + 5 * (i % 2)} Y{10 + i % 100} F300"
                                                    for i in range(400)]
    lines.append("M5 S0")
    job.write_text("\n".join(lines) + "\n")
    record = tmp_path / "record.json"
    url = f"sim://grbl?profile=laser&time_scale=0.25&record={record}"
    process = subprocess.Popen(
        [sys.executable, "-m", "station.cli", "send", str(job), "--laser", "--port", url],
        stderr=subprocess.PIPE, text=True, cwd=Path(__file__).resolve().parents[3], env=dict(os.environ),
    )
    seen: list[str] = []
    burning = threading.Event()

    def read() -> None:
        for line in process.stderr:
            seen.append(line)
            if line.startswith("send:") and "running" in line and " 0/" not in line:
                burning.set()  # lines confirmed after M4: the laser is on

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        assert burning.wait(60), "".join(seen)
        process.send_signal(signal.SIGTERM)
        assert process.wait(60) == 130
    finally:
        if process.poll() is None:
            process.kill()
    reader.join(10)
    assert "station: interrupted" in "".join(seen)
    document = json.loads(record.read_text())
    samples, resets = document["samples"], document["resets"]
    assert any(power > 0 for _, _, _, _, power, _ in samples)  # it was burning
    assert resets, "no soft reset reached the machine"
    assert all(power == 0.0 for t, _, _, _, power, _ in samples if t >= resets[-1])
    assert samples[-1][4] == 0.0
    assert "M5S0" in document["received"][document["received"].index("M4S700"):]  or 3 in document["alarms"]


def test_the_example_profile_without_homing_takes_a_job_as_wide_as_its_bed(tmp_path, capsys):
    from drivers.profiles import load_profile

    path = Path(__file__).resolve().parents[3] / "examples" / "profiles" / "grbl_diode_laser_no_homing.toml"
    profile = load_profile(path)
    assert (profile.width, profile.height, profile.is_laser) == (300.0, 200.0, True)
    job = tmp_path / "panel.gcode"
    job.write_text(laser_job(300, 100, rows=2))
    port = f"{profile.port}&{FAST}"
    assert main(["send", str(job), "--profile", str(path), "--port", port, "--json"]) == 0
    assert last_json(capsys.readouterr().out)["state"] == "done"
    job.write_text(laser_job(301, 100, rows=2))
    assert main(["send", str(job), "--profile", str(path), "--port", port]) == 2
    assert "this job is 301.0 mm wide; your machine travels 300.0 mm in X ($130)" in capsys.readouterr().err


def _start_long_laser_job(tmp_path, *options: str, ignore_sigint: bool = False):
    """``station send`` of a laser job lasting about a minute (a separate process); returns it, its record file and
    the station's database once the machine has confirmed lines after ``M4`` (the laser burns)."""
    from station.paths import database_path

    job = tmp_path / "long.gcode"
    lines = ["G21 G90", "G0 X10 Y10", "M4 S700"] + [f"G1 X{10 + 5 * (i % 2)} Y{10 + i % 100} F300"
                                                    for i in range(400)]
    job.write_text("\n".join([*lines, "M5 S0"]) + "\n")
    record = tmp_path / "record.json"
    url = f"sim://grbl?profile=laser&time_scale=0.25&record={record}"

    def ignore() -> None:  # what a shell does to a background job of a script
        signal.signal(signal.SIGINT, signal.SIG_IGN)

    process = subprocess.Popen(
        [sys.executable, "-m", "station.cli", "send", str(job), "--laser", "--port", url, *options],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=Path(__file__).resolve().parents[3],
        env=dict(os.environ), preexec_fn=ignore if ignore_sigint else None,
    )
    database = database_path()
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and process.poll() is None:
        if database.exists():
            from station.db import open_database
            from station.joblog import JobLog

            connection = open_database(database)
            try:
                records = JobLog(connection).recent(1)
            finally:
                connection.close()
            if records and records[0].lines_acked > 3:  # recorded every 2 s while it runs
                return process, record, database
        time.sleep(0.2)
    process.kill()
    raise AssertionError(f"the job did not start: {process.communicate()}")


def _jobs_json() -> list[dict]:
    out = subprocess.run([sys.executable, "-m", "station.cli", "jobs", "--json"], capture_output=True, text=True,
                         check=True, cwd=Path(__file__).resolve().parents[3], env=dict(os.environ)).stdout
    return json.loads(out)["jobs"]


def _laser_off_after_the_reset(record: Path) -> None:
    document = json.loads(record.read_text())
    samples, resets = document["samples"], document["resets"]
    assert any(power > 0 for _, _, _, _, power, _ in samples)  # it was burning
    assert resets, "no soft reset reached the machine"
    assert all(power == 0.0 for t, _, _, _, power, _ in samples if t >= resets[-1])


def test_an_interrupted_send_json_prints_the_job_with_where_to_resume_and_the_laser_off(tmp_path):
    process, record, _ = _start_long_laser_job(tmp_path, "--json")
    try:
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130, err
    result = json.loads(out)
    assert result["state"] == "interrupted" and result["laser_off"] is True
    assert isinstance(result["resume_line"], int) and 3 <= result["resume_line"] < result["lines_total"]
    assert "interrupted by SIGINT" in result["message"] and "laser off" in result["message"]
    assert f"resume from line {result['resume_line']}" in err and "laser off" in err
    _laser_off_after_the_reset(record)
    (job,) = _jobs_json()
    assert (job["status"], job["resume_line"]) == ("interrupted", result["resume_line"])


def test_send_started_with_sigint_ignored_still_stops_on_kill_int(tmp_path):
    # a background job of a script: the shell left SIGINT ignored, which Python keeps unless told otherwise
    process, record, _ = _start_long_laser_job(tmp_path, ignore_sigint=True)
    try:
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=30)  # the job itself would burn for more than a minute
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130, err
    assert "station: interrupted by SIGINT" in err and "laser off" in err
    _laser_off_after_the_reset(record)
    (job,) = _jobs_json()
    assert job["status"] == "interrupted" and job["resume_line"] is not None
