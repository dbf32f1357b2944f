"""The fitted success model (PSP) as plain JSON data, and a portable model that predicts from it.

A LAYOUT.json written by ``station optimize`` carries the model it was optimized on under the key ``"model"``, so
that other commands (``station tolerances``, ``station guide``) can score layouts near it without simulating. The
file may come from anyone, so it holds numbers only and is read without executing anything from it (no pickle,
no joblib). Format ``"chaos-station psp model 1"``::

    "model": {
      "format": "chaos-station psp model 1",
      "parameters": ["track.x", "track.z", "track.roll"],   # the design space the indices refer to, in order
      "lower": [...], "upper": [...],                       # its bounds in real units (m, deg)
      "space": "normalized",                                # inputs are u = (x - lower) / (upper - lower)
      "combine": "product",                                 # PSP(u) = product of the factors' probabilities
      "factors": [
        {"event": "ball_rolls", "kind": "quasi_deterministic"},                 # contributes 1
        {"event": "e", "kind": "constant", "subspace": [0, 2], "probability": 0.9},  # too few of a class for an SVM
        {"event": "ball_hits_domino", "kind": "svm", "subspace": [0, 1],        # parameter indices it depends on
         "scaler": {"mean": [...], "scale": [...]},                             # z = (u[subspace] - mean) / scale
         "kernel": "rbf", "gamma": 10.0,                                        # K(z, s) = exp(-gamma |z - s|^2)
         "support_vectors": [[...], ...], "dual_coef": [...], "intercept": 0.3, # f(z) = sum dual_coef K + intercept
         "platt": {"a": -2.1, "b": 0.05}}                                       # p = 1 / (1 + exp(a f + b))
      ]
    }

Format ``"chaos-station psp model 2"`` is the same with one more way to combine the factors (written only when a
model uses it; a model that multiplies its factors is still written as version 1, which every reader reads)::

      "combine": "calibrated_product",                      # PSP(u) = 1 / (1 + exp(a logit(product) + b))
      "calibration": {"a": -1.3, "b": -0.4},                # Platt's sigmoid of the product's logit
                                                            # (logit clipped to [-30, 30])

This is exactly :meth:`design.robust.psp.FactorizedPSP.predict_proba`: quasi-deterministic events have no classifier
and contribute 1; a classifier with too few members of a class predicts its constant; an SVM's decision value is
that of scikit-learn's ``SVC.decision_function`` (positive = success) on standardized inputs, mapped by Platt's
sigmoid with the exponent clipped to [-500, 500] as :class:`~design.robust.psp.CalibratedSVM` does.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from design.contraption.errors import ScenarioFormatError
from design.contraption.fields import describe
from design.robust.probability import IDENTITY_PLATT, combine_factors, platt_probability

__all__ = ["MODEL_FORMAT", "MODEL_FORMAT_2", "ModelFormatError", "PortableFactor", "PortablePSP", "layout_model",
           "model_from_json", "model_to_json"]

#: The ``format`` of the model key when the factors are multiplied (every reader reads it).
MODEL_FORMAT = "chaos-station psp model 1"
#: The ``format`` of a model whose product is calibrated (``"combine": "calibrated_product"``).
MODEL_FORMAT_2 = "chaos-station psp model 2"
#: The formats read, and the ways each combines its factors.
COMBINE_BY_FORMAT = {MODEL_FORMAT: ("product",), MODEL_FORMAT_2: ("product", "calibrated_product")}
#: The kinds of factor, in words.
FACTOR_KINDS = ("quasi_deterministic", "constant", "svm")


class ModelFormatError(ScenarioFormatError):
    """The ``model`` of a LAYOUT.json is malformed or fits another design space; names the file and the field."""


@dataclass(frozen=True)
class PortableFactor:
    """One factor of the PSP: an event's calibrated classifier as arrays (see the module docstring).

    Attributes
    ----------
    event : str
    kind : str
        ``"quasi_deterministic"`` (probability 1), ``"constant"`` or ``"svm"``.
    subspace : tuple of int
        Parameter indices the factor reads.
    probability : float
        The constant's probability (``kind == "constant"``).
    mean, scale : ndarray
        The standardization of the subspace's inputs.
    gamma : float
    support_vectors : ndarray, shape (n_support, len(subspace))
    dual_coef : ndarray, shape (n_support,)
    intercept : float
    platt_a, platt_b : float
    """

    event: str
    kind: str
    subspace: tuple[int, ...] = ()
    probability: float = 1.0
    mean: np.ndarray | None = None
    scale: np.ndarray | None = None
    gamma: float = 0.0
    support_vectors: np.ndarray | None = None
    dual_coef: np.ndarray | None = None
    intercept: float = 0.0
    platt_a: float = -1.0
    platt_b: float = 0.0

    def decision_function(self, U: np.ndarray) -> np.ndarray:
        """The SVM's signed score of normalized layouts ``U`` (n, d): positive on the success side."""
        Z = (U[:, list(self.subspace)] - self.mean) / self.scale
        # |z - s|^2 directly (not |z|^2 + |s|^2 - 2 z.s), which loses digits when z is near a support vector.
        squared = np.sum((Z[:, None, :] - self.support_vectors[None, :, :]) ** 2, axis=2)
        return np.exp(-self.gamma * squared) @ self.dual_coef + self.intercept

    def probability_of(self, U: np.ndarray) -> np.ndarray:
        """The factor's calibrated probability of each layout, shape (n,)."""
        if self.kind == "quasi_deterministic":
            return np.ones(len(U))
        if self.kind == "constant":
            return np.full(len(U), self.probability)
        return platt_probability(self.decision_function(U), (self.platt_a, self.platt_b))


