"""``station simulate`` and ``station scenario check``."""

from __future__ import annotations

import json

from PIL import Image

from station.cli import main


def test_simulate_success_and_failure_exit_codes(capsys):
    assert main(["simulate", "simple", "--layout", "success"]) == 0
    out = capsys.readouterr().out
    assert "SIMPLE: SUCCESS (5/5 events" in out and "ball_hits_domino" in out
    assert main(["simulate", "simple", "--layout", "failure"]) == 1
    assert "FAILURE" in capsys.readouterr().out


def test_simulate_json_and_x(capsys):
    assert main(["simulate", "simple", "--x=-0.06,0.06,30", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["success"] is True
    assert data["events"]["last_stops"]["state"] == "success"
    assert isinstance(data["events"]["ball_rolls"]["time"], float)
    assert data["layout"] == {"track.x": -0.06, "track.z": 0.06, "track.roll": 30.0}


def test_simulate_impossible_layout_says_which_pair(capsys):
    assert main(["simulate", "simple", "--x=-0.15,0.0,15"]) == 1
    out = capsys.readouterr().out
    assert "physically impossible" in out and "floor and track interpenetrate by" in out


def test_simulate_layout_file_and_render(tmp_path, capsys):
    layout = tmp_path / "l.json"
    layout.write_text(json.dumps({"track.roll": 30}))
    out_png = tmp_path / "views.png"
    assert main(["simulate", "simple", "--layout", str(layout), "--render", str(out_png)]) == 0
    image = Image.open(out_png)
    assert image.size[0] > 800 and image.size[1] > 600
    # Not blank: the parts are drawn in colour.
    colours = image.convert("RGB").getcolors(maxcolors=100000)
    assert len(colours) > 20


def test_simulate_bad_input_exit_2(tmp_path, capsys):
    assert main(["simulate", "simple", "--x=1,2"]) == 2
    assert "expected 3 values" in capsys.readouterr().err
    assert main(["simulate", "simple", "--x=-0.06,0.06,99"]) == 2
    assert "track.roll = 99 is outside its range [15, 75]" in capsys.readouterr().err
    assert main(["simulate", str(tmp_path / "missing.toml")]) == 2
    bad = tmp_path / "bad.toml"
    bad.write_text('[[objects]]\nname = "a"\ntype = "Sphere"\n')
    assert main(["simulate", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "bad.toml: objects[0].type: expected one of" in err and "Traceback" not in err
    assert main(["simulate", "simple", "--layout", "nonsense"]) == 2
    assert main(["simulate", "simple", "--render", str(tmp_path / "x.jpg")]) == 2


def test_scenario_check_lists_parameters(capsys):
    assert main(["scenario", "check", "ballrun"]) == 0
    out = capsys.readouterr().out
    assert "valid scenario 'BALLRUN'" in out
    assert "top_track.roll" in out and "[5, 35] deg" in out
    assert "ball_in_goblet [Inclusion] after low_plank_leaves & ball_rolls_bottom" in out
    assert main(["scenario", "check", "simple", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [p["name"] for p in data["design_space"]] == ["track.x", "track.z", "track.roll"]
    assert len(data["content_hash"]) == 64


def test_scenario_check_reports_errors(tmp_path, capsys):
    bad = tmp_path / "s.json"
    bad.write_text(json.dumps({"objects": [{"name": "b", "type": "Box", "shape": {"size": [1, 1]}}], "events": []}))
    assert main(["scenario", "check", str(bad)]) == 2
    assert "s.json: objects[0].shape.size: expected an array of 3 items, got 2" in capsys.readouterr().err
