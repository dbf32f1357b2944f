"""``station trial log|list|show|export|import`` on the local SQLite file, as a maker uses them."""

from __future__ import annotations

import csv
import json
import sqlite3

import pytest

from station.paths import database_path

from ..conftest import EXAMPLES, log_json, run_cli

SIMPLE_LAYOUT = {"track.x": -0.06, "track.z": 0.06, "track.roll": 30.0}  # simple.toml's "success" layout

PROFILE = """\
[profile]
format = "chaos-station physics"
version = 1
name = "wood-fit-1"
created = "2026-12-03T10:00:00Z"
source = "calibrate sim: 12 trials of SIMPLE"
[values]
"wood.friction" = 0.42
"""


def check_json(tmp_path, *, content_hash=None, layout=None, as_built=None, version=1, name="check.json"):
    """A CHECK.json as the as-built check writes it (CONTRACT19), for SIMPLE's success layout."""
    from station.services.trials import load_trial_scenario

    scenario = load_trial_scenario("simple")
    layout = dict(SIMPLE_LAYOUT if layout is None else layout)
    data = {"format": "chaos-station check", "version": version, "scenario": scenario.name,
            "content_hash": content_hash or scenario.content_hash, "layout": layout, "view": "top",
            "plane": {"residual_mm": 0.4, "reference_ids": [0, 1, 2, 3], "moved_mm": None},
            "parts": [{"name": "track", "tag_id": 7, "found": True,
                       "measured": {"center_mm": [-58.2, 0.5], "heading_deg": 0.3},
                       "error": {"du_mm": 1.8, "dv_mm": 0.5, "distance_mm": 1.87, "heading_deg": 0.3},
                       "within_tolerance": True, "instruction": "ok", "cost": 0.1}],
            "missing_tags": [], "unknown_tags": [], "duplicate_tags": [], "by_eye": ["dominoes"],
            "as_built": as_built or {**layout, "track.x": layout["track.x"] + 0.0018},
            "not_measured": ["track.z", "track.roll"],
            "residual_error": {"position_mm": 0.7, "heading_deg": 0.4},
            "predicted_success_as_built": 0.91, "predicted_success_as_designed": 0.95, "prediction_note": None,
            "simulated_success_as_built": None}
    path = tmp_path / name
    path.write_text(json.dumps(data))
    return path, data


def test_log_list_show_with_check_physics_times_and_photos(tmp_path, capsys):
    check, data = check_json(tmp_path)
    profile = tmp_path / "fit.toml"
    profile.write_text(PROFILE)
    photo = tmp_path / "run1.jpg"
    photo.write_bytes(b"\xff\xd8 not really a jpeg")
    first = log_json(capsys, "simple", "success", "--outcome", "last_stops=yes", "--time", "ball_rolls=0.0",
                     "--time", "last_stops=2.25", "--as-built", str(check), "--physics", str(profile),
                     "--who", "ann", "--notes", "third try, new felt", "--photo", str(photo))
    code, out, _ = run_cli(capsys, "trial", "log", str(EXAMPLES / "simple.toml"), "failure",
                           "--outcome", "ball_hits_domino=no", "--predict", "0")
    assert code == 0 and int(out) == first + 1

    code, out, _ = run_cli(capsys, "trial", "show", str(first), "--json")
    trial = json.loads(out)
    assert trial["id"] == first and len(trial["uid"]) == 32
    assert trial["scenario"]["name"] == "SIMPLE"
    assert trial["scenario"]["content"] == (EXAMPLES / "simple.toml").read_text(encoding="utf-8")
    assert trial["layout"] == SIMPLE_LAYOUT
    assert trial["as_built"] == data["as_built"] and trial["check"] == data
    assert trial["physics"] == {"name": "wood-fit-1", "content": PROFILE}
    assert list(trial["outcomes"]) == ["ball_rolls", "ball_hits_domino", "first_topples", "last_topples",
                                       "last_stops"]
    assert set(trial["outcomes"].values()) == {"yes"} and trial["success"] is True
    assert trial["times"] == {"ball_rolls": 0.0, "last_stops": 2.25}
    assert trial["who"] == "ann" and trial["notes"] == "third try, new felt"
    assert trial["photos"] == [str(photo.resolve())]
    assert trial["created_at"].endswith("Z")

    code, out, _ = run_cli(capsys, "trial", "list", "--json")
    listed = json.loads(out)
    assert [t["id"] for t in listed] == [first, first + 1]
    assert listed[1]["success"] is False and listed[1]["check"] is None
    assert listed[1]["outcomes"]["first_topples"] == "not-reached"

    code, out, _ = run_cli(capsys, "trial", "list")
    lines = out.splitlines()
    assert len(lines) == 2
    assert "SIMPLE  success  5/5 events  as built (check)  physics wood-fit-1  ann" in lines[0]
    assert "SIMPLE  failure  1/5 events  as designed" in lines[1]
    assert run_cli(capsys, "trial", "list", "--scenario", "ballrun", "--json")[1].strip() == "[]"
    code, out, _ = run_cli(capsys, "trial", "show", str(first))
    assert "last_stops        yes  at 2.250 s" in out and "track.x = -0.06  as built -0.0582 (+0.0018)" in out