@dataclass(frozen=True)
class PortablePSP:
    """A fitted PSP loaded from JSON: predicts like the :class:`~design.robust.psp.FactorizedPSP` it was saved from.

    Attributes
    ----------
    parameter_names : tuple of str
    lower, upper : ndarray
        The design space's bounds in real units (the normalization of :meth:`predict`'s inputs).
    factors : tuple of PortableFactor
    combine_platt : tuple of float
        (a, b) of the sigmoid of the product's logit (:data:`~design.robust.probability.IDENTITY_PLATT`: the
        product itself).
    """

    parameter_names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    factors: tuple[PortableFactor, ...]
    combine_platt: tuple[float, float] = IDENTITY_PLATT

    @property
    def dim(self) -> int:
        return len(self.parameter_names)

    @property
    def event_names(self) -> tuple[str, ...]:
        return tuple(f.event for f in self.factors)

    @property
    def parameters_used(self) -> tuple[int, ...]:
        """Indices of the parameters some SVM factor reads (the PSP is flat along the others)."""
        return tuple(sorted({i for f in self.factors if f.kind == "svm" for i in f.subspace}))

    def factor_probabilities(self, U: np.ndarray) -> np.ndarray:
        """``(n, n_factors)``: each factor's probability of each normalized layout."""
        U = np.atleast_2d(np.asarray(U, dtype=float))
        if U.shape[1] != self.dim:
            raise ValueError(f"PSP model: layouts must have {self.dim} columns, got {U.shape[1]}")
        return np.column_stack([f.probability_of(U) for f in self.factors]) if self.factors else np.ones((len(U), 0))

    def predict(self, U: np.ndarray) -> np.ndarray:
        """The PSP of each normalized layout ``U`` (n, d) or (d,): the (calibrated) product of the factors, (n,)."""
        return combine_factors(self.factor_probabilities(U), self.combine_platt)


# --------------------------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------------------------
def _floats(values) -> list:
    return np.asarray(values, dtype=float).tolist()


def model_to_json(model, problem=None) -> dict[str, Any]:
    """A fitted :class:`~design.robust.psp.FactorizedPSP` as JSON-ready data (format :data:`MODEL_FORMAT`).

    Parameters
    ----------
    model : FactorizedPSP
        Fitted (``model.models_``); its problem (``model.problem_``) gives names and bounds unless ``problem`` does.
    problem : LayoutProblem, optional
    """
    problem = problem if problem is not None else model.problem_
    factors = []
    for event_model in model.models_:
        classifier = event_model.classifier
        entry: dict[str, Any] = {"event": event_model.event}
        if classifier is None:
            entry["kind"] = "quasi_deterministic"
        elif classifier.constant_ is not None:
            entry.update(kind="constant", subspace=list(event_model.subspace),
                         probability=float(classifier.constant_))
        else:
            scaler, svc = classifier.model_[0], classifier.model_[-1]
            entry.update(
                kind="svm", subspace=[int(i) for i in event_model.subspace],
                scaler={"mean": _floats(scaler.mean_), "scale": _floats(scaler.scale_)},
                kernel="rbf", gamma=float(svc._gamma),
                support_vectors=_floats(svc.support_vectors_), dual_coef=_floats(svc.dual_coef_[0]),
                intercept=float(svc.intercept_[0]),
                platt={"a": float(classifier.platt_[0]), "b": float(classifier.platt_[1])},
            )
        factors.append(entry)
    platt = tuple(float(v) for v in getattr(model, "combine_platt_", IDENTITY_PLATT))
    calibrated = platt != IDENTITY_PLATT
    return {
        "format": MODEL_FORMAT_2 if calibrated else MODEL_FORMAT,
        "parameters": list(problem.parameter_names),
        "lower": _floats(problem.lower),
        "upper": _floats(problem.upper),
        "space": "normalized",
        "combine": "calibrated_product" if calibrated else "product",
        **({"calibration": {"a": platt[0], "b": platt[1]}} if calibrated else {}),
        "factors": factors,
    }


