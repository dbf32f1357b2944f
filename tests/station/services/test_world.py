"""The world twin as the station drives it: the simulated maker knows only what the guide says (the manifest's
parameters and how to set each), never the layout's own values."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

LAYOUT = {"x": [-0.15, 0.06, 68.0]}  # a SIMPLE layout: track.x, track.z (m), track.roll (deg)


@pytest.fixture(scope="module")
def simple_job(tmp_path_factory):
    from station.services.guide import GuideRequest, make_guide

    path = tmp_path_factory.mktemp("layout") / "layout.json"
    path.write_text(json.dumps(LAYOUT))
    return make_guide(GuideRequest("simple", str(path), tolerances=False))


def _without(guide, parameter: str):
    """The guide with ``parameter`` stated nowhere (as an older or partial guide would have it)."""
    parts = tuple(replace(p, settings=tuple(q for q in p.settings if q.name != parameter)) for p in guide.parts)
    return replace(guide, parts=parts)


def test_a_parameter_the_guide_does_not_state_is_not_read_from_the_layout(simple_job):
    from station.services import world as worlds

    scenario = simple_job.scenario
    guide = _without(simple_job.guide, "track.z")
    names = list(scenario.design_space.names)
    z = names.index("track.z")
    other = np.array(LAYOUT["x"], dtype=float)
    other[z] = 0.09  # another layout with another height, the same guide
    world = worlds.open_world("sim://world?seed=4")
    worlds.prepare_world(world, scenario)
    worlds.place_parts(world, guide, attempt=1, highlighted=True, scenario=scenario)
    runs = [worlds.run_attempt(scenario, x, guide, world) for x in (np.array(LAYOUT["x"]), other)]
    # the height as placed is the maker's guess, whichever layout the station designed
    assert runs[0].as_placed["track.z"] == runs[1].as_placed["track.z"]
    lower, upper = scenario.design_space.lower[z], scenario.design_space.upper[z]
    guesses = []
    for attempt in range(300):
        worlds.place_parts(world, guide, attempt=attempt, highlighted=True, scenario=scenario)
        guesses.append(worlds.as_placed_layout(scenario, guide, world)[z])
    guesses = np.array(guesses)
    assert lower <= guesses.min() and guesses.max() <= upper
    # spread over the whole range, not gathered round the layout's 60 mm
    assert guesses.std() == pytest.approx((upper - lower) / np.sqrt(12.0), rel=0.15)
    assert np.mean(np.abs(guesses - LAYOUT["x"][z]) < 0.002) < 0.2


@pytest.mark.parametrize("how, option, sigma", [("ruler", "ruler_mm", 1.5), ("jig", "jig_mm", 0.2)])
def test_a_stated_height_is_set_as_the_guide_says_with_its_error(simple_job, how, option, sigma):
    from station.services import world as worlds

    scenario = simple_job.scenario
    parts = tuple(replace(p, settings=tuple(replace(q, set_with=how) if q.name == "track.z" else q
                                             for q in p.settings)) for p in simple_job.guide.parts)
    guide = replace(simple_job.guide, parts=parts)
    (stated,) = [q.value for p in guide.parts for q in p.settings if q.name == "track.z"]
    z = list(scenario.design_space.names).index("track.z")
    world = worlds.open_world(f"sim://world?seed=5&{option}={sigma}")
    heights = []
    for attempt in range(300):
        worlds.place_parts(world, guide, attempt=attempt, highlighted=True, scenario=scenario)
        heights.append(worlds.as_placed_layout(scenario, guide, world)[z] * 1000.0)
    errors = np.array(heights) - stated
    assert errors.std() == pytest.approx(sigma, rel=0.15)
    assert abs(errors.mean()) < 4 * sigma / np.sqrt(len(errors))


def _spread_over_attempts(job, guide, attempts: int = 100) -> dict[str, float]:
    """Each design parameter's standard deviation as the world's maker set it over ``attempts`` placements."""
    from station.services import world as worlds

    world = worlds.open_world("sim://world?seed=3")
    placed = []
    for attempt in range(attempts):
        worlds.place_parts(world, guide, attempt=attempt, highlighted=True, scenario=job.scenario)
        placed.append(worlds.as_placed_layout(job.scenario, guide, world))
    return dict(zip(job.scenario.design_space.names, np.std(placed, axis=0)))


def test_the_station_predicts_each_parameter_with_the_error_the_worlds_maker_makes(simple_job):
    # A forecast places every parameter with the error of how the guide tells the maker to set it (a jig's height
    # 0.2 mm out, a part laid by eye 1 mm with the highlight, a parameter no guide states guessed over its range),
    # the same error the world twin's maker makes: measured over 100 placements, within 20 %.
    from station.services import world as worlds
    from station.services.guide import GuideRequest, make_guide

    job = make_guide(GuideRequest("causalityswitch_ball", None, tolerances=False, jigs=True))
    sigma = worlds.guide_sigma(job.guide, job.scenario, highlighted=True)
    assert sigma["track_joint.z"] == pytest.approx(0.0002) and sigma["track_joint.roll"] == pytest.approx(0.2)
    assert sigma["switch.x"] == pytest.approx(0.001)
    for name, spread in _spread_over_attempts(job, job.guide).items():
        assert spread == pytest.approx(sigma[name], rel=0.2), name
    guessed = _without(simple_job.guide, "track.z")
    sigma = worlds.guide_sigma(guessed, simple_job.scenario, highlighted=True)
    assert sigma["track.z"] == pytest.approx(0.15 / np.sqrt(12))  # its range, 0 to 150 mm
    assert _spread_over_attempts(simple_job, guessed)["track.z"] == pytest.approx(sigma["track.z"], rel=0.2)


def test_a_forecast_sets_each_parameter_as_the_guide_says(simple_job, monkeypatch):
    # As designed, every parameter is placed with the error of its way of setting; after a check, the ones it did
    # not measure (here the track's height and tilt, off the plane) keep theirs, the rest take the check's residual.
    from station.services import world as worlds
    from station.services.assemble import Assembly
    from station.services.trials import load_trial_scenario

    asked = []
    monkeypatch.setattr("station.services.assemble.predict_layout",
                        lambda scenario, x, request, report=None: asked.append(request))
    monkeypatch.setattr("station.services.assemble.Forecast", lambda *args: None)
    assembly = Assembly(simple_job, load_trial_scenario("simple"), camera="sim://camera?supersample=1",
                        world=worlds.open_world("sim://world?seed=2"), highlighted=True, station_camera=False)
    assembly.forecast()
    sigma = worlds.guide_sigma(simple_job.guide, simple_job.scenario, highlighted=True)
    assert asked[-1].set_sigma == sigma and set(asked[-1].unmeasured) == set(sigma)
    assembly.placed()
    assembly.check_parts(seed=1)
    assembly.forecast()
    assert asked[-1].set_sigma == sigma and set(asked[-1].unmeasured) == {"track.z", "track.roll"}


def test_a_forecast_takes_the_checks_error_for_what_the_side_camera_measured(monkeypatch):
    # On its jig stand the track's height and tilt are measured by the side camera: the forecast after that check
    # places them with the check's residual error, not with the jig's (how the guide told the maker to set them).
    from calibration.sim_runs import placement_sigma
    from station.services import world as worlds
    from station.services.assemble import Assembly
    from station.services.guide import GuideRequest, make_guide
    from station.services.trials import load_trial_scenario

    asked = []
    monkeypatch.setattr("station.services.assemble.predict_layout",
                        lambda scenario, x, request, report=None: asked.append(request))
    monkeypatch.setattr("station.services.assemble.Forecast", lambda *args: None)
    job = make_guide(GuideRequest("simple", "success", tolerances=False, jigs=True))
    assembly = Assembly(job, load_trial_scenario("simple"), camera="sim://camera?supersample=1",
                        side_camera="sim://camera?view=side&height=700&tilt=-20&supersample=1",
                        world=worlds.open_world("sim://world?seed=2"), highlighted=True, station_camera=False)
    assembly.placed()
    assembly.check_parts(seed=1)
    assembly.forecast()
    request = asked[-1]
    assert request.unmeasured == ()
    names = list(job.scenario.design_space.names)
    sigma = dict(zip(names, placement_sigma(job.scenario, request.position_sigma_m, request.angle_sigma_deg,
                                            request.unmeasured, request.set_sigma)))
    residual = assembly.check.to_json()["residual_error"]  # as CHECK.json gives it
    assert sigma["track.z"] == pytest.approx(residual["position_mm"] / 1000.0)
    assert sigma["track.roll"] == pytest.approx(residual["heading_deg"])
    assert request.set_sigma["track.z"] == pytest.approx(0.0002) != pytest.approx(sigma["track.z"])


def test_the_loops_side_camera_sees_over_causalityswitchs_parts_to_the_ball_track_on_its_stand():
    # The parts before the board hide its lower tags from a camera at the board's mid-height; the loop's side camera,
    # raised and looking down, finds the board's plane and measures the ball track's height and tilt through J1.
    from station.services import world as worlds
    from station.services.assemble import Assembly
    from station.services.guide import GuideRequest, make_guide
    from station.services.loop import LoopSettings
    from station.services.trials import load_trial_scenario

    settings = LoopSettings(jigs=True)
    job = make_guide(GuideRequest("causalityswitch_ball", "success", tolerances=False, jigs=True))
    assembly = Assembly(job, load_trial_scenario("causalityswitch_ball"), camera=settings.camera,
                        side_camera=settings.side_camera, world=worlds.open_world("sim://world?seed=1"),
                        highlighted=True, station_camera=False)
    assembly.placed()
    check = assembly.check_parts(seed=1).to_json()
    (side,) = [view for view in check["views"] if view["view"] == "side"]
    assert side["plane"] is not None and side["missing_reference_tags"] == []
    assert check["measured_by"]["track_joint.z"] == "side" and check["measured_by"]["track_joint.roll"] == "side"
    truth = dict(zip(job.scenario.design_space.names, worlds.as_placed_layout(job.scenario, job.guide,
                                                                             assembly.world)))
    assert check["as_measured"]["track_joint.z"] == pytest.approx(truth["track_joint.z"], abs=0.0005)


def test_a_guide_without_a_parameter_and_no_ranges_is_refused(simple_job):
    from station.errors import ServiceError
    from station.services import world as worlds

    guide = _without(simple_job.guide, "track.roll")
    world = worlds.open_world("sim://world?seed=4")
    worlds.place_parts(world, guide, attempt=1, highlighted=False)
    with pytest.raises(ServiceError, match="track.roll"):
        worlds.as_placed_layout(simple_job.scenario, guide, world)


def test_the_simulated_maker_cuts_the_jigs_on_the_laser_twin():
    from station.errors import ServiceError
    from station.services import world as worlds
    from station.services.guide import GuideRequest, make_guide

    job = make_guide(GuideRequest("simple", "success", tolerances=False, jigs=True))
    (sheet,) = worlds.cut_jigs(job)
    assert sheet["state"] == "done" and sheet["lines"] > 100
    with pytest.raises(ServiceError, match="no jigs"):
        worlds.cut_jigs(make_guide(GuideRequest("simple", "success", tolerances=False)))


def test_the_loop_with_jigs_sets_their_parameters_on_them_and_says_so(tmp_path, station_home, monkeypatch):
    from drivers.sim.world import forget_worlds, world_named
    from station.loopstore import LoopStore
    from station.services import loop as loops
    from station.services.loop import LoopSettings, run_loop

    # SIMPLE's "success" layout, whose track a stand can carry (the optimizer's may stand it too steep for one)
    success = {"parameters": [{"name": n, "value": v, "lower": lo, "upper": hi} for n, v, lo, hi in
                              (("track.x", -0.06, -0.15, 0.0), ("track.z", 0.06, 0.0, 0.15),
                               ("track.roll", 30.0, 15.0, 75.0))]}
    monkeypatch.setattr(loops._Loop, "optimized", lambda self, *args: success)
    settings = LoopSettings(attempts=1, loops=1, budget=20, candidates=1, rounds=0, baseline=1, predict_samples=1,
                            fit_draws=1, fit_sobol=2, fit_rounds=0, workers=1, jigs=True)
    database = f"sqlite:///{tmp_path / 'loop.sqlite3'}"
    forget_worlds()
    placed = []
    place = loops._Loop.attempt

    def attempt(self, *args, **kwargs):
        stored = place(self, *args, **kwargs)
        placed.append({n: s["set_with"] for n, s in self.world.settings().items()})
        return stored

    monkeypatch.setattr(loops._Loop, "attempt", attempt)
    try:
        result = run_loop("simple", "sim://world?seed=3&name=jigs", settings, database=database)
        assert world_named("jigs") is not None
    finally:
        forget_worlds()
    # loop 1 on the stand J1 (it sets the track's place along the table, its height and its tilt); the baseline,
    # the thesis's workflow, with a ruler
    assert placed == [{"track.x": "jig", "track.z": "jig", "track.roll": "jig"},
                      {"track.x": "check", "track.z": "ruler", "track.roll": "ruler"}]
    assert result.to_json()["jigs"] is True and result.loops[0].jigs
    with LoopStore(database) as store:
        (loop_attempt,) = store.attempts(result.run_id, 1)
        (baseline,) = store.attempts(result.run_id, 0)
        trial = store.trial(loop_attempt.trial_id)
        assert "set on laser-cut jigs J1" in trial["notes"]
        assert "jigs" not in store.trial(baseline.trial_id)["notes"]
        # its check read the stand's face tag with the side camera: the height and tilt measured, not placed blind
        assert "the side camera measured track.z, track.roll" in trial["notes"]
        assert [v["view"] for v in trial["check"]["views"]] == ["top", "side"]
        assert trial["check"]["measured_by"] == {"track.x": "top", "track.z": "side", "track.roll": "side"}
        assert store.trial(baseline.trial_id)["check"] is None
    # another run: with jigs or without is part of what a run is
    plain = run_loop("simple", "sim://world?seed=3", LoopSettings(**{**settings.__dict__, "jigs": False}),
                     database=database)
    assert plain.run_id != result.run_id and plain.to_json()["jigs"] is False


def test_the_loops_resume_command_keeps_jigs():
    import shlex

    from station.cli import build_parser
    from station.commands.loop import resume_command

    args = build_parser().parse_args(["loop", "simple", "--world", "sim://world?seed=2", "--jigs"])
    words = shlex.split(resume_command(args))
    assert "--jigs" in words
    assert build_parser().parse_args(words[1:]).jigs is True


@pytest.mark.slow  # two guides with their tolerance maps: about 20 s
def test_an_assembly_with_jigs_sets_their_parameters_on_them(station_home, monkeypatch):
    from station.services import assemble

    cut = []
    # the attempt cuts through the name it imported, so that is the one to replace
    monkeypatch.setattr(assemble, "cut_jigs", lambda job, *args: cut.append([j.id for j in job.jigs.plan.jigs]))
    for jigs, expected in ((True, "jig"), (False, "ruler")):
        request = assemble.AssemblyRequest("simple", "success", world="sim://world?seed=1", samples=1, jigs=jigs)
        assembly = assemble.open_assembly(request)
        try:
            assembly.placed()
            assert {n: s["set_with"] for n, s in assembly.world.settings().items()}["track.z"] == expected
        finally:
            assembly.close()
    assert cut == [["J1"]]  # the simulated maker cut them once, for the assembly with jigs