def test_export_import_round_trip_and_duplicates_refused(tmp_path, capsys, monkeypatch):
    log_json(capsys, "simple", "success", "--outcome", "last_stops=yes", "--time", "last_stops=2.1",
             "--who", "bo")
    log_json(capsys, "ballrun", "failure", "--outcome", "ball_hits_plank=no", "--notes", "ramp wobbled")
    out = tmp_path / "trials.json"
    assert run_cli(capsys, "trial", "export", "--out", str(out))[0] == 0
    exported = json.loads(out.read_text())
    assert exported["format"] == "chaos-station trials" and exported["version"] == 1
    assert [t["scenario"]["name"] for t in exported["trials"]] == ["SIMPLE", "BALLRUN"]

    # another station (another data folder) imports it: the same trials, new ids, nothing lost
    monkeypatch.setenv("CHAOS_STATION_HOME", str(tmp_path / "other"))
    code, text, _ = run_cli(capsys, "trial", "import", str(out), "--json")
    assert code == 0 and json.loads(text) == {"added": [1, 2], "duplicates": []}
    again = tmp_path / "again.json"
    run_cli(capsys, "trial", "export", "--out", str(again))
    assert json.loads(again.read_text()) == exported
    # the same file again: every trial refused by its uid, none added twice
    code, text, _ = run_cli(capsys, "trial", "import", str(out))
    assert code == 0 and "0 trial(s) added" in text and "2 refused: already in the log" in text
    connection = sqlite3.connect(database_path())
    assert connection.execute("SELECT count(*) FROM trials").fetchone() == (2,)
    assert connection.execute("SELECT count(*) FROM scenarios").fetchone() == (2,)
    assert connection.execute("PRAGMA journal_mode").fetchone() == ("wal",)
    connection.close()


def test_csv_export_one_row_per_trial(tmp_path, capsys):
    log_json(capsys, "simple", "success", "--outcome", "last_stops=yes", "--time", "last_stops=2.5",
             "--notes", "comma, and \"quotes\"")
    log_json(capsys, "ballrun", "failure", "--outcome", "ball_hits_plank=no")
    out = tmp_path / "trials.csv"
    code, text, _ = run_cli(capsys, "trial", "export", "--out", str(out))
    assert code == 0 and "2 trial(s) written" in text
    with open(out, newline="", encoding="utf-8") as stream:
        rows = list(csv.DictReader(stream))
    assert [r["scenario"] for r in rows] == ["SIMPLE", "BALLRUN"]
    assert rows[0]["success"] == "yes" and rows[0]["outcome:last_stops"] == "yes"
    assert float(rows[0]["time:last_stops"]) == 2.5 and rows[0]["notes"] == 'comma, and "quotes"'
    assert float(rows[0]["layout:track.roll"]) == 30.0
    assert rows[1]["outcome:ball_hits_plank"] == "no" and rows[1]["outcome:last_stops"] == ""
    assert rows[1]["outcome:ball_stops"] == "not-reached" and rows[0]["outcome:ball_stops"] == ""


def _refused(capsys, *argv: str) -> str:
    code, out, err = run_cli(capsys, *argv)
    assert code == 2 and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    return lines[0]


def test_a_logged_trial_says_its_physical_success_and_the_attempts_to_expect(capsys):
    code, out, err = run_cli(capsys, "trial", "log", "simple", "success", "--outcome", "last_stops=yes",
                             "--predict", "4", "--json")
    assert code == 0, err
    data = json.loads(out)
    physical = data["physical_success"]
    assert physical["samples"] == 4 and 0.0 <= physical["probability"] <= 1.0
    assert physical["interval"][0] <= physical["probability"] <= physical["interval"][1]
    code, out, err = run_cli(capsys, "trial", "log", "simple", "success", "--outcome", "last_stops=yes",
                             "--predict", "4")
    assert code == 0 and int(out) == data["id"] + 1
    assert f"trial {data['id'] + 1}: physical success" in err and "attempts" in err


