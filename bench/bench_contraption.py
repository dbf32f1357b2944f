"""Simulations per second of each example scenario, with and without early termination (thesis 4.3 / 5.2).

For each scenario: its success and failure layouts plus random physically valid layouts (fixed seed) are simulated
twice, stopping at the causal graph's termination and running to ``max_duration``. Prints simulations per second,
the speed-up in wall time and in time steps (the latter does not depend on the machine's load), and the fraction
of identical labels (global success) and identical decided event states between the two.
"""

from __future__ import annotations

import time

import numpy as np

from design.contraption import Simulator, load_scenario
from design.contraption.catalog import EXAMPLES_DIR, example_names

RANDOM_LAYOUTS = 8
SEED = 0


def layouts_for(scenario, sim: Simulator, rng: np.random.Generator) -> list[np.ndarray]:
    layouts = [scenario.layout(name) for name in ("success", "failure") if name in scenario.layouts]
    attempts = 0
    while len(layouts) < RANDOM_LAYOUTS + 2 and attempts < 200:
        attempts += 1
        x = scenario.design_space.from_normalized(rng.random(scenario.design_space.dim))
        if not sim.check_validity(x):
            layouts.append(x)
    return layouts


def main() -> None:
    rng = np.random.default_rng(SEED)
    header = (
        f"{'scenario':<26} {'n':>3} {'sims/s early':>12} {'sims/s full':>12} {'speed-up':>9} "
        f"{'steps ratio':>11} {'same label':>10} {'same events':>11} {'successes':>9}"
    )
    print(header)
    print("-" * len(header))
    speedups, step_ratios, agreements = [], [], []
    for name in example_names():
        scenario = load_scenario(EXAMPLES_DIR / f"{name}.toml")
        with Simulator(scenario) as sim:
            layouts = layouts_for(scenario, sim, rng)
            start = time.perf_counter()
            early = [sim.run(x, early_stop=True) for x in layouts]
            early_time = time.perf_counter() - start
            start = time.perf_counter()
            full = [sim.run(x, early_stop=False) for x in layouts]
            full_time = time.perf_counter() - start
        n = len(layouts)
        same_label = np.mean([a.success == b.success for a, b in zip(early, full)])
        # Events decided before the early stop keep their state and time in the full run.
        same_events = np.mean(
            [
                all(b.events[k] == v for k, v in a.events.items() if v.state in ("success", "failure"))
                for a, b in zip(early, full)
            ]
        )
        speedup = full_time / early_time
        steps_ratio = sum(r.steps for r in full) / sum(r.steps for r in early)
        speedups.append(speedup)
        step_ratios.append(steps_ratio)
        agreements.append(same_label)
        print(
            f"{scenario.name[:26]:<26} {n:>3} {n / early_time:>12.2f} {n / full_time:>12.2f} {speedup:>8.2f}x "
            f"{steps_ratio:>10.2f}x "
            f"{same_label:>10.0%} {same_events:>11.0%} {sum(r.success for r in early):>9}",
            flush=True,
        )
    print("-" * len(header))
    print(
        f"mean speed-up with early termination: {np.mean(speedups):.2f}x "
        f"(geometric {np.exp(np.mean(np.log(speedups))):.2f}x) in time, {np.mean(step_ratios):.2f}x in steps "
        f"(load-independent); identical labels: {np.mean(agreements):.0%}"
    )
