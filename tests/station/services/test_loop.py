"""The station loop on the simulated world: the world service, and `station loop` stopped and resumed.

The SIMPLE scenario with tiny budgets; nothing here asserts on the acceptance rates (bench/bench_loop.py does)."""

from __future__ import annotations

import json
import os
import re
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from common.progress import Cancelled, Reporter

ROOT = Path(__file__).resolve().parents[3]
LAYOUT = {"x": [-0.15, 0.06, 68.0]}  # a SIMPLE layout (track.x, track.z, track.roll) that succeeds as designed
TINY = ["--attempts", "2", "--loops", "2", "--budget", "20", "--reoptimize-budget", "20", "--candidates", "2",
        "--rounds", "1", "--baseline", "1",
        "--predict-samples", "3", "--fit-draws", "1", "--fit-sobol", "3", "--fit-rounds", "0", "--workers", "1"]


@pytest.fixture(scope="module")
def simple_job(tmp_path_factory):
    from station.services.guide import GuideRequest, make_guide

    path = tmp_path_factory.mktemp("layout") / "layout.json"
    path.write_text(json.dumps(LAYOUT))
    return make_guide(GuideRequest("simple", str(path), tolerances=False))


def test_the_camera_measures_parts_where_the_maker_put_them(simple_job):
    from station.services import world as worlds
    from station.services.check import check_frame

    guide = simple_job.guide
    world = worlds.open_world("sim://world?seed=4&place_mm=3&place_deg=3")
    hidden = worlds.prepare_world(world, simple_job.scenario)
    assert set(hidden) == set(simple_job.scenario.physics_parameters())
    for name, (_, (lo, hi)) in simple_job.scenario.uncertain_parameters().items():
        assert lo <= hidden[name] <= hi
    worlds.place_parts(world, guide, attempt=1, highlighted=False, scenario=simple_job.scenario)
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
    from station.errors import ServiceError
    from station.services import world as worlds

    with pytest.raises(ServiceError, match="not a world"):
        worlds.open_world("sim://camera")
    with pytest.raises(SimConfigError, match="place_mm"):
        worlds.open_world("sim://world?place_mm=x")


def test_a_loop_attempt_is_the_attempt_an_assembly_walks(tmp_path, station_home):
    # The loop's attempt and the same attempt walked by hand with station assemble's Assembly, on a world of the same
    # seed: placed with the highlight, checked, corrected as the check says, run, predicted as checked. The same
    # trial and the same prediction, so the two cannot drift apart.
    from common.progress import Reporter
    from station.loopstore import LoopStore
    from station.services import world as worlds
    from station.services.assemble import Assembly
    from station.services.guide import GuideRequest, make_guide
    from station.services.loop import _CAMERA, _PREDICT, ATTEMPT_BLOCK, LoopSettings, _Loop, _seed
    from station.services.trials import load_trial_scenario

    url = "sim://world?seed=5&place_mm=4"
    settings = LoopSettings(rounds=2, predict_samples=4, workers=1)
    scenario = load_trial_scenario("ballrun")
    job = make_guide(GuideRequest("ballrun", "success", tolerances=False))
    world = worlds.open_world(url)
    worlds.prepare_world(world, scenario)
    with LoopStore(str(tmp_path / "loop.sqlite3")) as store:
        loop = _Loop(store, scenario, world, url, settings, Reporter.of(None), tmp_path)
        stored, said = loop.attempt(job, None, None, 1, 2, checked=True)
        logged = store.trial(stored.trial_id)
    assert said.rounds >= 1 and said.corrections, "4 mm of placement error leaves parts to move"

    by_hand = worlds.open_world(url)
    worlds.prepare_world(by_hand, scenario)
    assembly = Assembly(job, scenario, camera=settings.camera, world=by_hand, attempt=ATTEMPT_BLOCK + 2, samples=4,
                        seed=_seed(5, _PREDICT, 1, 2), workers=1, highlighted=True, station_camera=False)
    assembly.placed()
    for r in range(settings.rounds + 1):
        assembly.check_parts(seed=_seed(5, _CAMERA, 1, 2, r))
        if not assembly.moves() or r == settings.rounds:
            break
        assembly.fix()
    assembly.accept()
    assembly.run()
    predicted = assembly.forecast().prediction.probability
    walked = assembly.trial()
    assert by_hand.placed() == world.placed() and assembly.fixes == said.rounds
    for key in ("layout", "as_built", "check", "outcomes", "times", "success", "physics"):
        assert logged[key] == walked[key], key
    assert stored.predicted == predicted


