"""The fitted PSP a LAYOUT.json carries: saved as numbers, read back without executing anything, predicting alike."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

from design.contraption.layout_io import read_layout
from design.robust import PSPSettings, SimulationExecutor, optimize_robust_layout
from design.robust.model_io import (
    MODEL_FORMAT,
    MODEL_FORMAT_2,
    ModelFormatError,
    layout_model,
    model_from_json,
    model_to_json,
)
from design.robust.problem import synthetic_chain

ROOT = Path(__file__).resolve().parents[3]
SIMPLE = ROOT / "examples" / "scenarios" / "simple.toml"
FIXTURE = Path(__file__).resolve().parents[2] / "data" / "robust" / "simple-layout-with-model.json"


def round_trip(payload: dict) -> dict:
    return json.loads(json.dumps(payload))


@pytest.fixture(scope="module")
def simple_fit():
    # The real thing: `station optimize simple --budget 40 --seed 1`, simulated in this process (a few seconds).
    from design.robust.contraption import load_problem

    problem = load_problem(SIMPLE)
    with SimulationExecutor(problem, backend="inline") as executor:
        result = optimize_robust_layout(problem, executor, budget=40, seed=1, settings=PSPSettings.recommended())
    return problem, result


def test_the_portable_model_predicts_as_the_fitted_one_on_simple(simple_fit):
    problem, result = simple_fit
    payload = round_trip(result.to_json(problem))
    # The recommended settings calibrate the product of the factors: version 2, its sigmoid saved.
    assert payload["model"]["format"] == MODEL_FORMAT_2
    assert payload["model"]["combine"] == "calibrated_product"
    assert payload["model"]["calibration"]["a"] < 0
    kinds = [f["kind"] for f in payload["model"]["factors"]]
    assert "svm" in kinds and "quasi_deterministic" in kinds
    portable = model_from_json(payload["model"], problem)
    U = np.random.default_rng(0).random((500, problem.dim))
    U = np.concatenate([U, result.u[None, :], result.model.samples_.U])  # also right on the support vectors
    np.testing.assert_allclose(portable.predict(U), result.model.predict_proba(U), rtol=0, atol=1e-9)
    np.testing.assert_allclose(portable.factor_probabilities(U), result.model.factor_probabilities(U), atol=1e-9)
    assert portable.predict(result.u)[0] == pytest.approx(payload["predicted_psp"], abs=1e-9)


def test_every_kind_of_factor_round_trips_on_a_synthetic_scenario():
    # The global PSP (one classifier of all parameters) and a factorized one whose events include a constant.
    from design.robust.psp import FactorizedPSP, explore

    problem = synthetic_chain()
    oracle = problem.simulate_batch
    settings = PSPSettings(n_initial=64, n_successes=10, max_exploration_steps=2, max_active_steps=0)
    samples = explore(problem, oracle, settings, seed=3)
    U = np.random.default_rng(1).random((300, problem.dim))
    for factorize in (True, False):
        psp = FactorizedPSP(settings.with_changes(factorize=factorize), random_state=3).fit(problem, samples)
        portable = model_from_json(round_trip(model_to_json(psp)), problem)
        np.testing.assert_allclose(portable.predict(U), psp.predict_proba(U), atol=1e-9)
    # A classifier with too few of a class is a constant.
    psp = FactorizedPSP(settings, random_state=3).fit(problem, samples)
    psp.models_[1].classifier.constant_ = 0.25
    data = round_trip(model_to_json(psp))
    assert data["factors"][1]["kind"] == "constant"
    np.testing.assert_allclose(model_from_json(data, problem).predict(U), psp.predict_proba(U), atol=1e-12)


def test_the_fixture_layout_carries_a_model_and_still_reads_as_a_layout():
    from design.robust.contraption import load_problem

    problem = load_problem(SIMPLE)
    data = json.loads(FIXTURE.read_text())
    layout = read_layout(FIXTURE, problem.scenario)  # the one layout reader ignores the model key
    np.testing.assert_allclose(layout.x, [p["value"] for p in data["parameters"]])
    model = layout_model(data, problem, file=str(FIXTURE))
    u = np.array([p["normalized"] for p in data["parameters"]])
    assert model.predict(u)[0] == pytest.approx(data["predicted_psp"], abs=1e-9)


def test_layouts_without_a_model_have_none():
    assert layout_model({"parameters": {"track.x": -0.1}}) is None
    assert layout_model({"x": [0.0, 0.1, 30]}) is None
    old = json.loads(FIXTURE.read_text())
    del old["model"]
    assert layout_model(old) is None


def _set(data: dict, path: list, value):
    node = data
    for key in path[:-1]:
        node = node[key]
    if value is KeyError:
        del node[path[-1]]
    else:
        node[path[-1]] = value


BAD = [
    (["format"], "chaos-station psp model 9", "model.format"),
    (["parameters"], ["a", "b", "c"], "model.parameters"),
    (["lower", 0], -1.0, "model.lower[0]"),
    (["factors"], {}, "model.factors"),
    (["factors", 1, "kind"], "forest", "model.factors[1].kind"),
    (["factors", 1, "gamma"], -1.0, "model.factors[1].gamma"),
    (["factors", 1, "gamma"], "10", "model.factors[1].gamma"),
    (["factors", 1, "platt", "a"], None, "model.factors[1].platt.a"),
    (["factors", 1, "platt"], KeyError, "model.factors[1].platt"),
    (["factors", 1, "subspace", 0], 7, "model.factors[1].subspace[0]"),
    (["factors", 1, "scaler", "scale", 0], 0.0, "model.factors[1].scaler.scale[0]"),
    (["factors", 1, "support_vectors", 0], [1.0] * 5, "model.factors[1].support_vectors[0]"),
    (["factors", 1, "dual_coef"], [1.0], "model.factors[1].dual_coef"),
    (["factors", 1, "kernel"], "poly", "model.factors[1].kernel"),
]


@pytest.mark.parametrize(("path", "value", "field"), BAD, ids=[f for _, _, f in BAD])
def test_a_malformed_model_is_one_line_naming_the_field(path, value, field):
    from design.robust.contraption import load_problem

    problem = load_problem(SIMPLE)
    data = json.loads(FIXTURE.read_text())
    assert data["model"]["factors"][1]["kind"] == "svm"
    model = copy.deepcopy(data["model"])
    _set(model, path, value)
    with pytest.raises(ModelFormatError) as raised:
        model_from_json(model, problem, file="layout.json")
    message = str(raised.value)
    assert message.startswith(f"layout.json: {field}") and "\n" not in message


def test_version_2_calibration_is_checked_and_version_1_still_multiplies(simple_fit):
    problem, result = simple_fit
    model = round_trip(result.to_json(problem))["model"]
    U = np.random.default_rng(2).random((50, problem.dim))
    factors = model_from_json(model, problem).factor_probabilities(U)
    # The same factors written as version 1 predict their plain product (what a version 1 file always meant).
    plain = {k: v for k, v in model.items() if k != "calibration"} | {"format": MODEL_FORMAT, "combine": "product"}
    np.testing.assert_allclose(model_from_json(plain, problem).predict(U), np.prod(factors, axis=1), atol=1e-12)
    for change, field, words in [
        ({"format": MODEL_FORMAT}, "model.combine", "expected 'product'"),
        ({"calibration": {"a": 1.0, "b": 0.0}}, "model.calibration.a", "expected a number in [-inf, 0]"),
        ({"calibration": {"a": -1.0}}, "model.calibration.b", "missing"),
        ({"format": "chaos-station psp model 3"}, "model.format", "expected 'chaos-station psp model 1' or"),
    ]:
        bad = copy.deepcopy(model) | change
        with pytest.raises(ModelFormatError) as error:
            model_from_json(bad, problem, file="layout.json")
        assert f"layout.json: {field}: {words}" in str(error.value)
    missing = {k: v for k, v in model.items() if k != "calibration"}
    with pytest.raises(ModelFormatError, match="model.calibration: missing"):
        model_from_json(missing, problem)
