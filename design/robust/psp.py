"""Parametric success probability (thesis 4.5-4.6): exploration, SVM active learning, Platt calibration, factorization.

- :func:`explore` is Algorithm 1 (Sobol start, Gaussian mixture around the best partially successful layouts).
- :class:`CalibratedSVM` is one classifier: RBF SVM on standardized data, C and γ by stratified k-fold
  cross-validation, then Platt scaling fitted on out-of-fold decision values of the chosen C, γ (the grid search is
  not repeated for calibration).
- :class:`FactorizedPSP` is the estimator of 4.6 (or of 4.5 with ``factorize=False``): quasi-deterministic events get
  no classifier, mutual information maps each other event to its parameters, and each event's classifier is refined
  by query synthesis near its decision boundary (Algorithm 2) before calibration. The PSP is the product.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize
from sklearn.feature_selection import mutual_info_classif
from sklearn.model_selection import GridSearchCV, StratifiedKFold, cross_val_predict
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC

from design.robust.probability import IDENTITY_PLATT, combine_factors, logit, platt_probability
from design.robust.problem import LayoutProblem, RobustError, topological_events
from design.robust.sampling import gaussian_mixture_draw, sample_physically_valid, sobol_valid
from design.robust.settings import PSPSettings

#: An oracle simulates valid normalized layouts ``(n, d)`` and returns per-event success ``(n, n_events)``.
Oracle = Callable[[np.ndarray], np.ndarray]


# --------------------------------------------------------------------------------------------------------------
# Platt scaling
# --------------------------------------------------------------------------------------------------------------
def fit_platt(scores: np.ndarray, labels: np.ndarray) -> tuple[float, float]:
    """Platt's (1999) maximum-likelihood fit of ``p = 1 / (1 + exp(a f + b))`` with his smoothed targets."""
    scores = np.asarray(scores, dtype=float)
    labels = np.asarray(labels, dtype=bool)
    n_pos, n_neg = labels.sum(), (~labels).sum()
    targets = np.where(labels, (n_pos + 1.0) / (n_pos + 2.0), 1.0 / (n_neg + 2.0))

    def loss(ab):
        z = ab[0] * scores + ab[1]
        # -log L with p = sigmoid(-z), written stably: log(1 + e^z) - (1 - t) z
        return np.sum(np.logaddexp(0.0, z) - (1.0 - targets) * z)

    def grad(ab):
        z = ab[0] * scores + ab[1]
        g = 1.0 / (1.0 + np.exp(-z)) - (1.0 - targets)
        return np.array([np.sum(g * scores), np.sum(g)])

    start = np.array([-1.0, np.log((n_neg + 1.0) / (n_pos + 1.0))])
    result = minimize(loss, start, jac=grad, method="BFGS")
    return float(result.x[0]), float(result.x[1])


def platt_log_loss(scores: np.ndarray, labels: np.ndarray, platt: tuple[float, float]) -> float:
    """Mean negative log likelihood of Boolean ``labels`` under Platt's sigmoid of ``scores``."""
    z = platt[0] * np.asarray(scores, dtype=float) + platt[1]
    # p = sigmoid(-z): -log p = log(1 + e^z), -log(1 - p) = log(1 + e^-z)
    return float(np.mean(np.where(labels, np.logaddexp(0.0, z), np.logaddexp(0.0, -z))))


