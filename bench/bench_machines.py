"""Drawing-machine models: curve sampling time, batch throughput, slider-bound and feasibility speed.

Run with ``.venv/bin/python -m bench machines``. Prints figures only (no timing assertions).
"""

from __future__ import annotations

import numpy as np

from bench import best_time
from design.machines import get_machine, machine_names
from design.machines.parameters import random_in_boxes

POINTS = 4096
BATCH_DESIGNS = 1000
BATCH_POINTS = 256
SEED = 0


def random_feasible_designs(machine, k: int, seed: int = SEED) -> dict[str, np.ndarray]:
    """``k`` feasible designs by rejection sampling in the parameter boxes (gear radii 1..12, lengths <= 25)."""
    rng = np.random.default_rng(seed)
    chosen: dict[str, list[np.ndarray]] = {p.name: [] for p in machine.parameters}
    found = 0
    while found < k:
        rows = random_in_boxes(machine.parameters, 50_000, rng)
        ok = machine.feasible_mask(rows)
        for name in chosen:
            chosen[name].append(rows[name][ok])
        found += int(ok.sum())
    return {name: np.concatenate(parts)[:k] for name, parts in chosen.items()}


def main() -> None:
    names = [n for n in machine_names() if n in ("spirograph", "elliptic_spirograph", "cycloid_drawing_machine",
                                                  "hoot_nanny")]  # fmt: skip
    print(f"curve sampling, one design, {POINTS} points (best of 7):")
    print(f"  {'machine':<25} {'time spacing':>13} {'arc length':>11} {'ratio':>6}")
    for name in names:
        machine = get_machine(name)
        design = machine.defaults()
        uniform = best_time(lambda m=machine, d=design: m.sample(d, POINTS, "time"))
        arclength = best_time(lambda m=machine, d=design: m.sample(d, POINTS, "arclength"))
        print(f"  {name:<25} {uniform * 1e3:>10.2f} ms {arclength * 1e3:>8.2f} ms {arclength / uniform:>5.1f}x")

    print(f"\nbatch sampling, {BATCH_DESIGNS} random feasible designs x {BATCH_POINTS} points (sample_many):")
    print(f"  {'machine':<25} {'time spacing':>16} {'arc length':>16} {'one by one':>16} {'batch gain':>10}")
    for name in names:
        machine = get_machine(name)
        rows = random_feasible_designs(machine, BATCH_DESIGNS)
        uniform = best_time(lambda m=machine, r=rows: m.sample_many(r, BATCH_POINTS, "time", check=False), 3)
        arclength = best_time(lambda m=machine, r=rows: m.sample_many(r, BATCH_POINTS, "arclength", check=False), 3)
        single_rows = [{k: float(v[i]) for k, v in rows.items()} for i in range(100)]
        single = best_time(lambda m=machine, r=single_rows: [m.sample(x, BATCH_POINTS, "time") for x in r], 3) / 100
        print(
            f"  {name:<25} {BATCH_DESIGNS / uniform:>10.0f} des/s {BATCH_DESIGNS / arclength:>10.0f} des/s "
            f"{1 / single:>10.0f} des/s {single * BATCH_DESIGNS / uniform:>9.1f}x"
        )

    print("\nslider bounds (feasible_interval at the default design, best of 20), and vectorized feasibility:")
    for name in names:
        machine = get_machine(name)
        design = machine.defaults()
        timings = [
            best_time(lambda m=machine, d=design, p=p: m.feasible_interval(d, p), 20) * 1e3
            for p in machine.continuous_names
        ]
        rows = random_feasible_designs(machine, 10, seed=1)
        grid = {k: np.resize(v, 100_000) for k, v in rows.items()}
        mask = best_time(lambda m=machine, g=grid: m.feasible_mask(g), 3)
        print(
            f"  {name:<25} feasible_interval mean {np.mean(timings):.2f} ms, max {np.max(timings):.2f} ms "
            f"({len(timings)} sliders); feasible_mask {100_000 / mask / 1e6:.2f} M designs/s"
        )


if __name__ == "__main__":
    main()
