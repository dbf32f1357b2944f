"""``station plot``, ``station ports``, ``station send`` through the CLI entry point."""

from __future__ import annotations

import json

import numpy as np

from station.cli import main

FAST_PLOTTER = "sim://grbl?profile=plotter&time_scale=0.002"
FAST_LASER = "sim://grbl?profile=laser&time_scale=0.002"


def test_plot_a_drawing_machine_then_send_it(tmp_path, capsys):
    job = tmp_path / "spiro.gcode"
    assert main(["plot", "spirograph", "--set", "d=2.5", "--size", "120", "--out", str(job), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["machine"] == "spirograph" and summary["params"]["d"] == 2.5
    assert summary["points_out"] < summary["points_in"]
    width = summary["extent_mm"][2] - summary["extent_mm"][0]
    height = summary["extent_mm"][3] - summary["extent_mm"][1]
    assert abs(max(width, height) - 120.0) < 1e-6
    text = job.read_text()
    assert text.startswith("(chaos-station pen plot job for GRBL pen plotter)\nG21\nG90\nG94\nM3 S50\n")
    assert main(["send", str(job), "--profile", "plotter", "--port", FAST_PLOTTER, "--json"]) == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert result["state"] == "done" and result["lines_acked"] == result["lines_total"]


def test_plot_from_a_pattern_file_to_stdout(tmp_path, capsys):
    t = np.linspace(0, 2 * np.pi, 500)
    pattern = tmp_path / "p.json"
    pattern.write_text(json.dumps({"machine": "x", "params": {}, "period": 6.28,
                                   "points": np.column_stack([np.cos(t), np.sin(t)]).tolist()}))
    assert main(["plot", "--pattern", str(pattern), "--profile", "laser", "--tolerance", "0.1"]) == 0
    out = capsys.readouterr()
    assert "M4 S300" in out.out and out.out.rstrip().endswith("M5 S0")
    assert "500 ->" in out.err


def test_plot_bad_input_is_one_clear_line(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    assert main(["plot", "--pattern", str(bad)]) == 2
    assert "not valid JSON" in capsys.readouterr().err
    assert main(["plot", "spirograph", "--pattern", str(bad)]) == 2
    assert "not both" in capsys.readouterr().err
    assert main(["plot"]) == 2
    assert main(["plot", "spirograph", "--size", "5000"]) == 2
    assert "does not fit" in capsys.readouterr().err
    assert main(["plot", "spirograph", "--profile", str(tmp_path / "none.toml")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_send_dry_run_frame_and_refusals(tmp_path, capsys):
    job = tmp_path / "job.gcode"
    job.write_text("G21\nG90\nG0 X10 Y10\nG1 X30 Y10 F3000\nG1 X30 Y40\nG41\nG0 X0 Y0\n")
    assert main(["send", str(job), "--port", FAST_PLOTTER, "--dry-run", "--json"]) == 1
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert result["errors"][0][0] == 6 and "error:20" in result["errors"][0][1]
    job.write_text("G21\nG90\nG0 X10 Y10\nG1 X30 Y10 F3000\nG1 X30 Y40\nG0 X0 Y0\n")
    assert main(["send", str(job), "--port", FAST_PLOTTER, "--frame", "--json"]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["frame"] is True
    assert main(["send", str(job), "--port", FAST_PLOTTER, "--from-line", "99"]) == 2
    assert "--from-line must be between 1 and 6" in capsys.readouterr().err
    assert main(["send", str(job), "--profile", "laser", "--port", FAST_PLOTTER]) == 2
    assert "laser mode is off ($32=0)" in capsys.readouterr().err
    job.write_text("G0 X900 Y10\n")
    assert main(["send", str(job), "--port", FAST_LASER]) == 2
    assert "leaves the machine's travel" in capsys.readouterr().err
    assert main(["send", str(tmp_path / "missing.gcode"), "--port", FAST_LASER]) == 2


def test_send_refuses_files_that_are_not_gcode_in_one_line(tmp_path, capsys):
    # these used to kill the job thread with a traceback and leave `station send` waiting forever
    garbage = tmp_path / "garbage.gcode"
    garbage.write_bytes(b"\x00\x01\n")
    assert main(["send", str(garbage), "--port", FAST_PLOTTER]) == 2
    err = capsys.readouterr().err
    assert "job 'garbage.gcode': line 1: cannot parse" in err and "Traceback" not in err
    binary = tmp_path / "image.gcode"
    binary.write_bytes(b"\xff\xd8\xff\xe0JFIF")
    assert main(["send", str(binary), "--port", FAST_PLOTTER]) == 2
    assert "job 'image.gcode': not a G-code text file" in capsys.readouterr().err


def test_an_unexpected_failure_in_the_job_thread_ends_the_job_safely(monkeypatch):
    from drivers.grbl import GrblConnection, Job, JobRunner

    def broken(self):
        raise RuntimeError("a bug")

    monkeypatch.setattr(JobRunner, "preflight", broken)
    with GrblConnection(FAST_LASER) as conn:
        runner = JobRunner(conn, Job.from_text("j", "G21\nM4 S500\nG1 X10 F600\n", laser=True))
        runner.start()
        result = runner.wait(20.0)
        assert not runner.running
        assert result is not None and result.state == "error" and "a bug" in result.message
        assert result.laser_off
        assert conn.port.machine.snapshot().samples[-1].power == 0


def test_ports_lists_simulated_machines(capsys):
    assert main(["ports", "--no-probe", "--json"]) == 0
    ports = json.loads(capsys.readouterr().out)
    assert {"sim://grbl?profile=plotter", "sim://grbl?profile=laser"} <= {p["url"] for p in ports}
