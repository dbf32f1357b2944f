"""Adversarial input to the trial log, as a maker or another station's file may give it: an id SQLite cannot hold,
notes a spreadsheet would run, names that rewrite a terminal line, a CHECK.json that is not what a check writes, an
event time past the scenario's duration, outputs that cannot be written. Each is one line naming the field (exit 2)
or is written harmlessly; never a traceback, never a file name the maker did not give."""

from __future__ import annotations

import csv
import json

import pytest

from station.services.trials import build_trial, layout_values, load_trial_scenario
from station.triallog import TrialStore

from ..conftest import log_json, run_cli

SIMPLE_LAYOUT = {"track.x": -0.06, "track.z": 0.06, "track.roll": 30.0}  # simple.toml's "success" layout
FORMULA = '=HYPERLINK("http://x","y")'
BIDI = "ann\u202eslin\u2066"  # a right-to-left override and an isolate: `trial list` would show "ann" + reversed text


def _refused(capsys, *argv: str) -> str:
    code, out, err = run_cli(capsys, *argv)
    assert code == 2 and out == "", err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def _check(tmp_path, name: str = "check.json", **changes) -> str:
    """A CHECK.json of SIMPLE's success layout as `station check --out` writes it, with ``changes``."""
    scenario = load_trial_scenario("simple")
    data = {"format": "chaos-station check", "version": 1, "scenario": scenario.name,
            "content_hash": scenario.content_hash, "layout": SIMPLE_LAYOUT, "view": "top",
            "plane": {"residual_mm": 0.4, "reference_ids": [0, 1, 2, 3], "moved_mm": None},
            "parts": [{"name": "track", "tag_id": 7, "found": True,
                       "measured": {"center_mm": [-58.2, 0.5], "heading_deg": 0.3},
                       "error": {"du_mm": 1.8, "dv_mm": 0.5, "distance_mm": 1.87, "heading_deg": 0.3},
                       "within_tolerance": True, "instruction": "ok", "cost": 0.1}],
            "missing_tags": [], "unknown_tags": [], "duplicate_tags": [], "by_eye": ["dominoes"],
            "as_built": {**SIMPLE_LAYOUT, "track.x": -0.0582}, "as_measured": {"track.x": -0.0582},
            "not_measured": ["track.z", "track.roll"], "residual_error": {"position_mm": 0.7, "heading_deg": 0.4},
            "predicted_success_as_built": None, "predicted_success_as_designed": None, "prediction_note": None,
            "simulated_success_as_built": None, "not_simulated": []}
    data.update(changes)
    path = tmp_path / name
    path.write_text(json.dumps(data))
    return str(path)


def test_an_id_sqlite_cannot_hold_is_one_line(capsys):
    log_json(capsys, "simple", "success", "--outcome", "last_stops=yes")
    for given in ("99999999999999999999999", str(2**63), "0"):
        line = _refused(capsys, "trial", "show", given)
        assert line == ("station: error: ID: expected a trial id, a whole number from 1 to 9223372036854775807, "
                        f"got {given}")
    assert "no trial 2 in the log" in _refused(capsys, "trial", "show", "2")  # in range, not there
    assert run_cli(capsys, "trial", "show", "1")[0] == 0


def test_the_csv_export_never_holds_a_live_formula_and_numbers_stay_numbers(tmp_path, capsys):
    log_json(capsys, "simple", "success", "--outcome", "last_stops=yes", "--notes", FORMULA, "--who", "@ann")
    # notes also arrive through `trial import`: another station's export, edited by hand
    exported = tmp_path / "t.json"
    assert run_cli(capsys, "trial", "export", "--out", str(exported))[0] == 0
    data = json.loads(exported.read_text())
    formulas = ["+cmd|' /C calc'!A0", "-2+3", "\ufe6b=1", "\uff1dSUM(A1)", "-0.5"]
    for i, note in enumerate(formulas):
        data["trials"].append({**data["trials"][0], "uid": f"{i + 1:032x}", "notes": note})
    data["trials"][-1]["photos"] = ["\t=cmd.jpg", " @x.jpg"]  # a photo's path is any text
    exported.write_text(json.dumps(data))
    assert run_cli(capsys, "trial", "import", str(exported))[0] == 0
    out = tmp_path / "t.csv"
    assert run_cli(capsys, "trial", "export", "--out", str(out))[0] == 0
    with open(out, newline="", encoding="utf-8") as stream:
        rows = list(csv.DictReader(stream))
    notes = [row["notes"] for row in rows]
    # OWASP: a cell that could start a formula gets a leading ' (shown as text); every other cell is as it was
    assert notes == [f"'{FORMULA}", "'+cmd|' /C calc'!A0", "'-2+3", "\ufe6b=1", "'\uff1dSUM(A1)", "-0.5"]
    assert rows[0]["who"] == "'@ann" and rows[-1]["photos"] == "'\t=cmd.jpg; @x.jpg"
    # negative numbers stay numbers (the designed layout's track.x is -0.06); every cell is quoted, so a reader that
    # splits on ';' keeps a note "a;=1" whole
    assert {row["layout:track.x"] for row in rows} == {"-0.06"}
    assert all(line.startswith('"') and line.endswith('"') for line in out.read_text().splitlines())
    # the JSON export keeps the text as given: it is data, read back by import
    assert run_cli(capsys, "trial", "export", "--out", str(exported))[0] == 0
    assert json.loads(exported.read_text())["trials"][0]["notes"] == FORMULA


