"""The robust-layout pipeline on the real SIMPLE scenario (pybullet), and the station commands."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from sklearn.metrics import roc_auc_score

from design.contraption.simulation import SIMULATOR_REVISION
from design.robust import FactorizedPSP, PSPSettings, SimulationExecutor, explore, optimize_robust_layout
from design.robust.executor import SimulationCache, cache_scope
from design.robust.sampling import sobol_valid
from station.cli import main

ROOT = Path(__file__).resolve().parents[3]
SIMPLE = ROOT / "examples" / "scenarios" / "simple.toml"
TINY = PSPSettings(n_initial=48, n_successes=20, max_exploration_steps=3, max_active_steps=1)

pytestmark = pytest.mark.skipif(not SIMPLE.exists(), reason="the SIMPLE scenario file is missing")


@pytest.fixture(scope="module")
def simple():
    from design.robust.contraption import load_problem

    return load_problem(SIMPLE)


@pytest.fixture(scope="module")
def simple_data(simple):
    # One shared simulated sample of SIMPLE (explored) and a held-out Sobol set with its simulated truth.
    samples = explore(simple, lambda U: np.stack([simple.simulate(u) for u in U]), TINY, seed=0, max_simulations=70)
    held_out = sobol_valid(simple, 64, seed=777)
    truth = np.array([simple.simulate(u).all() for u in held_out])
    return samples, held_out, truth


def test_simple_problem_mirrors_the_scenario(simple):
    assert simple.parameter_names == ("track.x", "track.z", "track.roll")
    assert simple.event_parents["ball_hits_domino"] == ("ball_rolls",)
    np.testing.assert_allclose(simple.to_real(simple.to_normalized([-0.06, 0.06, 30.0])), [-0.06, 0.06, 30.0])
    # The track buried in the floor is impossible (D∅); the file's own layout is valid.
    assert not simple.is_valid(np.array([[0.5, 0.0, 0.9]]))[0]
    assert simple.validity_margins(np.array([0.5, 0.0, 0.9]))[0] < 0
    assert simple.is_valid(simple.initial_layout()[None, :])[0]


def test_simple_validity_constraint_agrees_with_validity_and_has_a_slope(simple):
    rng = np.random.default_rng(0)
    U = rng.random((40, simple.dim))
    margins = np.array([simple.validity_margins(u)[0] for u in U])
    assert np.array_equal(margins >= 0, simple.is_valid(U))
    assert (margins < 0).any() and (margins >= 0).any()
    # Not flat: somewhere between an invalid layout and a valid one the gradient points towards validity.
    bad = U[np.argmin(margins)]
    gradient = simple.validity_jacobian(bad)
    assert gradient.shape == (1, simple.dim) and np.linalg.norm(gradient) > 0
    step = 0.01 * gradient[0] / np.linalg.norm(gradient)
    assert simple.validity_margins(np.clip(bad + step, 0, 1))[0] > simple.validity_margins(bad)[0]


def test_simple_psp_separates_success_from_failure(simple, simple_data):
    samples, held_out, truth = simple_data
    assert 0 < truth.sum() < len(truth)
    psp = FactorizedPSP(TINY, random_state=0).fit(simple, samples)
    p = psp.predict_proba(held_out)
    assert np.all((p >= 0) & (p <= 1))
    assert roc_auc_score(truth, p) > 0.7
    assert p[truth].mean() > p[~truth].mean()


def test_simple_optimization_is_valid_and_cached(simple, tmp_path):
    cache = tmp_path / "cache.sqlite3"
    # A worker process: it knows the problem by its content hash, the cache files it under the simulator's revision.
    with SimulationExecutor(simple, backend="processes", workers=1, cache_path=cache) as executor:
        first = optimize_robust_layout(simple, executor, budget=60, seed=1, settings=TINY)
    assert simple.is_valid(first.u[None, :])[0]
    assert first.n_simulations <= 60
    assert cache_scope(simple) == f"{simple.content_hash}@simulator-{SIMULATOR_REVISION}"
    assert SimulationCache(cache).count(cache_scope(simple)) == SimulationCache(cache).count() > 0
    with SimulationExecutor(simple, workers=1, cache_path=cache) as executor:
        second = optimize_robust_layout(simple, executor, budget=60, seed=1, settings=TINY)
        assert executor.n_simulated == 0
    np.testing.assert_array_equal(first.u, second.u)


def test_cli_optimize_then_robustness(tmp_path, capsys):
    out = tmp_path / "layout.json"
    code = main(["optimize", str(SIMPLE), "--budget", "30", "--workers", "1", "--seed", "2", "--out", str(out)])
    assert code in (0, 1)
    layout = json.loads(out.read_text())
    assert layout["scenario"] == "SIMPLE" and len(layout["content_hash"]) == 64
    assert [p["name"] for p in layout["parameters"]] == ["track.x", "track.z", "track.roll"]
    for p in layout["parameters"]:
        assert p["lower"] <= p["value"] <= p["upper"] and 0 <= p["normalized"] <= 1
    assert 0 <= layout["predicted_psp"] <= 1
    assert set(layout["event_probabilities"]) == {"ball_rolls", "ball_hits_domino", "first_topples",
                                                  "last_topples", "last_stops"}
    assert layout["simulations_used"] <= layout["simulation_budget"] == 30
    assert code == (0 if layout["simulated_success"] else 1)
    # the headline is the physical success on the table (placed by the guide), the model's score a detail
    physical = layout["physical_success"]
    assert physical["samples"] == 48 and physical["interval"][0] <= physical["probability"] <= physical["interval"][1]
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].startswith("SIMPLE: physical success on the table ") and "placed by the guide" in printed[0]
    assert not any("predicted PSP" in line and not line.startswith("detail: ") for line in printed)
    assert any(line.startswith("detail: the success model's own score (predicted PSP)") for line in printed)
    plot = tmp_path / "curve.png"
    code = main(["robustness", str(SIMPLE), str(out), "--eval", "48", "--local", "20", "--workers", "1", "--json",
                 "--plot", str(plot)])
    assert code == 0
    result = json.loads(capsys.readouterr().out)
    assert 0 <= result["rho_g"] <= 1 and len(result["rho_l"]) == 31
    assert plot.stat().st_size > 1000


def test_cli_compare_prints_a_table(tmp_path, capsys):
    plot = tmp_path / "compare.png"
    code = main(["compare", str(SIMPLE), "--methods", "ours,b1", "--runs", "2", "--budget", "24", "--eval", "32",
                 "--local", "8", "--workers", "1", "--json", "--plot", str(plot)])
    assert code == 0
    captured = capsys.readouterr()
    table = json.loads(captured.out)
    assert [row["method"] for row in table["methods"]] == ["ours", "b1"]
    assert all(0 <= row["rho_g_mean"] <= 1 for row in table["methods"])
    assert plot.exists()
    # Each run is reported on stderr as it ends, so a stopped comparison keeps its finished figures.
    runs = [line for line in captured.err.splitlines() if " seed " in line and "rho_g" in line]
    assert [line.split(":")[0] for line in runs] == ["ours seed 0", "ours seed 1", "b1 seed 0", "b1 seed 1"]
    ours = [float(line.split("rho_g ")[1].split(",")[0]) for line in runs[:2]]
    assert np.mean(ours) == pytest.approx(table["methods"][0]["rho_g_mean"], abs=1e-3)


def test_cli_bad_input_is_one_clear_line(tmp_path, capsys):
    assert main(["optimize", str(SIMPLE), "--out", str(tmp_path / "x.txt")]) == 2
    assert "expected one of .json" in capsys.readouterr().err
    assert main(["compare", str(SIMPLE), "--methods", "ours,b9"]) == 2
    assert "--methods" in capsys.readouterr().err
    assert main(["optimize", str(SIMPLE), "--budget", "5", "--out", str(tmp_path / "x.json")]) == 2
    assert "--budget" in capsys.readouterr().err
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"content_hash": "0" * 64, "parameters": []}))
    assert main(["robustness", str(SIMPLE), str(other)]) == 2
    assert "content_hash" in capsys.readouterr().err
    broken = tmp_path / "broken.json"
    broken.write_text("{")
    assert main(["robustness", str(SIMPLE), str(broken)]) == 2
    assert "broken.json: not valid JSON (Expecting property name" in capsys.readouterr().err
    assert main(["optimize", str(tmp_path / "nope.toml"), "--out", str(tmp_path / "y.json")]) == 2
    capsys.readouterr()
    assert main(["optimize", str(SIMPLE), "--placement-error", "0.9", "--out", str(tmp_path / "z.json")]) == 2
    assert "placement_error must be in [0, 0.5], got 0.9" in capsys.readouterr().err
    assert not (tmp_path / "z.json").exists()


def test_cli_optimize_with_the_recommended_settings_stays_within_the_budget(tmp_path, capsys):
    from station.commands.robust import DEFAULT_SETTINGS, psp_settings

    assert psp_settings("thesis") == PSPSettings() and psp_settings("recommended") == PSPSettings.recommended()
    assert DEFAULT_SETTINGS == "recommended"
    out = tmp_path / "layout.json"
    code = main(["optimize", str(SIMPLE), "--budget", "30", "--workers", "1", "--recommended", "--out", str(out)])
    layout = json.loads(out.read_text())
    assert layout["simulations_used"] <= 30
    assert code == (0 if layout["simulated_success"] else 1)
    # The layout file says how it was made; a budget of 30 left one simulation for each of the six verified
    # candidates (three optima, three layouts of the start): a quarter of the budget at most.
    settings = layout["psp_settings"]
    assert settings["cv_scoring"] == "calibrated_log_loss" and settings["verification_candidates"] == 3
    assert settings["verification_start_candidates"] == 3 and settings["verification_samples"] == 1
    # Which candidates were checked, where each came from, and the one kept (unless none worked).
    checked = layout["verification"]
    assert {row["source"] for row in checked} <= {"model", "start"} and 1 <= len(checked) <= 6
    assert sum(row["kept"] for row in checked) == (0 if layout["fallback_to_best_sample"] else 1)
    printed = capsys.readouterr().out
    assert f"checked {len(checked)} candidate(s), 1 simulation(s) each, radius 0.01:" in printed
    assert ("<- kept" in printed) != layout["fallback_to_best_sample"]
    restored = PSPSettings(**{k: tuple(v) if isinstance(v, list) else v for k, v in settings.items()})
    assert restored.cv_scoring == "calibrated_log_loss" and restored.calibrate_product
    out_thesis = tmp_path / "thesis.json"
    main(["optimize", str(SIMPLE), "--budget", "30", "--workers", "1", "--settings", "thesis",
          "--out", str(out_thesis)])
    assert json.loads(out_thesis.read_text())["psp_settings"]["cv_scoring"] == "accuracy"
    capsys.readouterr()
    assert main(["optimize", str(SIMPLE), "--settings", "best", "--out", str(tmp_path / "x.json")]) == 2
    assert "--settings must be one of recommended, thesis or a LAYOUT.json, got 'best'" in capsys.readouterr().err
    assert not (tmp_path / "x.json").exists()


def test_cli_optimize_repeats_a_run_from_its_layout_file(tmp_path, capsys):
    first, again = tmp_path / "first.json", tmp_path / "again.json"
    common = ["optimize", str(SIMPLE), "--budget", "30", "--workers", "1", "--seed", "3"]
    main([*common, "--settings", "thesis", "--global-psp", "--out", str(first)])
    main([*common, "--settings", str(first), "--out", str(again)])
    old, new = json.loads(first.read_text()), json.loads(again.read_text())
    assert new["psp_settings"] == old["psp_settings"] and new["psp_settings"]["factorize"] is False
    assert [p["normalized"] for p in new["parameters"]] == [p["normalized"] for p in old["parameters"]]
    assert new["simulations_used"] == old["simulations_used"] and new["verification"] == old["verification"]
    capsys.readouterr()
    # A flag given beside the file changes its settings.
    main([*common, "--settings", str(first), "--placement-error", "0.1", "--out", str(tmp_path / "eps.json")])
    eps = json.loads((tmp_path / "eps.json").read_text())["psp_settings"]
    assert eps["placement_error"] == 0.1 and eps["factorize"] is False

    def refused(content, expected):
        source = tmp_path / "source.json"
        if content is not None:
            source.write_text(content)
        capsys.readouterr()
        assert main([*common, "--settings", str(source), "--out", str(tmp_path / "x.json")]) == 2
        assert expected in capsys.readouterr().err
        source.unlink(missing_ok=True)

    refused(None, "--settings: no such file")
    refused("{", "source.json: not valid JSON (Expecting property name")
    refused('{"scenario": "SIMPLE"}', "source.json: field 'psp_settings' is missing")
    refused('{"psp_settings": null}', "field 'psp_settings' is null")
    refused('{"psp_settings": {"n_initial": "many"}}', "field 'psp_settings': n_initial must be an integer, got 'many'")
    refused('{"psp_settings": {"cv_folds": 1}}', "field 'psp_settings': cv_folds must be an integer >= 2, got 1")
    refused('{"psp_settings": {"speed": 3}}', "field 'psp_settings': unknown setting(s) ['speed']")
    assert not (tmp_path / "x.json").exists()


def test_progress_bar_and_thesis_budgets():
    import io

    from design.robust import Progress
    from station.commands.robust import DEFAULT_BUDGET, ProgressBar, thesis_budget

    stream = io.StringIO()
    bar = ProgressBar(stream)
    bar(Progress("exploration", 0, 100))
    bar(Progress("exploration", 5, 100))
    bar(Progress("active learning", 60, 100, 0.91, None))
    assert stream.getvalue().splitlines() == ["exploration: 0/100 simulations", "active learning: 60/100 simulations"]
    assert thesis_budget("CAUSALITYSWITCH (ball faster)") == 614
    assert thesis_budget("ballrun") == 1120
    assert thesis_budget("SIMPLE") == DEFAULT_BUDGET
