"""The simulation budget of a robust-layout run: what it reports, how it counts, and how it is shared out.

:class:`BudgetedOracle` runs simulations through an executor, counts them against the budget and reports a
:class:`Progress` after each; :func:`plan_budget` shares a budget between verification, exploration and active
learning (:mod:`design.robust.pipeline` runs the method itself).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from common.progress import Progress as BaseProgress
from common.progress import Reporter
from design.robust.executor import SimulationExecutor
from design.robust.problem import RobustError
from design.robust.settings import PSPSettings


@dataclass(frozen=True, init=False)
class Progress(BaseProgress):
    """What a long run reports: its phase, simulations used of the budget, CV accuracy and best PSP so far.

    A :class:`common.progress.Progress` (``stage``, ``done``, ``total``, ``message``) so every front end can draw
    it; ``phase``, ``simulations`` and ``budget`` are read-only aliases of the first three, and the constructor
    keeps its positional order ``(phase, simulations, budget, cv_accuracy, best_psp, detail, unit)`` so existing
    callers are unchanged. ``unit`` names what ``simulations`` and ``budget`` count, for a phase that counts
    something else (e.g. the valid layouts of an evaluation set being drawn). ``message`` defaults to ``detail``.
    """

    cv_accuracy: float | None = None
    best_psp: float | None = None
    detail: str = ""
    unit: str = "simulations"

    def __init__(self, stage: str, done: float = 0, total: float | None = None, cv_accuracy: float | None = None,
                 best_psp: float | None = None, detail: str = "", unit: str = "simulations",
                 message: str | None = None) -> None:
        # Frozen: fields are set through object.__setattr__, as dataclasses do in their own __init__.
        for name, value in (("stage", stage), ("done", done), ("total", total), ("cv_accuracy", cv_accuracy),
                            ("best_psp", best_psp), ("detail", detail), ("unit", unit),
                            ("message", detail if message is None else message)):
            object.__setattr__(self, name, value)

    @property
    def phase(self) -> str:
        """Alias of ``stage``."""
        return self.stage

    @property
    def simulations(self) -> float:
        """Alias of ``done``."""
        return self.done

    @property
    def budget(self) -> float | None:
        """Alias of ``total``."""
        return self.total


class BudgetExhausted(RobustError):
    """More simulations were requested than the budget allows (a programming error in a method)."""


class BudgetedOracle:
    """Counts simulations against a budget, reports progress, and runs them through an executor.

    ``report`` receives a :class:`Progress` after every simulation and phase change, and is asked between
    simulations whether to stop (:class:`common.progress.Cancelled`).
    """

    def __init__(self, executor: SimulationExecutor, budget: int | None, *, report: Reporter | None = None,
                 expected: int | None = None) -> None:
        self.executor = executor
        self.budget = budget
        self.expected = expected  # shown as the total when there is no budget (e.g. an evaluation set)
        self.used = 0
        self.reporter = Reporter.of(report)
        self.phase = "start"
        self.cv_accuracy: float | None = None
        self.best_psp: float | None = None

    def remaining(self) -> int:
        return self.budget - self.used if self.budget is not None else 10**9

    def report(self, detail: str = "") -> None:
        total = self.budget or max(self.expected or 0, self.used)
        self.reporter.emit(Progress(stage=self.phase, done=self.used, total=total, cv_accuracy=self.cv_accuracy,
                                    best_psp=self.best_psp, detail=detail))

    def __call__(self, U: np.ndarray) -> np.ndarray:
        U = np.atleast_2d(U)
        if self.budget is not None and self.used + len(U) > self.budget:
            raise BudgetExhausted(f"{len(U)} more simulations would exceed the budget of {self.budget}")

        def one_done(n: int) -> None:
            self.used += n
            self.report()

        start = self.used
        events = self.executor.run(U, on_result=one_done, report=self.reporter)
        self.used = start + len(U)  # cache hits count too: the budget is the method's, not the machine's
        self.report()
        return events


@dataclass(frozen=True)
class BudgetPlan:
    """How a simulation budget is shared out (all ``None`` without a budget).

    Attributes
    ----------
    settings : PSPSettings
        The settings, with ``verification_samples`` lowered when the budget is too small for them.
    reserve : int
        Simulations kept for checking the result (candidates x samples).
    exploration_cap, initial_cap : int or None
        Most simulations the exploration, and within it the Sobol start, may use.
    """

    settings: PSPSettings
    reserve: int
    exploration_cap: int | None
    initial_cap: int | None


def plan_budget(settings: PSPSettings, budget: int | None) -> BudgetPlan:
    """Share ``budget`` between verification, the exploration (and its Sobol start) and active learning.

    Verification simulates ``verification_samples`` layouts for each of the model's candidates and each start
    candidate, and never takes over a quarter of the budget: a small one gets fewer simulations per candidate. The
    exploration may use ``exploration_share`` of the rest, its Sobol start ``initial_share``; active learning gets
    what the exploration leaves.
    """
    verified = settings.verification_candidates + settings.verification_start_candidates
    reserve = verified * settings.verification_samples
    if budget is None:
        return BudgetPlan(settings, reserve, None, None)
    if reserve > max(1, budget // 4):
        per_candidate = max(1, (budget // 4) // verified)
        settings = settings.with_changes(verification_samples=per_candidate)
        reserve = verified * per_candidate
    learning = budget - reserve
    return BudgetPlan(settings, reserve, max(10, int(settings.exploration_share * learning)),
                      max(10, int(settings.initial_share * learning)))
