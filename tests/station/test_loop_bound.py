"""The loop's ceiling (bench/bench_loop_bound.py) places each parameter as the loop's maker does at best: what the
camera check measures at the check's move error, the rest as the guide tells the maker to set them."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench import bench_loop_bound as bound
from calibration.sim_runs import placement_sigma
from drivers.sim.world import parse_world_options
from station.services.trials import load_trial_scenario
from station.services.world import guide_sigma

DEFAULTS = parse_world_options("sim://world")


@pytest.fixture(scope="module")
def simple():
    return load_trial_scenario("simple")


def test_simple_without_jigs_checks_the_place_and_rules_the_height(simple):
    precision = bound.loop_precision(simple, None, jigs=False)
    set_sigma = guide_sigma(bound.guide_job(simple, None, jigs=False).guide, simple, highlighted=True)
    assert precision.how == {"track.x": "check (top)", "track.z": "ruler", "track.roll": "ruler"}
    assert precision.sigma["track.x"] == pytest.approx(DEFAULTS["fix_mm"] / 1000.0)
    assert precision.sigma["track.z"] == pytest.approx(set_sigma["track.z"])  # the ruler's 1.5 mm
    assert precision.sigma["track.roll"] == pytest.approx(set_sigma["track.roll"])  # the protractor's 2 deg
    assert precision.sigma["track.z"] > bound.POSITION_SIGMA_M and precision.sigma["track.roll"] > bound.ANGLE_SIGMA_DEG


def test_simple_with_jigs_keeps_the_jigs_finer_setting_the_side_camera_measures(simple):
    precision = bound.loop_precision(simple, None, jigs=True)
    set_sigma = guide_sigma(bound.guide_job(simple, None, jigs=True).guide, simple, highlighted=True)
    assert precision.jigs
    assert precision.how == {"track.x": "check (top)", "track.z": "jig", "track.roll": "jig"}
    assert precision.sigma["track.x"] == pytest.approx(DEFAULTS["fix_mm"] / 1000.0)  # the jig laid by eye is coarser
    assert precision.sigma["track.z"] == pytest.approx(set_sigma["track.z"])
    assert precision.sigma["track.roll"] == pytest.approx(set_sigma["track.roll"])
    assert set_sigma["track.z"] < DEFAULTS["fix_mm"] / 1000.0 and set_sigma["track.roll"] < DEFAULTS["fix_deg"]
    # a check finer than the jig: the side camera's measure is what the maker corrects the tilt and height by
    fine = bound.loop_precision(simple, None, jigs=True, world="sim://world?fix_mm=0.1&fix_deg=0.1")
    assert fine.how == {"track.x": "check (top)", "track.z": "check (side)", "track.roll": "check (side)"}
    assert fine.sigma == pytest.approx({"track.x": 0.0001, "track.z": 0.0001, "track.roll": 0.1})


def test_causalityswitch_without_jigs_has_nothing_the_check_measures():
    scenario = load_trial_scenario("causalityswitch_ball")
    precision = bound.loop_precision(scenario, None, jigs=False)
    set_sigma = guide_sigma(bound.guide_job(scenario, None, jigs=False).guide, scenario, highlighted=True)
    assert not any(how.startswith("check") for how in precision.how.values())
    assert precision.sigma == pytest.approx(set_sigma)


def test_the_simulations_place_each_parameter_with_its_own_error(simple, monkeypatch):
    import calibration.sim_predict

    seen = {}
    monkeypatch.setattr(calibration.sim_predict, "predict_success", lambda scenario, x, **kw: seen.update(kw))
    precision = bound.Precision({"track.x": 0.0005, "track.z": 0.0015, "track.roll": 2.0}, {})
    bound._success(simple, {}, None, np.zeros(3), 4, 1, precision.exact("track.z"))
    sigma = placement_sigma(simple, 0.0005, 0.5, seen["unmeasured"], seen["set_sigma"])
    assert sigma.tolist() == pytest.approx([0.0005, 0.0, 2.0])


def test_the_limits_are_the_parameters_whose_exact_placement_gains_most():
    rows = [{"limits": {"a.z": {"exact": 0.9, "gain": 0.2, "sigma": 0.0015, "how": "ruler"},
                        "b.x": {"exact": 0.71, "gain": 0.01, "sigma": 0.001, "how": "sheet"}}},
            {"limits": {"a.z": {"exact": 0.8, "gain": 0.1, "sigma": 0.0015, "how": "ruler"},
                        "b.x": {"exact": 0.7, "gain": 0.0, "sigma": 0.001, "how": "sheet"}}}]
    assert bound.limiting(rows) == [("a.z", pytest.approx(0.15), "1.5 mm", "ruler")]
    assert bound.pooled([{"successes": 30, "samples": 40}, {"successes": 10, "samples": 40}])[0] == 0.5


def test_the_table_of_stored_rows_keeps_a_worlds_last_row(tmp_path, capsys):
    def row(seed, successes, jigs=True):
        return {"scenario": "simple", "precision": "loop", "jigs": jigs, "seed": seed, "success": successes / 32,
                "successes": successes, "samples": 32,
                "limits": {"track.x": {"exact": 1.0, "gain": 0.1, "sigma": 0.0005, "how": "check (top)"}}}

    rows = tmp_path / "rows.jsonl"
    rows.write_text("\n".join(json.dumps(r) for r in (row(1, 8), row(1, 32), row(2, 16), row(1, 0, False))) + "\n")
    assert bound.main(["--table", str(rows)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[2].startswith("| simple | no | 1: 0.00 |")
    assert lines[3] == ("| simple | yes | 1: 1.00 / 2: 0.50 | 0.75 [0.63, 0.84] | 1/2 | track.x +0.10 (0.5 mm, "
                        "check (top)) |")
    rows.write_text("not json\n")
    assert bound.main(["--table", str(rows)]) == 2
    assert capsys.readouterr().out.startswith(f"bench_loop_bound: --table {rows}: expected the JSON lines")


def test_a_part_the_jig_plan_leaves_by_hand_keeps_its_ruler_and_says_why(simple):
    steep = np.array([-0.1418, 0.06082, 68.41])  # a track too steep to rest on a jig's edge
    precision = bound.loop_precision(simple, steep, jigs=True)
    set_sigma = guide_sigma(bound.guide_job(simple, steep, jigs=True).guide, simple, highlighted=True)
    assert precision.how["track.z"].startswith("ruler, no jig: ")
    assert precision.sigma["track.z"] == pytest.approx(set_sigma["track.z"]) == DEFAULTS["ruler_mm"] / 1000.0


def test_the_loops_layouts_are_read_from_its_database(simple, tmp_path):
    import sqlite3

    database = tmp_path / "loop.sqlite3"
    with sqlite3.connect(database) as connection:
        connection.executescript("CREATE TABLE loop_runs (id INTEGER PRIMARY KEY, scenario_name TEXT, world TEXT);"
                                 "CREATE TABLE loop_loops (run_id INTEGER, loop_number INTEGER, layout TEXT);")
        connection.executemany("INSERT INTO loop_runs VALUES (?, ?, ?)",
                               [(1, simple.name, "sim://world?seed=2"), (2, simple.name, "sim://world?seed=3")])
        layout = lambda x: json.dumps({"x": x})  # noqa: E731
        connection.executemany("INSERT INTO loop_loops VALUES (?, ?, ?)",
                               [(1, 1, layout([-0.1, 0.05, 40.0])), (1, 2, layout([-0.1, 0.05, 40.0])),
                                (1, 3, layout([-0.12, 0.04, 45.0])), (2, 1, layout([-0.05, 0.02, 30.0]))])
    found = bound.loop_layouts(str(database), simple, 2)
    assert [x.tolist() for x in found] == [[-0.1, 0.05, 40.0], [-0.12, 0.04, 45.0]]


def test_what_the_top_camera_measured_stands_when_the_side_camera_reads_nothing():
    # the loop's side camera sees no jig face of this BRANCHING layout (its parts stand before it): the top view's
    # lever and goblet places are still measured, and the ceiling places them at the check's move error
    scenario = load_trial_scenario("branching")
    x = np.array([-0.010385388315079366, 1.356849279552506, 0.11142502250155722, 0.17753690163154934])
    job = bound.guide_job(scenario, x, jigs=True)
    assert bound.checked_by(job, jigs=True) == {"lever.x": "top", "goblet.x": "top"}
    precision = bound.loop_precision(scenario, x, jigs=True)
    assert precision.how["lever.x"] == precision.how["goblet.x"] == "check (top)"


def test_a_flat_rows_label_survives_out_and_its_table_files_it_as_flat(tmp_path, monkeypatch, capsys):
    from types import SimpleNamespace

    measured = SimpleNamespace(probability=0.5, interval=(0.33, 0.67), successes=16, events={"end": 0.5})
    monkeypatch.setattr(bound, "_success", lambda *args: measured)
    out = tmp_path / "rows.jsonl"
    assert bound.main(["--scenarios", "simple", "--seeds", "1", "--precision", "flat", "--scan", "2", "--scan-top",
                       "1", "--samples", "32", "--workers", "1", "--no-limits", "--out", str(out)]) == 0
    (row,) = [json.loads(line) for line in out.read_text().splitlines()]
    assert row["precision"] == "flat" and row["sigma"] == {"track.x": 0.0005, "track.z": 0.0005, "track.roll": 0.5}
    assert bound.flat_row(row)
    # a row that keeps the per-parameter errors under "precision" is flat by its "how"
    assert bound.flat_row({"precision": row["sigma"], "how": row["how"], "jigs": False})
    assert not bound.flat_row({"precision": row["sigma"], "how": {"track.x": "check (top)"}, "jigs": False})
    assert [(name, jigs) for name, jigs, _ in bound.stored_table(str(out))] == [("simple", None)]
    capsys.readouterr()
    assert bound.main(["--table", str(out)]) == 0
    assert capsys.readouterr().out.splitlines()[2].startswith("| simple | flat | 1: 0.50 |")
