"""Different seeds give different runs: the counterparts of the suite's determinism tests.

A determinism test ("the same seed gives the same run") also passes when the seed is ignored altogether. Each test
here pairs with one of them and checks that another seed changes the run:

- tests/design/robust/test_pipeline.py::test_placement_error_energy_is_the_mean_over_clipped_offsets
  (placement offsets);
- tests/design/robust/test_pipeline.py::test_pipeline_is_reproducible_and_the_cache_avoids_resimulation and
  ::test_process_and_dask_backends_give_the_local_result (the whole optimization);
- tests/station/commands/test_robust_simple.py::test_simple_optimization_is_valid_and_cached (on SIMPLE: which layouts
  of the real scenario are simulated) and ::test_cli_optimize_repeats_a_run_from_its_layout_file
  (``--seed`` of the CLI).

(tests/design/sketch/test_synthetic.py has its own counterpart, next to its determinism test.)
"""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from design.robust import PSPSettings, SimulationExecutor, explore, optimize_robust_layout, synthetic_chain
from design.robust.optimize import placement_offsets

ROOT = Path(__file__).resolve().parents[3]
SIMPLE = ROOT / "examples" / "scenarios" / "simple.toml"
#: The settings of tests/design/robust/test_pipeline.py's reproducibility test.
SMALL = PSPSettings(n_initial=128, n_successes=40, max_exploration_steps=20)


def simulated_layouts(cache: Path) -> set[str]:
    """The layouts (cache keys) a run simulated."""
    with sqlite3.connect(cache) as db:
        return {row[0] for row in db.execute("SELECT layout FROM simulations")}


def test_placement_offsets_depend_on_the_seed():
    a, again, b = (placement_offsets(2, 0.1, 32, seed=s) for s in (3, 3, 4))
    assert np.array_equal(a, again)
    # The origin comes first whatever the seed; every other offset moves.
    assert np.array_equal(a[0], b[0]) and not np.isclose(a[1:], b[1:]).any()


def test_another_seed_gives_another_optimization_run(tmp_path):
    problem = synthetic_chain()
    runs, layouts = {}, {}
    for seed in (4, 4, 5):
        cache = tmp_path / f"seed-{seed}-{len(runs)}.sqlite3"
        with SimulationExecutor(problem, backend="inline", cache_path=cache) as executor:
            runs.setdefault(seed, []).append(optimize_robust_layout(problem, executor, budget=200, seed=seed,
                                                                    settings=SMALL))
        layouts.setdefault(seed, []).append(simulated_layouts(cache))
    (first, again), (other,) = runs[4], runs[5]
    assert layouts[4][0] == layouts[4][1] and np.array_equal(first.u, again.u)
    # Another seed simulates other layouts (a scrambled Sobol start and exploration draws of its own): the two runs
    # share hardly any, and start their optimization from another best sample.
    shared = layouts[4][0] & layouts[5][0]
    assert len(shared) < 0.1 * min(len(layouts[4][0]), len(layouts[5][0]))
    assert not np.array_equal(first.u_best_sample, other.u_best_sample)
    assert (first.seed, other.seed) == (4, 5)


@pytest.mark.skipif(not SIMPLE.exists(), reason="the SIMPLE scenario file is missing")
def test_another_seed_simulates_other_layouts_of_simple():
    # Which layouts of the real scenario a run simulates first (its Sobol start, then exploration) is all the seed
    # decides; the physics has no randomness. The oracle records them instead of simulating (every event fails).
    from design.robust.contraption import load_problem

    simple = load_problem(SIMPLE)
    settings = PSPSettings(n_initial=12, n_successes=20, max_exploration_steps=2, max_active_steps=1, n_per_step=6)

    def asked(seed: int) -> np.ndarray:
        rows = []

        def oracle(U):
            rows.append(np.array(U))
            return np.zeros((len(U), len(simple.event_names)), dtype=bool)

        explore(simple, oracle, settings, seed, max_simulations=24)
        return np.concatenate(rows)

    first, again, other = asked(1), asked(1), asked(2)
    assert np.array_equal(first, again)
    assert first.shape == other.shape and simple.is_valid(other).all()
    assert not np.isclose(first[:, None, :], other[None, :, :]).all(axis=2).any()


def test_cli_optimize_seed_changes_the_run(tmp_path, monkeypatch, capsys):
    # The CLI on a cheap synthetic problem (the scenario loader is replaced): --seed must reach the pipeline.
    import station.commands.robust as robust
    from station.cli import main

    monkeypatch.setattr(robust, "_load_problem", lambda path: synthetic_chain())
    # A one-point SVM grid keeps the learning quick (--settings takes them from a LAYOUT.json).
    settings = tmp_path / "settings.json"
    settings.write_text(json.dumps({"psp_settings": {"c_grid": [10.0], "gamma_grid": [1.0]}}))
    outputs = []
    for seed in (3, 3, 4):
        out = tmp_path / f"layout-{len(outputs)}.json"
        code = main(["optimize", "synthetic", "--budget", "40", "--workers", "1", "--seed", str(seed),
                     "--settings", str(settings), "--out", str(out)])
        assert code in (0, 1), capsys.readouterr().err
        outputs.append(json.loads(out.read_text()))
    first, again, other = outputs
    assert first["best_sample"] == again["best_sample"] and first["parameters"] == again["parameters"]
    assert other["best_sample"]["normalized"] != first["best_sample"]["normalized"]
    assert [o["seed"] for o in outputs] == [3, 3, 4]