def test_a_loop_attempt_on_jigs_has_the_side_camera_correct_the_height_and_tilt(tmp_path, station_home):
    # A loose jig (3 mm, 3 deg) sets SIMPLE's track off in height and tilt: the attempt's check reads the stand's
    # face tag with the side camera, the maker sets the height and tilt again as it says (the world's parameters
    # really change), and the attempt's record says so: the trial's notes and its CHECK.json.
    from common.progress import Reporter
    from station.loopstore import LoopStore
    from station.services import world as worlds
    from station.services.guide import GuideRequest, make_guide
    from station.services.loop import LoopSettings, _Loop
    from station.services.trials import load_trial_scenario

    url = "sim://world?seed=3&jig_mm=3&jig_deg=3"
    settings = LoopSettings(rounds=2, predict_samples=2, workers=1, jigs=True)
    scenario = load_trial_scenario("simple")
    job = make_guide(GuideRequest("simple", "success", tolerances=False, jigs=True))
    world = worlds.open_world(url)
    worlds.prepare_world(world, scenario)
    names = list(scenario.design_space.names)
    designed = dict(zip(names, job.layout.x))
    with LoopStore(str(tmp_path / "loop.sqlite3")) as store:
        loop = _Loop(store, scenario, world, url, settings, Reporter.of(None), tmp_path)
        stored, said = loop.attempt(job, None, None, 1, 1, checked=True)
        trial = store.trial(stored.trial_id)
    (track,) = said.corrections
    changed = dict((name, change) for name, change, _ in track.parameters)
    assert set(changed) == {"track.z", "track.roll"} and abs(changed["track.z"]) > 1.0, track
    assert "the side camera had track.z set" in trial["notes"] and "the side camera measured track.z" in trial["notes"]
    assert trial["check"]["measured_by"]["track.z"] == "side"
    placed = dict(zip(names, worlds.as_placed_layout(scenario, job.guide, world)))
    assert abs(placed["track.z"] - designed["track.z"]) < 0.001  # set again within a millimetre
    assert trial["check"]["as_measured"]["track.z"] == pytest.approx(placed["track.z"], abs=0.0005)


def test_the_side_camera_is_part_of_a_run_only_with_jigs():
    from station.services.loop import LoopSettings

    assert "side_camera" not in LoopSettings().identity()  # runs without jigs carry on as they were
    assert LoopSettings(jigs=True).identity()["side_camera"].startswith("sim://camera?view=side")
    assert LoopSettings(jigs=True, side_camera="sim://camera?view=side&height=500").identity() != \
        LoopSettings(jigs=True).identity()


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
                                        "forecast_success", "physics"}
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
    # loop 2 weighed loop 1's layout (its first option) with its record on the table
    (text,) = connection.execute("SELECT layout FROM loop_loops WHERE loop_number = 2").fetchone()
    choice = json.loads(text)["physical_choice"]
    assert choice["record"][0] == [figures["loops"][0]["successes"], 2]
    assert all(n == 0 for _, n in choice["record"][1:])
    connection.close()
    # a finished run again: nothing new, the same figures
    assert json.loads(_loop(killed_env).stdout) == figures


def _tiny_settings():
    from station.cli import build_parser
    from station.commands.loop import resume_command

    args = build_parser().parse_args(["loop", "simple", "--world", "sim://world?seed=2", *TINY])
    return args, resume_command(args)