def test_bad_input_is_refused_in_one_line_naming_the_field(tmp_path, capsys):
    log = ("trial", "log", "simple", "success")
    assert "--outcome ball_bounces: unknown event; the scenario SIMPLE has" in _refused(
        capsys, *log, "--outcome", "ball_bounces=yes")
    assert "--outcome last_stops: given twice" in _refused(
        capsys, *log, "--outcome", "last_stops=yes", "--outcome", "last_stops=no")
    assert "--outcome last_stops: expected yes, no or not-reached, got 'ja'" in _refused(
        capsys, *log, "--outcome", "last_stops=ja")
    assert "--outcome ball_hits_domino: missing" in _refused(capsys, *log, "--outcome", "ball_rolls=yes")
    other_scenario, _ = check_json(tmp_path, content_hash="0" * 64, name="other.json")
    line = _refused(capsys, *log, "--outcome", "last_stops=yes", "--as-built", str(other_scenario))
    assert line.startswith("station: error: --as-built: ") and "content_hash: a check of another scenario" in line
    other_layout, _ = check_json(tmp_path, layout={**SIMPLE_LAYOUT, "track.roll": 45.0}, name="moved.json")
    line = _refused(capsys, *log, "--outcome", "last_stops=yes", "--as-built", str(other_layout))
    assert "layout.track.roll: a check of another layout (45.0 checked, 30.0 designed)" in line
    newer, _ = check_json(tmp_path, version=2, name="v2.json")
    assert "version: expected 1, got 2" in _refused(
        capsys, *log, "--outcome", "last_stops=yes", "--as-built", str(newer))
    bad_profile = tmp_path / "p.toml"
    bad_profile.write_text(PROFILE.replace("version = 1", "version = 3"))
    assert "--physics: " in _refused(capsys, *log, "--outcome", "last_stops=yes", "--physics", str(bad_profile))
    assert "--photo: " in _refused(capsys, *log, "--outcome", "last_stops=yes", "--photo", "nope.jpg")
    assert "no trial 99" in _refused(capsys, "trial", "show", "99")
    assert "--out: " in _refused(capsys, "trial", "export", "--out", str(tmp_path / "t.xlsx"))
    # nothing above was logged
    assert run_cli(capsys, "trial", "list", "--json")[1].strip() == "[]"


@pytest.mark.parametrize(("change", "field"), [
    (lambda d: d.update(version=2), "version: expected 1 (this station reads version 1), got 2"),
    (lambda d: d.update(format="chaos-station check"), "format: expected 'chaos-station trials'"),
    (lambda d: d["trials"][0].update(uid="xyz"), "trials[0].uid: expected a uuid4 as 32 lower-case hex digits"),
    (lambda d: d["trials"][0]["outcomes"].update(ball_rolls="maybe"), "trials[0].outcomes.ball_rolls: expected"),
    (lambda d: d["trials"][0]["outcomes"].pop("last_stops"), "trials[0].outcomes.last_stops: missing"),
    (lambda d: d["trials"][0].update(success=False), "trials[0].success: expected True"),
    (lambda d: d["trials"][0]["scenario"].update(content_hash="ab" * 32),
     "trials[0].scenario.content_hash: expected the content's hash"),
    (lambda d: d["trials"][0]["layout"].pop("track.x"), "trials[0].layout: expected the scenario's parameters"),
    (lambda d: d["trials"].append(dict(d["trials"][0])), "trials[1].uid: the same as trials[0].uid"),
])
def test_import_refuses_a_bad_file_in_one_line_and_adds_nothing(tmp_path, capsys, change, field):
    log_json(capsys, "simple", "success", "--outcome", "last_stops=yes")
    out = tmp_path / "t.json"
    run_cli(capsys, "trial", "export", "--out", str(out))
    data = json.loads(out.read_text())
    data["trials"][0]["uid"] = "f" * 32  # not a duplicate of the trial in the log
    change(data)
    out.write_text(json.dumps(data))
    line = _refused(capsys, "trial", "import", str(out))
    assert f"{out}: {field}" in line
    assert len(json.loads(run_cli(capsys, "trial", "list", "--json")[1])) == 1


def test_the_check_of_an_optimized_layout_feeds_the_trial_log(tmp_path, capsys):
    # The optimizer writes LAYOUT.json at full precision, CHECK.json writes the layout to six decimals: the check
    # of that very layout is accepted by the trial log and by the prediction.
    layout, check = str(tmp_path / "layout.json"), str(tmp_path / "check.json")
    code, _, err = run_cli(capsys, "optimize", "simple", "--budget", "20", "--seed", "1", "--out", layout)
    assert code == 0, err
    values = {p["name"]: p["value"] for p in json.loads((tmp_path / "layout.json").read_text())["parameters"]}
    assert any(round(v, 6) != v for v in values.values())  # the case at hand: values a rounding changes
    code, _, err = run_cli(capsys, "check", "simple", layout, "--camera", "sim://camera", "--sim-offset",
                           "track=2,-1", "--predict", "0", "--out", check)
    assert code == 0, err
    code, out, err = run_cli(capsys, "trial", "log", "simple", layout, "--as-built", check,
                             "--outcome", "last_stops=yes", "--predict", "0", "--json")
    assert code == 0, err
    code, out, err = run_cli(capsys, "trial", "show", str(json.loads(out)["id"]), "--json")
    built = json.loads(out)["as_built"]
    assert abs(built["track.x"] - (values["track.x"] + 0.002)) < 0.0005  # the check's measurement, not the design
    code, _, err = run_cli(capsys, "predict", "simple", layout, "--as-built", check, "--samples", "2")
    assert code == 0, err
