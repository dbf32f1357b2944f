"""Recorded simulation outcomes: seeded random layouts of every example scenario, their labels, event outcomes and
step counts, to check that a faster simulator gives the same outcomes as a named commit.

A fixture file (one per scenario, ``tests/data/simulation/<stem>.json``) holds the scenario's named layouts and
``n`` layouts drawn uniformly over its design space (valid or not: ``valid`` says which, by
:func:`~design.contraption.simulation.check_validity`), each simulated with ``early_stop=True``: the label, every
event's ``[state, time, woke]`` and the number of steps.

Regenerate from a commit (the code is taken from that commit with ``git archive``, this script from the work tree,
so outcomes are those of the named code whatever the work tree holds)::

    .venv/bin/python -m bench.simulation_fixtures --commit 599036c --n 50 --out tests/data/simulation

and compare the work tree's simulator with recorded files (``--check``; the equivalence rule is :func:`compare`)::

    .venv/bin/python -m bench.simulation_fixtures --check tests/data/simulation

This module only uses what every simulator revision has (``load_scenario``, ``simulate``, ``check_validity``), so it
runs under old commits too.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import zlib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "examples" / "scenarios"
#: Base seed of the random layouts; each scenario's own seed mixes in a CRC of its file's stem.
SEED = 39


def random_layouts(scenario, n: int, seed: int) -> np.ndarray:
    """``n`` layouts uniform over the scenario's design space (real units), seeded."""
    space = scenario.design_space
    rng = np.random.default_rng(seed)
    return space.lower + rng.random((n, space.dim)) * (space.upper - space.lower)


def scenario_seed(stem: str) -> int:
    return SEED * 1_000_003 + zlib.crc32(stem.encode())


def outcome(result) -> dict:
    """What a fixture keeps of a :class:`~design.contraption.simulation.SimulationResult`."""
    return {
        "success": bool(result.success),
        "steps": int(result.steps),
        "events": {name: [o.state, o.time, o.woke] for name, o in result.events.items()},
    }


def record(path: Path, n: int) -> dict:
    """Simulate the named layouts and ``n`` random layouts of the scenario file ``path``."""
    from design.contraption import load_scenario
    from design.contraption.simulation import check_validity, simulate

    scenario = load_scenario(path)
    seed = scenario_seed(path.stem)
    layouts = [(name, np.asarray(scenario.layout(name), dtype=float)) for name in sorted(scenario.layouts)]
    layouts += [(f"random-{i}", x) for i, x in enumerate(random_layouts(scenario, n, seed))]
    rows = []
    for name, x in layouts:
        row = {"name": name, "x": [float(v) for v in x], "valid": not check_validity(scenario, x)}
        row.update(outcome(simulate(scenario, x, early_stop=True)))
        rows.append(row)
    settings = scenario.settings
    return {
        "scenario": path.name,
        "name": scenario.name,
        "content_hash": scenario.content_hash,
        "time_step": settings.time_step,
        "max_duration": settings.max_duration,
        "early_stop": True,
        "seed": seed,
        "layouts": rows,
    }


def dumps(data: dict) -> str:
    """The fixture as JSON text with one line per layout (small, and diffs read layout by layout)."""
    head = {k: v for k, v in data.items() if k != "layouts"}
    lines = [json.dumps(row, separators=(",", ":")) for row in data["layouts"]]
    text = json.dumps(head, indent=1)[:-2] + ',\n "layouts": [\n  ' + ",\n  ".join(lines) + "\n ]\n}\n"
    assert json.loads(text) == data
    return text


