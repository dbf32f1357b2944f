"""A simulation batch's start-up paid once per worker, batches cut into a few tasks per worker, and a Dask run on
four local workers giving the serial results."""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest

from design.contraption import simulate
from design.contraption.simulation import Simulator
from design.robust import SimulationExecutor
from design.robust.executor import MAX_CHUNK, TASKS_PER_WORKER
from design.robust.problem import synthetic_chain
from design.robust.sampling import sobol_valid

ROOT = Path(__file__).resolve().parents[3]
SIMPLE = ROOT / "examples" / "scenarios" / "simple.toml"

pytestmark = pytest.mark.skipif(not SIMPLE.exists(), reason="the SIMPLE scenario file is missing")


@pytest.fixture(scope="module")
def simple():
    from design.robust.contraption import load_problem

    return load_problem(SIMPLE)


@pytest.fixture(scope="module")
def layouts(simple):
    return sobol_valid(simple, 12, seed=3)


def in_new_thread(function):
    """Run ``function`` in a fresh thread (empty thread-local simulators, as in a new worker) and return its value."""
    box = {}

    def target():
        try:
            box["value"] = function()
        except BaseException as error:  # noqa: BLE001 - re-raised in the test's thread
            box["error"] = error

    thread = threading.Thread(target=target)
    thread.start()
    thread.join()
    if "error" in box:
        raise box["error"]
    return box["value"]


def test_a_worker_makes_one_simulator_for_all_its_tasks(simple, layouts, monkeypatch):
    made = []
    original = Simulator.__init__

    def counting(self, *args, **kwargs):
        made.append(self)
        original(self, *args, **kwargs)

    monkeypatch.setattr(Simulator, "__init__", counting)

    def worker():
        simple.prepare_worker()
        return [simple.simulate(u) for u in layouts]

    outcomes = in_new_thread(worker)
    assert len(made) == 1  # made while preparing; every simulation reuses it
    monkeypatch.setattr(Simulator, "__init__", original)
    # The kept simulator carries nothing from one layout to the next: each outcome is a fresh simulator's.
    for u, kept in zip(layouts, outcomes):
        fresh = simulate(simple.scenario, simple.to_real(u), early_stop=True, client=None)
        np.testing.assert_array_equal(kept, [fresh.events[name].state == "success" for name in simple.event_names])


def test_a_batch_goes_out_in_a_few_tasks_per_worker():
    problem = synthetic_chain()
    U = np.random.default_rng(2).random((200, len(problem.parameter_names)))
    with SimulationExecutor(problem, backend="inline") as executor:
        serial = executor.run(U)
    with SimulationExecutor(problem, workers=2) as executor:
        assert executor.backend == "processes"
        parallel = executor.run(U)
        assert executor.n_tasks == 2 * TASKS_PER_WORKER
        assert executor.n_simulated == 200
    np.testing.assert_array_equal(serial, parallel)
    with SimulationExecutor(problem, workers=2) as executor:
        executor.run(np.random.default_rng(3).random((2000, len(problem.parameter_names))))
        assert executor.n_tasks == 2000 // MAX_CHUNK + 1  # a task stays small enough for progress and a stop


def test_dask_on_four_local_workers_gives_the_serial_results(simple, layouts):
    distributed = pytest.importorskip("distributed")
    with SimulationExecutor(simple, backend="inline") as executor:
        serial = executor.run(layouts)
    options = {"n_workers": 4, "threads_per_worker": 1, "processes": False, "dashboard_address": None}
    with distributed.LocalCluster(**options) as cluster, distributed.Client(cluster) as client:
        with SimulationExecutor(simple, scheduler=client) as executor:
            assert executor.backend == "dask"
            remote = executor.run(layouts)
            assert executor.n_simulated == len(layouts)
    np.testing.assert_array_equal(serial, remote)
    assert serial.any() and not serial.all()  # the layouts tell successes from failures
