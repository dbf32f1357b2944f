"""``station machines`` and ``station pattern``: JSON round trip, output files, bad input (exit 2, one line)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from design.machines import get_machine, machine_names
from station import cli

BUILTINS = ["spirograph", "elliptic_spirograph", "cycloid_drawing_machine", "hoot_nanny"]


def run(capsys, *argv):
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_machines_json_lists_machines_and_parameters(capsys):
    code, out, err = run(capsys, "machines", "--json")
    assert code == 0 and err == ""
    listed = {m["name"]: m for m in json.loads(out)["machines"]}
    assert list(listed)[:4] == BUILTINS
    assert set(listed) == set(machine_names())
    hoot = listed["hoot_nanny"]
    assert [p["name"] for p in hoot["parameters"]] == ["r_t", "r_g1", "r_g2", "theta_12", "r_p1", "r_p2", "l1", "l2"]
    r_t = hoot["parameters"][0]
    assert r_t["kind"] == "discrete" and r_t["lower"] == 1 and r_t["upper"] == 29 and r_t["default"] == 10
    assert {c["name"] for c in hoot["constraints"]} >= {"arm1_long_enough", "pen_on_turntable", "arms_reach"}


def test_machines_text(capsys):
    code, out, _ = run(capsys, "machines")
    assert code == 0
    for name in BUILTINS:
        assert name in out
    assert "theta_12" in out and "discrete" in out and "continuous" in out


@pytest.mark.parametrize("name", BUILTINS)
def test_pattern_json_round_trip(capsys, name):
    model = get_machine(name)
    gear = model.discrete_names[0]
    params = model.defaults()
    code, out, err = run(capsys, "pattern", name, "--points", "500", "--spacing", "time", "--json")
    assert code == 0 and err == ""
    document = json.loads(out)
    assert document["machine"] == name
    assert document["params"] == params
    assert isinstance(document["params"][gear], int)
    assert document["period"] == pytest.approx(model.period(params))
    points = np.array(document["points"])
    assert points.shape == (500, 2)
    assert points[0].tolist() == points[-1].tolist()
    np.testing.assert_allclose(points, model.sample(params, 500, "time"), atol=1e-12)


def test_pattern_set_overrides_and_coerces_gear_radii(capsys):
    code, out, _ = run(
        capsys, "pattern", "spirograph", "--set", "r_f=7", "--set", "r_r=2.0", "--set", "d=1.25", "--json"
    )
    assert code == 0
    document = json.loads(out)
    assert document["params"] == {"r_f": 7, "r_r": 2, "d": 1.25}
    assert document["period"] == pytest.approx(4 * np.pi)
    assert len(document["points"]) == 2048


def test_pattern_writes_svg_png_and_json(capsys, tmp_path):
    svg, png, doc = tmp_path / "p.svg", tmp_path / "p.png", tmp_path / "p.json"
    assert run(capsys, "pattern", "hoot_nanny", "--out", str(svg), "--mechanism", "0.5")[0] == 0
    assert run(capsys, "pattern", "hoot_nanny", "--out", str(png), "--size", "200")[0] == 0
    code, out, _ = run(capsys, "pattern", "hoot_nanny", "--out", str(doc), "--json")
    assert code == 0
    assert json.loads(doc.read_text()) == json.loads(out)
    text = svg.read_text()
    assert text.startswith("<?xml") and "<polyline" in text and text.count("<polyline") > 5  # pattern + parts
    image = Image.open(png)
    assert image.size == (200, 200)
    pixels = np.asarray(image.convert("L"))
    assert 0.005 < (pixels < 128).mean() < 0.5  # something is drawn, not everything
    assert len(np.unique(pixels)) > 10  # antialiased


@pytest.mark.parametrize(
    "argv, message",
    [
        (["pattern", "harmonograph"], "parameter 'machine' must be one of spirograph"),
        (["pattern", "spirograph", "--set", "bogus=1"], "spirograph: parameter 'bogus' must be one of r_f, r_r, d"),
        (["pattern", "spirograph", "--set", "r_f=5.5"], "parameter 'r_f' must be an integer gear radius"),
        (["pattern", "spirograph", "--set", "r_f=99"], "parameter 'r_f' must be an integer gear radius in [2, 29]"),
        (["pattern", "spirograph", "--set", "d=4"], "pen_inside_gear"),
        (["pattern", "hoot_nanny", "--set", "l1=5"], "l1 must exceed r_g1 + r_p1 = 5.8, got 5"),
        (["pattern", "spirograph", "--set", "d"], "expected NAME=VALUE"),
        (["pattern", "spirograph", "--points", "2"], "--points must be an integer in [3,"),
        (["pattern", "spirograph", "--out", "x.txt"], "expected one of .json, .png, .svg"),
    ],
)
def test_bad_input_exits_2_with_one_line(capsys, argv, message):
    code, out, err = run(capsys, *argv)
    assert code == 2
    assert out == ""
    assert err.count("\n") == 1 and err.startswith("station: error: ")
    assert message in err


def test_design_file_round_trip_and_set_wins(capsys, tmp_path):
    first = tmp_path / "first.json"
    assert run(capsys, "pattern", "hoot_nanny", "--set", "l1=13", "--out", str(first))[0] == 0
    code, out, _ = run(capsys, "pattern", "hoot_nanny", "--design", str(first), "--set", "l2=7.5", "--json")
    assert code == 0
    params = json.loads(out)["params"]
    assert params["l1"] == 13 and params["l2"] == 7.5
    flat = tmp_path / "flat.json"
    flat.write_text(json.dumps({"r_f": 7, "r_r": 2}))
    code, out, _ = run(capsys, "pattern", "spirograph", "--design", str(flat), "--json")
    assert json.loads(out)["params"] == {"r_f": 7, "r_r": 2, "d": 2.0}


def test_example_designs_are_feasible(capsys):
    from pathlib import Path

    examples = sorted((Path(__file__).parents[3] / "examples" / "patterns").glob("*.json"))
    assert len(examples) >= 4
    for path in examples:
        machine = json.loads(path.read_text())["machine"]
        code, out, err = run(capsys, "pattern", machine, "--design", str(path), "--points", "64", "--json")
        assert code == 0, err


@pytest.mark.parametrize(
    "content, message",
    [
        ("{not json", "not valid JSON"),
        ("[1, 2]", "expected a list of designs with one for 'spirograph', found machines []"),
        ("3", "expected a JSON object, got int"),
        ('{"machine": "hoot_nanny", "params": {}}', "field 'machine' is 'hoot_nanny', but the command draws"),
        ('{"params": [1]}', "field 'params' must be an object"),
        ('{"params": {"d": "x"}}', "parameter 'd' must be a finite real number"),
    ],
    ids=["not-json", "a-list", "a-number", "another-machine", "params-not-an-object", "parameter-not-a-number"],
)
def test_bad_design_file_exits_2_naming_the_file(capsys, tmp_path, content, message):
    path = tmp_path / "bad.json"
    path.write_text(content)
    code, out, err = run(capsys, "pattern", "spirograph", "--design", str(path))
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and message in err


def test_missing_design_file_exits_2(capsys, tmp_path):
    code, _, err = run(capsys, "pattern", "spirograph", "--design", str(tmp_path / "nope.json"))
    assert code == 2 and "nope.json" in err and err.count("\n") == 1
