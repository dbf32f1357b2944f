"""``station jigs``: what it writes, the jigs.json contract, and bad input as one line before any work."""

from __future__ import annotations

import json
import math

import pytest
from PIL import Image

from station.cli import main


def test_jigs_writes_the_laser_files_the_manifest_and_a_picture_of_each_jig(tmp_path, capsys):
    out = tmp_path / "jigs"
    assert main(["jigs", "causalityswitch_ball", "success", "--out", str(out), "--no-tolerances"]) == 0
    printed = capsys.readouterr().out
    assert "J1 stand for `ball_track` (step 2): sets track_joint.z, track_joint.roll; tag 500" in printed
    assert "lower end against the stop" in printed
    for name in ("jigs.svg", "jigs.gcode", "jigs.json", "sheet.png", "jig-J1.png"):
        assert (out / name).is_file(), name
    data = json.loads((out / "jigs.json").read_text())
    (jig,) = data["jigs"]
    assert {"id", "part", "parameters", "tag_id", "thickness_mm", "outline_mm", "support_mm",
            "footprint_mm"} <= set(jig)
    assert jig["id"] == "J1" and jig["part"] == "ball_track" and jig["tag_id"] == 500
    assert jig["parameters"] == ["track_joint.z", "track_joint.roll"]
    assert data["material"] == "plywood_3mm" and jig["thickness_mm"] == 3.0 and data["kerf_mm"] == 0.15
    # the support: the ball track's underside, 11.5 deg (the layout's -11.4552), its lower end towards the switch
    (x0, y0), (x1, y1) = jig["support_mm"]
    assert math.degrees(math.atan2(y1 - y0, x1 - x0)) == pytest.approx(11.4552, abs=0.01)
    assert min(y for _, y in jig["outline_mm"]) == 0.0  # the plate stands on the table
    # the footprint lies on the guide's plane under the track (its middle at u = -76.8, v = 60)
    us = [u for u, _ in jig["footprint_mm"]]
    vs = [v for _, v in jig["footprint_mm"]]
    assert min(us) < -76.8 < max(us) and min(vs) < 60.0 < max(vs)
    assert "layer-engrave" in (out / "jigs.svg").read_text() and "layer-cut" in (out / "jigs.svg").read_text()
    gcode = (out / "jigs.gcode").read_text()
    assert gcode.rstrip().endswith("M5 S0") and "jigs: CAUSALITYSWITCH (ball faster)" in gcode
    assert Image.open(out / "jig-J1.png").size[0] > 400


def test_json_prints_the_manifest_it_writes(tmp_path, capsys):
    out = tmp_path / "j"
    assert main(["jigs", "simple", "success", "--out", str(out), "--json", "--kerf", "0.2",
                 "--material", "mdf_3mm", "--sheet", "300x200", "--no-tolerances"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed == json.loads((out / "jigs.json").read_text())
    assert printed["kerf_mm"] == 0.2 and printed["kerf_source"] == "given" and printed["material"] == "mdf_3mm"
    assert printed["sheet_mm"] == [300.0, 200.0]
    assert not printed["layout"]["source"].startswith("/")  # no path of this machine


@pytest.mark.parametrize("argv, words", [
    (["--material", "velvet"], "no material 'velvet'; known: acrylic_3mm_black, cardboard_2mm, mdf_3mm, plywood_3mm"),
    (["--sheet", "400"], "--sheet '400': expected WIDTHxHEIGHT in mm"),
    (["--kerf", "5"], "--kerf must be a width in mm from 0 to 2, got 5.0"),
    (["--kerf", "-1"], "--kerf"),
    (["--profile", "plotter"], "is a plotter, not a laser"),
    (["--profile", "nowhere.toml"], "nowhere.toml"),
])
def test_bad_input_is_one_line_and_writes_nothing(argv, words, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    try:
        code = main(["jigs", "simple", "success", "--out", "out", *argv])
    except SystemExit as exit_:  # argparse's own refusal (a number below 0)
        code = exit_.code
    assert code == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert words in line, line
    assert not (tmp_path / "out").exists()


def test_an_output_folder_that_is_a_file_is_refused_before_any_work(tmp_path, capsys):
    taken = tmp_path / "taken"
    taken.write_text("")
    assert main(["jigs", "simple", "success", "--out", str(taken)]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert "--out" in line and "is a file" in line


def test_a_layout_with_nothing_to_jig_says_so(tmp_path, capsys):
    # LONGCHAIN's parts stand off its board: their heights and tilts are drawn on the sheet, no plate holds them
    assert main(["jigs", "longchain", "success", "--out", str(tmp_path / "o"), "--no-tolerances"]) == 0
    printed = capsys.readouterr().out
    assert "nothing to cut" in printed and "stands 48 mm in front of the board" in printed
    assert json.loads((tmp_path / "o" / "jigs.json").read_text())["jigs"] == []