# --------------------------------------------------------------------------------------------------------------
# One calibrated classifier
# --------------------------------------------------------------------------------------------------------------
class CalibratedSVM:
    """RBF SVM with cross-validated C, γ and Platt calibration (thesis 4.5.2-4.5.3), scikit-learn shaped.

    Parameters
    ----------
    c_grid, gamma_grid : sequence of float
        Values searched for C and γ.
    cv_folds : int
        Stratified folds (3).
    random_state : int
        Seed of the fold shuffling.
    scoring : {"accuracy", "roc_auc", "neg_log_loss", "calibrated_log_loss"}
        What the search maximizes. The thesis's accuracy cannot tell a useful classifier from a constant one when
        one class dominates (an event failing on 15 % of layouts is 85 % "accurate" by always saying success);
        ROC AUC scores the ranking that Platt scaling turns into probabilities, but fold by fold.
        ``"calibrated_log_loss"`` minimizes the log loss of the Platt-calibrated out-of-fold probabilities, pooled
        over the folds as Platt scaling pools them (see :meth:`_fit_calibrated_search`).

    Attributes
    ----------
    constant_ : float or None
        When a class has fewer members than ``cv_folds``, no SVM can be cross-validated: the classifier predicts
        this constant (Laplace-smoothed success rate) instead.
    model_ : Pipeline
        StandardScaler + SVC fitted on all data with the chosen C, γ.
    best_params_ : dict
        Chosen C and γ.
    cv_accuracy_ : float
        Mean stratified cross-validated accuracy of the chosen C, γ (whatever the scoring).
    cv_score_ : float
        Its mean cross-validated score under ``scoring``.
    platt_ : tuple of float
        (a, b) of ``p = 1 / (1 + exp(a f + b))``.
    support_indices_ : ndarray
        Rows of the training data that are support vectors.
    held_out_probability_ : ndarray
        After calibration: each training row's calibrated probability from the fold that did not see it (the
        leave-one-out rate for a constant), what :class:`FactorizedPSP` calibrates the product of its factors on.
    """

    def __init__(self, c_grid=(0.1, 1.0, 10.0, 100.0, 1000.0), gamma_grid=(0.01, 0.1, 1.0, 10.0), cv_folds=3,
                 random_state=0, scoring="accuracy"):
        self.c_grid = c_grid
        self.gamma_grid = gamma_grid
        self.cv_folds = cv_folds
        self.random_state = random_state
        self.scoring = scoring

    def _folds(self) -> StratifiedKFold:
        return StratifiedKFold(n_splits=self.cv_folds, shuffle=True, random_state=self.random_state)

    def fit(self, X: np.ndarray, y: np.ndarray, calibrate: bool = True) -> CalibratedSVM:
        """Search C, γ; fit the SVM on all data; then (``calibrate``) fit Platt scaling on out-of-fold scores."""
        X = np.asarray(X, dtype=float)
        y = np.asarray(y, dtype=bool)
        if X.ndim != 2 or len(X) != len(y):
            raise RobustError(f"classifier: X must be (n, d) with one label per row, got {X.shape} and {y.shape}")
        n_pos, n_neg = int(y.sum()), int((~y).sum())
        self.n_samples_ = len(y)
        self.platt_ = (-1.0, 0.0)
        if min(n_pos, n_neg) < self.cv_folds:
            self.constant_ = (n_pos + 1.0) / (len(y) + 2.0)
            self.model_ = None
            self.best_params_ = {}
            self.cv_accuracy_ = max(n_pos, n_neg) / max(len(y), 1)
            self.cv_score_ = float("nan")
            self.support_indices_ = np.zeros(0, dtype=int)
            return self
        self.constant_ = None
        if self.scoring == "calibrated_log_loss":
            return self._fit_calibrated_search(X, y, calibrate)
        search = GridSearchCV(
            make_pipeline(StandardScaler(), SVC(kernel="rbf")),
            {"svc__C": list(self.c_grid), "svc__gamma": list(self.gamma_grid)},
            cv=self._folds(),
            scoring={"chosen": self.scoring, "accuracy": "accuracy"},
            refit="chosen",
        )
        search.fit(X, y)
        self.model_ = search.best_estimator_
        self.best_params_ = {"C": search.best_params_["svc__C"], "gamma": search.best_params_["svc__gamma"]}
        self.cv_score_ = float(search.best_score_)
        self.cv_accuracy_ = float(search.cv_results_["mean_test_accuracy"][search.best_index_])
        self.support_indices_ = np.asarray(self.model_[-1].support_, dtype=int)
        if calibrate:
            self.calibrate(X, y)
        return self

    def _fit_calibrated_search(self, X: np.ndarray, y: np.ndarray, calibrate: bool) -> CalibratedSVM:
        """Choose C, γ by the log loss of Platt-calibrated out-of-fold probabilities, the numbers the PSP reports.

        Per-fold scores (accuracy, ROC AUC) judge each fold's decision values apart, but Platt scaling maps the
        pooled out-of-fold values of all folds with one sigmoid. A weak setting (small C and γ: every point a
        support vector, a nearly flat decision function whose offset is the fold's intercept) ranks each fold
        perfectly (AUC 1) while the folds' values do not compare: pooled, they carry almost nothing and Platt
        answers the base rate everywhere (P = 0.5 at a tilted plank's steep end, where the block always
        slides). The pooled log loss sees exactly that; ties keep the grid's first (most regularized) setting.
        """
        folds = self._folds()
        best = None
        for c in self.c_grid:
            for gamma in self.gamma_grid:
                model = make_pipeline(StandardScaler(), SVC(kernel="rbf", C=c, gamma=gamma))
                scores = cross_val_predict(model, X, y, cv=folds, method="decision_function")
                platt = fit_platt(scores, y)
                loss = platt_log_loss(scores, y, platt)
                if best is None or loss < best[0] - 1e-12:
                    best = (loss, c, gamma, scores, platt)
        loss, c, gamma, scores, platt = best
        self.model_ = make_pipeline(StandardScaler(), SVC(kernel="rbf", C=c, gamma=gamma)).fit(X, y)
        self.best_params_ = {"C": c, "gamma": gamma}
        self.cv_score_ = -float(loss)
        self.cv_accuracy_ = float(np.mean((scores > 0) == y))
        self.support_indices_ = np.asarray(self.model_[-1].support_, dtype=int)
        if calibrate:
            self.platt_ = platt
            self.held_out_probability_ = platt_probability(scores, platt)
        return self

    def calibrate(self, X: np.ndarray, y: np.ndarray) -> CalibratedSVM:
        """Platt scaling on out-of-fold decision values of the already chosen C, γ (no new grid search)."""
        y = np.asarray(y, dtype=bool)
        if self.constant_ is None:
            scores = cross_val_predict(self.model_, X, y, cv=self._folds(), method="decision_function")
            # The SVC's classes are (False, True): a positive score means success.
            self.platt_ = fit_platt(scores, y)
            self.held_out_probability_ = platt_probability(scores, self.platt_)
        else:
            # Leave one out: the constant the other rows give each row.
            self.held_out_probability_ = (y.sum() - y + 1.0) / (len(y) - 1.0 + 2.0)
        return self

    def decision_function(self, X: np.ndarray) -> np.ndarray:
        """Signed score: positive on the success side of the boundary."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if self.constant_ is not None:
            return np.full(len(X), np.log(self.constant_ / (1.0 - self.constant_)))
        return self.model_.decision_function(X)

    def success_probability(self, X: np.ndarray) -> np.ndarray:
        """Calibrated probability of success, shape ``(n,)``."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if self.constant_ is not None:
            return np.full(len(X), self.constant_)
        return platt_probability(self.decision_function(X), self.platt_)

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """``(n, 2)``: probabilities of failure and success (scikit-learn convention)."""
        p = self.success_probability(X)
        return np.column_stack([1.0 - p, p])

    def predict(self, X: np.ndarray) -> np.ndarray:
        return self.decision_function(X) > 0


