"""A stop asked for in the middle of each long workflow ends it with the one :class:`common.progress.Cancelled`,
between two units of work, the work done so far kept: a simulation batch, an optimization, a simulator calibration,
a laser job and a pen plot being written, and the station loop."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from calibration.sim_fit import FitSettings, Runner, fit_simulator
from calibration.sim_trials import fit_trials
from common.progress import Cancelled, Progress, Reporter
from design.contraption import load_scenario
from design.robust import PSPSettings, SimulationCache, SimulationExecutor, synthetic_chain
from design.robust.executor import cache_scope
from drivers.profiles import load_profile
from station.services import plot as plot_service
from station.services import robust
from station.services.fabricate import FabricationRequest, fabricate
from station.services.loop import LoopSettings, run_loop
from station.services.world import synthetic_trials

ROOT = Path(__file__).resolve().parents[2]
SMALL = PSPSettings(n_initial=128, n_successes=40, max_exploration_steps=20)


def stopping_at(condition) -> tuple[list[Progress], Reporter]:
    """A reporter that keeps what it is told and asks to stop once ``condition(seen)`` holds."""
    seen: list[Progress] = []
    return seen, Reporter(seen.append, stop=lambda: condition(seen))


def test_a_simulation_batch_stops_between_arrivals_with_the_finished_ones_cached(tmp_path):
    problem = synthetic_chain()
    cache = tmp_path / "sims.sqlite3"
    layouts = np.random.default_rng(3).random((20, problem.dim)) * 0.5
    arrived: list[int] = []
    with SimulationExecutor(problem, backend="inline", cache_path=cache) as executor:
        with pytest.raises(Cancelled):
            executor.run(layouts, on_result=arrived.append, report=Reporter(stop=lambda: len(arrived) >= 5))
        assert executor.n_simulated == 5
    assert SimulationCache(cache).count(cache_scope(problem)) == 5


def test_an_optimization_stops_and_says_how_many_new_simulations_the_cache_keeps():
    problem = synthetic_chain()
    seen, report = stopping_at(lambda seen: bool(seen) and seen[-1].done >= 40)
    with pytest.raises(Cancelled) as stopped:
        robust.optimize(problem, 200, 0, SMALL, workers=1, report=report)
    assert 0 < stopped.value.new_simulations <= 40 <= seen[-1].done
    assert stopped.value.cache == robust.simulation_cache_path()
    assert SimulationCache(stopped.value.cache).count(cache_scope(problem)) == stopped.value.new_simulations
    assert f"the {stopped.value.new_simulations} new simulations of this run are kept" in str(stopped.value)


def test_a_simulator_calibration_stops_between_its_simulation_batches():
    slide = load_scenario(ROOT / "tests" / "data" / "calibration" / "slide.toml")
    rng = np.random.default_rng(1)
    trials = fit_trials(synthetic_trials(slide, [[a] for a in rng.uniform(30, 40, 4)], {"wood.friction": 0.55},
                                         seed=2), {"SLIDE": slide})
    seen, report = stopping_at(lambda seen: len(seen) >= 3)
    with pytest.raises(Cancelled):
        fit_simulator(trials, slide.uncertain_parameters(), run=Runner(report=report),
                      settings=FitSettings(draws=4, sobol=8, rounds=2, per_round=3, seed=0))
    assert len(seen) == 3 and {p.stage for p in seen} == {"simulations"}


def test_a_laser_job_stops_between_its_steps():
    seen, report = stopping_at(lambda seen: bool(seen) and seen[-1].stage == "nesting")
    with pytest.raises(Cancelled):
        fabricate(FabricationRequest("hoot_nanny", {}, 4.0), report=report)
    stages = list(dict.fromkeys(p.stage for p in seen))
    assert stages == ["sizes", "gears", "nesting"]  # stopped before any sheet or its job was written


def test_a_pen_plot_stops_between_its_layers_before_any_gcode_is_written(tmp_path):
    sources = []
    for number in range(3):  # three drawings, one layer (one pen) each
        svg = tmp_path / f"layer{number}.svg"
        svg.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="100mm" viewBox="0 0 100 100">'
                       f'<path style="fill:none;stroke:black" d="M 10,{10 + 20 * number} L 90,{20 + 20 * number}"/>'
                       "</svg>")
        sources.append(plot_service.SvgSource(svg))
    composition = plot_service.Composition(sources)
    seen, report = stopping_at(lambda seen: [p.stage for p in seen].count("optimize") >= 2)
    with pytest.raises(Cancelled):
        plot_service.plot(composition, load_profile("plotter"), report=report)
    assert [p.stage for p in seen] == ["compose", "optimize", "optimize"]  # the second layer's turn: stopped
    done = plot_service.plot(composition, load_profile("plotter"), report=Reporter())
    assert len(done.layers) == 3 and "G1" in done.gcode  # the same plot, not stopped, runs to its end


def test_the_loop_stops_in_the_middle_with_what_it_logged(tmp_path):
    settings = LoopSettings(attempts=1, loops=1, budget=20, baseline=0, predict_samples=2, fit_draws=1,
                            fit_sobol=3, fit_rounds=0, workers=1)
    seen, report = stopping_at(lambda seen: len(seen) >= 2)
    with pytest.raises(Cancelled) as stopped:
        run_loop("simple", "sim://world?seed=2", settings, database=str(tmp_path / "loop.sqlite3"), report=report)
    log = stopped.value.partial
    assert log.run_id == 1 and log.attempts == 0 and str(stopped.value).startswith("run 1 stopped:")
    assert len(seen) == 2 and seen[0].stage.startswith("loop 1")