# --------------------------------------------------------------------------------------------------------------
# Reading: every field checked, each error one line naming the field
# --------------------------------------------------------------------------------------------------------------
class _ModelReader:
    def __init__(self, file: str, root: str) -> None:
        self.file = file
        self.root = root

    def fail(self, where: str, message: str) -> ModelFormatError:
        return ModelFormatError(self.file, where, message)

    def table(self, value: Any, where: str, required: Sequence[str]) -> dict:
        if not isinstance(value, dict):
            raise self.fail(where, f"expected a table (a JSON object), got {describe(value)}")
        for key in required:
            if key not in value:
                raise self.fail(f"{where}.{key}", "missing")
        return value

    def text(self, value: Any, where: str, expected: Sequence[str] | None = None) -> str:
        if not isinstance(value, str) or (expected is not None and value not in expected):
            wanted = " or ".join(repr(e) for e in expected) if expected is not None else "text"
            raise self.fail(where, f"expected {wanted}, got {describe(value)}")
        return value

    def number(self, value: Any, where: str, low: float = -math.inf, high: float = math.inf,
               positive: bool = False) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise self.fail(where, f"expected a finite number, got {describe(value)}")
        if not low <= value <= high or (positive and value <= 0):
            bound = "a positive number" if positive else f"a number in [{low:g}, {high:g}]"
            raise self.fail(where, f"expected {bound}, got {value!r}")
        return float(value)

    def vector(self, value: Any, where: str, length: int | None = None, positive: bool = False) -> np.ndarray:
        if not isinstance(value, list):
            raise self.fail(where, f"expected an array of numbers, got {describe(value)}")
        if length is not None and len(value) != length:
            raise self.fail(where, f"expected {length} numbers, got {len(value)}")
        return np.array([self.number(v, f"{where}[{i}]", positive=positive) for i, v in enumerate(value)])

    def matrix(self, value: Any, where: str, columns: int) -> np.ndarray:
        if not isinstance(value, list) or not value:
            raise self.fail(where, f"expected a non-empty array of rows of {columns} numbers, got "
                            f"{describe(value) if value != [] else 'an empty array'}")
        rows = [self.vector(row, f"{where}[{i}]", columns) for i, row in enumerate(value)]
        return np.array(rows).reshape(len(rows), columns)

    def subspace(self, value: Any, where: str, dim: int) -> tuple[int, ...]:
        if not isinstance(value, list) or not value:
            raise self.fail(where, f"expected a non-empty array of parameter indices in [0, {dim - 1}], got "
                            f"{describe(value) if value != [] else 'an empty array'}")
        indices = []
        for i, index in enumerate(value):
            if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < dim:
                raise self.fail(f"{where}[{i}]", f"expected a parameter index in [0, {dim - 1}], got "
                                f"{describe(index)}")
            if index in indices:
                raise self.fail(f"{where}[{i}]", f"index {index} is listed twice; expected each index once")
            indices.append(index)
        return tuple(indices)

    def factor(self, value: Any, where: str, dim: int) -> PortableFactor:
        entry = self.table(value, where, ("event", "kind"))
        event = self.text(entry["event"], f"{where}.event")
        kind = self.text(entry["kind"], f"{where}.kind", FACTOR_KINDS)
        if kind == "quasi_deterministic":
            return PortableFactor(event, kind)
        required = ("subspace", "probability") if kind == "constant" else (
            "subspace", "scaler", "kernel", "gamma", "support_vectors", "dual_coef", "intercept", "platt")
        self.table(entry, where, required)
        subspace = self.subspace(entry["subspace"], f"{where}.subspace", dim)
        if kind == "constant":
            return PortableFactor(event, kind, subspace, self.number(entry["probability"], f"{where}.probability",
                                                                     0.0, 1.0))
        width = len(subspace)
        scaler = self.table(entry["scaler"], f"{where}.scaler", ("mean", "scale"))
        self.text(entry["kernel"], f"{where}.kernel", ("rbf",))
        support = self.matrix(entry["support_vectors"], f"{where}.support_vectors", width)
        platt = self.table(entry["platt"], f"{where}.platt", ("a", "b"))
        return PortableFactor(
            event, kind, subspace,
            mean=self.vector(scaler["mean"], f"{where}.scaler.mean", width),
            scale=self.vector(scaler["scale"], f"{where}.scaler.scale", width, positive=True),
            gamma=self.number(entry["gamma"], f"{where}.gamma", positive=True),
            support_vectors=support,
            dual_coef=self.vector(entry["dual_coef"], f"{where}.dual_coef", len(support)),
            intercept=self.number(entry["intercept"], f"{where}.intercept"),
            platt_a=self.number(platt["a"], f"{where}.platt.a"),
            platt_b=self.number(platt["b"], f"{where}.platt.b"),
        )

    def read(self, data: Any, problem) -> PortablePSP:
        root = self.root
        data = self.table(data, root, ("format", "parameters", "lower", "upper", "factors"))
        if data["format"] not in COMBINE_BY_FORMAT:
            raise self.fail(f"{root}.format", f"expected {MODEL_FORMAT!r} or {MODEL_FORMAT_2!r}, got "
                            f"{describe(data['format'])}")
        if "space" in data:
            self.text(data["space"], f"{root}.space", ("normalized",))
        combine = self.text(data["combine"], f"{root}.combine", COMBINE_BY_FORMAT[data["format"]]) \
            if "combine" in data else "product"
        platt = IDENTITY_PLATT
        if combine == "calibrated_product":
            self.table(data, root, ("calibration",))
            table = self.table(data["calibration"], f"{root}.calibration", ("a", "b"))
            platt = (self.number(table["a"], f"{root}.calibration.a", high=0.0),
                     self.number(table["b"], f"{root}.calibration.b"))
        names = data["parameters"]
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise self.fail(f"{root}.parameters", f"expected an array of parameter names, got {describe(names)}")
        expected = list(problem.parameter_names) if problem is not None else names
        if names != expected:
            raise self.fail(f"{root}.parameters", f"the model was fitted on parameters {names}, not on the "
                            f"scenario's {expected}; optimize the layout again for this scenario")
        dim = len(names)
        lower = self.vector(data["lower"], f"{root}.lower", dim)
        upper = self.vector(data["upper"], f"{root}.upper", dim)
        if np.any(upper <= lower):
            raise self.fail(f"{root}.upper", "expected every upper bound above its lower bound")
        if problem is not None:
            # The inputs are normalized by these bounds: a model of other ranges would score the wrong points.
            for what, mine, theirs in (("lower", lower, problem.lower), ("upper", upper, problem.upper)):
                off = np.flatnonzero(~np.isclose(mine, np.asarray(theirs, dtype=float), rtol=1e-9, atol=1e-12))
                if len(off):
                    i = int(off[0])
                    raise self.fail(f"{root}.{what}[{i}]", f"{names[i]}'s range in the model ({mine[i]:g}) is not "
                                    f"the scenario's ({float(theirs[i]):g}); optimize the layout again")
        factors = data["factors"]
        if not isinstance(factors, list):
            raise self.fail(f"{root}.factors", f"expected an array of factors, got {describe(factors)}")
        return PortablePSP(tuple(names), lower, upper,
                           tuple(self.factor(f, f"{root}.factors[{i}]", dim) for i, f in enumerate(factors)), platt)


