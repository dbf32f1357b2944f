"""The robust-layout pipeline end to end and the method comparison.

:func:`optimize_robust_layout` runs exploration (Algorithm 1), the (factorized) PSP with query synthesis
(Algorithm 2) and Platt calibration, then SLSQP from the best sample, and re-simulates the result, all within a
simulation budget. :func:`compare_methods` runs ours and the baselines B1-B3 at the same budget over several seeds
and measures ρ_g of each result on one shared evaluation set (Table 4.2, Figure 4.18). The simulation budget, its
oracle and the :class:`Progress` a run reports are in :mod:`design.robust.budget` (re-exported here).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from common.progress import Reporter
from design.robust.baselines import baseline_b1, baseline_b2, baseline_b3
from design.robust.budget import (  # noqa: F401 - Progress, BudgetExhausted, ... re-exported from here
    BudgetedOracle,
    BudgetExhausted,
    BudgetPlan,
    Progress,
    plan_budget,
)
from design.robust.executor import SimulationExecutor
from design.robust.model_io import model_to_json
from design.robust.optimize import optimize_layout, placement_offsets
from design.robust.problem import LayoutProblem, RobustError, check_seed
from design.robust.psp import EventModel, FactorizedPSP, Samples, explore
from design.robust.robustness import (
    EvaluationSet,
    RobustnessCurve,
    densest_successes,
    estimated_global_robustness,
    evaluation_set,
    predicted_global_robustness,
    robustness_curve,
)
from design.robust.sampling import sobol_valid, valid_in_ball
from design.robust.settings import METHODS, PSPSettings, RobustnessSettings

#: Which layout :func:`optimize_robust_layout` returns for the same problem, executor outcomes, budget, seed and
#: settings depends on this code: stores of optimized layouts keyed by those inputs (the station loop's) carry this
#: number too. Bump it with any change to the pipeline's choices.
OPTIMIZER_REVISION = 1


@dataclass
class RobustLayout:
    """Result of :func:`optimize_robust_layout` (normalized layouts; ``problem.to_real`` gives real units)."""

    scenario: str
    content_hash: str
    parameter_names: tuple[str, ...]
    event_names: tuple[str, ...]
    u: np.ndarray
    u_best_sample: np.ndarray
    psp: float
    psp_best_sample: float
    factor_names: tuple[str, ...]
    factor_probabilities: np.ndarray
    subspaces: dict[str, tuple[str, ...]]
    quasi_deterministic: tuple[str, ...]
    cv_accuracy: float
    simulated_events: np.ndarray
    simulated_success: bool
    n_simulations: int
    n_new_simulations: int
    budget: int | None
    seconds: float
    seed: int
    optimizer: dict = field(default_factory=dict)
    model: FactorizedPSP | None = None
    #: The settings the run used (after :func:`plan_budget`), so that it can be repeated.
    settings: PSPSettings | None = None

    def kept_candidate(self) -> str:
        """Where the layout came from, in words: the verified candidate kept, or the fallback to the best sample."""
        if "fallback" in self.optimizer:
            return "no checked candidate worked: the best simulated sample"
        kept = next((row for row in self.optimizer.get("verification", []) if row.get("kept")), None)
        if kept is None:
            return "the model's optimum"
        source = "an optimum of the model" if kept["source"] == "model" else "a success of the uniform start"
        return (f"{source} (of {len(self.optimizer['verification'])} checked; local success "
                f"{kept['local_success_rate']:.2f}, score {kept['score']:.3f})")

    def to_json(self, problem: LayoutProblem) -> dict:
        """The LAYOUT.json content: hash, parameters in real units and normalized, predictions, budget used, and
        the fitted model under ``"model"`` (``"chaos-station psp model 1"`` or ``2``, see
        :mod:`design.robust.model_io`)."""
        real = problem.to_real(self.u)
        return {
            "format": "chaos-station robust layout 1",
            "scenario": self.scenario,
            "content_hash": self.content_hash,
            "parameters": [
                {"name": name, "value": float(real[i]), "normalized": float(self.u[i]),
                 "lower": float(problem.lower[i]), "upper": float(problem.upper[i])}
                for i, name in enumerate(self.parameter_names)
            ],
            "predicted_psp": float(self.psp),
            "event_probabilities": {name: float(p) for name, p in zip(self.factor_names, self.factor_probabilities)},
            "quasi_deterministic_events": list(self.quasi_deterministic),
            "event_subspaces": {k: list(v) for k, v in self.subspaces.items()},
            "cv_accuracy": float(self.cv_accuracy),
            "simulated_success": bool(self.simulated_success),
            "simulated_events": {name: bool(s) for name, s in zip(self.event_names, self.simulated_events)},
            "simulations_used": int(self.n_simulations),
            "simulation_budget": self.budget,
            "best_sample": {"normalized": [float(v) for v in self.u_best_sample],
                            "predicted_psp": float(self.psp_best_sample)},
            "verification": self.optimizer.get("verification", []),
            "fallback_to_best_sample": "fallback" in self.optimizer,
            "seed": self.seed,
            "seconds": round(self.seconds, 3),
            "psp_settings": None if self.settings is None else {
                k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self.settings).items()},
            # The fitted PSP as numbers (design/robust/model_io.py), for scoring layouts near this one without
            # simulating (station tolerances); absent when the run kept no model.
            **({} if self.model is None else {"model": model_to_json(self.model, problem)}),
        }


@dataclass(frozen=True)
class Optimized:
    """What the optimization after learning found, before any of it is simulated.

    Attributes
    ----------
    u : ndarray
        The model's best layout (valid).
    candidates : list of ndarray
        Layouts worth verifying, best first (``u`` is the first).
    info : dict
        The optimizer's report (JSON-friendly), with ``start_sample``, the row of the samples it started from.
    best_sample : int
        Row of the best-ranked sample, the fallback if ``u`` fails in simulation.
    psp_best_sample : float
        Its PSP.
    """

    u: np.ndarray
    candidates: list[np.ndarray]
    info: dict
    best_sample: int
    psp_best_sample: float


def _rank_samples(scores: np.ndarray, samples: Samples) -> np.ndarray:
    """Rows of ``samples``, simulated successes first (they are known to work), then by decreasing score."""
    return np.lexsort((-scores, ~samples.success))


def optimize_from_samples(
    problem: LayoutProblem,
    psp: FactorizedPSP,
    samples: Samples,
    settings: PSPSettings,
    seed: int = 0,
    on_best_sample: Callable[[float], None] | None = None,
) -> Optimized:
    """Thesis 4.7 after learning: rank the simulated samples, then SLSQP from the best of them.

    Samples rank by PSP, simulated successes first; under a placement error, successes rank by their mean PSP over
    the offsets. SLSQP runs from the ``optimizer_starts`` best-ranked samples (at least ``verification_candidates``
    of them, so that each verified candidate is an optimum) and the lowest energy wins (the first start wins ties,
    so one start is the thesis's method).
    """
    if settings.objective == "global_robustness":
        return _optimize_predicted_robustness(problem, psp, samples, settings, seed, on_best_sample)
    scores = psp.predict_proba(samples.U)
    offsets = placement_offsets(problem.dim, settings.placement_error, settings.placement_samples, seed)
    ranks = scores.copy()
    successes = np.flatnonzero(samples.success)
    if offsets is not None and len(successes):
        around = np.clip(samples.U[successes, None, :] + offsets[None, :, :], 0.0, 1.0)
        ranks[successes] = psp.predict_proba(around.reshape(-1, problem.dim)).reshape(len(successes), -1).mean(axis=1)
    ranking = _rank_samples(ranks, samples)
    best = int(ranking[0])
    psp_best = float(scores[best])
    if on_best_sample is not None:
        on_best_sample(psp_best)
    results = []
    for start in ranking[: max(settings.optimizer_starts, settings.verification_candidates)]:
        candidate, candidate_info = optimize_layout(problem, psp, samples.U[start], settings.smooth_min_alpha,
                                                    settings.optimizer_max_iterations, offsets)
        results.append((candidate, {**candidate_info, "start_sample": int(start)}))
    order = sorted(range(len(results)), key=lambda i: (results[i][1]["energy"], i))  # stable: first start on ties
    u, info = results[order[0]]
    return Optimized(u, [results[i][0] for i in order], info, best, psp_best)


def _optimize_predicted_robustness(problem, psp, samples, settings, seed, on_best_sample):
    """``objective="global_robustness"``: the layout of highest ρ_g predicted by the PSP (see PSPSettings).

    The best-ranked sample is the simulated success of highest ρ̂_g. Only the parameters in some event's subspace
    move: the PSP says nothing about the others, so they keep the best sample's values, which are known to work.
    Candidates are the samples and a Sobol sample of the design space (both with those parameters fixed); the best
    is refined among valid layouts drawn in a small ball around it. The search is gradient-free because ρ̂_g counts
    layouts in balls and is piecewise constant.
    """
    reference = sobol_valid(problem, settings.reference_layouts, seed + 1)
    reference_probability = psp.predict_proba(reference)
    robustness = RobustnessSettings()

    def predicted(U: np.ndarray) -> np.ndarray:
        return predicted_global_robustness(U, psp.predict_proba(U), reference, reference_probability, robustness)

    sample_scores = predicted(samples.U)
    ranking = _rank_samples(sample_scores, samples)
    best = int(ranking[0])
    u_best = samples.U[best]
    psp_best = float(psp.predict_proba(u_best)[0])
    if on_best_sample is not None:
        on_best_sample(psp_best)
    free = sorted(set().union(*(m.subspace for m in psp.models_ if m.classifier is not None)))
    u, score = u_best, float(sample_scores[best])
    runners_up: list[np.ndarray] = []
    if free:
        fixed = [i for i in range(problem.dim) if i not in free]

        def pinned(U: np.ndarray) -> np.ndarray:
            U = np.array(U, dtype=float)
            U[:, fixed] = u_best[fixed]
            return U[problem.is_valid(U)]

        pool = np.concatenate([pinned(samples.U), pinned(sobol_valid(problem, settings.candidate_layouts, seed + 2))])
        if len(pool):
            pool_scores = predicted(pool)
            top = int(np.argmax(pool_scores))
            if pool_scores[top] > score:
                u, score = pool[top], float(pool_scores[top])
        radius = np.zeros(problem.dim)
        radius[free] = settings.refine_radius
        nearby = valid_in_ball(problem, u, radius, settings.refine_layouts, np.random.default_rng(seed),
                               "layouts near the best candidate")
        if len(nearby):
            nearby_scores = predicted(nearby)
            if nearby_scores.max() > score:
                u, score = nearby[int(np.argmax(nearby_scores))], float(nearby_scores.max())
        if len(pool):  # runners-up for verification, best first
            runners_up = list(pool[np.argsort(-pool_scores, kind="stable")[: 4 * settings.verification_candidates]])
    u = np.asarray(u, dtype=float)
    info = {"energy_start": -float(sample_scores[best]), "energy": -score, "iterations": 0,
            "message": "highest predicted global robustness", "predicted_rho_g": score,
            "predicted_rho_g_best_sample": float(sample_scores[best]), "start_sample": best,
            "free_parameters": [problem.parameter_names[i] for i in free]}
    return Optimized(u, [u, *runners_up], info, best, psp_best)


def verify_candidates(problem: LayoutProblem, oracle, candidates, settings: PSPSettings, seed: int = 0,
                      reference: tuple[np.ndarray, np.ndarray] | None = None, additional=()):
    """Simulate the model's best candidates and keep the one that does best in simulation.

    Each of the first ``verification_candidates`` distinct candidates (at least ``verification_radius`` apart), then
    each ``additional`` layout not within that distance of them (the start candidates), is simulated together with
    ``verification_samples - 1`` valid layouts drawn uniformly in the ball of ``verification_radius`` around it.
    The kept candidate succeeds itself and has the highest score (the model's order, then the additional layouts'
    order, breaks ties); if none succeeds itself, the model's first. The score is the success rate in its ball, or
    with ``verification_score="rho_g"`` and a ``reference`` (uniform layouts and their success), ρ_g estimated
    from the reference as evaluation set and the ball as local layouts. With one candidate and one sample this is
    the thesis's single re-simulation of the result.

    Returns
    -------
    u : ndarray
    events : ndarray
        The simulated events of ``u`` itself.
    report : list of dict
        Per verified candidate: ``u``, ``source`` ("model" or "start"), ``success`` (its own simulation),
        ``local_success_rate``, ``score``, ``simulations`` and ``kept``.
    """
    distinct: list[np.ndarray] = []

    def add_distinct(layouts, limit: int) -> None:
        for candidate in layouts:
            if len(distinct) >= limit:
                return
            candidate = np.asarray(candidate, dtype=float)
            if all(np.linalg.norm(candidate - c) >= settings.verification_radius for c in distinct):
                distinct.append(candidate)

    add_distinct(candidates, settings.verification_candidates)
    n_model = len(distinct)
    add_distinct(additional, n_model + len(additional))
    rng = np.random.default_rng(seed)
    groups = [np.concatenate([candidate[None, :], valid_in_ball(problem, candidate, settings.verification_radius,
                                                                settings.verification_samples - 1, rng,
                                                                "verification layouts")])
              for candidate in distinct]
    # One batch for every candidate: the workers share all of it instead of waiting at each candidate's end.
    events = oracle(np.concatenate(groups))
    report, firsts, start = [], [], 0
    for index, (candidate, group) in enumerate(zip(distinct, groups)):
        group_events = events[start:start + len(group)]
        start += len(group)
        success = group_events.all(axis=1)
        firsts.append(group_events[0])
        score = float(success.mean())
        if settings.verification_score == "rho_g" and reference is not None:
            score = estimated_global_robustness(candidate, np.concatenate([reference[0], group]),
                                                np.concatenate([reference[1], success]))
        report.append({"u": [float(v) for v in candidate], "source": "model" if index < n_model else "start",
                       "success": bool(success[0]),
                       "local_success_rate": float(success.mean()), "score": score, "simulations": len(group)})
    chosen = min(range(len(report)), key=lambda i: (not report[i]["success"], -report[i]["score"], i))
    for index, row in enumerate(report):
        row["kept"] = index == chosen
    return distinct[chosen], firsts[chosen], report


def optimize_robust_layout(
    problem: LayoutProblem,
    executor: SimulationExecutor,
    budget: int | None = None,
    seed: int = 0,
    settings: PSPSettings | None = None,
    report: Reporter | None = None,
) -> RobustLayout:
    """Ours: exploration, PSP (factorized by default), optimization, re-simulation, within ``budget`` simulations.

    Parameters
    ----------
    budget : int, optional
        Hard cap on simulations (``None``: the thesis's stopping rules only). At least 20.
    seed : int
        Seeds every random process.
    report : Reporter, optional
        Receives a :class:`Progress` after every simulation and phase change; asked between simulations whether to
        stop (:class:`common.progress.Cancelled`).
    """
    settings = settings or PSPSettings()
    if budget is not None and (isinstance(budget, bool) or int(budget) != budget or budget < 20):
        raise RobustError(f"{problem.name}: the simulation budget must be an integer >= 20, got {budget!r}")
    seed = check_seed(seed)
    started = time.perf_counter()
    new_before = executor.n_simulated
    oracle = BudgetedOracle(executor, budget, report=report)
    plan = plan_budget(settings, budget)
    settings, reserve = plan.settings, plan.reserve

    oracle.phase = "exploration"
    oracle.report()
    samples = explore(problem, oracle, settings, seed, plan.exploration_cap, plan.initial_cap)

    oracle.phase = "active learning"

    def model_trained(model: EventModel) -> None:
        if model.classifier is not None:
            oracle.cv_accuracy = model.classifier.cv_accuracy_
        oracle.report(f"event {model.event}")

    def remaining_for_learning() -> int:
        return oracle.remaining() - reserve if budget is not None else 10**9

    psp = FactorizedPSP(settings, random_state=seed).fit(problem, samples, oracle, remaining_for_learning,
                                                         model_trained)
    oracle.cv_accuracy = psp.cv_accuracy_

    def best_sample_chosen(psp_best: float) -> None:
        oracle.best_psp = psp_best
        oracle.phase = "optimization"
        oracle.report()

    optimized = optimize_from_samples(problem, psp, samples, settings, seed, best_sample_chosen)
    best, psp_best, info = optimized.best_sample, optimized.psp_best_sample, optimized.info
    u_best = samples.U[best]
    oracle.best_psp = float(psp.predict_proba(optimized.u)[0])

    oracle.phase = "check"
    sobol_start = samples.U[: samples.n_initial], samples.success[: samples.n_initial]
    start_candidates = densest_successes(*sobol_start, settings.verification_start_candidates)
    u, events, verification = verify_candidates(problem, oracle, optimized.candidates, settings, seed, sobol_start,
                                                start_candidates)
    info = {**info, "verification": verification}
    if not events.all() and settings.fallback_to_best_sample and samples.success[best]:
        u, events = u_best, samples.events[best]
        info = {**info, "fallback": "the optimized layout failed in simulation; kept the best sample"}
        for row in verification:
            row["kept"] = False
    factors = psp.factor_probabilities(u)[0]
    oracle.best_psp = float(psp.predict_proba(u)[0])
    oracle.phase = "done"
    oracle.report()
    names = problem.parameter_names
    return RobustLayout(
        scenario=problem.name,
        content_hash=problem.content_hash,
        parameter_names=tuple(names),
        event_names=tuple(problem.event_names),
        u=u,
        u_best_sample=u_best,
        psp=oracle.best_psp,
        psp_best_sample=psp_best,
        factor_names=tuple(m.event for m in psp.models_),
        factor_probabilities=factors,
        subspaces={m.event: tuple(names[i] for i in m.subspace) for m in psp.models_ if not m.quasi_deterministic},
        quasi_deterministic=tuple(m.event for m in psp.models_ if m.quasi_deterministic),
        cv_accuracy=psp.cv_accuracy_,
        simulated_events=np.asarray(events, dtype=bool),
        simulated_success=bool(np.all(events)),
        n_simulations=oracle.used,
        n_new_simulations=executor.n_simulated - new_before,
        budget=budget,
        seconds=time.perf_counter() - started,
        seed=seed,
        optimizer=info,
        model=psp,
        settings=settings,
    )


# --------------------------------------------------------------------------------------------------------------
# Comparison with the baselines
# --------------------------------------------------------------------------------------------------------------
@dataclass
class MethodRun:
    """One run of one method: its layout, simulations, time and robustness."""

    method: str
    seed: int
    u: np.ndarray
    n_simulations: int
    seconds: float
    curve: RobustnessCurve


@dataclass
class Comparison:
    """Runs of every method, the shared evaluation set and the budget given to the baselines."""

    scenario: str
    budget: int
    evaluation_size: int
    runs: list[MethodRun]

    def table(self) -> list[dict]:
        """Per method: ρ_g mean and standard error, mean time and simulations (Table 4.2)."""
        rows = []
        for method in dict.fromkeys(r.method for r in self.runs):
            runs = [r for r in self.runs if r.method == method]
            values = np.array([r.curve.global_robustness for r in runs])
            sem = float(values.std(ddof=1) / np.sqrt(len(values))) if len(values) > 1 else 0.0
            rows.append({
                "method": method,
                "runs": len(runs),
                "rho_g_mean": float(values.mean()),
                "rho_g_sem": sem,
                "seconds_mean": float(np.mean([r.seconds for r in runs])),
                "simulations_mean": float(np.mean([r.n_simulations for r in runs])),
            })
        return rows

    def mean_curves(self) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Per method: ε, mean ρ_l and its standard error (Figure 4.18)."""
        curves = {}
        for method in dict.fromkeys(r.method for r in self.runs):
            stack = np.array([r.curve.local for r in self.runs if r.method == method])
            sem = stack.std(axis=0, ddof=1) / np.sqrt(len(stack)) if len(stack) > 1 else np.zeros(stack.shape[1])
            curves[method] = (self.runs[0].curve.epsilon, stack.mean(axis=0), sem)
        return curves


def compare_methods(
    problem: LayoutProblem,
    executor: SimulationExecutor,
    methods: Sequence[str] = METHODS,
    runs: int = 5,
    budget: int | None = None,
    seed: int = 0,
    settings: PSPSettings | None = None,
    robustness: RobustnessSettings | None = None,
    report: Reporter | None = None,
    on_run: Callable[[MethodRun], None] | None = None,
    on_timed: Callable[[str, int, bool], None] | None = None,
) -> Comparison:
    """Ours and the baselines at the same simulation budget over ``runs`` seeds, scored by ρ_g (thesis 4.8.3).

    As in the thesis, when "ours" is among the methods its runs come first and the baselines get B = the mean number
    of simulations ours used; ``budget`` caps ours (and is B when ours is not compared). Seeds are ``seed`` to
    ``seed + runs - 1``, so a comparison can be extended by more seeds later; ``on_run`` receives each run as it
    ends (a long comparison that is stopped keeps what it reported). ``on_timed(method, seed, running)`` is called as
    the timed part of each run starts (``True``) and ends (``False``), so a caller can measure more than its wall
    time there (e.g. the CPU time of the worker processes).
    """
    unknown = sorted(set(methods) - set(METHODS))
    if unknown or not methods:
        raise RobustError(f"compare: methods must be among {', '.join(METHODS)}, got {list(methods)}")
    if isinstance(runs, bool) or int(runs) != runs or runs < 1:
        raise RobustError(f"compare: runs must be a positive integer, got {runs!r}")
    if "ours" not in methods and budget is None:
        raise RobustError("compare: without 'ours', give the baselines' simulation budget")
    seed = check_seed(seed)
    robustness = robustness or RobustnessSettings()
    unbounded = BudgetedOracle(executor, None, report=report, expected=robustness.n_evaluation)
    unbounded.phase = "evaluation set"
    evaluation: EvaluationSet = evaluation_set(problem, unbounded, robustness.n_evaluation)
    results: list[MethodRun] = []
    ordered = [m for m in METHODS if m in methods]
    baseline_budget = budget
    for method in ordered:
        for run in range(runs):
            run_seed = seed + run
            if on_timed is not None:
                on_timed(method, run_seed, True)
            started = time.perf_counter()
            if method == "ours":
                layout = optimize_robust_layout(problem, executor, budget, run_seed, settings, report)
                u, used = layout.u, layout.n_simulations
            else:
                oracle = BudgetedOracle(executor, None, report=report)
                oracle.phase = f"{method} run {run + 1}/{runs}"
                function = {"b1": baseline_b1, "b2": baseline_b2, "b3": baseline_b3}[method]
                kwargs = {} if method == "b1" else {"settings": robustness}
                result = function(problem, oracle, int(baseline_budget), run_seed, **kwargs)
                u, used = result.u, result.n_simulations
            seconds = time.perf_counter() - started
            if on_timed is not None:
                on_timed(method, run_seed, False)
            unbounded.phase = f"robustness of {method}"
            curve = robustness_curve(problem, unbounded, evaluation, u, robustness, seed=run_seed)
            results.append(MethodRun(method, run_seed, u, used, seconds, curve))
            if on_run is not None:
                on_run(results[-1])
        if method == "ours":
            baseline_budget = int(round(np.mean([r.n_simulations for r in results if r.method == "ours"])))
    return Comparison(problem.name, int(baseline_budget or 0), len(evaluation.U), results)
