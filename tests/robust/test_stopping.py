"""Stopping a run of worker processes (Ctrl-C, SIGTERM, a stop button) ends it quietly and keeps the cache."""

from __future__ import annotations

import dataclasses
import threading
from pathlib import Path

import numpy as np
import pytest

from design.robust import SimulationExecutor, synthetic_chain

ROOT = Path(__file__).resolve().parents[2]
SIMPLE = ROOT / "examples" / "scenarios" / "simple.toml"


def slow_chain(seconds: float = 0.05):
    """synthetic_chain whose simulations take a while, so that a stop finds work running and queued."""
    return dataclasses.replace(synthetic_chain("SLOW-CHAIN"), simulation_seconds=seconds)


def test_an_interrupt_with_simulations_queued_leaves_no_thread_error(monkeypatch):
    # The pool's manager thread died with InvalidStateError when futures the main thread had cancelled were still
    # in its pending items as the terminated workers broke the pool (Python 3.11 prints it on stderr).
    errors = []
    monkeypatch.setattr(threading, "excepthook", lambda hook: errors.append(hook.exc_value))
    problem = slow_chain(0.3)
    U = np.random.default_rng(0).random((64, problem.dim)) * 0.5  # all valid: far from the forbidden ball
    managers = []

    def interrupt(n: int) -> None:
        managers.append(executor._pool._executor_manager_thread)
        raise KeyboardInterrupt

    for _ in range(2):  # a race, though with slow simulations the old code failed on every run tried
        with pytest.raises(KeyboardInterrupt):
            with SimulationExecutor(problem, backend="processes", workers=1) as executor:
                executor.run(U, on_result=interrupt)
        managers[-1].join(timeout=30)
        assert not managers[-1].is_alive()
        assert errors == []
        U = U + 1e-3  # new layouts (nothing cached: the cache is in memory, per executor)


def test_a_stopped_executor_runs_again():
    from design.robust import SimulationCancelled

    problem = slow_chain(0.02)
    U = np.random.default_rng(1).random((40, problem.dim)) * 0.5
    executor = SimulationExecutor(problem, backend="processes", workers=1)
    try:
        done = []
        with pytest.raises(SimulationCancelled):
            executor.run(U, on_result=done.append, should_stop=lambda: len(done) >= 2)
        assert executor._pool is None  # the queued simulations of the stopped run were dropped with their pool
        out = executor.run(U[:6])
        np.testing.assert_array_equal(out, problem.simulate_batch(U[:6]))
    finally:
        executor.close()
