"""Simulator calibration recovers hidden material values (issue 20's acceptance), seeded.

Trials are made by the simulator itself under hidden material values with 1 mm / 1 degree placement errors
(:mod:`calibration.sim_synthetic`), written in the trial log's export format, read back and fitted with the default
settings (:class:`calibration.sim_fit.FitSettings`). Targets: friction within ±5 % from 10 runs with event times
and from 30 runs with outcomes only; restitution within ±15 %; the held-out Brier score of the success probability
improves. Scenarios: SLIDE (a block on a tilted plank, friction) and BOUNCE (a ball dropped on a plate, restitution),
tests/calibration/data. About 2-4 minutes on one core.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parents[1] / "tests" / "calibration" / "data"

#: (label, scenario file, hidden values, designed layouts' range, runs, with times, tolerance)
CASES = [
    ("friction, 10 timed runs", "slide.toml", {"wood.friction": 0.55}, (27.0, 37.0), 10, True, 0.05),
    ("friction, 30 runs, outcomes only", "slide.toml", {"wood.friction": 0.55}, (25.0, 36.0), 30, False, 0.05),
    ("restitution, 10 timed runs", "bounce.toml", {"rubber.restitution": 0.72}, (0.035, 0.15), 10, True, 0.15),
    ("restitution, 30 runs, outcomes only", "bounce.toml", {"rubber.restitution": 0.72}, (0.03, 0.12), 30, False,
     0.15),
]


def run_case(label, file, hidden, span, runs, times, tolerance, seed: int = 0) -> bool:
    from calibration.sim_fit import FitSettings, fit_simulator
    from calibration.sim_synthetic import export, synthetic_trials
    from calibration.sim_trials import export_trials, fit_trials
    from design.contraption import load_scenario

    scenario = load_scenario(DATA / file)
    rng = np.random.default_rng(100 + seed)
    layouts = [[v] for v in rng.uniform(*span, runs)]
    raw = export(synthetic_trials(scenario, layouts, hidden, seed=200 + seed, times=times))
    trials = fit_trials(export_trials(raw), {scenario.name: scenario})
    start = time.perf_counter()
    fit = fit_simulator(trials, scenario.uncertain_parameters(), settings=FitSettings(seed=seed))
    seconds = time.perf_counter() - start
    ok = True
    print(f"  {label} ({scenario.name}, seed {seed}): {fit.trials} fitted + {fit.held_out} held out, "
          f"{fit.simulations} simulations, {seconds:.0f} s")
    for p in fit.parameters:
        truth = hidden[p.name]
        error = (p.value - truth) / truth
        inside = p.interval[0] <= truth <= p.interval[1]
        good = abs(error) <= tolerance
        ok &= good
        print(f"    {p.name}: hidden {truth:.3f}, file {p.before:.3f}, fitted {p.value:.4f} ({error:+.1%}; target "
              f"±{tolerance:.0%}: {'ok' if good else 'MISSED'}), 95 % interval [{p.interval[0]:.4f}, "
              f"{p.interval[1]:.4f}] {'holds' if inside else 'misses'} the hidden value")
    if fit.brier_before is not None:
        better = fit.brier_after < fit.brier_before
        ok &= better or fit.brier_before == 0.0
        print(f"    held-out Brier {fit.brier_before:.4f} -> {fit.brier_after:.4f} "
              f"({'improves' if better else 'does not improve'})")
    print(f"    log-likelihood {fit.log_likelihood_before:.1f} -> {fit.log_likelihood_after:.1f}")
    return ok


def main() -> None:
    results = [run_case(*case) for case in CASES]
    print(f"  recovery: {sum(results)} of {len(results)} cases met their targets")


if __name__ == "__main__":
    main()
