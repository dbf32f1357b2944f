"""Simulator calibration: fit a scenario's uncertain material values to logged physical trials (thesis 2.5, 4.8).

The authors of the thesis calibrated domino friction, restitution and angular damping offline from 480 fps video
(4.8). Here the data are the station's trial log: for each physical run, the layout as built (or as designed), the
placement error of that layout, and which events happened (and when, where timed). The fit maximizes the
likelihood of those observations under the simulator:

- **Likelihood.** For material values θ, each trial is simulated ``draws`` times at its layout plus Gaussian
  placement errors (the check's residual error, else 1 mm / 1 degree; a parameter the check did not measure at
  least 1 mm / 1 degree). An event's observed outcome has probability
  ``(k + α) / (draws + 3α)`` (``k`` draws agree, α = 1/2: never 0 or 1 from a few draws); an event that happened at
  a logged time ``t`` has the density ``(Σ_agreeing N(t; t_m, s) + α / T) / (draws + 3α)`` (a kernel estimate of
  the simulated times, ``s`` at least the timing error ``time_sigma``; ``T`` the scenario's duration). The events
  are taken as independent given the layout (a composite likelihood: the intervals are somewhat too narrow when
  events repeat one another). The same placement draws serve every θ (common random numbers), so differences of
  likelihood between values are not drowned in sampling noise.
- **Prior.** A value's range is read as its plausible span around the scenario's value (the maker's measurement or
  the thesis's calibration): a Gaussian prior centred on that value with a standard deviation of ``prior_width``
  (default a quarter) of the range, independently per value. With a few trials and several values the likelihood
  is flat along most directions, and its maximum alone lands on the ranges' edges (a world-1 CAUSALITYSWITCH fit
  from five trials put table friction at 1.5x, wood friction at its upper bound); the prior keeps what the trials
  do not tell at the scenario's value. ``prior_width=None`` is plain maximum likelihood.
- **Search.** A scrambled Sobol design over the parameters' ranges (plus the scenario's own values), a Gaussian
  process surrogate of the log-likelihood (scikit-learn, Matérn 5/2 with a white-noise term), then rounds of local
  refinement around the maximum of the surrogate plus the log-prior (the posterior's mode); the estimate is that
  mode.
- **Uncertainty.** A Laplace interval: the posterior's curvature at the mode (±1.96 σ, clipped to the range);
  where it is not curved downwards (no prior), the values within 1.92 of the maximum along the axis.
- **Check.** A share of the trials is held out before fitting; the Brier score of the success probability on them,
  with the scenario's values and with the fitted ones, says whether the fit predicts better.

Simulations go through :class:`~design.robust.executor.SimulationExecutor` (inline, local processes or Dask, with
its cache) via a :class:`Runner`; progress is reported as ``Progress("simulations", done, total)`` and a cancel
request stops between batches (:class:`common.progress.Cancelled`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import minimize
from scipy.stats import qmc

from calibration.errors import CalibrationError
from calibration.sim_runs import NO, NOT_REACHED, YES, OutcomeProblem, noisy_layouts
from calibration.sim_trials import FitTrial
from common.progress import Progress, Reporter

_ALPHA = 0.5
_LOG_DROP_95 = 1.920729  # half the 95 % quantile of chi-square with 1 degree of freedom


@dataclass(frozen=True)
class FitSettings:
    """How much simulation the fit spends (the defaults suit a few dozen trials of a small scenario)."""

    draws: int = 8  #: placement draws per trial and candidate
    sobol: int = 16  #: candidates of the initial Sobol design
    rounds: int = 3  #: refinement rounds
    per_round: int = 4  #: candidates per round
    held_out: float = 0.3  #: share of the trials kept for the predictive check (none below 5 trials)
    predictive_draws: int = 16  #: draws per held-out trial for its success probability
    time_sigma: float = 0.02  #: timing error of logged event times (s)
    #: the prior's standard deviation as a share of each value's range (None: maximum likelihood, no prior)
    prior_width: float | None = 0.25
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("draws", "sobol", "predictive_draws"):
            if int(getattr(self, name)) < 1:
                raise CalibrationError(f"sim fit: {name} must be an integer >= 1, got {getattr(self, name)!r}")
        if self.rounds < 0 or self.per_round < 1:
            raise CalibrationError("sim fit: rounds must be >= 0 and per_round >= 1")
        if not 0.0 <= self.held_out < 1.0:
            raise CalibrationError(f"sim fit: held_out must be in [0, 1), got {self.held_out!r}")
        if not self.time_sigma > 0:
            raise CalibrationError(f"sim fit: time_sigma must be > 0, got {self.time_sigma!r}")
        if self.prior_width is not None and not self.prior_width > 0:
            raise CalibrationError(f"sim fit: prior_width must be > 0 (a share of each range) or None, got "
                                   f"{self.prior_width!r}")


class Runner:
    """Runs the simulations of :class:`OutcomeProblem` s, one executor per problem (made on first use, kept).

    Parameters
    ----------
    make_executor : callable, optional
        ``problem -> SimulationExecutor``; default: inline with an in-memory cache.
    report : Reporter, optional
        Given ``Progress("simulations", done, total)``; asked between batches and by the executors between
        simulations whether to stop (:class:`common.progress.Cancelled`).
    """

    def __init__(self, make_executor: Callable[[OutcomeProblem], Any] | None = None, *,
                 report: Reporter | None = None) -> None:
        self.make_executor = make_executor or _inline_executor
        self.report = Reporter.of(report)
        self.total = 0
        self.done = 0
        self._executors: dict[str, Any] = {}

    def expect(self, n: int) -> None:
        """Add ``n`` to the expected number of simulations (the progress bar's total)."""
        self.total += int(n)
        self.report.emit(Progress("simulations", self.done, self.total, f"{self.done}/{self.total} simulations"))

    def __call__(self, problem: OutcomeProblem, U: np.ndarray) -> np.ndarray:
        self.report.check()
        executor = self._executors.get(problem.content_hash)
        if executor is None:
            executor = self._executors[problem.content_hash] = self.make_executor(problem)

        def arrived(n: int) -> None:
            self.done += n
            self.report.emit(Progress("simulations", self.done, max(self.total, self.done),
                                      f"{self.done}/{max(self.total, self.done)} simulations"))

        before = executor.n_cache_hits
        out = executor.run(U, on_result=arrived, report=self.report)
        hits = executor.n_cache_hits - before
        if hits:
            arrived(hits)
        return out

    def close(self) -> None:
        for executor in self._executors.values():
            executor.close()
        self._executors.clear()

    def __enter__(self) -> Runner:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _inline_executor(problem: OutcomeProblem):
    from design.robust.executor import SimulationExecutor

    return SimulationExecutor(problem, backend="inline", cache_path=None)


@dataclass(frozen=True)
class FittedParameter:
    """A fitted material value: the estimate, its 95 % interval, the scenario's value before, the range searched."""

    name: str
    value: float
    interval: tuple[float, float]
    before: float
    range: tuple[float, float]


@dataclass(frozen=True)
class EventAgreement:
    """How well the simulator agrees with the trials on one event, before and after the fit (fitted trials).

    ``observed_yes`` is the share of trials where it happened; ``predicted_yes_*`` the mean simulated probability
    that it happens; ``agreement_*`` the mean simulated probability of what was observed (1 is perfect).
    """

    scenario: str
    event: str
    observed_yes: float
    predicted_yes_before: float
    predicted_yes_after: float
    agreement_before: float
    agreement_after: float


@dataclass
class SimFit:
    """The result of :func:`fit_simulator`."""

    parameters: list[FittedParameter]
    trials: int
    held_out: int
    brier_before: float | None
    brier_after: float | None
    log_likelihood_before: float
    log_likelihood_after: float
    agreement: list[EventAgreement]
    simulations: int
    candidates: int
    scenarios: list[str] = field(default_factory=list)
    #: The candidate material values simulated ``(n, d)``, in :attr:`parameters`' order, and their log-likelihoods.
    evaluated: np.ndarray = field(default_factory=lambda: np.empty((0, 0)))
    evaluated_log_likelihood: np.ndarray = field(default_factory=lambda: np.empty(0))
    #: The prior's width the fit used (a share of each range; None: maximum likelihood).
    prior_width: float | None = None

    def values(self) -> dict[str, float]:
        return {p.name: p.value for p in self.parameters}

    def intervals(self) -> dict[str, tuple[float, float]]:
        return {p.name: p.interval for p in self.parameters}

    def to_json(self) -> dict[str, Any]:
        """The contract's ``station calibrate sim --json``."""
        return {"parameters": [{"name": p.name, "value": p.value, "interval": list(p.interval)}
                               for p in self.parameters],
                "trials": self.trials + self.held_out, "brier_before": self.brier_before,
                "brier_after": self.brier_after}

    def fit_summary(self) -> dict[str, Any]:
        """Numbers for a physics profile's ``[fit]`` table."""
        return {"trials": self.trials + self.held_out, "held_out": self.held_out,
                "brier_before": self.brier_before, "brier_after": self.brier_after,
                "log_likelihood_before": round(self.log_likelihood_before, 4),
                "log_likelihood_after": round(self.log_likelihood_after, 4),
                "simulations": self.simulations, "prior_width": self.prior_width}


class _Groups:
    """The trials grouped by the scenario content they were built with, each with its problem and placements."""

    def __init__(self, trials: Sequence[FitTrial], names: Sequence[str], ranges: Mapping[str, tuple[float, float]],
                 draws: int, seed: int) -> None:
        self.names = list(names)
        by_hash: dict[str, list[int]] = {}
        for i, trial in enumerate(trials):
            by_hash.setdefault(trial.scenario.content_hash, []).append(i)
        self.groups = []
        for members in by_hash.values():
            scenario = trials[members[0]].scenario
            own = [n for n in self.names if n in scenario.physics_parameters()]
            problem = OutcomeProblem(scenario, own, ranges)
            index = [self.names.index(n) for n in own]
            layouts = []
            for i in members:
                # Common random numbers: one generator per (seed, trial), the same placements for every candidate.
                rng = np.random.default_rng([seed, i])
                trial = trials[i]
                layouts.append(noisy_layouts(scenario, trial.layout, draws, trial.position_sigma_m,
                                             trial.angle_sigma_deg, rng, trial.unmeasured))
            self.groups.append((problem, index, members, np.concatenate(layouts)))
        self.draws = draws
        self.n = len(trials)

    def simulate(self, run: Runner, thetas: np.ndarray) -> list[np.ndarray]:
        """Per candidate: runs' numbers by trial, a list (over trials, in input order) of ``(draws, outputs)``."""
        thetas = np.atleast_2d(thetas)
        per_candidate: list[list[Any]] = [[None] * self.n for _ in thetas]
        for problem, index, members, layouts in self.groups:
            rows = np.vstack([problem.rows(theta[index], layouts) for theta in thetas])
            out = run(problem, rows)
            size = len(layouts)
            for c in range(len(thetas)):
                block = out[c * size:(c + 1) * size]
                for j, i in enumerate(members):
                    per_candidate[c][i] = (problem, block[j * self.draws:(j + 1) * self.draws])
        return per_candidate


def _trial_log_likelihood(problem: OutcomeProblem, out: np.ndarray, trial: FitTrial, time_sigma: float) -> float:
    _, codes, times = problem.split(out)
    m = len(codes)
    total = 0.0
    duration = trial.scenario.settings.max_duration
    for k in range(codes.shape[1]):
        agree = codes[:, k] == trial.codes[k]
        t_obs = trial.times[k]
        if trial.codes[k] == YES and np.isfinite(t_obs):
            t_sim = times[agree, k]
            if len(t_sim):
                spread = float(np.std(t_sim)) if len(t_sim) > 1 else 0.0
                s = max(time_sigma, 1.06 * spread * len(t_sim) ** -0.2)
                density = float(np.sum(np.exp(-0.5 * ((t_obs - t_sim) / s) ** 2)) / (s * np.sqrt(2 * np.pi)))
            else:
                density = 0.0
            total += np.log((density + _ALPHA / duration) / (m + 3 * _ALPHA))
        else:
            total += np.log((np.count_nonzero(agree) + _ALPHA) / (m + 3 * _ALPHA))
    return float(total)


def _log_likelihoods(groups: _Groups, run: Runner, trials: Sequence[FitTrial], thetas: np.ndarray,
                     time_sigma: float) -> np.ndarray:
    outs = groups.simulate(run, thetas)
    return np.array([sum(_trial_log_likelihood(problem, out, trials[i], time_sigma)
                         for i, (problem, out) in enumerate(per_trial)) for per_trial in outs])


def fit_simulator(trials: Sequence[FitTrial], parameters: Mapping[str, tuple[float, tuple[float, float]]],
                  run: Runner | None = None, settings: FitSettings | None = None) -> SimFit:
    """Fit material values to physical trials.

    Parameters
    ----------
    trials : sequence of FitTrial
        The logged runs (:func:`calibration.sim_trials.fit_trials`).
    parameters : mapping
        ``name -> (value before, (low, high))``: what to fit, from where, within which range
        (:meth:`~design.contraption.model.Scenario.uncertain_parameters`).
    run : Runner, optional
        Where simulations run (default: inline, in-memory cache).
    settings : FitSettings, optional

    Raises
    ------
    CalibrationError
        No trials, no parameters, or a parameter none of the trials' scenarios has.
    common.progress.Cancelled
        Stopped on request (simulations done are cached by the executors).
    """
    settings = settings or FitSettings()
    trials = list(trials)
    if not trials:
        raise CalibrationError("sim fit: no trials of these scenarios to fit")
    if not parameters:
        raise CalibrationError("sim fit: no parameters to fit (mark a material value uncertain with a range)")
    names = list(parameters)
    for name in names:
        if not any(name in t.scenario.physics_parameters() for t in trials):
            raise CalibrationError(f"sim fit: parameter {name!r} is not a material value of any trial's scenario")
    lower = np.array([parameters[n][1][0] for n in names], dtype=float)
    upper = np.array([parameters[n][1][1] for n in names], dtype=float)
    before = np.array([parameters[n][0] for n in names], dtype=float)
    ranges = {n: (float(lo), float(hi)) for n, lo, hi in zip(names, lower, upper)}
    own_run = run is None
    run = run or Runner()
    try:
        return _fit(trials, names, lower, upper, before, ranges, run, settings)
    finally:
        if own_run:
            run.close()


def _fit(trials, names, lower, upper, before, ranges, run: Runner, settings: FitSettings) -> SimFit:
    rng = np.random.default_rng(settings.seed)
    n_held = int(round(settings.held_out * len(trials))) if len(trials) >= 5 else 0
    order = rng.permutation(len(trials))
    held = [trials[i] for i in sorted(order[:n_held])]
    fitted = [trials[i] for i in sorted(order[n_held:])]
    groups = _Groups(fitted, names, ranges, settings.draws, settings.seed)
    d = len(names)
    to_real = lambda u: lower + np.asarray(u) * (upper - lower)  # noqa: E731
    per_candidate = len(fitted) * settings.draws
    n_candidates = settings.sobol + 1 + settings.rounds * settings.per_round
    run.expect(per_candidate * (n_candidates + 1) + 2 * len(held) * settings.predictive_draws)

    u0 = (before - lower) / (upper - lower)
    prior = _log_prior(u0, settings.prior_width)
    sobol = qmc.Sobol(d, scramble=True, seed=settings.seed).random(settings.sobol)
    U = np.vstack([u0[None, :], sobol])
    y = _log_likelihoods(groups, run, fitted, to_real(U), settings.time_sigma)
    for r in range(settings.rounds):
        posterior = _posterior(_surrogate(U, y, settings.seed), prior)
        best = _argmax(posterior, U, y + prior(U), rng)
        radius = 0.15 / (2 ** r)
        new = [best] + [np.clip(best + rng.normal(0, radius, d), 0, 1) for _ in range(settings.per_round - 1)]
        new_y = _log_likelihoods(groups, run, fitted, to_real(np.array(new)), settings.time_sigma)
        U, y = np.vstack([U, new]), np.concatenate([y, new_y])
    posterior = _posterior(_surrogate(U, y, settings.seed), prior)
    u_hat = _argmax(posterior, U, y + prior(U), rng)
    theta = to_real(u_hat)
    sd = _laplace_sd(posterior, u_hat)
    parameters = []
    for k, name in enumerate(names):
        if sd is not None and np.isfinite(sd[k]):
            lo_u, hi_u = u_hat[k] - 1.959964 * sd[k], u_hat[k] + 1.959964 * sd[k]
        else:
            lo_u, hi_u = _axis_interval(posterior, u_hat, k)
        interval = (float(to_real_axis(lower, upper, k, max(lo_u, 0.0))),
                    float(to_real_axis(lower, upper, k, min(hi_u, 1.0))))
        parameters.append(FittedParameter(name, float(theta[k]), interval, float(before[k]),
                                          (float(lower[k]), float(upper[k]))))
    # Before and after, on the fitted trials (the same placements: cache hits for the scenario's own values).
    outs_before, outs_after = groups.simulate(run, np.vstack([before, theta]))
    ll_before = sum(_trial_log_likelihood(p, o, fitted[i], settings.time_sigma) for i, (p, o) in enumerate(outs_before))
    ll_after = sum(_trial_log_likelihood(p, o, fitted[i], settings.time_sigma) for i, (p, o) in enumerate(outs_after))
    agreement = _agreement(fitted, outs_before, outs_after)
    brier_before = brier_after = None
    if held:
        held_groups = _Groups(held, names, ranges, settings.predictive_draws, settings.seed + 1)
        b_outs, a_outs = held_groups.simulate(run, np.vstack([before, theta]))
        truth = np.array([t.success for t in held], dtype=float)
        p_before = np.array([float(np.mean(p.split(o)[0])) for p, o in b_outs])
        p_after = np.array([float(np.mean(p.split(o)[0])) for p, o in a_outs])
        brier_before = float(np.mean((p_before - truth) ** 2))
        brier_after = float(np.mean((p_after - truth) ** 2))
    return SimFit(parameters, len(fitted), len(held), brier_before, brier_after, float(ll_before), float(ll_after),
                  agreement, run.done, len(U), sorted({t.scenario.name for t in trials}), to_real(U), y,
                  settings.prior_width)


def to_real_axis(lower: np.ndarray, upper: np.ndarray, k: int, u: float) -> float:
    return float(lower[k] + u * (upper[k] - lower[k]))


def _surrogate(U: np.ndarray, y: np.ndarray, seed: int):
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel

    d = U.shape[1]
    kernel = (ConstantKernel(1.0, (1e-3, 1e3)) * Matern(length_scale=np.full(d, 0.3), length_scale_bounds=(0.02, 20.0),
                                                         nu=2.5)
              + WhiteKernel(1e-2, (1e-6, 1.0)))
    gp = GaussianProcessRegressor(kernel, normalize_y=True, n_restarts_optimizer=2, random_state=seed)
    import warnings

    from sklearn.exceptions import ConvergenceWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        gp.fit(U, y)
    return gp


def _log_prior(u0: np.ndarray, width: float | None) -> Callable[[np.ndarray], np.ndarray]:
    """The log-prior (up to a constant) of points ``(n, d)`` in normalized units: Gaussian around ``u0`` with
    standard deviation ``width`` on every axis; zero everywhere when ``width`` is None."""
    if width is None:
        return lambda U: np.zeros(len(np.atleast_2d(U)))
    return lambda U: -0.5 * np.sum(((np.atleast_2d(U) - u0) / width) ** 2, axis=1)


def _posterior(gp, prior: Callable[[np.ndarray], np.ndarray]) -> Callable[[np.ndarray], np.ndarray]:
    """The surrogate's log-likelihood plus the log-prior, of points ``(n, d)``."""
    return lambda U: gp.predict(np.atleast_2d(U)) + prior(U)


def _argmax(f, U: np.ndarray, y: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The maximum of ``f`` (points -> values) in the unit box: L-BFGS-B from the best candidates (by their values
    ``y``) and a few random starts."""
    d = U.shape[1]
    starts = [U[i] for i in np.argsort(-y)[:3]] + [rng.random(d) for _ in range(3)]
    best_u, best_v = U[int(np.argmax(y))], -np.inf
    objective = lambda u: -float(f(u[None, :])[0])  # noqa: E731
    for start in starts:
        result = minimize(objective, start, method="L-BFGS-B", bounds=[(0.0, 1.0)] * d)
        if -result.fun > best_v:
            best_u, best_v = np.clip(result.x, 0, 1), -result.fun
    return best_u


def _laplace_sd(posterior, u: np.ndarray, h: float = 0.02) -> np.ndarray | None:
    """Standard deviations (normalized units) from the Hessian of ``posterior`` (points -> values) at ``u``; None if
    not curved down."""
    d = len(u)
    f = lambda v: float(posterior(np.clip(v, -0.2, 1.2)[None, :])[0])  # noqa: E731
    hessian = np.zeros((d, d))
    f0 = f(u)
    for i in range(d):
        for j in range(i, d):
            ei, ej = np.eye(d)[i] * h, np.eye(d)[j] * h
            if i == j:
                hessian[i, i] = (f(u + ei) - 2 * f0 + f(u - ei)) / h ** 2
            else:
                hessian[i, j] = hessian[j, i] = (f(u + ei + ej) - f(u + ei - ej) - f(u - ei + ej) + f(u - ei - ej)) / (
                    4 * h * h)
    if not np.all(np.linalg.eigvalsh(hessian) < 0):
        return None
    covariance = np.linalg.inv(-hessian)
    return np.sqrt(np.clip(np.diag(covariance), 0.0, None))


def _axis_interval(posterior, u: np.ndarray, k: int) -> tuple[float, float]:
    """The values of axis ``k`` (others at ``u``) whose ``posterior`` (points -> values) is within 1.92 of
    ``u``'s."""
    grid = np.linspace(0.0, 1.0, 201)
    points = np.repeat(u[None, :], len(grid), axis=0)
    points[:, k] = grid
    values = posterior(points)
    inside = grid[values >= float(posterior(u[None, :])[0]) - _LOG_DROP_95]
    return (float(inside.min()), float(inside.max())) if len(inside) else (0.0, 1.0)


def _agreement(trials: Sequence[FitTrial], outs_before, outs_after) -> list[EventAgreement]:
    rows: dict[tuple[str, str], list[tuple[float, float, float, float, float]]] = {}
    for i, trial in enumerate(trials):
        (problem, before), (_, after) = outs_before[i], outs_after[i]
        codes_b, codes_a = problem.split(before)[1], problem.split(after)[1]
        for k, event in enumerate(problem.event_names):
            rows.setdefault((trial.scenario.name, event), []).append((
                float(trial.codes[k] == YES), float(np.mean(codes_b[:, k] == YES)),
                float(np.mean(codes_a[:, k] == YES)), float(np.mean(codes_b[:, k] == trial.codes[k])),
                float(np.mean(codes_a[:, k] == trial.codes[k]))))
    return [EventAgreement(scenario, event, *np.mean(np.array(values), axis=0).tolist())
            for (scenario, event), values in rows.items()]


__all__ = ["NO", "NOT_REACHED", "YES", "EventAgreement", "FitSettings", "FittedParameter", "Runner", "SimFit",
           "fit_simulator"]
