"""``station calibrate sim`` (through a stand-in ``station calibrate``, as the lead wires it), ``station predict``."""

from __future__ import annotations

import json
import sys
import types
from pathlib import Path

import numpy as np
import pytest

import station.cli as cli
from design.contraption import load_scenario
from design.contraption.physics_profile import load_profile
from station.services.world import synthetic_trials
from station.services.world import trials_export as export

SLIDE = Path(__file__).resolve().parents[2] / "data" / "calibration" / "slide.toml"


@pytest.fixture
def calibrate(monkeypatch):
    """``station calibrate`` with only ``sim`` (the real module belongs to another helper)."""
    from station.commands._calibrate_sim import add_sim_parser

    def register(subparsers):
        parser = subparsers.add_parser("calibrate", help="calibrate")
        add_sim_parser(parser.add_subparsers(dest="calibrate_command"))

    module = types.ModuleType("calibrate_stand_in")
    module.register = register
    monkeypatch.setitem(sys.modules, "calibrate_stand_in", module)
    names = [n for n in cli.command_modules() if not n.endswith(".calibrate")]
    monkeypatch.setattr(cli, "command_modules", lambda: [*names, "calibrate_stand_in"])
    def run(*argv) -> int:
        try:
            return cli.main(["calibrate", "sim", *map(str, argv)])
        except SystemExit as stop:  # the stand-in's own parser: argparse's refusal, one line on stderr
            return stop.code

    return run


@pytest.fixture(scope="module")
def trials_file(tmp_path_factory):
    slide = load_scenario(SLIDE)
    rng = np.random.default_rng(3)
    trials = synthetic_trials(slide, [[a] for a in rng.uniform(30, 38, 6)], {"wood.friction": 0.56}, seed=4)
    path = tmp_path_factory.mktemp("trials") / "trials.json"
    path.write_text(json.dumps(export(trials)))
    return path


def test_calibrate_sim_json_and_profile(calibrate, trials_file, tmp_path, capsys):
    out = tmp_path / "slide.toml"
    assert calibrate(SLIDE, "--trials-json", trials_file, "--draws", "2", "--workers", "1", "--out", out,
                     "--json") == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data) == {"parameters", "trials", "brier_before", "brier_after"}
    assert data["trials"] == 6 and [p["name"] for p in data["parameters"]] == ["wood.friction"]
    value = data["parameters"][0]["value"]
    lo, hi = data["parameters"][0]["interval"]
    assert 0.3 <= lo <= value <= hi <= 0.8
    profile = load_profile(out)
    assert profile.values == {"wood.friction": value} and profile.fit["trials"] == 6
    assert profile.fit["prior_width"] == 0.25
    assert profile.source == "calibrate sim: 6 trials of SLIDE"


@pytest.mark.parametrize(("argv", "message"), [
    (["--params", "wood.fricton"], "--params: 'wood.fricton' is not an uncertain material value of the scenarios; "
                                   "they have: wood.friction"),
    (["--trials", "0"], "--trials must be an integer >= 1, got 0"),
    (["--physics", "p.toml"], "--physics: calibrate sim fits the physics"),
    (["--prior-width", "-0.1"], "--prior-width: expected a number >= 0, got '-0.1'"),
])
def test_calibrate_sim_refuses_bad_input_in_one_line(calibrate, trials_file, capsys, argv, message):
    assert calibrate(SLIDE, "--trials-json", trials_file, *argv) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err


def test_calibrate_sim_bad_trial_files(calibrate, tmp_path, capsys):
    assert calibrate(SLIDE, "--trials-json", tmp_path / "none.json") == 2
    assert "--trials-json" in capsys.readouterr().err
    wrong = tmp_path / "wrong.json"
    wrong.write_text(json.dumps({"format": "chaos-station trials", "version": 9, "trials": []}))
    assert calibrate(SLIDE, "--trials-json", wrong) == 2
    assert "wrong.json: version: expected 1" in capsys.readouterr().err
    assert calibrate(SLIDE) == 2
    assert "--trials-json EXPORT.json is required" in capsys.readouterr().err


def test_predict_as_built_from_a_check(tmp_path, capsys):
    layout = tmp_path / "layout.json"
    layout.write_text(json.dumps({"parameters": {"plank.roll": 25.0}}))
    check = {"format": "chaos-station check", "version": 1, "scenario": "SLIDE", "layout": {"plank.roll": 25.0},
             "as_built": {"plank.roll": 37.0}, "residual_error": {"position_mm": 0.5, "heading_deg": 0.5}}
    (tmp_path / "CHECK.json").write_text(json.dumps(check))
    argv = ["predict", str(SLIDE), str(layout), "--samples", "8", "--workers", "1", "--json"]
    assert cli.main(argv) == 0
    designed = json.loads(capsys.readouterr().out)
    assert designed["probability"] == 0.0 and designed["expected_attempts"] is None
    assert cli.main([*argv, "--as-built", str(tmp_path / "CHECK.json")]) == 0
    built = json.loads(capsys.readouterr().out)
    assert built["as_built"] is True and built["probability"] == 1.0 and built["expected_attempts"] == 1.0
    assert built["placement_error"] == {"position_mm": 0.5, "heading_deg": 0.5, "unmeasured": []}
    # a parameter the check did not measure is placed as with no check (at least 1 degree), and is named
    (tmp_path / "CHECK.json").write_text(json.dumps({**check, "not_measured": ["plank.roll"]}))
    assert cli.main([*argv, "--as-built", str(tmp_path / "CHECK.json")]) == 0
    assert json.loads(capsys.readouterr().out)["placement_error"]["unmeasured"] == ["plank.roll"]
    (tmp_path / "CHECK.json").write_text(json.dumps({**check, "not_measured": ["plank.x"]}))
    assert cli.main([*argv, "--as-built", str(tmp_path / "CHECK.json")]) == 2
    assert "not_measured: 'plank.x' is not a design parameter (expected one of plank.roll)" in capsys.readouterr().err
    check["layout"] = {"plank.roll": 30.0}
    (tmp_path / "CHECK.json").write_text(json.dumps(check))
    assert cli.main([*argv, "--as-built", str(tmp_path / "CHECK.json")]) == 2
    assert "layout.plank.roll: a check of another layout (30.0 checked, 25.0 designed)" in capsys.readouterr().err
    check.update(scenario="BALLRUN", layout={})
    (tmp_path / "CHECK.json").write_text(json.dumps(check))
    assert cli.main([*argv, "--as-built", str(tmp_path / "CHECK.json")]) == 2
    assert "scenario: a check of scenario 'BALLRUN', not of 'SLIDE'" in capsys.readouterr().err
