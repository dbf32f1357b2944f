"""Simulator calibration: trials made by the simulator under hidden material values are fitted back (fast version;
the full acceptance is bench/bench_sim_calibration.py)."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

from calibration.errors import CalibrationError
from calibration.sim_fit import FitSettings, fit_simulator
from calibration.sim_predict import attempts_of, predict_success
from calibration.sim_runs import NOT_REACHED, YES, OutcomeProblem, noisy_layouts, placement_sigma, wilson_interval
from calibration.sim_trials import export_trials, fit_trials
from design.contraption import load_scenario
from station.services.world import synthetic_trials
from station.services.world import trials_export as export

DATA = Path(__file__).resolve().parents[1] / "data" / "calibration"
EXAMPLES = Path(__file__).parents[2] / "examples" / "scenarios"


@pytest.fixture(scope="module")
def slide():
    return load_scenario(DATA / "slide.toml")


@pytest.fixture(scope="module")
def slide_trials(slide):
    rng = np.random.default_rng(1)
    return synthetic_trials(slide, [[a] for a in rng.uniform(30, 40, 10)], {"wood.friction": 0.55}, seed=2)


def test_friction_recovered_from_ten_timed_runs(slide, slide_trials):
    trials = fit_trials(slide_trials, {"SLIDE": slide})
    fit = fit_simulator(trials, slide.uncertain_parameters(),
                        settings=FitSettings(draws=4, sobol=8, rounds=2, per_round=3, seed=0))
    (friction,) = fit.parameters
    print(f"friction: hidden 0.55, fitted {friction.value:.4f} [{friction.interval[0]:.4f}, "
          f"{friction.interval[1]:.4f}], log-likelihood {fit.log_likelihood_before:.1f} -> "
          f"{fit.log_likelihood_after:.1f}")
    assert abs(friction.value - 0.55) <= 0.05 * 0.55
    assert friction.interval[0] <= friction.value <= friction.interval[1]
    assert fit.log_likelihood_after > fit.log_likelihood_before
    lands = next(a for a in fit.agreement if a.event == "block_lands")
    assert lands.agreement_after >= lands.agreement_before
    assert set(fit.to_json()) == {"parameters", "trials", "brier_before", "brier_after"}
    assert fit.to_json()["trials"] == 10 and fit.held_out == 3


def test_restitution_recovered_from_bounce_times():
    bounce = load_scenario(DATA / "bounce.toml")
    rng = np.random.default_rng(5)
    raw = synthetic_trials(bounce, [[z] for z in rng.uniform(0.05, 0.2, 6)], {"rubber.restitution": 0.72}, seed=6)
    fit = fit_simulator(fit_trials(raw, {"BOUNCE": bounce}), bounce.uncertain_parameters(),
                        settings=FitSettings(draws=2, sobol=8, rounds=1, per_round=3, held_out=0.0, seed=0))
    (restitution,) = fit.parameters
    print(f"restitution: hidden 0.72, fitted {restitution.value:.4f}")
    assert abs(restitution.value - 0.72) <= 0.15 * 0.72
    assert fit.brier_before is None and fit.held_out == 0


def test_the_prior_keeps_a_value_the_trials_say_nothing_about():
    # A vertical drop does not depend on the ball's friction: the likelihood is flat along it, and only the prior
    # (centred on the scenario's 0.5) decides it; restitution is still read from the bounce times.
    bounce = load_scenario(DATA / "bounce.toml")
    rng = np.random.default_rng(5)
    raw = synthetic_trials(bounce, [[z] for z in rng.uniform(0.05, 0.2, 6)], {"rubber.restitution": 0.72}, seed=6)
    parameters = {**bounce.uncertain_parameters(), "rubber.friction": (0.5, (0.2, 0.8))}
    fit = fit_simulator(fit_trials(raw, {"BOUNCE": bounce}), parameters,
                        settings=FitSettings(draws=2, sobol=8, rounds=1, per_round=3, held_out=0.0, seed=0))
    values, intervals = fit.values(), fit.intervals()
    print(f"prior 0.25: restitution {values['rubber.restitution']:.3f}, friction {values['rubber.friction']:.3f} "
          f"{intervals['rubber.friction']}")
    assert abs(values["rubber.restitution"] - 0.72) <= 0.15 * 0.72
    assert abs(values["rubber.friction"] - 0.5) <= 0.05
    low, high = intervals["rubber.friction"]
    assert 0.2 <= low < 0.5 < high <= 0.8
    assert fit.prior_width == 0.25 and fit.fit_summary()["prior_width"] == 0.25
    with pytest.raises(CalibrationError, match="prior_width"):
        FitSettings(prior_width=0.0)


def test_outcome_problem_numbers_through_the_executor_cache(slide, tmp_path):
    from design.robust.executor import SimulationCache, SimulationExecutor, cache_scope

    problem = OutcomeProblem(slide, ["wood.friction"], {"wood.friction": (0.3, 0.8)})
    rows = problem.rows(np.array([[0.5], [0.5]]), np.array([[35.0], [20.0]]))
    with SimulationExecutor(problem, backend="inline", cache_path=tmp_path / "c.sqlite3") as executor:
        out = executor.run(rows)
    success, codes, times = problem.split(out)
    assert success.tolist() == [1.0, 0.0]
    assert codes[0].tolist() == [YES, YES] and codes[1].tolist() == [0.0, NOT_REACHED]
    assert np.isfinite(times[0]).all() and np.isnan(times[1]).all()
    with SimulationExecutor(problem, backend="inline", cache_path=tmp_path / "c.sqlite3") as executor:
        again = executor.run(rows)
        assert executor.n_simulated == 0 and executor.n_cache_hits == 2
    np.testing.assert_array_equal(again, out)
    assert SimulationCache(tmp_path / "c.sqlite3").count(cache_scope(problem)) == 2


def test_trials_are_read_as_logged_and_bad_ones_refused(slide, slide_trials):
    trials = fit_trials(export_trials(export(slide_trials)), {"SLIDE": slide, "OTHER": slide})
    assert len(trials) == 10 and trials[0].layout.shape == (1,)
    assert (trials[0].position_sigma_m, trials[0].angle_sigma_deg) == (0.001, 1.0)
    checked = copy.deepcopy(slide_trials[0])
    checked["as_built"] = {"plank.roll": 33.5}
    checked["check"] = {"residual_error": {"position_mm": 2.0, "heading_deg": 0.5}}
    (one,) = fit_trials([checked], {"SLIDE": slide})
    assert one.as_built and one.layout[0] == 33.5 and (one.position_sigma_m, one.angle_sigma_deg) == (0.002, 0.5)
    assert one.unmeasured == ()
    checked["check"]["not_measured"] = ["plank.roll"]
    assert fit_trials([checked], {"SLIDE": slide})[0].unmeasured == ("plank.roll",)
    assert fit_trials(slide_trials, {"BALLRUN": slide}) == []
    for change, message in [
        (lambda t: t["outcomes"].update(block_slides="maybe"),
         "t.json: trials[0].outcomes.block_slides: expected yes, no or not-reached, got 'maybe'"),
        (lambda t: t["outcomes"].pop("block_lands"),
         "t.json: trials[0].outcomes.block_lands: expected yes, no or not-reached, got nothing"),
        (lambda t: t["times"].update(nothing=1.0), "t.json: trials[0].times.nothing: not an event of 'SLIDE'"),
        (lambda t: t["layout"].update({"plank.x": 0.1}), "t.json: trials[0].layout.plank.x: not a design parameter"),
        (lambda t: t.update(success="yes"), "t.json: trials[0].success: expected true or false"),
        (lambda t: t.update(check={"not_measured": ["plank.x"]}),
         "t.json: trials[0].check.not_measured: 'plank.x' is not a design parameter (expected one of plank.roll)"),
        (lambda t: t.update(check={"not_measured": "plank.roll"}),
         "t.json: trials[0].check.not_measured: expected a list of design parameter names, got 'plank.roll'"),
        (lambda t: t["scenario"].update(content="[[objects]]\nname = 1\n"), "trials[0].scenario.content"),
    ]:
        bad = copy.deepcopy(slide_trials[0])
        change(bad)
        with pytest.raises(CalibrationError) as error:
            fit_trials([bad], {"SLIDE": slide}, "t.json")
        assert message in str(error.value) and "\n" not in str(error.value)
    with pytest.raises(CalibrationError, match="t.json: version: expected 1"):
        export_trials({"format": "chaos-station trials", "version": 2, "trials": []}, "t.json")


@pytest.mark.parametrize("position, angle, unmeasured, expected", [
    (0.0002, 0.3, (), [0.0002, 0.3, 0.0002, 0.0002]),
    # what a check did not measure is placed as with no check: 1 mm, 1 degree
    (0.0002, 0.3, ("plank.x", "track.roll"), [0.001, 1.0, 0.0002, 0.0002]),
    # and never more precisely than what it measured
    (0.003, 2.0, ("track.roll", "goblet.x"), [0.003, 2.0, 0.003, 0.003]),
])
def test_a_parameter_no_check_measured_keeps_the_unchecked_error(position, angle, unmeasured, expected):
    scenario = load_scenario(EXAMPLES / "branching.toml")
    assert scenario.design_space.names == ("plank.x", "track.roll", "lever.x", "goblet.x")
    assert placement_sigma(scenario, position, angle, unmeasured).tolist() == expected
    layouts = noisy_layouts(scenario, scenario.design_space.default, 4000, position, angle,
                            np.random.default_rng(0), unmeasured)
    assert np.allclose(layouts.std(axis=0), expected, rtol=0.05)


def test_predicted_success_with_interval_and_attempts(slide):
    steep = predict_success(slide, np.array([38.0]), samples=12, seed=0)
    assert steep.probability == 1.0 and steep.attempts == 1.0 and steep.interval[0] > 0.7
    # Near the threshold, a profile's friction interval spreads the outcomes.
    near = predict_success(slide, np.array([30.5]), values={"wood.friction": 0.5},
                           intervals={"wood.friction": (0.45, 0.55)}, samples=24, seed=1)
    assert 0.0 < near.probability < 1.0
    assert near.interval[0] < near.probability < near.interval[1]
    assert near.attempts_interval[0] <= near.attempts <= near.attempts_interval[1]
    assert attempts_of(0.0, (0.0, 0.1)) == (np.inf, (10.0, np.inf))


def test_wilson_interval_matches_the_formula():
    lo, hi = wilson_interval(8, 10)
    assert (round(lo, 4), round(hi, 4)) == (0.4902, 0.9433)  # the textbook values for 8 of 10
    assert wilson_interval(0, 0) == (0.0, 1.0)
