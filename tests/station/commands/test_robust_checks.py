"""Bad input to ``station optimize``, ``robustness`` and ``compare`` is refused in one line, before any work."""

from __future__ import annotations

import gc
import json
from pathlib import Path

import numpy as np
import pytest

from common.progress import Cancelled, Reporter
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

ROOT = Path(__file__).resolve().parents[3]
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


def bad_outputs(tmp_path: Path, suffix: str) -> list[tuple[str, str]]:
    """(path, expected words) of output paths that cannot be written at the end of a run."""
    a_file = tmp_path / "a_file.txt"
    a_file.write_text("x")
    (tmp_path / f"folder{suffix}").mkdir()
    return [
        (str(tmp_path / "nonexistent_dir" / f"o{suffix}"), f"the folder {tmp_path / 'nonexistent_dir'} does not exist"),
        (str(a_file / f"o{suffix}"), f"{a_file} is not a folder"),
        (str(tmp_path / f"folder{suffix}"), "is a folder; expected a file name ending in"),
        (str(tmp_path / "o.bmp"), "expected one of"),
    ]


def test_optimize_checks_its_output_before_any_simulation(tmp_path, capsys):
    from station.commands.robust import simulation_cache_path

    for path, expected in bad_outputs(tmp_path, ".json"):
        assert main(["optimize", str(SIMPLE), "--budget", "20", "--workers", "1", "--out", path]) == 2
        line = one_error_line(capsys)
        assert expected in line and ("--out" in line or "output file" in line), line
    assert not simulation_cache_path().exists()  # refused before the executor (and its cache) existed


@pytest.mark.parametrize("command", [
    ["robustness", str(SIMPLE), "{tmp}/layout.json", "--eval", "8", "--local", "2", "--workers", "1"],
    ["compare", str(SIMPLE), "--methods", "b1", "--runs", "1", "--budget", "20", "--eval", "8", "--local", "2",
     "--workers", "1"],
])
def test_robustness_and_compare_check_the_plot_path_before_any_simulation(command, tmp_path, capsys):
    from station.commands.robust import simulation_cache_path

    layout = tmp_path / "layout.json"
    layout.write_text(json.dumps({"parameters": [{"name": n, "value": v} for n, v in
                                                 [("track.x", -0.06), ("track.z", 0.06), ("track.roll", 30.0)]]}))
    argv = [part.replace("{tmp}", str(tmp_path)) for part in command]
    for path, expected in bad_outputs(tmp_path, ".png"):
        assert main([*argv, "--plot", path]) == 2
        line = one_error_line(capsys)
        assert expected in line and ("--plot" in line or "output file" in line), line
    assert not simulation_cache_path().exists()


def test_an_unreachable_scheduler_is_one_line_naming_it(tmp_path, capsys, monkeypatch):
    import design.robust.executor as executor_module

    # The real timeout is a few seconds; the test need not wait for it.
    monkeypatch.setattr(executor_module, "SCHEDULER_CONNECT_TIMEOUT", 0.5)
    out = tmp_path / "o.json"
    assert main(["optimize", str(SIMPLE), "--budget", "20", "--scheduler", "tcp://127.0.0.1:1", "--out", str(out)]) == 2
    line = one_error_line(capsys)
    assert line.startswith("station: error: --scheduler: no Dask scheduler answered at tcp://127.0.0.1:1 within 0.5 s")
    assert "dask scheduler" in line and "leave --scheduler out" in line
    assert main(["compare", str(SIMPLE), "--methods", "b1", "--runs", "1", "--budget", "20",
                 "--scheduler", "no port here"]) == 2
    assert "expected tcp://HOST:PORT" in one_error_line(capsys)
    assert not out.exists()


def test_the_executor_reaches_its_scheduler_when_asked():
    from design.robust.executor import SchedulerUnreachable

    problem = synthetic_chain()
    executor = SimulationExecutor(problem, scheduler="tcp://127.0.0.1:1", connect_timeout=0.5)
    with pytest.raises(SchedulerUnreachable, match="tcp://127.0.0.1:1 within 0.5 s"):
        executor.connect()
    # The failed client is finalized at once: left to a later garbage collection, its __del__ can deadlock a new
    # client's start-up (distributed's loop runners share one lock).
    from distributed import Client

    assert not [o for o in gc.get_objects() if isinstance(o, Client)]
    executor.close()
    with SimulationExecutor(problem, backend="inline") as inline:
        inline.connect()  # nothing to reach
        assert inline.run(np.full((1, 3), 0.4)).shape == (1, 4)


def test_the_service_names_the_value_and_the_command_names_the_flag(tmp_path):
    # The Robust screen calls the service: its refusals must not speak of command-line flags.
    from station.commands.robust import usage_error
    from station.errors import ServiceError, UsageError
    from station.services import robust as service

    refusals = [
        (lambda: service.psp_settings("bogus"), "settings", "--settings must be one of recommended, thesis or a "
                                                            "LAYOUT.json, got 'bogus'"),
        (lambda: service.psp_settings(str(tmp_path / "gone.json")), "settings",
         f"--settings: no such file {tmp_path / 'gone.json'}"),
        (lambda: service.check_seed(-1), "seed", "--seed must be a non-negative integer, got -1"),
        (lambda: service.check_count(0, "n_evaluation"), "n_evaluation", "--eval must be an integer >= 1, got 0"),
        (lambda: service.default_budget(synthetic_chain(), 3), "budget", "--budget must be an integer >= 20, got 3"),
        (lambda: service.parse_methods("ours,b9"), "methods",
         "--methods: expected a comma-separated list among ours,b1,b2,b3, got 'ours,b9'"),
    ]
    for refuse, field, cli_message in refusals:
        with pytest.raises(ServiceError) as caught:
            refuse()
        assert caught.value.field == field and "--" not in str(caught.value)
        reworded = usage_error(caught.value)
        assert isinstance(reworded, UsageError) and str(reworded) == cli_message
    with pytest.raises(Cancelled) as stopped:
        with service.simulations(synthetic_chain(), workers=1, report=Reporter(stop=lambda: True)):
            pass  # stopped before any work: nothing new in the cache
    assert stopped.value.new_simulations == 0 and stopped.value.cache == service.simulation_cache_path()