def test_a_stopped_run_keeps_its_id_when_resumed_and_says_so(tmp_path, station_home):
    # stopped before its first layout is made (nothing simulated): each resume finds the same run, and the next
    # run's id is the next number (an insert that found the run used one up)
    from station.services.loop import LoopSettings, run_loop

    database = str(tmp_path / "ids.sqlite3")
    settings = LoopSettings(attempts=2, loops=2, baseline=1)
    started, stops = [], []
    for world in ("sim://world?seed=2", "sim://world?seed=2", "sim://world?seed=2", "sim://world?seed=3"):
        with pytest.raises(Cancelled) as stopped:
            run_loop("simple", world, settings, database=database, report=Reporter(stop=lambda: True),
                     on_start=started.append)
        stops.append(stopped.value)
    assert [(log.run_id, log.resumed) for log in started] == [(1, False), (1, True), (1, True), (2, False)]
    assert started[1].resuming() == "resuming run 1: 0 attempts already logged"
    assert [(stop.partial.run_id, stop.partial.attempts) for stop in stops] == [(1, 0), (1, 0), (1, 0), (2, 0)]
    assert str(stops[0]) == "run 1 stopped: 0 attempts logged (loop 1: 0 of 2)"
    connection = sqlite3.connect(database)
    try:
        assert connection.execute("SELECT seq FROM sqlite_sequence WHERE name = 'loop_runs'").fetchone() == (2,)
    finally:
        connection.close()


def test_what_a_stopped_run_has_logged_is_said_per_loop():
    from station.services.loop import RunLog

    log = RunLog(4, True, {1: 2, 2: 1}, {1: 2, 2: 2, 3: 2, 0: 1})
    assert log.logged_words() == "3 attempts logged (loop 1: 2 of 2, loop 2: 1 of 2)"
    assert log.resuming() == "resuming run 4: 3 attempts already logged"
    done = RunLog(5, True, {0: 1, 1: 1}, {0: 1, 1: 1})
    assert done.logged_words() == "2 attempts logged (loop 1: 1 of 1, baseline: 1 of 1)"
    assert RunLog(6, False, {1: 1}, {1: 3}).resuming() == "resuming run 6: 1 attempt already logged"


def test_the_resume_command_is_the_same_run():
    import shlex

    from station.cli import build_parser

    args, command = _tiny_settings()
    words = shlex.split(command)
    assert words[:5] == ["station", "loop", "simple", "--world", "sim://world?seed=2"]
    again = build_parser().parse_args(words[1:])
    assert vars(again) | {"func": None} == vars(args) | {"func": None}
    defaults = shlex.split(resume_of(["loop", "simple", "--world", "sim://world?seed=2"]))
    assert defaults == ["station", "loop", "simple", "--world", "sim://world?seed=2"]  # the defaults left out


def resume_of(argv):
    from station.cli import build_parser
    from station.commands.loop import resume_command

    return resume_command(build_parser().parse_args(argv))


