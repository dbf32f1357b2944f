"""The tolerance map: known answers on synthetic models, verification by simulation, and `station tolerances`."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from common.progress import Reporter
from design.robust.problem import EllipsoidEvent, SyntheticProblem
from design.robust.tolerance import (
    RATIO,
    ToleranceEntry,
    care_level,
    model_tolerances,
    simulated_tolerances,
    verify_tolerances,
)
from station.cli import main

FIXTURE = Path(__file__).resolve().parents[2] / "data" / "robust" / "simple-layout-with-model.json"
#: x in [-0.1, 0.1] m (0.2 m wide), roll in [0, 90] deg.
PROBLEM = SyntheticProblem("BLOCK", ("block.x", "block.roll"), (-0.1, 0.0), (0.1, 90.0),
                           (EllipsoidEvent("stands", (), (0, 1), (0.5, 0.5), (0.1, 0.2)),))


class Bump:
    """A model whose success falls off as exp(-((u - centre) / width)^2) along each parameter."""

    def __init__(self, centre, width):
        self.centre = np.asarray(centre, dtype=float)
        self.width = np.asarray(width, dtype=float)

    def predict(self, U):
        U = np.atleast_2d(U)
        return 0.8 * np.exp(-np.sum(((U - self.centre) / self.width) ** 2, axis=1))


def test_the_delta_is_where_the_predicted_success_falls_to_90_percent():
    model = Bump([0.5, 0.5], [0.05, 0.1])
    result = model_tolerances(model, PROBLEM, np.array([0.5, 0.5]))
    assert result.source == "model" and result.layout_psp == pytest.approx(0.8)
    x, roll = result.entries
    # exp(-(t / w)^2) = 0.9 at t = w sqrt(-ln 0.9), normalized; then in mm (x 200 mm wide) and degrees (90 wide).
    t = np.sqrt(-np.log(RATIO))
    assert (x.part, x.kind, x.unit) == ("block", "position", "mm")
    assert x.delta == pytest.approx(0.05 * t * 200.0, rel=1e-5)
    assert (roll.kind, roll.unit) == ("angle", "deg")
    assert roll.delta == pytest.approx(0.1 * t * 90.0, rel=1e-5)
    for entry in result.entries:
        assert entry.predicted_ratio == pytest.approx(RATIO, abs=1e-5)
        assert not entry.bound_limited and entry.limited_by == "success"


def test_each_side_is_searched_and_the_smaller_is_the_tolerance():
    # Off-centre: the success falls sooner on the side towards which the layout already leans.
    model = Bump([0.5, 0.5], [0.05, 0.1])
    result = model_tolerances(model, PROBLEM, np.array([0.52, 0.5]))
    x = result.entries[0]
    assert x.minus > x.plus == pytest.approx(x.delta)
    # (0.02 + t)^2 = 0.02^2 - w^2 ln 0.9 on the + side
    t = -0.02 + np.sqrt(0.02**2 - 0.05**2 * np.log(RATIO))
    assert x.delta == pytest.approx(t * 200.0, rel=1e-5)


def test_a_flat_model_is_bound_limited_and_a_collision_is_said():
    flat = Bump([0.5, 0.5], [1e6, 1e6])
    result = model_tolerances(flat, PROBLEM, np.array([0.3, 0.9]))
    x, roll = result.entries
    assert x.bound_limited and x.limited_by == "bound" and x.delta == pytest.approx(0.3 * 200.0)
    assert roll.bound_limited and roll.delta == pytest.approx(0.1 * 90.0)
    assert care_level(result.entries) == "loose"
    # Beyond x = 0.4 the parts overlap: the tolerance ends there and says why.
    collide = model_tolerances(flat, PROBLEM, np.array([0.3, 0.5]), is_valid=lambda U: U[:, 0] <= 0.4)
    assert collide.entries[0].limited_by == "collision"
    assert collide.entries[0].delta == pytest.approx(0.1 * 200.0, rel=1e-5)


def test_a_layout_the_model_gives_no_chance_has_no_tolerance():
    result = model_tolerances(Bump([0.0, 0.0], [0.01, 0.01]), PROBLEM, np.array([0.9, 0.9]))
    assert [e.delta for e in result.entries] == [None, None] and care_level(result.entries) is None


def test_the_care_rule():
    def entry(delta, unit="mm", bound=False):
        return ToleranceEntry("p.x", "p", "position", delta, unit, bound_limited=bound)

    assert care_level([entry(1.9), entry(30, "deg")]) == "tight"
    assert care_level([entry(1.9, bound=True), entry(30, "deg")]) == "normal"  # a range end is a lower bound
    assert care_level([entry(6.1), entry(6.5, "deg")]) == "loose"
    assert care_level([entry(4.0), entry(6.5, "deg")]) == "normal"
    assert care_level([entry(None)]) is None


def oracle_within(half_width: float, index: int = 0):
    """Simulated success: parameter ``index`` within ``half_width`` of 0.5."""
    return lambda U: (np.abs(np.atleast_2d(U)[:, index] - 0.5) <= half_width)[:, None]


def test_verification_measures_the_success_rate_at_plus_minus_delta():
    model = Bump([0.5, 0.5], [0.05, 0.1])
    u = np.array([0.5, 0.5])
    tolerances = model_tolerances(model, PROBLEM, u)
    calls = []

    def oracle(U):
        calls.append(len(U))
        return oracle_within(0.02)(U)  # x fails past 0.02 (4 mm); the model's delta for x is about 3.2 mm

    verified = verify_tolerances(tolerances, PROBLEM, u, oracle, 10, seed=0, model=model)
    assert calls == [1, 10, 10] and verified.layout_success
    x, roll = verified.entries
    assert x.measured == 1.0 and roll.measured == 1.0 and x.simulations == 10
    assert x.predicted == pytest.approx(0.8 * RATIO, abs=0.02)  # the model's mean over the same layouts
    # A stricter world: x fails beyond 1 mm, so the layouts at ±3.2 mm all fail.
    strict = verify_tolerances(tolerances, PROBLEM, u, oracle_within(0.005), 10, seed=0)
    assert strict.entries[0].measured == 0.0
    # One side only fails: x fails above 0.5 + 0.001.
    one_sided = verify_tolerances(tolerances, PROBLEM, u, lambda U: (np.atleast_2d(U)[:, 0] <= 0.501)[:, None], 10)
    x = one_sided.entries[0]
    assert (x.measured_minus, x.measured_plus, x.measured) == (1.0, 0.0, 0.5)


def test_without_a_model_delta_is_searched_by_simulation():
    u = np.array([0.5, 0.5])
    result = simulated_tolerances(PROBLEM, u, oracle_within(0.2), 6, steps=6, seed=0)
    assert result.source == "simulation" and result.layout_success
    x, roll = result.entries
    # The true limit is 0.2 (40 mm); a bisection of 6 steps of the 0.5 room, inside it.
    assert 0.2 - 0.5 / 2**6 - 1e-9 <= x.delta / 200.0 <= 0.2
    assert roll.bound_limited and roll.delta == pytest.approx(45.0)
    failing = simulated_tolerances(PROBLEM, u, lambda U: np.zeros((len(np.atleast_2d(U)), 1), bool), 4)
    assert failing.layout_success is False and all(e.delta is None for e in failing.entries)


def test_station_tolerances_on_simple_from_the_layout_s_model(capsys):
    assert main(["tolerances", "simple", str(FIXTURE), "--json"]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["source"] == "model" and payload["scenario"] == "SIMPLE"
    assert [e["parameter"] for e in payload["entries"]] == ["track.x", "track.z", "track.roll"]
    assert [e["unit"] for e in payload["entries"]] == ["mm", "mm", "deg"]
    assert all(e["delta"] is None or e["delta"] >= 0 for e in payload["entries"])
    assert set(payload["care"]) == {"track"}
    assert main(["tolerances", "simple", str(FIXTURE)]) == 0
    text = capsys.readouterr().out
    assert "from the layout's fitted success model" in text and "track.roll" in text and "care per part" in text


def test_station_tolerances_verifies_by_simulation(capsys):
    assert main(["tolerances", "simple", str(FIXTURE), "--verify", "4", "--workers", "1", "--json"]) == 0
    payload = json.loads(capsys.readouterr().out)
    measured = [e["measured"] for e in payload["entries"] if e["delta"] is not None]
    assert measured and all(0.0 <= m <= 1.0 for m in measured)
    assert all(e["simulations"] == 4 for e in payload["entries"] if e["delta"] is not None)


def test_a_hand_written_layout_has_no_tolerances_without_verify(tmp_path, capsys):
    layout = tmp_path / "hand.json"
    layout.write_text(json.dumps({"parameters": {"track.x": -0.06, "track.z": 0.06, "track.roll": 30}}))
    assert main(["tolerances", "simple", str(layout)]) == 0
    assert "carries no fitted model" in capsys.readouterr().out
    assert main(["tolerances", "simple", str(layout), "--json"]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["source"] == "none" and all(e["delta"] is None for e in payload["entries"])


def test_bad_input_is_one_line(tmp_path, capsys):
    assert main(["tolerances", "simple", str(FIXTURE), "--verify", "-1"]) == 2
    err = capsys.readouterr().err
    assert "--verify must be an integer >= 0" in err and err.count("\n") == 1
    broken = json.loads(FIXTURE.read_text())
    broken["model"]["factors"][1]["gamma"] = "fast"
    path = tmp_path / "broken.json"
    path.write_text(json.dumps(broken))
    assert main(["tolerances", "simple", str(path)]) == 2
    err = capsys.readouterr().err
    assert "model.factors[1].gamma: expected a finite number" in err and err.count("\n") == 1


def test_a_parameter_the_model_ignores_is_said():
    class OnlyX(Bump):
        parameters_used = (0,)

        def predict(self, U):
            U = np.atleast_2d(U)
            return 0.8 * np.exp(-(((U[:, 0] - 0.5) / 0.05) ** 2))

    x, roll = model_tolerances(OnlyX([0.5, 0.5], [0.05, 1.0]), PROBLEM, np.array([0.5, 0.5])).entries
    assert x.in_model and roll.in_model is False and roll.limited_by == "bound"


def test_the_service_takes_a_loaded_scenario_and_gives_the_guide_its_tolerances():
    from design.contraption import load_scenario
    from projector.guide import ParameterTolerance
    from station.services.tolerances import tolerance_map

    scenario = load_scenario(Path(__file__).resolve().parents[3] / "examples" / "scenarios" / "simple.toml")
    seen = []
    result = tolerance_map(scenario, str(FIXTURE), report=Reporter(seen.append))
    assert result.map.source == "model" and seen[0].stage == "tolerance map" and seen[-1].done == 3
    guide = result.parameter_tolerances()
    assert list(guide) == ["track"] and all(isinstance(t, ParameterTolerance) for t in guide["track"])
    assert [t.unit for t in guide["track"]] == ["mm", "mm", "deg"] and guide["track"][0].source == "model"
    assert result.care() == {"track": care_level(result.map.entries)}


def test_a_model_the_simulations_contradict_gives_no_tolerances_searched_by_simulation(tmp_path, capsys):
    # The fixture's model scores its layout 0.87; a LAYOUT.json whose own simulations say 0.05 has a model too weak
    # there to trust: the guide's tolerances are then searched by simulation, and the guide and sheet say why.
    from projector.pdf_lists import tolerance_source_text
    from station.services.guide import GuideRequest, make_guide
    from station.services.tolerances import WEAK_MODEL_VERIFY

    data = json.loads(FIXTURE.read_text())
    data["physical_success"] = {"probability": 0.05, "interval": [0.01, 0.2], "expected_attempts": 20.0,
                                "attempts_interval": [5.0, 100.0], "samples": 48}
    weak = tmp_path / "weak.json"
    weak.write_text(json.dumps(data))
    job = make_guide(GuideRequest("simple", str(weak)))
    guide = job.guide
    assert job.tolerances.map.source == "simulation" and job.tolerances.verify == WEAK_MODEL_VERIFY
    assert guide.tolerance_source == "simulation" and "the success model is weak at this layout" in guide.tolerance_note
    assert "0.87" in guide.tolerance_note and "0.05" in guide.tolerance_note
    assert tolerance_source_text(guide).startswith("The success model is weak at this layout")
    manifest = guide.manifest()
    assert manifest["tolerance_note"] == guide.tolerance_note
    assert manifest["headline"].startswith("physical success on the table 0.05 (95 %: 0.01-0.20)")
    # the same file as its own simulations agree with it: the model's tolerances, no note
    data["physical_success"]["probability"] = 0.9
    weak.write_text(json.dumps(data))
    agreed = make_guide(GuideRequest("simple", str(weak))).guide
    assert agreed.tolerance_source == "model" and agreed.tolerance_note is None
    assert agreed.headline.startswith("physical success on the table 0.90")
