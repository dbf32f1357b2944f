"""Bad input to ``station optimize``, ``robustness`` and ``compare`` is refused in one line, before any work."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from design.robust import (
    RobustError,
    RobustnessSettings,
    SimulationExecutor,
    baseline_b1,
    compare_methods,
    evaluation_set,
    optimize_robust_layout,
    robustness_curve,
    synthetic_chain,
)
from station.cli import main

ROOT = Path(__file__).resolve().parents[2]
SIMPLE = ROOT / "examples" / "scenarios" / "simple.toml"


def one_error_line(capsys) -> str:
    """The single stderr line of a refused command (and nothing on stdout)."""
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert "Traceback" not in captured.err and captured.out == ""
    return lines[0]


@pytest.mark.parametrize("command", [
    ["optimize", str(SIMPLE), "--budget", "20", "--workers", "1", "--out", "{tmp}/o.json"],
    ["robustness", str(SIMPLE), "{tmp}/layout.json", "--eval", "8", "--local", "2", "--workers", "1"],
    ["compare", str(SIMPLE), "--methods", "b1", "--runs", "1", "--budget", "20", "--eval", "8", "--local", "2",
     "--workers", "1"],
])
def test_a_negative_seed_is_one_clear_line(command, tmp_path, capsys):
    layout = tmp_path / "layout.json"
    layout.write_text(json.dumps({"parameters": []}))
    argv = [part.replace("{tmp}", str(tmp_path)) for part in command] + ["--seed", "-1"]
    assert main(argv) == 2
    assert one_error_line(capsys) == "station: error: --seed must be a non-negative integer, got -1"
    assert not (tmp_path / "o.json").exists()


def test_the_pipeline_refuses_a_negative_seed_before_simulating():
    problem = synthetic_chain()
    calls = []

    def oracle(U):
        calls.append(len(U))
        return problem.simulate_batch(U)

    with SimulationExecutor(problem, backend="inline") as executor:
        with pytest.raises(RobustError, match="seed must be a non-negative integer, got -1"):
            optimize_robust_layout(problem, executor, budget=40, seed=-1)
        with pytest.raises(RobustError, match="seed must be a non-negative integer, got -2"):
            compare_methods(problem, executor, ["b1"], runs=1, budget=20, seed=-2)
    evaluation = evaluation_set(problem, oracle, 16)
    calls.clear()
    with pytest.raises(RobustError, match="got -3"):
        robustness_curve(problem, oracle, evaluation, np.full(3, 0.4), RobustnessSettings(n_local=2), seed=-3)
    with pytest.raises(RobustError, match="got -4"):
        baseline_b1(problem, oracle, 10, seed=-4)
    assert calls == []