def model_from_json(data: Any, problem=None, *, file: str = "<data>", field: str = "model") -> PortablePSP:
    """The portable model of :func:`model_to_json`'s data, every field checked; nothing in it is executed.

    Parameters
    ----------
    data : dict
        The ``model`` value of a LAYOUT.json.
    problem : LayoutProblem, optional
        When given, the model must be of its design space (same parameter names, in order, and bounds).
    file, field : str
        Named in errors (``"layout.json: model.factors[1].gamma: expected a positive number, got -1"``).

    Raises
    ------
    ModelFormatError
        A missing or malformed field, another format version, or a model of another design space.
    """
    return _ModelReader(file, field).read(data, problem)


def layout_model(data: Any, problem=None, *, file: str = "<data>") -> PortablePSP | None:
    """The fitted model a LAYOUT.json's data carries (its ``model`` key), or None for a layout without one.

    Older LAYOUT.json files and hand-written layouts (``{"parameters": {...}}``, ``{"x": [...]}``) have no model;
    a ``model`` that is there is checked as :func:`model_from_json` does.
    """
    if not isinstance(data, dict):
        return None
    table = data["layout"] if set(data) == {"layout"} and isinstance(data["layout"], dict) else data
    if table.get("model") is None:
        return None
    return model_from_json(table["model"], problem, file=file)