def test_control_and_bidirectional_characters_are_refused_on_input_and_escaped_on_output(tmp_path, capsys):
    log = ("trial", "log", "simple", "success", "--outcome", "last_stops=yes", "--predict", "0")
    line = _refused(capsys, *log, "--who", BIDI)
    assert line == ("station: error: --who: expected plain text, got a control or bidirectional character (\\u202e) "
                    "in 'ann\\u202eslin\\u2066'")
    assert "--who: expected plain text" in _refused(capsys, *log, "--who", "ann\x1b[2J")
    assert "--notes: expected plain text (new lines and tabs allowed)" in _refused(
        capsys, *log, "--notes", "ok\u2067then")
    log_json(capsys, "simple", "success", "--outcome", "last_stops=yes", "--notes", "line one\nline two\tend")
    # an export from elsewhere with such a name is refused by import, naming the field
    exported = tmp_path / "t.json"
    run_cli(capsys, "trial", "export", "--out", str(exported))
    data = json.loads(exported.read_text())
    data["trials"][0].update(uid="e" * 32, who=BIDI)
    exported.write_text(json.dumps(data))
    assert f"{exported}: trials[0].who: expected plain text" in _refused(capsys, "trial", "import", str(exported))
    # a log written by other means (an older station, the Python API) is shown escaped, never raw
    scenario = load_trial_scenario("simple")
    record = build_trial(scenario, layout_values(scenario, scenario.layout("success")), {"last_stops": "yes"})
    with TrialStore() as store:
        store.add({**record, "who": BIDI, "notes": "\x1b[31mred\x1b[0m"})
    code, out, _ = run_cli(capsys, "trial", "list")
    assert code == 0 and "\u202e" not in out and "\u2066" not in out
    assert out.splitlines()[-1].endswith("  ann\\u202eslin\\u2066")
    code, out, _ = run_cli(capsys, "trial", "show", "2")
    assert code == 0 and "\x1b" not in out and "  notes: \\x1b[31mred\\x1b[0m" in out.splitlines()
    code, out, _ = run_cli(capsys, "trial", "show", "1")
    assert "  notes: line one\\nline two\\tend" in out.splitlines()
    code, out, _ = run_cli(capsys, "trial", "show", "2", "--json")  # JSON is data: kept as stored, escaped by JSON
    assert json.loads(out)["who"] == BIDI and "\u202e" not in out