@pytest.mark.slow  # a loop stopped after its first attempt, then resumed to its end: 15-40 s on two cores
def test_an_interrupted_loop_says_what_it_logged_and_its_command_resumes_it(tmp_path, station_home):
    import shlex

    database = tmp_path / "interrupted.sqlite3"
    env = {**os.environ, "PYTHONPATH": str(ROOT), "CHAOS_STATION_HOME": str(station_home),
           "CHAOS_STATION_DATABASE": str(database)}
    argv = ["loop", "simple", "--world", "sim://world?seed=2", "--attempts", "3", "--loops", "1", "--budget", "20",
            "--candidates", "1", "--rounds", "1", "--baseline", "0", "--predict-samples", "3", "--workers", "1"]
    process = subprocess.Popen([sys.executable, "-m", "station", *argv], cwd=ROOT, env=env, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 300
    while _attempts(database) < 1 and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)
    process.send_signal(signal.SIGINT)  # Ctrl-C
    out, err = process.communicate(timeout=300)
    assert process.returncode == 130, err[-2000:]
    logged = _attempts(database)
    assert 1 <= logged < 3, "the interrupt came too late to test a resume"
    said = err.splitlines()
    words = "attempt" if logged == 1 else "attempts"
    assert (f"station: stopped run 1: {logged} {words} logged (loop 1: {logged} of 3), each with its trial in the "
            "trial log") in said, said[-5:]
    (resume,) = [line.split(": ", 2)[2] for line in said if line.startswith("station: the same command resumes it: ")]
    assert said[-1] == "station: interrupted" and "Traceback" not in err
    assert out.count("(trial ") == logged  # each attempt logged was said
    # the printed command, as a maker would paste it, resumes the run and says so
    words = shlex.split(resume)
    assert words[:2] == ["station", "loop"]
    resumed = subprocess.run([sys.executable, "-m", "station", *words[1:]], cwd=ROOT, env=env, capture_output=True,
                             text=True, timeout=600)
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    lines = resumed.stdout.splitlines()
    assert lines[0] == f"resuming run 1: {logged} {'attempt' if logged == 1 else 'attempts'} already logged"
    assert lines[-1].startswith("run 1 in the station database")
    assert sum(line.startswith("loop 1, attempt ") and "already logged" in line for line in lines) == logged
    assert _attempts(database) == 3
    connection = sqlite3.connect(database)
    try:
        assert connection.execute("SELECT id FROM loop_runs").fetchall() == [(1,)]
        assert connection.execute("SELECT seq FROM sqlite_sequence WHERE name = 'loop_runs'").fetchone() == (1,)
    finally:
        connection.close()


