"""design's progress reports are the one common Progress type."""

import numpy as np
import pytest

from common.progress import Cancelled, Reporter
from common.progress import Progress as BaseProgress
from design.robust import SimulationExecutor, synthetic_chain
from design.robust.budget import BudgetedOracle
from design.robust.pipeline import Progress


def test_robust_progress_is_common_progress_and_aliases_agree():
    p = Progress("active learning", 60, 100, 0.91, None, "fit")
    assert isinstance(p, BaseProgress)
    assert (p.phase, p.simulations, p.budget) == (p.stage, p.done, p.total) == ("active learning", 60, 100)
    assert p.cv_accuracy == 0.91 and p.message == "fit" and p.unit == "simulations"
    assert p.fraction == 0.6


def test_the_simulation_budget_reports_design_progress_through_the_reporter_and_stops_there():
    problem = synthetic_chain()
    seen: list[BaseProgress] = []
    layouts = np.random.default_rng(0).random((12, problem.dim)) * 0.5
    with SimulationExecutor(problem, backend="inline") as executor:
        oracle = BudgetedOracle(executor, 100, report=Reporter(seen.append, stop=lambda: len(seen) >= 4))
        oracle.phase, oracle.cv_accuracy = "exploration", 0.8
        with pytest.raises(Cancelled):
            oracle(layouts)
        assert executor.n_simulated == 4  # one report per simulation, the stop asked after the fourth
    assert all(isinstance(p, Progress) and p.cv_accuracy == 0.8 for p in seen)  # the subclass, its fields kept
    assert [(p.stage, p.done, p.total) for p in seen] == [("exploration", n, 100) for n in range(1, 5)]
