"""``station guide``: the manifest (--json), the projector (--project), and bad input as one line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from station.cli import main

LAYOUT = Path(__file__).resolve().parents[2] / "data" / "robust" / "simple-layout-with-model.json"


def test_json_is_the_manifest_with_layout_steps_and_model_tolerances(capsys):
    assert main(["guide", "simple", str(LAYOUT), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["scenario"] == "SIMPLE" and data["view"] == "top" and data["units"] == "mm"
    assert data["tolerance_source"] == "model"
    assert [part["name"] for part in data["parts"]][-1] == "ball"
    assert [tag["id"] for tag in data["reference_tags"]] == [583, 584, 585, 586]
    assert len(data["steps"]) == len(data["parts"]) and data["steps"][0].startswith("1. ")
    assert data["layout"]["format"] == "LAYOUT.json"
    track = next(part for part in data["parts"] if part["name"] == "track")
    assert {t["parameter"] for t in track["tolerances"]} == {"track.x", "track.z", "track.roll"}
    assert all(t["delta"] is not None and t["delta"] > 0 for t in track["tolerances"])


def test_project_shows_a_step_on_the_simulated_projector(capsys):
    assert main(["guide", "ballrun", "success", "--project", "--step", "3", "--no-tolerances"]) == 0
    out = capsys.readouterr().out
    assert "projected step 3 of 8 on projector (sim://projector?name=projector)" in out and "NOT at true scale" in out


@pytest.mark.parametrize("argv, words", [
    (["guide", "simple", "success"], "nothing to write: give --pdf"),
    (["guide", "simple", "success", "--json", "--step", "2"], "--step goes with --project"),
    (["guide", "simple", "success", "--json", "--view", "front"], "--view must be one of top, side, got 'front'"),
    (["guide", "simple", "success", "--json", "--verify", "-1"], "--verify must be an integer >= 0"),
    (["guide", "simple", "success", "--pdf", "x.pdf", "--paper", "a5"], "--paper must be one of a4, letter, a3"),
    (["guide", "simple", "success", "--pdf", "x.txt"], "expected one of .pdf"),
    (["guide", "simple", "success", "--project", "--step", "9", "--no-tolerances"], "--step must be from 1 to 3"),
    (["guide", "simple", "nowhere.json", "--json"], "nowhere.json"),
])
def test_bad_input_is_one_line(argv, words, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert words in line, line
