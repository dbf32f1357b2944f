"""Where a simulation's wall time goes: inside pybullet's ``stepSimulation`` (the engine) or outside it (building the
world, the event checks, the rope impulses, the rest), per example scenario.

Each part is timed with ``time.perf_counter`` around the calls (no profiler, whose own cost would swamp the Python
side). The layouts: each scenario's ``success`` layout and ``--n`` seeded random layouts of its design space.
``--commit`` measures the code of a commit instead of the work tree (taken with ``git archive``, as
:mod:`bench.simulation_fixtures` does), for a before/after comparison on the same machine::

    .venv/bin/python -m bench.simulation_overhead --n 5
    .venv/bin/python -m bench.simulation_overhead --n 5 --commit 599036c

The figures are ratios of one run on a possibly busy machine: read the shares, not the microseconds.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _timed(owner, name: str, key: str, parts: dict[str, float]) -> None:
    function = getattr(owner, name)

    def timed(*args, **kwargs):
        start = time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            parts[key] = parts.get(key, 0.0) + time.perf_counter() - start

    setattr(owner, name, timed)


def measure(stems: list[str], n: int) -> None:
    """Print, per scenario, the shares of wall time in the engine, in building, in event checks and in ropes."""
    import numpy as np

    from design.contraption import load_scenario, simulation
    from design.contraption import world as world_module
    from design.contraption.bullet import pybullet

    parts: dict[str, float] = {}
    simulator = simulation._thread_simulator(None)
    number = simulator.client._client
    raw_step = pybullet.stepSimulation

    def step(*_, **__):
        start = time.perf_counter()
        raw_step(physicsClientId=number)
        parts["engine"] = parts.get("engine", 0.0) + time.perf_counter() - start

    # Both ways the simulator may reach the engine: the client's attribute and pybullet's function.
    simulator.client.stepSimulation = step
    pybullet.stepSimulation = step
    _timed(simulation, "build_world", "build", parts)
    _timed(simulation.Supervisor, "update", "events", parts)
    _timed(world_module.World, "enforce_ropes", "ropes", parts)
    print(f"{'scenario':26s} {'sims':>4s} {'steps':>6s} {'engine':>7s} {'outside':>7s} {'build':>6s} "
          f"{'events':>6s} {'ropes':>6s} {'us/step engine/all':>19s}")
    for stem in stems:
        scenario = load_scenario(ROOT / "examples" / "scenarios" / f"{stem}.toml")
        space = scenario.design_space
        random = np.random.default_rng(1).random((n, space.dim))
        layouts = [scenario.layout("success"), *(space.lower + random * (space.upper - space.lower))]
        simulation.simulate(scenario, layouts[0])  # warm up: imports, first client
        parts.clear()
        steps = 0
        start = time.perf_counter()
        for x in layouts:
            steps += simulation.simulate(scenario, x).steps
        wall = time.perf_counter() - start
        share = {key: value / wall for key, value in parts.items()}
        print(f"{stem:26s} {len(layouts):4d} {steps:6d} {share.get('engine', 0):7.1%} "
              f"{1 - share.get('engine', 0):7.1%} {share.get('build', 0):6.1%} {share.get('events', 0):6.1%} "
              f"{share.get('ropes', 0):6.1%} {1e6 * parts.get('engine', 0) / steps:9.0f}/{1e6 * wall / steps:<9.0f}",
              flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=5, help="random layouts per scenario (default 5)")
    parser.add_argument("--commit", help="measure the code of this commit (default: the work tree)")
    parser.add_argument("--only", nargs="*", default=[], help="scenario file stems (default: every example)")
    args = parser.parse_args(argv)
    stems = args.only or sorted(p.stem for p in (ROOT / "examples" / "scenarios").glob("*.toml"))
    if args.commit is None or os.environ.get("SIMULATION_OVERHEAD_TREE"):
        measure(stems, args.n)
        return 0
    sha = subprocess.run(["git", "rev-parse", args.commit], cwd=ROOT, check=True, capture_output=True,
                         text=True).stdout.strip()
    with tempfile.TemporaryDirectory(prefix="simulation-overhead-") as tree:
        archive = subprocess.run(["git", "archive", sha], cwd=ROOT, check=True, capture_output=True)
        subprocess.run(["tar", "-x", "-C", tree], input=archive.stdout, check=True)
        # The commit's modules on the path; this script (from the work tree) drives them.
        env = dict(os.environ, PYTHONPATH=tree, SIMULATION_OVERHEAD_TREE="1")
        subprocess.run([sys.executable, str(Path(__file__).resolve()), "--n", str(args.n), "--only", *stems],
                       cwd=tree, env=env, check=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
