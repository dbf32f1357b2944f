"""The resumable Table 4.2 bench (bench/bench_robust.py): each finished run is stored as it ends, a rerun skips the
stored runs and reads them back, and no run leaves its simulations for another's (honest times)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench import bench_robust
from design.robust import PSPSettings, SimulationCache, synthetic_chain
from design.robust.executor import cache_scope

SMALL = PSPSettings(n_initial=32, n_successes=10, max_exploration_steps=5)
N_EVALUATION = 96


class Interrupted(Exception):
    """Stands in for the end of a work session in the middle of a run."""


def resumable(problem, directory, runs=1):
    return bench_robust.run_resumable(problem, "chain", 60, runs, N_EVALUATION, 6, ("ours", "b1"), settings=SMALL,
                                      settings_name="small", directory=directory, backend="inline", workers=1,
                                      log=lambda line: None)


def test_an_interrupted_comparison_resumes_where_it_stopped_and_reads_its_runs_back(tmp_path, monkeypatch):
    problem = synthetic_chain()
    real = bench_robust.compare_methods
    calls = []

    def interrupted_at_b1(problem, executor, methods, *args, **kwargs):
        if methods == ["b1"]:
            raise Interrupted
        return real(problem, executor, methods, *args, **kwargs)

    monkeypatch.setattr(bench_robust, "compare_methods", interrupted_at_b1)
    with pytest.raises(Interrupted):
        resumable(problem, tmp_path)
    stored = json.loads(next(tmp_path.glob("chain-*.json")).read_text())
    assert list(stored["runs"]) == ["ours/seed0"]
    assert stored["config"]["scope"] == cache_scope(problem)

    def counted(problem, executor, methods, runs, budget, seed, *args, **kwargs):
        calls.append((methods[0], seed, budget))
        return real(problem, executor, methods, runs, budget, seed, *args, **kwargs)

    monkeypatch.setattr(bench_robust, "compare_methods", counted)
    comparison, store, missing = resumable(problem, tmp_path)
    ours = store.get("ours", 0, 60)
    # only the missing run ran, at the baselines' budget: what ours used
    assert calls == [("b1", 0, ours["simulations"])] and missing == []
    assert comparison.budget == ours["simulations"]
    # the CPU seconds of each run's timed part are stored beside its wall time (compare_methods's on_timed)
    assert all(isinstance(r["cpu_seconds"], float) for r in store.runs.values())
    # the evaluation set is all the shared cache holds: each run paid for its own simulations
    assert SimulationCache(store.evaluation_cache).count() == N_EVALUATION

    def not_again(*args, **kwargs):
        raise AssertionError("a stored run ran again")

    monkeypatch.setattr(bench_robust, "compare_methods", not_again)
    again, _, missing = resumable(problem, tmp_path)
    assert missing == []
    assert [(r.method, r.seed, r.n_simulations, r.seconds) for r in again.runs] == \
        [(r.method, r.seed, r.n_simulations, r.seconds) for r in comparison.runs]
    for read, ran in zip(again.runs, comparison.runs, strict=True):
        assert read.curve.global_robustness == ran.curve.global_robustness
        assert np.array_equal(read.u, ran.u) and np.array_equal(read.curve.local, ran.curve.local)
    assert again.table() == comparison.table()
    # more seeds: the stored ones stay, the table says what is missing without running it
    _, _, missing = bench_robust.run_resumable(problem, "chain", 60, 2, N_EVALUATION, 6, ("ours", "b1"),
                                               settings=SMALL, settings_name="small", directory=tmp_path,
                                               run_missing=False)
    assert missing == ["ours seed 1", "b1 seed 0", "b1 seed 1"]
