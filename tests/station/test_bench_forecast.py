"""bench/bench_forecast.py: each captured prediction made again with one ingredient true, and the forecasts it
compares."""

from __future__ import annotations

import numpy as np
import pytest

from bench.bench_forecast import given_record, summarize, variants
from calibration.sim_runs import placement_sigma
from station.services.contraption import open_scenario

NAMES = ["track.x", "track.z", "track.roll"]  # SIMPLE's design parameters


def _row():
    return {"names": NAMES, "x": [0.20, 0.05, -10.0],
            "as_placed": {"track.x": 0.203, "track.z": 0.051, "track.roll": -9.8},
            "values": {"wood.friction": 0.5}, "intervals": {"wood.friction": [0.4, 0.6]},
            "position_sigma_m": 0.0001, "angle_sigma_deg": 0.4, "unmeasured": ["track.x"],
            "set_sigma": {"track.z": 0.0002, "track.roll": 0.2, "track.x": 0.001}, "samples": 16, "seed": 7,
            "hidden": {"wood.friction": 0.42}}


def test_each_variant_replaces_one_ingredient_by_the_worlds_truth():
    simple = open_scenario("simple")
    made = variants(_row(), 48)
    station = made["station"]
    assert made["as made"]["samples"] == 16 and station["samples"] == 48 and made["truth"]["samples"] == 1

    def sigma(v):
        return dict(zip(simple.design_space.names, placement_sigma(simple, v["position_sigma_m"], v["angle_sigma_deg"],
                                                                   v["unmeasured"], v["set_sigma"])))

    def layout(v):
        return dict(zip(NAMES, np.asarray(v["layout"]).tolist()))

    assert made["hidden physics"]["values"] == {"wood.friction": 0.42} and made["hidden physics"]["intervals"] is None
    assert made["profile centre"]["values"] == {"wood.friction": 0.5} and made["profile centre"]["intervals"] is None
    # what the check did not measure at its true place, exactly; the rest as the station has it
    unmeasured = made["true unmeasured"]
    assert layout(unmeasured) == {"track.x": 0.203, "track.z": 0.05, "track.roll": -10.0}
    assert sigma(unmeasured) == pytest.approx({"track.x": 0.0, "track.z": 0.0001, "track.roll": 0.4})
    # what it measured at its true place, exactly; the unmeasured still with the error of how it was set
    measured = made["true measured"]
    assert layout(measured) == {"track.x": 0.20, "track.z": 0.051, "track.roll": -9.8}
    assert sigma(measured) == pytest.approx({"track.x": 0.001, "track.z": 0.0, "track.roll": 0.0})
    assert sigma(station) == pytest.approx({"track.x": 0.001, "track.z": 0.0001, "track.roll": 0.4})
    assert layout(made["true placement"]) == _row()["as_placed"]
    assert sigma(made["true placement"]) == {"track.x": 0.0, "track.z": 0.0, "track.roll": 0.0}


def test_a_record_weighs_the_material_draws_by_its_likelihood():
    # Half the draws always work, half never: 3 successes in 3 say the workshop's physics is among the first, 3
    # failures among the others; a mixed record, or draws all alike, say nothing.
    runs = [(2, 2), (0, 2)] * 4
    assert given_record(runs, 0, 0) == 0.5
    assert given_record(runs, 3, 3) == pytest.approx(1.0 / (1.0 + 0.2 ** 3))
    assert given_record(runs, 0, 3) == pytest.approx(1.0 - 1.0 / (1.0 + 0.2 ** 3))
    assert given_record(runs, 1, 2) == pytest.approx(0.5)
    assert given_record([(1, 2)] * 8, 3, 3) == pytest.approx(0.5)


def test_the_summary_is_the_mean_and_brier_score_per_variant_and_loop():
    table = [{"world": "w", "loop": 1, "attempt": 1, "success": True, "station": 0.75, "truth": 1.0},
             {"world": "w", "loop": 1, "attempt": 2, "success": False, "station": 0.25, "truth": 0.0},
             {"world": "w", "loop": 2, "attempt": 1, "success": True, "station": 0.5, "truth": 1.0}]
    summary = summarize(table)
    assert summary["all"]["attempts"] == 3 and summary["all"]["success_rate"] == pytest.approx(2 / 3)
    assert summary["all"]["station"] == {"mean": pytest.approx(0.5), "brier": pytest.approx((0.0625 * 2 + 0.25) / 3)}
    assert summary["loop 1"]["station"]["brier"] == pytest.approx(0.0625) and summary["loop 2"]["truth"]["brier"] == 0