def _classifier(settings, seed: int) -> CalibratedSVM:
    """An unfitted classifier with the settings' grids, folds and scoring."""
    return CalibratedSVM(settings.c_grid, settings.gamma_grid, settings.cv_folds, seed, settings.cv_scoring)


# --------------------------------------------------------------------------------------------------------------
# Exploration (Algorithm 1)
# --------------------------------------------------------------------------------------------------------------
@dataclass
class Samples:
    """Simulated layouts: ``U`` ``(n, d)`` normalized, ``events`` ``(n, n_events)`` per-event success.

    ``n_initial`` counts the leading rows that are the uniform (Sobol) start of the exploration, when known.
    """

    U: np.ndarray
    events: np.ndarray
    n_initial: int | None = None

    @property
    def n_successful_events(self) -> np.ndarray:
        return self.events.sum(axis=1)

    @property
    def success(self) -> np.ndarray:
        return self.events.all(axis=1)

    def add(self, U: np.ndarray, events: np.ndarray) -> None:
        self.U = np.concatenate([self.U, U])
        self.events = np.concatenate([self.events, events])


def explore(
    problem: LayoutProblem,
    oracle: Oracle,
    settings,
    seed: int,
    max_simulations: int | None = None,
    initial_cap: int | None = None,
) -> Samples:
    """Algorithm 1: Sobol start, then a Gaussian mixture around the top N⁺ partially successful layouts.

    Stops when N⁺ global successes are found, after kᵉ steps, or when ``max_simulations`` are used; the Sobol start
    uses at most ``initial_cap`` simulations.
    """
    rng = np.random.default_rng(seed)
    cap = max_simulations if max_simulations is not None else np.inf
    n0 = int(min(settings.n_initial, cap))
    if initial_cap is not None:
        n0 = max(1, min(n0, int(initial_cap)))
    U0 = sobol_valid(problem, n0, seed)
    samples = Samples(U0, oracle(U0), n_initial=len(U0))
    n_events = len(problem.event_names)
    variance = settings.exploration_sigma
    for _step in range(settings.max_exploration_steps):
        successes = int(samples.success.sum())
        room = int(min(settings.n_per_step, cap - len(samples.U)))
        if successes >= settings.n_successes or room <= 0:
            break
        counts = samples.n_successful_events
        top = np.argsort(-counts, kind="stable")[: settings.n_successes]
        weights = counts[top].astype(float)
        if weights.sum() == 0:  # nothing partially succeeded yet: spread evenly around the top points
            weights = np.ones(len(top))
        draw = gaussian_mixture_draw(samples.U[top], weights, np.sqrt(variance), rng)
        Uk = sample_physically_valid(problem, draw, room, "exploration layouts")
        samples.add(Uk, oracle(Uk))
        if samples.events.shape[1] != n_events:
            raise RobustError(f"{problem.name}: the simulator returned {samples.events.shape[1]} events, "
                              f"expected {n_events}")
    return samples