@pytest.mark.parametrize(("changes", "field"), [
    ({"scenario": "BALLRUN"}, "scenario: a check of scenario 'BALLRUN', not of 'SIMPLE'"),
    ({"residual_error": "big"}, 'residual_error: expected {"position_mm": a number >= 0, "heading_deg": a number '
                                '>= 0}, got \'big\''),
    ({"residual_error": {"bogus": -1}}, "residual_error.bogus: unknown field; expected position_mm, heading_deg"),
    ({"residual_error": {"position_mm": -1, "heading_deg": 0.4}},
     "residual_error.position_mm: expected a number >= 0, got -1"),
    ({"residual_error": {"position_mm": 0.7}}, "residual_error.heading_deg: expected a number >= 0, got None"),
    ({"parts": {"a": 1}}, "parts: expected a list of checked parts ({name, tag_id, found, measured, error, "
                          "within_tolerance, instruction, cost}), got {'a': 1}"),
    ({"parts": [{"name": "track"}]}, "parts[0].tag_id: missing; expected a tag id (a whole number)"),
    ({"as_built": {**SIMPLE_LAYOUT, "ramp.x": 0.1}}, "as_built.ramp.x: not a design parameter of SIMPLE"),
    ({"as_built": {"track.x": 0.1}, "as_measured": {}}, "as_built.track.z: expected a number, got None"),
    ({"as_measured": {"track.x": "far"}}, "as_measured.track.x: expected a number, got 'far'"),
    ({"not_measured": "track.z"}, "not_measured: expected a list of design parameter names"),
    ({"version": True}, "version: expected 1, got True"),
    ({"layout": {**SIMPLE_LAYOUT, "track.roll": 45.0}},
     "layout.track.roll: a check of another layout (45.0 checked, 30.0 designed)"),
])
def test_trial_log_and_predict_refuse_the_same_check_naming_the_field(tmp_path, capsys, changes, field):
    check = _check(tmp_path, **changes)
    line = _refused(capsys, "trial", "log", "simple", "success", "--outcome", "last_stops=yes", "--as-built", check,
                    "--predict", "0")
    assert line.startswith(f"station: error: --as-built: {check}: {field}"), line
    line = _refused(capsys, "predict", "simple", "success", "--as-built", check, "--samples", "2")
    assert line.startswith(f"station: error: --as-built {check}: {field}"), line
    assert json.loads(run_cli(capsys, "trial", "list", "--json")[1]) == []


def test_a_good_check_is_taken_by_both_with_its_placement_error(tmp_path, capsys):
    check = _check(tmp_path)
    trial_id = log_json(capsys, "simple", "success", "--outcome", "last_stops=yes", "--as-built", check)
    code, out, _ = run_cli(capsys, "trial", "show", str(trial_id), "--json")
    assert json.loads(out)["as_built"]["track.x"] == -0.0582
    code, out, err = run_cli(capsys, "predict", "simple", "success", "--as-built", check, "--samples", "2", "--json")
    assert code == 0, err
    assert json.loads(out)["placement_error"] == {"position_mm": 0.7, "heading_deg": 0.4,
                                                  "unmeasured": ["track.z", "track.roll"]}


def test_an_event_time_past_the_scenarios_duration_is_refused_saying_the_limit(tmp_path, capsys):
    line = _refused(capsys, "trial", "log", "simple", "success", "--outcome", "last_stops=yes", "--time",
                    "last_stops=1e308", "--predict", "0")
    assert line == ("station: error: --time last_stops: expected at most 4 s, the scenario SIMPLE's duration "
                    "([settings] max_duration), got 1e+308")
    log_json(capsys, "simple", "success", "--outcome", "last_stops=yes", "--time", "last_stops=4")  # the limit
    exported = tmp_path / "t.json"
    run_cli(capsys, "trial", "export", "--out", str(exported))
    data = json.loads(exported.read_text())
    data["trials"][0].update(uid="d" * 32, times={"last_stops": 4.5})
    exported.write_text(json.dumps(data))
    assert f"{exported}: trials[0].times.last_stops: expected at most 4 s" in _refused(
        capsys, "trial", "import", str(exported))


def test_an_output_that_cannot_be_written_names_the_flag_and_the_path_given(tmp_path, capsys):
    log_json(capsys, "simple", "success", "--outcome", "last_stops=yes")
    assert _refused(capsys, "trial", "export", "--out", "/proc/x.json") == (
        "station: error: --out: '/proc/x.json': cannot create a file in '/proc' (No such file or directory)")
    folder = tmp_path / "adir.json"
    folder.mkdir()
    assert _refused(capsys, "trial", "export", "--out", str(folder)) == (
        f"station: error: --out: '{folder}': is a folder; expected a file to write")
    assert _refused(capsys, "trial", "export", "--out", str(tmp_path / "none" / "t.csv")) == (
        f"station: error: --out: '{tmp_path / 'none' / 't.csv'}': the folder '{tmp_path / 'none'}' does not exist")
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        code, _, err = run_cli(capsys, "trial", "export", "--out", str(locked / "t.json"))
        if code:  # (root may write anywhere)
            assert err == (f"station: error: --out: '{locked / 't.json'}': cannot create a file in '{locked}' "
                           "(Permission denied)\n")
    finally:
        locked.chmod(0o700)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["adir.json", "locked"]  # nothing left aside
    assert list(folder.iterdir()) == []
