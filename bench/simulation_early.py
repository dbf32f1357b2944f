"""Early termination on the recorded layouts (tests/data/simulation): steps with no early stop, with the stop at
the verdict (what the recordings hold: their runs stopped there), and with the reach stop (the run stops once no
awake event can still happen before its timeout; design/contraption/reach.py), with identical outcomes.

Per scenario: the layouts, the three step totals and their ratios, identical labels and identical outcomes (labels,
event states, times within a step: bench.simulation_fixtures.compare), the share of CPU time the reach checks
take, the CPU time per simulation (this process's: the machine is shared) with the stop at the verdict only (the
same code with the reach checks switched off) and with the reach stop, and what is left: among failures, the steps
simulated after the deciding event woke (a stop could not come earlier than that without knowing the physics), by
the deciding event's type. The "no early stop" total is the scenario's ``max_duration`` in steps per layout, which
is what such a run steps (no need to run it).

Run: ``python -m bench.simulation_early [--scenarios simple,ballrun] [--limit N] [--json OUT.json]`` or
``python -m bench.bench_simulation --early``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

from bench.simulation_fixtures import compare, outcome
from design.contraption import load_scenario
from design.contraption import reach as reach_module
from design.contraption import simulation as simulation_module

ROOT = Path(__file__).resolve().parents[1]
FIXTURES = ROOT / "tests" / "data" / "simulation"


class _Timer:
    """CPU time spent in the reach checks (the bounds and the events' tests), by wrapping them."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self._saved = []

    def wrap(self, owner, name: str) -> None:
        original = getattr(owner, name)
        self._saved.append((owner, name, original))

        def timed(*args, **kwargs):
            start = time.process_time()
            try:
                return original(*args, **kwargs)
            finally:
                self.seconds += time.process_time() - start

        setattr(owner, name, timed)

    def restore(self) -> None:
        for owner, name, original in reversed(self._saved):
            setattr(owner, name, original)
        self._saved.clear()


def measure(stem: str, limit: int | None = None) -> dict:
    data = json.loads((FIXTURES / f"{stem}.json").read_text())
    scenario = load_scenario(ROOT / "examples" / "scenarios" / data["scenario"])
    dt = data["time_step"]
    n_steps = int(round(data["max_duration"] / dt))
    rows = data["layouts"][:limit] if limit else data["layouts"]
    types = {spec.name: spec.type for spec in scenario.event_specs}
    timer = _Timer()
    timer.wrap(reach_module.Reach, "__init__")
    timer.wrap(reach_module.Reach, "bounds")
    timer.wrap(simulation_module.Supervisor, "may_change")
    timer.wrap(simulation_module.Supervisor, "surely_may_change")
    verdict_steps = reach_steps = 0
    # Each layout twice, one run after the other (the machine's load drifts): with the reach checks off (no awake
    # event counts as bounded, so the run stops at the verdict only), then on.
    bounded = simulation_module.Supervisor.bounded
    same_label = same_outcome = 0
    left: Counter = Counter()
    left_runs: Counter = Counter()
    wall = verdict_wall = 0.0
    try:
        for row in rows:
            simulation_module.Supervisor.bounded = lambda self: False
            start = time.process_time()
            simulation_module.simulate(scenario, np.array(row["x"]), early_stop=True)
            verdict_wall += time.process_time() - start
            simulation_module.Supervisor.bounded = bounded
            start = time.process_time()
            result = simulation_module.simulate(scenario, np.array(row["x"]), early_stop=True)
            wall += time.process_time() - start
            new = outcome(result)
            verdict_steps += row["steps"]
            reach_steps += new["steps"]
            same_label += new["success"] == row["success"]
            same_outcome += not compare(row, new, dt)
            if not row["success"]:
                stop = row["steps"] * dt
                deciding = [(name, woke) for name, (state, t, woke) in row["events"].items()
                            if state == "failure" and abs(t - stop) < dt / 2]
                if deciding:
                    name, woke = max(deciding, key=lambda item: item[1])
                    extra = max(0, new["steps"] - int(round(woke / dt)))
                    left[f"{name} ({types[name]})"] += extra
                    left_runs[f"{name} ({types[name]})"] += extra > 0
    finally:
        simulation_module.Supervisor.bounded = bounded
        timer.restore()
    n = len(rows)
    return {
        "scenario": data["name"], "file": stem, "n": n, "no_stop": n * n_steps, "verdict": verdict_steps,
        "reach": reach_steps, "same_label": same_label / n, "same_outcome": same_outcome / n,
        "check_share": timer.seconds / wall if wall else 0.0, "wall_verdict": verdict_wall / n, "wall_reach": wall / n,
        "left": dict(left.most_common()),
        "left_runs": dict(left_runs),
    }


def main(argv: list[str] | None = None) -> list[dict]:
    parser = argparse.ArgumentParser(prog="simulation_early", description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", default="", help="comma-separated fixture stems (default: all)")
    parser.add_argument("--limit", type=int, help="the first N recorded layouts of each file")
    parser.add_argument("--json", type=Path, help="write the figures here")
    args = parser.parse_args(argv if argv is not None else sys.argv[1:] if __name__ == "__main__" else [])
    known = sorted(p.stem for p in FIXTURES.glob("*.json"))
    stems = [s.strip() for s in args.scenarios.split(",") if s.strip()] or known
    unknown = sorted(set(stems) - set(known))
    if unknown:
        raise SystemExit(f"simulation_early: --scenarios: unknown {unknown}; expected some of {', '.join(known)}")
    header = (f"{'scenario':<26} {'n':>3} {'no stop':>8} {'at verdict':>10} {'reach':>8} {'no/verdict':>10} "
              f"{'no/reach':>8} {'verdict/reach':>13} {'same label':>10} {'same outcome':>12} {'checks':>6} "
              f"{'s/sim verdict':>13} {'s/sim reach':>11}")
    print(header)
    print("-" * len(header))
    rows = []
    for stem in stems:
        row = measure(stem, args.limit)
        rows.append(row)
        print(f"{stem[:26]:<26} {row['n']:>3} {row['no_stop']:>8} {row['verdict']:>10} {row['reach']:>8} "
              f"{row['no_stop'] / row['verdict']:>9.2f}x {row['no_stop'] / row['reach']:>7.2f}x "
              f"{row['verdict'] / row['reach']:>12.2f}x {row['same_label']:>10.0%} {row['same_outcome']:>12.0%} "
              f"{row['check_share']:>6.1%} {row['wall_verdict']:>13.3f} {row['wall_reach']:>11.3f}", flush=True)
        top = ", ".join(f"{k}: {v} steps in {row['left_runs'][k]} runs" for k, v in list(row["left"].items())[:3])
        print(f"{'':<26} failures' steps after the deciding event woke: {top or '-'}", flush=True)
    print("-" * len(header))
    total = {k: sum(r[k] for r in rows) for k in ("no_stop", "verdict", "reach")}
    no_stop, verdict, reach = total["no_stop"], total["verdict"], total["reach"]
    print(f"{'all':<26} {sum(r['n'] for r in rows):>3} {no_stop:>8} {verdict:>10} {reach:>8} "
          f"{no_stop / verdict:>9.2f}x {no_stop / reach:>7.2f}x {verdict / reach:>12.2f}x", flush=True)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1), encoding="utf-8")
    return rows


if __name__ == "__main__":
    main()