def test_bad_loop_arguments_are_one_line(tmp_path, station_home):
    env = {**os.environ, "PYTHONPATH": str(ROOT), "CHAOS_STATION_HOME": str(station_home),
           "CHAOS_STATION_DATABASE": str(tmp_path / "t.sqlite3")}
    for extra, words in ((["--attempts", "0"], "--attempts"), (["--world", "sim://world?seed=x"], "seed"),
                         (["--camera", "0"], "--camera"), (["--world", "sim://projector"], "--world"),
                         (["--reoptimize-budget", "3"], "--reoptimize-budget"),
                         (["--prediction-weight", "0"], "--prediction-weight"),
                         (["--fit-prior-width", "-1"], "--fit-prior-width")):
        result = subprocess.run([sys.executable, "-m", "station", "loop", "simple", "--world", "sim://world", *extra],
                                cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
        assert result.returncode == 2, (extra, result.stderr)
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and words in lines[0], (extra, result.stderr)


#: A loop whose maker places badly enough (8 mm, 8 deg) and whose optimization is good enough (80) for the check to
#: have parts moved; small everywhere else.
SAID = ["--world", "sim://world?seed=2&place_mm=8&place_deg=8", "--attempts", "3", "--loops", "2", "--budget", "80",
        "--reoptimize-budget", "20", "--candidates", "2", "--rounds", "2", "--baseline", "1", "--predict-samples", "3",
        "--fit-draws", "1", "--fit-sobol", "4", "--fit-rounds", "0", "--workers", "1"]
ATTEMPT_LINE = re.compile(r"^(?:loop (\d+)|baseline), attempt (\d+) \(trial (\d+)\): (.*); ran: (success|failed.*)$")


def test_the_loop_says_each_stage_and_attempt_in_short_lines(tmp_path, station_home):
    """Every progress line names the loop and what it does (calibrating, re-optimizing, choosing among candidate
    layouts); every attempt has a line saying what the check had corrected and how the run went, matching the
    trial it logged; no line is longer than 120 characters, the physics a table of its own."""
    database = tmp_path / "said.sqlite3"
    env = {**os.environ, "PYTHONPATH": str(ROOT), "CHAOS_STATION_HOME": str(station_home),
           "CHAOS_STATION_DATABASE": str(database)}
    result = subprocess.run([sys.executable, "-m", "station", "loop", "simple", *SAID], cwd=ROOT, env=env,
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-2000:]
    progress = result.stderr.splitlines()
    assert progress and all(re.match(r"(loop \d+|baseline)\b", line) for line in progress), progress
    assert any(line.startswith("loop 1: optimizing the layout (exploration): ") for line in progress)
    assert any(line.startswith("loop 2: calibrating the simulator from 3 trials: ") and line.endswith(" simulations")
               for line in progress)
    assert any(line.startswith("loop 2: re-optimizing the layout for the calibrated physics (") for line in progress)
    assert "loop 1: choosing the layout to place: 2/2 candidate layouts" in progress
    assert any(line.startswith("loop 2, attempt 3: predicting its physical success as checked: ") for line in progress)

    lines = result.stdout.splitlines()
    assert max(len(line) for line in lines) <= 120, max(lines, key=len)
    said = {}
    for line in lines:
        match = ATTEMPT_LINE.match(line)
        if match:
            loop, attempt, trial, check, ran = match.groups()
            said[int(loop or 0), int(attempt)] = (int(trial), check, ran == "success")
    assert sorted(said) == [(0, 1), (1, 1), (1, 2), (1, 3), (2, 1), (2, 2), (2, 3)]
    connection = sqlite3.connect(database)
    try:
        stored = connection.execute("SELECT a.loop_number, a.attempt, a.trial_id, a.success, a.check_rounds, t.notes "
                                    "FROM loop_attempts a JOIN trials t ON t.id = a.trial_id").fetchall()
    finally:
        connection.close()
    moved = 0
    for loop, attempt, trial, success, rounds, notes in stored:
        line_trial, check, line_success = said[loop, attempt]
        assert (line_trial, line_success) == (trial, bool(success))
        if loop == 0:
            assert check == "placed from the printed sheet, not checked"
        elif rounds:  # the parts the check had moved, and in the trial's notes the check's own words for them
            moved += 1
            assert re.fullmatch(r"the check had `track` (moved \d+\.\d mm( and turned \d+\.\d deg)?|turned "
                                r"\d+\.\d deg)( in \d rounds)?", check), check
            assert "the maker corrected as the check said" in notes and "move `track`" in notes, notes
        else:
            assert check == "the check found every part within its tolerance"
    assert moved, "no attempt needed a correction: the test shows no correction line"
    # each loop's figures: its successes are its attempts' lines', its physics a table of name-value cells
    for k in (1, 2):
        (summary,) = [line for line in lines if line.startswith(f"loop {k}: ") and "attempts succeeded" in line]
        successes = int(summary.split(": ")[1].split(" of ")[0])
        assert successes == sum(ok for (loop, _), (_, _, ok) in said.items() if loop == k)
        heads = [line for line in lines[lines.index(summary) + 1:][:8] if not line.startswith("    ")]  # unwrapped
        assert heads[0].startswith("  predicted physical success on the table: ")
        assert heads[1].startswith("  layout placed: ") and heads[2].startswith("  corrections: ")
        assert heads[3].startswith("  physics: ")
    table = [line for line in lines if re.match(r"^    \w+\.\w+ +[-\d.e]+", line)]
    assert sum("domino.angular_damping" in line for line in table) == 2  # in both loops' tables


def test_a_loops_progress_and_attempts_are_said_in_its_words():
    """An optimizer's or calibration's progress is labelled with what the loop is doing, its own figures kept; an
    attempt's corrections are each part's moves over its rounds, summed, in the check's words."""
    from common.progress import Progress
    from design.robust.budget import Progress as RobustProgress
    from station.services.loop import AttemptReport, _corrections, labelled

    phase = labelled(RobustProgress("exploration", 4, 20, cv_accuracy=0.8, best_psp=0.5), "loop 2: re-optimizing")
    assert (phase.stage, phase.done, phase.total, phase.cv_accuracy, phase.unit) == (
        "loop 2: re-optimizing (exploration)", 4, 20, 0.8, "simulations")
    fit = labelled(Progress("simulations", 12, 216), "loop 2: calibrating the simulator from 5 trials")
    assert (fit.stage, fit.done, fit.total, fit.unit) == ("loop 2: calibrating the simulator from 5 trials", 12, 216,
                                                           "simulations")
    assert labelled(RobustProgress("check", 1, 2), "loop 1: optimizing").stage == \
        "loop 1: optimizing (verifying its best layouts)"

    # a move is designed minus measured: +u is to the maker's right; two rounds on the track add up
    rounds = [[{"name": "track", "du_mm": 2.0, "dv_mm": 1.0, "dheading_deg": -3.0},
               {"name": "plank", "du_mm": 0.0, "dv_mm": 0.0, "dheading_deg": 4.0}],
              [{"name": "track", "du_mm": 1.0, "dv_mm": 3.0, "dheading_deg": 0.0}]]
    track, plank = _corrections(rounds, "top")
    assert (track.name, track.distance_mm, track.turn_deg) == ("track", pytest.approx(5.0), pytest.approx(-3.0))
    assert track.instruction == "move `track` 3.0 mm right and 4.0 mm away from you, turn it 3.0 deg clockwise"
    assert plank.instruction == "turn `plank` 4.0 deg counter-clockwise"
    report = AttemptReport(1, 3, 12, False, True, (track, plank), rounds=2, left=("plank",), failed_at="last_stops")
    assert report.describe() == ("loop 1, attempt 3 (trial 12): the check had `track` moved 5.0 mm and turned "
                                 "3.0 deg, `plank` turned 4.0 deg in 2 rounds; still out of tolerance: `plank`; "
                                 "ran: failed at `last_stops`")
    assert report.correction_words().startswith("the maker corrected as the check said (2 rounds): move `track` 3.0 "
                                                "mm right")


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
    from station.services.layout_choice import LayoutChoiceRequest, candidate_layouts, choose_layout

    scores = iter([0.4, 0.9, 0.9])
    seen = []

    class Result:
        def __init__(self, seed):
            seen.append(seed)
            self.probability = next(scores)

    monkeypatch.setattr(predicting, "predict_layout", lambda scenario, x, request, **k: Result(request.seed))
    monkeypatch.setattr("design.contraption.layout_io.layout_from_data",
                        lambda data, scenario, file: type("L", (), {"x": [0.0, 0.0]})())
    rows = [{"u": [0.1, 0.2], "local_success_rate": 0.4, "kept": False},
            {"u": [0.7, 0.25], "local_success_rate": 0.8, "kept": False}]
    options = candidate_layouts(_payload([0.5, 0.5], rows), 3)
    # the repeat is dropped
    chosen = choose_layout(None, options + [options[0]], LayoutChoiceRequest(samples=5, seed=7))
    assert chosen["candidate"] == 1  # 0.9 beats 0.4; of the two 0.9s the first is kept
    assert chosen["physical_choice"] == {"chosen": 1, "predicted_physical_success": [0.4, 0.9, 0.9],
                                         "record": [[0, 0]] * 3, "prediction_weight": 4.0,
                                         "expected_success": [0.4, 0.9, 0.9],
                                         "lower_quartile": pytest.approx([0.2234, 0.8587, 0.8587], abs=1e-4),
                                         "samples": 5}
    assert seen == [7, 7, 7]  # every option meets the same draws
    assert choose_layout(None, [options[0]]) is options[0]  # nothing to choose: nothing simulated


@pytest.mark.parametrize(("predicted", "record", "weight", "expected"), [
    (0.6, (0, 0), 4.0, 0.6),          # never placed: the prediction
    (0.56, (5, 5), 4.0, 7.24 / 9),    # worked 5 in 5: (4 * 0.56 + 5) / 9
    (0.9, (0, 5), 4.0, 3.6 / 9),      # failed 5 in 5
    (0.5, (3, 6), 2.0, 0.5),          # the record agrees with the prediction
    (0.2, (1, 1), 1e9, 0.2),          # a huge weight: simulations only
])
def test_expected_success_is_the_prediction_updated_by_the_record(predicted, record, weight, expected):
    from station.services.layout_choice import expected_success

    assert expected_success(predicted, *record, weight=weight) == pytest.approx(expected)


def test_an_attempts_forecast_is_its_prediction_updated_by_its_layouts_record_before_it():
    """The record counts earlier attempts of loops that placed the same values (earlier in its own loop too), never
    the baseline's nor later ones."""
    from station.loopstore import AttemptRow
    from station.services.loop import record_forecasts

    def layout(a):
        return {"parameters": [{"name": "a", "value": a}]}

    def row(loop, attempt, success, predicted):
        return AttemptRow(loop, attempt, 0, success, predicted, 0)

    layouts = {0: layout(9.0), 1: layout(1.0), 2: layout(2.0), 3: layout(1.0)}
    attempts = [row(0, 1, True, None), row(1, 1, True, 0.5), row(1, 2, False, 0.5), row(2, 1, True, 0.8),
                row(3, 1, True, 0.6), row(3, 2, True, None), row(3, 3, False, 0.6)]
    assert record_forecasts(layouts, attempts, 2.0) == pytest.approx([
        None,
        0.5,                      # nothing before it
        (1.0 + 1) / 3,            # loop 1's first attempt worked
        0.8,                      # loop 2 placed other values
        (1.2 + 1) / 4,            # loop 1's record (1 of 2): loop 3 placed its values again
        None,                     # no prediction
        (1.2 + 3) / 6,            # loop 1's 1 of 2, loop 3's 2 of 2 so far
    ])


def test_a_layout_that_worked_on_the_table_is_kept_over_one_only_simulated_better(monkeypatch):
    """A placed layout's trials (matched by its values) update its prediction: 5/5 at 0.56 beats a new 0.75, 0/5 at
    0.9 loses to it; the record and the expected successes are in the choice."""
    from station.services import predict as predicting
    from station.services.layout_choice import LayoutChoiceRequest, candidate_layouts, choose_layout, layout_records

    monkeypatch.setattr("design.contraption.layout_io.layout_from_data",
                        lambda data, scenario, file: type("L", (), {"x": [0.0, 0.0]})())
    rows = [{"u": [0.1, 0.2], "local_success_rate": 0.4, "kept": False}]
    placed, new = candidate_layouts(_payload([0.5, 0.5], rows), 2)
    values = {p["name"]: p["value"] for p in placed["parameters"]}
    other = {"a": 1.0, "b": 0.0}
    worked = [{"layout": values, "success": True}] * 5 + [{"layout": other, "success": False}] * 3
    assert layout_records([placed, new], worked) == [(5, 5), (0, 0)]

    for trials, predictions, winner in ((worked, [0.56, 0.75], 0),
                                        ([{"layout": values, "success": False}] * 5, [0.9, 0.75], 1)):
        scores = iter(predictions)
        monkeypatch.setattr(predicting, "predict_layout",
                            lambda *a, scores=scores, **k: type("R", (), {"probability": next(scores)})())
        chosen = choose_layout(None, [placed, new], LayoutChoiceRequest(samples=5, trials=tuple(trials)))
        choice = chosen["physical_choice"]
        assert choice["chosen"] == winner, choice
        assert choice["record"][0][1] == 5 and choice["record"][1] == [0, 0]
        assert choice["expected_success"][1] == pytest.approx(0.75)
    with pytest.raises(ValueError, match="prediction_weight"):
        LayoutChoiceRequest(prediction_weight=0)


@pytest.mark.parametrize(("predicted", "record", "expected"), [
    (0.75, (0, 0), 0.25 ** (1 / 3)),   # Beta(3, 1): its cdf is q ** 3
    (0.5, (3, 4), 0.5),               # Beta(5, 3)'s lower quartile, from scipy's own beta (below)
    (1.0, (0, 0), None),              # a prediction of 1 is held at 0.99: Beta(3.96, 0.04)
])
def test_options_are_ranked_by_the_lower_quartile_of_their_success(predicted, record, expected):
    from scipy.stats import beta

    from station.services.layout_choice import choice_score

    if expected is None:
        assert 0.99 < choice_score(predicted, *record) <= 1.0
    elif record == (3, 4):
        assert choice_score(predicted, *record) == pytest.approx(beta.ppf(0.25, 5.0, 3.0))
    else:
        assert choice_score(predicted, *record) == pytest.approx(expected)


def test_a_near_tie_goes_to_the_layout_with_a_record_and_a_clear_win_to_the_higher_mean(monkeypatch):
    """The loop's world-3 case: 4 of 5 at 0.81 (expected 0.804) against a new 0.8125 keeps the placed layout; a new
    0.95 beats it; a placed layout that failed 3 of 5 at 0.6 loses to a new 0.75."""
    from station.services import predict as predicting
    from station.services.layout_choice import LayoutChoiceRequest, candidate_layouts, choose_layout

    monkeypatch.setattr("design.contraption.layout_io.layout_from_data",
                        lambda data, scenario, file: type("L", (), {"x": [0.0, 0.0]})())
    rows = [{"u": [0.1, 0.2], "local_success_rate": 0.4, "kept": False}]
    placed, new = candidate_layouts(_payload([0.5, 0.5], rows), 2)
    values = {p["name"]: p["value"] for p in placed["parameters"]}
    four_of_five = [{"layout": values, "success": True}] * 4 + [{"layout": values, "success": False}]
    two_of_five = [{"layout": values, "success": True}] * 2 + [{"layout": values, "success": False}] * 3
    for trials, predictions, winner in ((four_of_five, [0.81, 0.8125], 0), (four_of_five, [0.81, 0.95], 1),
                                        (two_of_five, [0.6, 0.75], 1)):
        scores = iter(predictions)
        monkeypatch.setattr(predicting, "predict_layout",
                            lambda *a, scores=scores, **k: type("R", (), {"probability": next(scores)})())
        request = LayoutChoiceRequest(samples=16, trials=tuple(trials))
        choice = choose_layout(None, [placed, new], request)["physical_choice"]
        assert choice["chosen"] == winner, choice
    assert choice["expected_success"][0] == pytest.approx((2.4 + 2) / 9)


@pytest.mark.parametrize(("choice", "words"), [
    (None, ""),
    ({"chosen": 1, "predicted_physical_success": [0.4, 0.9]},  # written before records were kept
     "; of 2 layouts the one expected to succeed most often physically (predicted 0.90)"),
    ({"chosen": 0, "predicted_physical_success": [0.56, 0.75], "record": [[5, 5], [0, 0]],
      "expected_success": [0.804, 0.75]},
     "; of 2 layouts the one expected to succeed most often physically (0.80: predicted 0.56, worked 5 of 5 times "
     "placed)"),
    ({"chosen": 0, "predicted_physical_success": [0.56, 0.75], "record": [[5, 5], [0, 0]],
      "expected_success": [0.804, 0.75], "lower_quartile": [0.7318, 0.63]},
     "; of 2 layouts the one surest to succeed often physically (expected 0.80: predicted 0.56, worked 5 of 5 "
     "times placed; 75 % sure of 0.73)"),
    ({"chosen": 1, "predicted_physical_success": [0.4, 0.9], "record": [[0, 0], [0, 0]],
      "expected_success": [0.4, 0.9], "lower_quartile": [0.2, 0.86]},
     "; of 2 layouts the one surest to succeed often physically (predicted 0.90; 75 % sure of 0.86)"),
])
def test_the_choice_is_told_in_a_few_words(choice, words):
    from station.services.layout_choice import describe_choice

    assert describe_choice({} if choice is None else {"physical_choice": choice}) == words
