"""Every default of thesis sections 4.5-4.8 as a named setting (frozen dataclasses)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields, replace

from design.robust.problem import RobustError

#: The layout methods of thesis Table 4.2: ours (PSP + optimization) and the baselines B1-B3.
METHODS = ("ours", "b1", "b2", "b3")


@dataclass(frozen=True)
class PSPSettings:
    """Settings of the PSP pipeline (thesis 4.5-4.7); defaults are the thesis's unless noted.

    Attributes
    ----------
    n_initial : int
        N₀ˢ, Sobol points of the initial exploration step (500).
    n_per_step : int
        Nₖˢ, points drawn per adaptive exploration step (10).
    n_successes : int
        N⁺, global successes that end the exploration (200).
    max_exploration_steps : int
        kᵉ, maximum adaptive exploration steps (500).
    exploration_sigma : float
        σ, diagonal covariance of each Gaussian of the exploration mixture, in normalized units (0.01, i.e. a
        standard deviation of 0.1).
    target_accuracy : float
        Cross-validated accuracy that ends active learning (0.9).
    max_active_steps : int
        k¹, maximum active-learning steps per classifier (5).
    n_queries : int
        Nˢ, layouts simulated per query-synthesis step (10, as Nₖˢ).
    query_oversampling : int
        Candidates drawn per kept query (10: "10 Nˢ" in Algorithm 2).
    cv_folds : int
        Stratified folds of the hyper-parameter search and of Platt calibration (3).
    cv_scoring : {"accuracy", "roc_auc", "neg_log_loss", "calibrated_log_loss"}
        What the C, γ search maximizes: the thesis's accuracy; ROC AUC, which does not prefer a constant
        classifier when an event mostly succeeds; or (ours) the log loss of the Platt-calibrated out-of-fold
        probabilities pooled over the folds, which alone sees that a setting's folds do not compare (ROC AUC
        scored a nearly flat decision function 1 fold by fold, and Platt scaling then said 0.5 everywhere; see
        :class:`~design.robust.psp.CalibratedSVM`). Active learning stops on accuracy either way.
    c_grid, gamma_grid : tuple of float
        Logarithmic ranges searched for the SVM's C and γ (γ on standardized data). The thesis does not give the
        ranges; these are ours.
    quasi_deterministic : float
        Events whose conditional success rate is at least this get no classifier (0.95).
    quasi_deterministic_sample : {"exploration", "initial"}
        Where that rate is measured: on every explored layout, as the thesis does, or on the uniform Sobol start
        only (ours). The exploration's Gaussian mixture concentrates layouts around earlier successes, where an
        event that fails on a quarter of the design space can still succeed 95 % of the time.
    quasi_deterministic_min_rows : int
        With ``"initial"``, the Sobol rows whose parents succeeded must be at least this many, else every explored
        layout is used (ours).
    mutual_information_threshold : float
        A parameter belongs to an event's subspace if its mutual information (nats) with the event exceeds this
        (0.2). When no parameter does, the parameters with at least half the largest value are kept (ours).
    subspace_check : bool
        Cross-validate each event's classifier on its mutual-information subspace and on every parameter, and keep
        the subspace only if it scores no worse under ``cv_scoring`` (ours; the thesis keeps it). Mutual
        information scores parameters one at a time: BALLRUN's "ball rolls on the bottom track" kept one of the
        parameters it depends on and was learnt as an average over the others, 0.77 where it always happened.
    factorize : bool
        Per-event factorized PSP (4.6) or one classifier of global success (4.5).
    calibrate_product : bool
        Calibrate the product of the factors against global success (ours; the thesis multiplies them): Platt
        scaling of its logit, fitted on the samples' out-of-fold factor probabilities (see
        :meth:`~design.robust.psp.FactorizedPSP._calibrate_product`). Increasing, so it moves no optimum.
    smooth_min_alpha : float
        α of the smooth minimum energy (4.7); the thesis does not give its value; 10 is ours.
    optimizer_max_iterations : int
        SLSQP iteration limit.
    objective : {"point", "global_robustness"}
        What the optimization maximizes. ``"point"`` is the thesis's: the smooth minimum of the per-event
        probabilities at the layout (4.7), optionally averaged over a placement error, by SLSQP. ``"global_robustness"``
        (ours) is ρ_g's own formula (4.8.3) with the PSP in place of simulated successes: the layout whose
        neighbourhoods at every scale the model predicts to succeed most, found among the samples, a Sobol set of
        candidates and a refinement around the best.
    reference_layouts, candidate_layouts : int
        With ``"global_robustness"``: the Sobol layouts that stand in for the evaluation set, and the candidates.
    refine_layouts : int
        With ``"global_robustness"``: layouts drawn around the best candidate to refine it.
    refine_radius : float
        Radius (normalized) of that refinement ball.
    verification_candidates : int
        How many of the model's best distinct candidates are simulated before one is kept (1: the thesis's single
        re-simulation of the result; ours uses several, see :func:`~design.robust.pipeline.verify_candidates`).
    verification_samples : int
        Simulations per verified candidate: itself and layouts drawn in the ball of ``verification_radius``
        around it. Candidates x samples come out of the learning budget; a budget too small for them gets fewer
        samples per candidate, so that verification takes at most a quarter of it.
    verification_radius : float
        Radius (normalized) of that ball, and the least distance between two verified candidates (0.05; ours with
        ``verification_score="rho_g"``: 0.01). With ``"rho_g"`` the start already covers ρ_g's larger balls, and a
        small ball measures what it cannot: how reliably the layout itself works when rebuilt almost exactly (in a
        chaotic contraption, a success can sit among failures at any scale).
    verification_start_candidates : int
        How many layouts of the uniform Sobol start are verified beside the model's candidates (0: the thesis's;
        ours: 3): the successes with the most success around them, ranked by ρ_g's formula estimated from the start
        alone (:func:`~design.robust.robustness.densest_successes`). The model's optima often sit where the
        classifiers extrapolate, at an edge or in a thin success region; these are simulated successes in the
        largest success regions the start has seen. They take ``verification_samples`` simulations each from the
        budget, like the model's candidates.
    verification_score : {"local_rate", "rho_g"}
        How verified candidates are compared (among those that succeed themselves): by the success rate in their
        ball, or (ours) by ρ_g's own formula (4.8.3) estimated from the uniform Sobol start of the exploration as
        the evaluation set and each candidate's ball as its local layouts. ``"rho_g"`` adds what the ball cannot
        see: whether the candidate sits in a large success region. No extra simulations.
    optimizer_starts : int
        SLSQP runs from this many of the best-ranked samples (simulated successes first) and keeps the lowest
        energy; 1 is the thesis's single start from the best sample.
    exploration_share : float
        When a simulation budget is given, the largest part of it the exploration may use (ours: the thesis has
        no budget for its own method, it measures one).
    initial_share : float
        When a simulation budget is given, the largest part of it the initial Sobol sample may use, so that small
        budgets still leave room for adaptive steps (ours).
    fallback_to_best_sample : bool
        If the optimized layout fails when re-simulated, return the best simulated sample instead (ours).
    placement_error : float
        ε of a uniform placement error (normalized units) that the optimization averages its energy over:
        0 optimizes the PSP at the point, as the thesis does; ε > 0 optimizes the mean over a fixed set of
        :attr:`placement_samples` offsets in [-ε, ε]^d (clipped to the design space), which keeps the optimizer
        away from corners where the classifiers extrapolate (ours).
    placement_samples : int
        Offsets of that mean (Sobol points, fixed by the seed).
    """

    n_initial: int = 500
    n_per_step: int = 10
    n_successes: int = 200
    max_exploration_steps: int = 500
    exploration_sigma: float = 0.01
    target_accuracy: float = 0.9
    max_active_steps: int = 5
    n_queries: int = 10
    query_oversampling: int = 10
    cv_folds: int = 3
    cv_scoring: str = "accuracy"
    c_grid: tuple[float, ...] = (0.1, 1.0, 10.0, 100.0, 1000.0)
    gamma_grid: tuple[float, ...] = (0.01, 0.1, 1.0, 10.0)
    quasi_deterministic: float = 0.95
    quasi_deterministic_sample: str = "exploration"
    quasi_deterministic_min_rows: int = 20
    mutual_information_threshold: float = 0.2
    subspace_check: bool = False
    factorize: bool = True
    calibrate_product: bool = False
    smooth_min_alpha: float = 10.0
    optimizer_max_iterations: int = 100
    optimizer_starts: int = 1
    verification_candidates: int = 1
    verification_samples: int = 1
    verification_radius: float = 0.05
    verification_start_candidates: int = 0
    verification_score: str = "local_rate"
    objective: str = "point"
    reference_layouts: int = 2048
    candidate_layouts: int = 2048
    refine_layouts: int = 256
    refine_radius: float = 0.1
    exploration_share: float = 0.75
    initial_share: float = 0.5
    fallback_to_best_sample: bool = True
    placement_error: float = 0.0
    placement_samples: int = 64

    def __post_init__(self) -> None:
        positive_ints = ("n_initial", "n_per_step", "n_successes", "max_exploration_steps", "n_queries",
                         "query_oversampling", "optimizer_max_iterations", "optimizer_starts", "placement_samples",
                         "reference_layouts", "candidate_layouts", "refine_layouts",
                         "verification_candidates", "verification_samples",
                         "quasi_deterministic_min_rows")
        for name in positive_ints:
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or value < 1:
                raise RobustError(f"PSP settings: {name} must be a positive integer, got {value!r}")
        if int(self.cv_folds) != self.cv_folds or self.cv_folds < 2:
            raise RobustError(f"PSP settings: cv_folds must be an integer >= 2, got {self.cv_folds!r}")
        if (isinstance(self.verification_start_candidates, bool)
                or int(self.verification_start_candidates) != self.verification_start_candidates
                or self.verification_start_candidates < 0):
            raise RobustError("PSP settings: verification_start_candidates must be an integer >= 0, "
                              f"got {self.verification_start_candidates!r}")
        if self.max_active_steps < 0:
            raise RobustError(f"PSP settings: max_active_steps must be >= 0, got {self.max_active_steps!r}")
        for name in ("target_accuracy", "quasi_deterministic", "exploration_share", "initial_share"):
            value = getattr(self, name)
            if not 0.0 < value <= 1.0:
                raise RobustError(f"PSP settings: {name} must be in (0, 1], got {value!r}")
        for name in ("exploration_sigma", "smooth_min_alpha"):
            if not getattr(self, name) > 0:
                raise RobustError(f"PSP settings: {name} must be > 0, got {getattr(self, name)!r}")
        if self.quasi_deterministic_sample not in ("exploration", "initial"):
            raise RobustError("PSP settings: quasi_deterministic_sample must be 'exploration' or 'initial', "
                              f"got {self.quasi_deterministic_sample!r}")
        if self.cv_scoring not in ("accuracy", "roc_auc", "neg_log_loss", "calibrated_log_loss"):
            raise RobustError("PSP settings: cv_scoring must be 'accuracy', 'roc_auc', 'neg_log_loss' or "
                              "'calibrated_log_loss', "
                              f"got {self.cv_scoring!r}")
        if self.verification_score not in ("local_rate", "rho_g"):
            raise RobustError("PSP settings: verification_score must be 'local_rate' or 'rho_g', "
                              f"got {self.verification_score!r}")
        if self.objective not in ("point", "global_robustness"):
            raise RobustError(f"PSP settings: objective must be 'point' or 'global_robustness', got {self.objective!r}")
        for name in ("refine_radius", "verification_radius"):
            if not 0.0 < getattr(self, name) <= 1.0:
                raise RobustError(f"PSP settings: {name} must be in (0, 1], got {getattr(self, name)!r}")
        if not 0.0 <= self.placement_error <= 0.5:
            raise RobustError(f"PSP settings: placement_error must be in [0, 0.5], got {self.placement_error!r}")
        if self.mutual_information_threshold < 0:
            raise RobustError(
                f"PSP settings: mutual_information_threshold must be >= 0, got {self.mutual_information_threshold!r}"
            )
        for name in ("c_grid", "gamma_grid"):
            grid = getattr(self, name)
            if not grid or any(not v > 0 for v in grid):
                raise RobustError(f"PSP settings: {name} must be a non-empty list of positive numbers, got {grid!r}")

    @classmethod
    def recommended(cls, **changes) -> PSPSettings:
        """The thesis's method with our changes (the station's default; ``PSPSettings()`` is the thesis's as published).

        It measures the quasi-deterministic test on the uniform start, searches C, γ by ROC AUC, and verifies the
        three best optima and the three densest successes of the start with 15 simulations each, in a ball of
        radius 0.01, keeping the one of highest estimated ρ_g (see the attributes). Figures against the thesis's
        settings and the baselines are on the results page docs/results/2026-12-04-robust-layouts.md.
        """
        return cls(**{**RECOMMENDED_CHANGES, **changes})

    @classmethod
    def from_mapping(cls, data: Mapping, source: str = "PSP settings") -> PSPSettings:
        """Settings from a JSON-like mapping, e.g. ``psp_settings`` of a LAYOUT.json, to repeat a run.

        Names missing from ``data`` keep the thesis's defaults. Unknown names and values of the wrong type raise a
        :class:`RobustError` naming ``source``, the setting and the expected type; lists become tuples.
        """
        if not isinstance(data, Mapping):
            raise RobustError(f"{source}: expected a table of settings, got {type(data).__name__}")
        known = {f.name: f for f in fields(cls)}
        unknown = sorted(set(data) - set(known))
        if unknown:
            raise RobustError(f"{source}: unknown setting(s) {unknown}; known: {sorted(known)}")
        values = {}
        for name, value in data.items():
            default = known[name].default
            if isinstance(default, tuple):
                ok = isinstance(value, (list, tuple)) and all(
                    isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
                expected, value = "a list of numbers", tuple(value) if ok else value
            elif isinstance(default, bool):
                ok, expected = isinstance(value, bool), "true or false"
            elif isinstance(default, int):
                ok, expected = isinstance(value, int) and not isinstance(value, bool), "an integer"
            elif isinstance(default, float):
                ok, expected = isinstance(value, (int, float)) and not isinstance(value, bool), "a number"
            else:
                ok, expected = isinstance(value, str), "a string"
            if not ok:
                raise RobustError(f"{source}: {name} must be {expected}, got {value!r}")
            values[name] = value
        try:
            return cls(**values)
        except RobustError as error:
            raise RobustError(f"{source}: {str(error).removeprefix('PSP settings: ')}") from None

    def with_changes(self, **changes) -> PSPSettings:
        """A copy with some settings changed (unknown names raise)."""
        known = {f.name for f in fields(self)}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise RobustError(f"PSP settings: unknown setting(s) {unknown}; known: {sorted(known)}")
        return replace(self, **changes)


#: What :meth:`PSPSettings.recommended` changes from the thesis's defaults.
RECOMMENDED_CHANGES = {
    "quasi_deterministic_sample": "initial",
    "cv_scoring": "calibrated_log_loss",
    "calibrate_product": True,
    "subspace_check": True,
    "verification_candidates": 3,
    "verification_samples": 15,
    "optimizer_starts": 3,
    "verification_start_candidates": 3,
    "verification_radius": 0.01,
    "verification_score": "rho_g",
}


@dataclass(frozen=True)
class RobustnessSettings:
    """Settings of the robustness measures and baselines (thesis 4.8.3, Appendix C.3).

    Attributes
    ----------
    n_evaluation : int
        Size of the Sobol evaluation set (the thesis used 100K-1M; ours is smaller by default for a 2-core machine).
    epsilon_step : float
        l_ε, the step of the ρ_l curve (1/30).
    thickness_factor : float
        η = thickness_factor · l_ε, the ball "thickness" (0.1).
    n_local : int
        Layouts simulated in B_η(x*) and added to the evaluation set (100).
    baseline_radius : float
        ε of the baselines' objective ρ_l(x, 0.1) (0.1).
    """

    n_evaluation: int = 2048
    epsilon_step: float = 1.0 / 30.0
    thickness_factor: float = 0.1
    n_local: int = 100
    baseline_radius: float = 0.1

    def __post_init__(self) -> None:
        for name in ("n_evaluation", "n_local"):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or value < 1:
                raise RobustError(f"robustness settings: {name} must be a positive integer, got {value!r}")
        for name in ("epsilon_step", "baseline_radius"):
            if not 0 < getattr(self, name) <= 1:
                raise RobustError(f"robustness settings: {name} must be in (0, 1], got {getattr(self, name)!r}")
        if not self.thickness_factor >= 0:
            raise RobustError(f"robustness settings: thickness_factor must be >= 0, got {self.thickness_factor!r}")
