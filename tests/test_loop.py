"""The station loop on the simulated world (issue 21): the world service, and `station loop` stopped and resumed.

The SIMPLE scenario with tiny budgets; nothing here asserts on the acceptance rates (bench/bench_loop.py does)."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYOUT = {"x": [-0.15, 0.06, 68.0]}  # a SIMPLE layout (track.x, track.z, track.roll) that succeeds as designed
TINY = ["--attempts", "2", "--loops", "2", "--budget", "20", "--reoptimize-budget", "20", "--candidates", "2",
        "--rounds", "1", "--baseline", "1",
        "--predict-samples", "3", "--fit-draws", "1", "--fit-sobol", "3", "--fit-rounds", "0", "--workers", "1"]


@pytest.fixture(scope="module")
def simple_job(tmp_path_factory):
    from station.services.guide import make_guide

    path = tmp_path_factory.mktemp("layout") / "layout.json"
    path.write_text(json.dumps(LAYOUT))
    return make_guide("simple", str(path), tolerances=False)


def test_the_camera_measures_parts_where_the_maker_put_them(simple_job):
    from station.services import world as worlds
    from station.services.check import check_frame

    guide = simple_job.guide
    world = worlds.open_world("sim://world?seed=4&place_mm=3&place_deg=3")
    hidden = worlds.prepare_world(world, simple_job.scenario)
    assert set(hidden) == set(simple_job.scenario.physics_parameters())
    for name, (_, (lo, hi)) in simple_job.scenario.uncertain_parameters().items():
        assert lo <= hidden[name] <= hi
    worlds.place_parts(world, guide, attempt=1, highlighted=False)
    placed = world.placed()["track"]
    drawn = next(p for p in guide.parts if p.name == "track")
    truth = np.subtract(placed["center_mm"], drawn.center_mm)
    image, lens = worlds.grab_placed("sim://camera?supersample=1", guide, world.placed(), seed=0)
    report = check_frame(simple_job, image, lens).to_json()
    (track,) = [p for p in report["parts"] if p["name"] == "track"]
    # measured by the camera from the rendered tag, independently of the world's numbers: within 0.3 mm, 0.3 deg
    assert track["error"]["du_mm"] == pytest.approx(truth[0], abs=0.3)
    assert track["error"]["dv_mm"] == pytest.approx(truth[1], abs=0.3)
    assert track["error"]["heading_deg"] == pytest.approx(placed["heading_deg"] - drawn.heading_deg, abs=0.3)
    # the instruction's move brings it back to within the maker's correcting error
    (move,) = worlds.check_moves(report, guide)
    world.apply([move], round=1)
    after = np.subtract(world.placed()["track"]["center_mm"], drawn.center_mm)
    assert np.hypot(*after) < np.hypot(*truth)
    # a run: every event ticked, the as-placed layout near the designed one, deterministic
    run = worlds.run_attempt(simple_job.scenario, simple_job.layout.x, guide, world)
    assert set(run.outcomes) == set(simple_job.scenario.events)
    assert set(run.times) == {e for e, o in run.outcomes.items() if o == "yes"}
    assert run.success == (run.outcomes["last_stops"] == "yes")
    assert run.as_placed["track.x"] == pytest.approx(LAYOUT["x"][0] + after[0] / 1000.0, abs=2e-4)
    assert worlds.run_attempt(simple_job.scenario, simple_job.layout.x, guide, world) == run


def test_a_world_is_a_sim_world_url(simple_job):
    from drivers.errors import SimConfigError
    from station.services import world as worlds
    from station.services.errors import ServiceError

    with pytest.raises(ServiceError, match="not a world"):
        worlds.open_world("sim://camera")
    with pytest.raises(SimConfigError, match="place_mm"):
        worlds.open_world("sim://world?place_mm=x")


def _loop(env, *extra, check=True):
    result = subprocess.run([sys.executable, "-m", "station", "loop", "simple", "--world", "sim://world?seed=2",
                             *TINY, "--json", *extra], cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    if check:
        assert result.returncode == 0, result.stderr[-2000:]
    return result


def _attempts(database: Path) -> int:
    if not database.exists():
        return 0
    connection = sqlite3.connect(database)
    try:
        return connection.execute("SELECT count(*) FROM loop_attempts").fetchone()[0]
    except sqlite3.OperationalError:  # not migrated yet
        return 0
    finally:
        connection.close()


def test_a_killed_loop_resumes_and_ends_with_the_same_figures(tmp_path, station_home):
    env = {**os.environ, "PYTHONPATH": str(ROOT), "CHAOS_STATION_HOME": str(station_home)}
    whole = _loop({**env, "CHAOS_STATION_DATABASE": str(tmp_path / "whole.sqlite3")})
    figures = json.loads(whole.stdout)
    assert [loop["attempts"] for loop in figures["loops"]] == [2, 2]
    assert figures["baseline"]["attempts"] == 1
    assert set(figures["loops"][0]) == {"loop", "attempts", "successes", "success_rate", "predicted_success",
                                        "physics"}
    assert figures["loops"][1]["physics"] != figures["loops"][0]["physics"]  # calibrated
    # the same run killed once its second attempt is logged, then run again
    database = tmp_path / "killed.sqlite3"
    killed_env = {**env, "CHAOS_STATION_DATABASE": str(database)}
    process = subprocess.Popen([sys.executable, "-m", "station", "loop", "simple", "--world", "sim://world?seed=2",
                                *TINY, "--json"], cwd=ROOT, env=killed_env, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, start_new_session=True)
    deadline = time.monotonic() + 300
    while _attempts(database) < 2 and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    os.killpg(process.pid, signal.SIGKILL)
    process.communicate()
    stored = _attempts(database)
    assert 2 <= stored < 5, "the kill came too late to test a resume"
    resumed = _loop(killed_env)
    assert json.loads(resumed.stdout) == figures
    connection = sqlite3.connect(database)
    # every attempt once, each with its trial (none logged twice by the resume)
    assert connection.execute("SELECT count(*) FROM loop_attempts").fetchone()[0] == 5
    assert connection.execute("SELECT count(*) FROM trials").fetchone()[0] == 5
    connection.close()
    # a finished run again: nothing new, the same figures
    assert json.loads(_loop(killed_env).stdout) == figures


def test_bad_loop_arguments_are_one_line(tmp_path, station_home):
    env = {**os.environ, "PYTHONPATH": str(ROOT), "CHAOS_STATION_HOME": str(station_home),
           "CHAOS_STATION_DATABASE": str(tmp_path / "t.sqlite3")}
    for extra, words in ((["--attempts", "0"], "--attempts"), (["--world", "sim://world?seed=x"], "seed"),
                         (["--camera", "0"], "--camera"), (["--world", "sim://projector"], "--world"),
                         (["--reoptimize-budget", "3"], "--reoptimize-budget")):
        result = subprocess.run([sys.executable, "-m", "station", "loop", "simple", "--world", "sim://world", *extra],
                                cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
        assert result.returncode == 2, (extra, result.stderr)
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and words in lines[0], (extra, result.stderr)


def _payload(kept_u, rows):
    params = [{"name": "a", "value": 0.0, "normalized": kept_u[0], "lower": 0.0, "upper": 10.0},
              {"name": "b", "value": 0.0, "normalized": kept_u[1], "lower": -1.0, "upper": 1.0}]
    return {"format": "chaos-station robust layout 1", "parameters": params, "predicted_psp": 0.9,
            "verification": rows}


def test_candidates_are_the_kept_layout_then_working_runners_up_best_first():
    from station.services.layout_choice import candidate_layouts, distinct_layouts

    rows = [{"u": [0.1, 0.2], "local_success_rate": 0.4, "kept": False},
            {"u": [0.5, 0.5], "local_success_rate": 1.0, "kept": True},
            {"u": [0.3, 0.9], "local_success_rate": 0.0, "kept": False},  # never worked: not a candidate
            {"u": [0.7, 0.25], "local_success_rate": 0.8, "kept": False}]
    payload = _payload([0.5, 0.5], rows)
    layouts = candidate_layouts(payload, 4)
    assert layouts[0] is payload
    assert [c["candidate"] for c in layouts[1:]] == [3, 0]
    assert layouts[1]["parameters"][0]["value"] == pytest.approx(7.0)
    assert layouts[1]["parameters"][1]["value"] == pytest.approx(-0.5)
    assert layouts[1]["parameters"][1]["normalized"] == pytest.approx(0.25)
    assert len(candidate_layouts(payload, 2)) == 2 and len(candidate_layouts(payload, 1)) == 1
    assert distinct_layouts([payload, layouts[1], dict(payload)]) == [payload, layouts[1]]


def test_the_layout_placed_is_the_one_predicted_to_succeed_most_often(monkeypatch):
    """choose_layout scores every option by its physical prediction and keeps the best, recording the scores."""
    from station.services import predict as predicting
    from station.services.layout_choice import candidate_layouts, choose_layout

    scores = iter([0.4, 0.9, 0.9])
    seen = []

    class Result:
        def __init__(self, seed):
            seen.append(seed)
            self.probability = next(scores)

    monkeypatch.setattr(predicting, "predict_layout", lambda *a, seed, **k: Result(seed))
    monkeypatch.setattr("design.contraption.layout_io.layout_from_data",
                        lambda data, scenario, file: type("L", (), {"x": [0.0, 0.0]})())
    rows = [{"u": [0.1, 0.2], "local_success_rate": 0.4, "kept": False},
            {"u": [0.7, 0.25], "local_success_rate": 0.8, "kept": False}]
    options = candidate_layouts(_payload([0.5, 0.5], rows), 3)
    chosen = choose_layout(None, options + [options[0]], None, samples=5, seed=7)  # the repeat is dropped
    assert chosen["candidate"] == 1  # 0.9 beats 0.4; of the two 0.9s the first is kept
    assert chosen["physical_choice"] == {"chosen": 1, "predicted_physical_success": [0.4, 0.9, 0.9], "samples": 5}
    assert seen == [7, 7, 7]  # every option meets the same draws
    assert choose_layout(None, [options[0]], None) is options[0]  # nothing to choose: nothing simulated