# --------------------------------------------------------------------------------------------------------------
# Factorized PSP (4.6) with query synthesis (Algorithm 2)
# --------------------------------------------------------------------------------------------------------------
@dataclass
class EventModel:
    """One factor of the PSP: an event's subspace and calibrated classifier (or none if quasi-deterministic)."""

    event: str
    subspace: tuple[int, ...]
    quasi_deterministic: bool
    success_rate: float
    classifier: CalibratedSVM | None
    n_samples: int
    active_steps: int = 0


class FactorizedPSP:
    """The parametric success probability, factorized per event (thesis 4.6) or global (4.5).

    Parameters
    ----------
    settings : PSPSettings
        Thesis defaults by name.
    random_state : int
        Seed of every random process (query sampling, folds, mutual information).

    Attributes
    ----------
    models_ : list of EventModel
        One per event, in causal order; in the global mode a single model named ``"global success"``.
    samples_ : Samples
        Every simulated layout used (exploration plus queries).
    event_names_ : tuple of str
    cv_accuracy_ : float
        Smallest cross-validated accuracy among the classifiers (1 if there are none).
    """

    def __init__(self, settings=None, random_state: int = 0) -> None:
        self.settings = settings
        self.random_state = random_state

    def fit(
        self,
        problem: LayoutProblem,
        samples: Samples,
        oracle: Oracle | None = None,
        remaining: Callable[[], int] | None = None,
        on_model: Callable[[EventModel], None] | None = None,
    ) -> FactorizedPSP:
        """Learn the PSP from explored ``samples``; with an ``oracle``, refine each classifier by query synthesis.

        Parameters
        ----------
        problem : LayoutProblem
            Its causal graph defines the factors; its validity filters queries.
        samples : Samples
            Explored layouts (extended in place by queries).
        oracle : callable, optional
            Simulates queries; without it there is no active learning.
        remaining : callable, optional
            Simulations left in the budget; queries stop at 0.
        on_model : callable, optional
            Called after each classifier (re)training (progress).
        """
        settings = self.settings if self.settings is not None else PSPSettings()
        if samples.U.ndim != 2 or samples.U.shape[1] != problem.dim:
            raise RobustError(f"{problem.name}: samples must have {problem.dim} columns, got {samples.U.shape}")
        if len(samples.U) == 0:
            raise RobustError(f"{problem.name}: cannot learn a PSP from no samples")
        rng = np.random.default_rng(self.random_state)
        self.problem_ = problem
        self.event_names_ = tuple(problem.event_names)
        self.samples_ = samples
        self._joins = dict(getattr(problem, "event_joins", {}) or {})
        index = {name: i for i, name in enumerate(self.event_names_)}
        if settings.factorize:
            targets = [(name, [index[p] for p in problem.event_parents.get(name, ())], index[name])
                       for name in topological_events(problem)]
        else:
            targets = [("global success", [], None)]
        self._targets = targets
        self.models_ = []
        for name, parents, column in targets:
            model = self._fit_event(problem, settings, rng, name, parents, column, oracle, remaining, on_model)
            self.models_.append(model)
        accuracies = [m.classifier.cv_accuracy_ for m in self.models_ if m.classifier is not None]
        self.cv_accuracy_ = float(min(accuracies)) if accuracies else 1.0
        self.combine_platt_ = IDENTITY_PLATT
        if settings.factorize and settings.calibrate_product and self.learned_factors:
            self.combine_platt_ = self._calibrate_product()
        return self

    def held_out_factor_probabilities(self) -> np.ndarray:
        """``(n_samples, n_models)``: each factor's probability of each simulated sample, from a model that did not
        train on it: the out-of-fold probability on the factor's own training rows, the fitted factor elsewhere
        (rows where its parents failed, and rows added after it was fitted)."""
        U, events = self.samples_.U, self.samples_.events
        columns = []
        for k, model in enumerate(self.models_):
            probability = np.ones(len(U))
            if model.classifier is not None:
                probability = model.classifier.success_probability(U[:, model.subspace])
                held_out = getattr(model.classifier, "held_out_probability_", None)
                condition, _ = self.factor_rows(events, k)
                # Samples only grow by appending: the factor trained on the first n_samples rows where it applies.
                trained = np.flatnonzero(condition)[: model.n_samples]
                if held_out is not None and len(held_out) == len(trained):
                    probability[trained] = held_out
            columns.append(probability)
        return np.column_stack(columns)

    def _calibrate_product(self) -> tuple[float, float]:
        """Platt scaling of the product's logit against global success, on the samples' held-out factors.

        Each factor is calibrated alone, on the rows where its parents happened; their product is not: factors
        that are each a little unsure (Platt's smoothed targets, a constant from few rows, an event whose subspace
        leaves out a parameter that matters) multiply into a PSP far below the success rate of the layouts it is
        given for (BALLRUN: 0.08 at an optimum whose neighbourhood always succeeded). One more sigmoid, fitted on
        probabilities no factor trained on, maps the product to the success it goes with. It is increasing, so it
        changes no ranking; a fit that would reverse the order is refused (the product is kept).
        """
        product = np.prod(self.held_out_factor_probabilities(), axis=1)
        platt = fit_platt(logit(product), self.samples_.success)
        return platt if platt[0] < 0 else IDENTITY_PLATT

    def factor_rows(self, events: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Where factor ``k`` applies among simulated ``events`` ``(n, n_events)`` and its label there.

        Returns the Boolean rows whose parents happened (all rows for a root event or the global model) and the
        factor's outcome on every row (the event, or global success).
        """
        _name, parents, column = self._targets[k]
        return self._labels(parents, column, np.asarray(events, dtype=bool))

    def _labels(self, parents, column, events=None):
        events = self.samples_.events if events is None else events
        if not parents:
            condition = np.ones(len(events), dtype=bool)
        elif column is not None and self._joins.get(self.event_names_[column], "all") == "any":
            condition = events[:, parents].any(axis=1)  # an "any" join wakes up when one parent succeeded
        else:
            condition = events[:, parents].all(axis=1)
        labels = events[:, column] if column is not None else events.all(axis=1)
        return condition, labels

    def _quasi_deterministic_rate(self, settings, condition, labels) -> float:
        """The event's success rate given its parents, on the sample the setting names (see PSPSettings)."""
        rows = condition
        n_initial = self.samples_.n_initial
        if settings.quasi_deterministic_sample == "initial" and n_initial is not None:
            initial = np.zeros_like(condition)
            initial[:n_initial] = condition[:n_initial]
            # Too few uniform rows where the parents succeeded say little; then use every explored row.
            if initial.sum() >= settings.quasi_deterministic_min_rows:
                rows = initial
        return float(labels[rows].mean()) if rows.any() else 0.0

    def _fit_event(self, problem, settings, rng, name, parents, column, oracle, remaining, on_model) -> EventModel:
        condition, labels = self._labels(parents, column)
        X, y = self.samples_.U[condition], labels[condition]
        rate = self._quasi_deterministic_rate(settings, condition, labels) if len(y) else 0.0
        if column is not None and len(y) and rate >= settings.quasi_deterministic:
            model = EventModel(name, (), True, rate, None, len(y))
            if on_model is not None:
                on_model(model)
            return model
        subspace = tuple(range(problem.dim))
        if column is not None and len(y) and 0 < y.sum() < len(y):
            subspace = self._subspace(X, y, settings)
        seed = int(rng.integers(2**31))
        classifier = _classifier(settings, seed)
        classifier.fit(X[:, subspace], y, calibrate=False)
        if settings.subspace_check and len(subspace) < problem.dim and classifier.constant_ is None:
            # Mutual information judges each parameter alone; an event that needs a parameter only together with
            # another is then learnt as an average over it, unsure exactly where that parameter is right (the
            # optimum). Keep the subspace only if cross-validation says it predicts no worse than every parameter.
            full = _classifier(settings, seed).fit(X, y, calibrate=False)
            if full.cv_score_ > classifier.cv_score_:
                subspace, classifier = tuple(range(problem.dim)), full
        model = EventModel(name, subspace, False, rate, classifier, len(y))
        if on_model is not None:
            on_model(model)
        for _step in range(settings.max_active_steps):
            if oracle is None or classifier.cv_accuracy_ >= settings.target_accuracy:
                break
            budget = settings.n_queries if remaining is None else min(settings.n_queries, remaining())
            if budget <= 0 or classifier.constant_ is not None:
                break
            queries = self._synthesize_queries(problem, settings, rng, classifier, X, subspace, budget)
            if len(queries) == 0:
                break
            self.samples_.add(queries, oracle(queries))
            condition, labels = self._labels(parents, column)
            X, y = self.samples_.U[condition], labels[condition]
            classifier = _classifier(settings, seed)
            classifier.fit(X[:, subspace], y, calibrate=False)
            model = EventModel(name, subspace, False, float(y.mean()), classifier, len(y), model.active_steps + 1)
            if on_model is not None:
                on_model(model)
        classifier.calibrate(X[:, subspace], y)
        return model

    def _subspace(self, X, y, settings) -> tuple[int, ...]:
        """Parameters whose mutual information with the event exceeds the threshold (4.6)."""
        information = mutual_info_classif(X, y, discrete_features=False, random_state=self.random_state)
        chosen = np.flatnonzero(information > settings.mutual_information_threshold)
        if len(chosen) == 0:
            chosen = np.flatnonzero(information >= 0.5 * information.max()) if information.max() > 0 else \
                np.arange(X.shape[1])
        return tuple(int(i) for i in chosen)

    def _synthesize_queries(self, problem, settings, rng, classifier, X, subspace, n) -> np.ndarray:
        """Algorithm 2, lines 7-11: sample around support vectors, keep the n closest to the boundary."""
        support = X[classifier.support_indices_]
        if len(support) == 0:
            return np.zeros((0, problem.dim))
        scores = np.abs(classifier.decision_function(support[:, subspace]))
        weights = scores if scores.sum() > 0 else np.ones(len(scores))
        # U: the inverse of the standardization scaling, zero outside the event's subspace (only D_i varies).
        spread = np.zeros(problem.dim)
        spread[list(subspace)] = classifier.model_[0].scale_
        scales = scores[:, None] * spread[None, :]
        draw = gaussian_mixture_draw(support, weights, scales, rng)
        try:
            candidates = sample_physically_valid(problem, draw, settings.query_oversampling * n, "queries")
        except RobustError:
            return np.zeros((0, problem.dim))
        closeness = np.abs(classifier.decision_function(candidates[:, subspace]))
        return candidates[np.argsort(closeness, kind="stable")[:n]]

    # -- prediction ------------------------------------------------------------------------------------------
    def _check(self, U) -> np.ndarray:
        if not hasattr(self, "models_"):
            raise RobustError("PSP: call fit before predicting")
        U = np.atleast_2d(np.asarray(U, dtype=float))
        if U.shape[1] != self.problem_.dim:
            raise RobustError(f"PSP: layouts must have {self.problem_.dim} columns, got {U.shape[1]}")
        return U

    def factor_probabilities(self, U: np.ndarray) -> np.ndarray:
        """``(n, n_models)`` calibrated probability of each factor (1 for quasi-deterministic events)."""
        U = self._check(U)
        columns = []
        for model in self.models_:
            if model.classifier is None:
                columns.append(np.ones(len(U)))
            else:
                columns.append(model.classifier.success_probability(U[:, model.subspace]))
        return np.column_stack(columns)

    def predict_proba(self, U: np.ndarray) -> np.ndarray:
        """The PSP of each layout: the product of the factors (Equation 4.8), calibrated when the settings say so
        (``calibrate_product``, see :meth:`_calibrate_product`)."""
        return combine_factors(self.factor_probabilities(U), getattr(self, "combine_platt_", IDENTITY_PLATT))

    @property
    def learned_factors(self) -> list[int]:
        """Indices of the models that have a classifier (the optimization's energy terms)."""
        return [i for i, m in enumerate(self.models_) if m.classifier is not None]
