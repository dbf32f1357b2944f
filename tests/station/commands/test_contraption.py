"""``station simulate`` and ``station scenario check``."""

from __future__ import annotations

import json

import pytest
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


def test_optimize_output_feeds_simulate_and_robustness(tmp_path, capsys):
    # `station simulate --layout` refused what `station optimize --out` wrote ("format: unknown design parameter").
    layout = tmp_path / "layout.json"
    assert main(["optimize", "simple", "--budget", "20", "--workers", "1", "--out", str(layout)]) in (0, 1)
    written = {p["name"]: p["value"] for p in json.loads(layout.read_text())["parameters"]}
    capsys.readouterr()
    code = main(["simulate", "simple", "--layout", str(layout), "--json"])
    assert code in (0, 1)
    data = json.loads(capsys.readouterr().out)
    assert data["layout"] == pytest.approx(written, abs=1e-12)
    assert data["layout_source"]["format"] == "LAYOUT.json" and data["layout_source"]["defaulted"] == []
    # The same values in the two hand-written forms simulate to the same outcome.
    names = list(written)
    forms = {"x.json": {"x": [written[n] for n in names]}, "p.json": {"parameters": written}}
    for name, content in forms.items():
        (tmp_path / name).write_text(json.dumps(content))
        assert main(["simulate", "simple", "--layout", str(tmp_path / name), "--json"]) == code
        again = json.loads(capsys.readouterr().out)
        assert again["layout"] == data["layout"] and again["events"] == data["events"]
    # The text output says which layout was used.
    main(["simulate", "simple", "--layout", str(layout)])
    assert f"layout: {layout} (the optimizer's LAYOUT.json)" in capsys.readouterr().out


def test_simulate_says_which_layout_and_what_was_defaulted(tmp_path, capsys):
    assert main(["simulate", "simple"]) == 0
    assert "layout: the scenario's defaults" in capsys.readouterr().out
    minimal = tmp_path / "m.json"
    minimal.write_text(json.dumps({"parameters": {"track.roll": 40}}))
    main(["simulate", "simple", "--layout", str(minimal)])
    out = capsys.readouterr().out
    assert f"layout: {minimal} (" in out
    assert "defaulted to the scenario's values: track.x, track.z" in out
    assert main(["simulate", "simple", "--layout", "success"]) == 0
    assert "layout: 'success' (named in " in capsys.readouterr().out


def test_robustness_reads_every_layout_form(tmp_path, capsys):
    # `station robustness` took only a LAYOUT.json: a hand-written {"parameters": {...}} was "not a list".
    minimal = tmp_path / "m.json"
    minimal.write_text(json.dumps({"parameters": {"track.roll": 30}}))
    common = ["--eval", "8", "--local", "4", "--workers", "1", "--json"]
    assert main(["robustness", "simple", str(minimal), *common]) == 0
    captured = capsys.readouterr()
    assert 0 <= json.loads(captured.out)["rho_g"] <= 1
    assert f"layout: {minimal} (" in captured.err and "defaulted to the scenario's values: track.x, track.z" in \
        captured.err
    assert main(["robustness", "simple", "success", *common]) == 0
    assert "layout: 'success' (named in " in capsys.readouterr().err


def test_unknown_scenario_name_lists_the_examples(capsys):
    # It said "nosuch: expected a .toml or .json scenario file, got 'no suffix'".
    for command in (["simulate", "nosuch"], ["scenario", "check", "balrun"], ["robustness", "nosuch", "x.json"]):
        assert main(command) == 2
        err = capsys.readouterr().err
        assert "no suffix" not in err
        assert "no such file and no example of that name" in err, err
        assert "ballrun, branching, causalityswitch_ball" in err and len(err.strip().splitlines()) == 1


def test_render_path_is_checked_before_simulating(tmp_path, capsys, monkeypatch):
    # `simulate --render /nonexistent_dir/x.png` simulated first, then refused the path.
    from design.contraption import Simulator

    def no_simulation(*args, **kwargs):
        raise AssertionError("simulated before checking the output path")

    monkeypatch.setattr(Simulator, "run", no_simulation)
    monkeypatch.setattr(Simulator, "check_validity", no_simulation)
    (tmp_path / "folder.png").mkdir()
    refused = {
        str(tmp_path / "nonexistent_dir" / "x.png"): "does not exist",
        str(tmp_path / "folder.png"): "is a folder",
        str(tmp_path / "x.jpg"): "expected one of .png",
    }
    for path, words in refused.items():
        assert main(["simulate", "simple", "--render", path]) == 2
        err = capsys.readouterr().err
        assert words in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "nonexistent_dir").exists()