def compare(expected: dict, actual: dict, time_step: float) -> list[str]:
    """Differences between a recorded outcome and a new one: the label, every event's state, and its time and
    wake-up time within one step. Step counts are not compared (a simulator may stop earlier once nothing can
    change); see :func:`steps_saved`."""
    problems = []
    if expected["success"] != actual["success"]:
        problems.append(f"label {expected['success']} -> {actual['success']}")
    for name, (state, time, woke) in expected["events"].items():
        new_state, new_time, new_woke = actual["events"][name]
        if new_state != state:
            problems.append(f"{name}: {state} -> {new_state}")
        for what, old, new in (("time", time, new_time), ("woke", woke, new_woke)):
            if (old is None) != (new is None) or (old is not None and abs(old - new) > time_step * 1.0001):
                problems.append(f"{name}: {what} {old} -> {new}")
    return problems


def check(folder: Path, limit: int | None = None) -> int:
    """Simulate every recorded layout with the work tree's code; print the differences; return their number."""
    from design.contraption import load_scenario
    from design.contraption.simulation import simulate

    bad = 0
    for file in sorted(folder.glob("*.json")):
        data = json.loads(file.read_text())
        scenario = load_scenario(SCENARIOS / data["scenario"])
        rows = data["layouts"][:limit] if limit else data["layouts"]
        old_steps = new_steps = 0
        for row in rows:
            result = simulate(scenario, np.array(row["x"]), early_stop=True)
            new = outcome(result)
            old_steps += row["steps"]
            new_steps += new["steps"]
            problems = compare(row, new, data["time_step"])
            if problems:
                bad += 1
                print(f"{file.stem} {row['name']}: " + "; ".join(problems))
        print(f"{file.stem}: {len(rows)} layouts, steps {old_steps} -> {new_steps}", flush=True)
    return bad


def generate(commit: str | None, n: int, out: Path, only: list[str]) -> None:
    out.mkdir(parents=True, exist_ok=True)
    paths = [p for p in sorted(SCENARIOS.glob("*.toml")) if not only or p.stem in only]
    if commit is None:
        for path in paths:
            data = record(path, n)
            (out / f"{path.stem}.json").write_text(dumps(data))
            print(f"{path.stem}: {len(data['layouts'])} layouts", flush=True)
        return
    full = subprocess.run(["git", "rev-parse", commit], cwd=ROOT, check=True, capture_output=True, text=True)
    sha = full.stdout.strip()
    with tempfile.TemporaryDirectory(prefix="simulation-fixtures-") as tree:
        archive = subprocess.run(["git", "archive", sha], cwd=ROOT, check=True, capture_output=True)
        subprocess.run(["tar", "-x", "-C", tree], input=archive.stdout, check=True)
        env = dict(os.environ, PYTHONPATH=tree)
        for path in paths:
            # The old code's modules come first on the path; this script (from the work tree) drives them.
            subprocess.run([sys.executable, str(Path(__file__).resolve()), "--n", str(n), "--out", str(out.resolve()),
                            "--only", path.stem, "--commit-name", sha], cwd=tree, env=env, check=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--commit", help="record with the code of this commit (default: the work tree)")
    parser.add_argument("--commit-name", help=argparse.SUPPRESS)
    parser.add_argument("--n", type=int, default=50, help="random layouts per scenario (default 50)")
    parser.add_argument("--out", type=Path, default=ROOT / "tests" / "data" / "simulation")
    parser.add_argument("--only", nargs="*", default=[], help="scenario file stems (default: every example)")
    parser.add_argument("--check", type=Path, help="compare the work tree's simulator with the files in this folder")
    parser.add_argument("--limit", type=int, help="with --check: the first N layouts of each file")
    args = parser.parse_args(argv)
    if args.check:
        return 1 if check(args.check, args.limit) else 0
    if args.commit_name:
        sys.path.insert(0, os.getcwd())
        for stem in args.only:
            path = Path.cwd() / "examples" / "scenarios" / f"{stem}.toml"  # the commit's scenario files
            data = record(path, args.n)
            data["commit"] = args.commit_name
            (args.out / f"{stem}.json").write_text(dumps(data))
            print(f"{stem}: {len(data['layouts'])} layouts", flush=True)
        return 0
    generate(args.commit, args.n, args.out, args.only)
    return 0


if __name__ == "__main__":
    sys.exit(main())
