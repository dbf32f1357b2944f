"""Simulation speed against a reference commit, the engine's share of it, and the engine's own limit.

For each example scenario, in one run: the same seeded layouts (the success and failure layouts, then random
physically valid ones) are simulated (early stop on) by this tree and by the reference commit's tree (a git
worktree made once under the system's temporary folder), each in its own subprocess (``bench/sim_probe.py``) run
one after the other. Printed per scenario:

- simulations per second, reference and now, and their ratio;
- the share of wall time inside ``stepSimulation`` (the probe wraps pybullet's own function), reference and now;
- the raw engine's steps per second on the same scenes, each layout's world built and stepped as many times as its
  simulation took in a bare loop with no station code around it (the limit a simulation can reach), against the
  steps per second a simulation makes now ("of limit");
- identical labels (global success) and, among events both runs decided alike, event times within one time step.

Ratios are the figures to read (the machine is shared); nothing here asserts on time.

``--equivalence N`` is the outcome check used to accept a change: N random valid layouts per scenario (plus the
success layouts), this tree against the reference (``--against reference``) or against this tree without the
candidate engine settings (``--against current``), both sides run at once (timings are not the point there).
Candidate settings: ``--engine KEY=VALUE`` (merged into every ``setPhysicsEngineParameter`` call, e.g.
``solverResidualThreshold=1e-4``) and ``--dynamics KEY=VALUE`` (``changeDynamics`` of every body as it is made,
e.g. ``sleepThreshold=0.02``). Acceptance: identical labels on >= 99 % of the layouts and every success layout
still a success. ``--moved 1e-9`` moves the candidate side's layouts by that fraction of each parameter's range
(seeded signs): how far the labels themselves follow the arithmetic, the floor any change of the engine's
arithmetic meets.

``--parallel N`` measures the robust executor instead: a batch of N valid layouts simulated in one process, then on
``--workers`` worker processes (a fresh pool, its start-up counted: "cold"), then a second batch on the warm pool;
efficiency is the serial time over workers x the pooled time, for the reference tree and this one.

``--early`` measures early termination instead, on the recorded layouts of tests/data/simulation: steps with no
early stop, with the stop at the verdict and with the reach stop, their ratios and identical labels
(``bench/simulation_early.py``).

Run: ``python -m bench.bench_simulation [--early [--limit N]] [--scenarios simple,longchain] [--layouts 6] [--seed 0]
[--reference 599036c] [--equivalence 500 [--against current] [--moved 1e-9]] [--engine K=V ...] [--dynamics K=V ...]
[--parallel N [--workers 2]] [--json OUT.json]`` or ``python -m bench simulation`` (every example scenario, 6
random layouts each).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from bench import simulation_early
from design.contraption import Simulator, load_scenario
from design.contraption.catalog import EXAMPLES_DIR, example_names

REPOSITORY = Path(__file__).resolve().parents[1]
PROBE = Path(__file__).resolve().with_name("sim_probe.py")
#: The simulator before the work on its speed.
REFERENCE = "599036c"
RANDOM_LAYOUTS = 6


def _value(text: str):
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return text


def _pairs(items: list[str], option: str) -> dict:
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise SystemExit(f"bench_simulation: {option}: expected KEY=VALUE, got {item!r}")
        out[key] = _value(value)
    return out


def reference_tree(commit: str) -> Path:
    """A worktree of ``commit`` (made once, kept for later runs)."""
    path = Path(tempfile.gettempdir()) / f"chaos-station-sim-ref-{commit}"
    if not (path / "design").is_dir():
        subprocess.run(["git", "-C", str(REPOSITORY), "worktree", "add", "--detach", str(path), commit],
                       check=True, capture_output=True)
    return path


def seeded_layouts(scenario, n: int, seed: int) -> tuple[list[np.ndarray], int]:
    """The file's success and failure layouts, then ``n`` random physically valid ones (seeded); how many of the
    first are success layouts."""
    rng = np.random.default_rng(seed)
    named = [scenario.layout(k) for k in ("success", "failure") if k in scenario.layouts]
    n_success = int("success" in scenario.layouts)
    layouts = list(named)
    space = scenario.design_space
    attempts = 0
    with Simulator(scenario) as sim:
        while len(layouts) < len(named) + n and attempts < 50 * max(n, 1):
            attempts += 1
            x = space.from_normalized(rng.random(space.dim))
            if not sim.check_validity(x):
                layouts.append(x)
    return layouts, n_success


def start_probe(root: Path, scenario_path: Path, layouts, workdir: Path, tag: str, *, engine=None,
                dynamics=None, bare: bool = False) -> tuple[subprocess.Popen, Path]:
    spec = {"scenario": str(scenario_path), "layouts": [np.asarray(x).tolist() for x in layouts],
            "engine": engine or {}, "dynamics": dynamics or {}, "bare": bare}
    source = workdir / f"{tag}.in.json"
    result = workdir / f"{tag}.out.json"
    source.write_text(json.dumps(spec), encoding="utf-8")
    process = subprocess.Popen([sys.executable, str(PROBE), "--root", str(root), "--input", str(source),
                                "--output", str(result)], cwd=str(root))
    return process, result


def finish_probe(process: subprocess.Popen, result: Path) -> dict:
    if process.wait() != 0:
        raise SystemExit(f"bench_simulation: the probe ({result.stem}) failed with exit code {process.returncode}")
    return json.loads(result.read_text(encoding="utf-8"))


def run_probe(*args, **kwargs) -> dict:
    return finish_probe(*start_probe(*args, **kwargs))


def compare(a: dict, b: dict) -> dict:
    """Identical labels, and event times within one step among events both runs decided alike."""
    dt = a["dt"]
    same_label = [x["success"] == y["success"] for x, y in zip(a["outcomes"], b["outcomes"])]
    times = []
    for x, y in zip(a["outcomes"], b["outcomes"]):
        for name, (state, t) in x["events"].items():
            other_state, other_t = y["events"][name]
            if state == other_state and t is not None and other_t is not None:
                times.append(abs(t - other_t) <= dt + 1e-9)
    return {"same_label": float(np.mean(same_label)), "n": len(same_label),
            "differing": [i for i, same in enumerate(same_label) if not same],
            "times_within_step": float(np.mean(times)) if times else 1.0}


def speed_table(names, args, reference_root: Path, workdir: Path) -> list[dict]:
    header = (f"{'scenario':<24} {'n':>3} {'sims/s ref':>10} {'sims/s now':>10} {'ratio':>6} {'engine ref':>10} "
              f"{'engine now':>10} {'steps/s now':>11} {'bare steps/s':>12} {'of limit':>8} {'same label':>10} "
              f"{'t within dt':>11}")
    print(header)
    print("-" * len(header))
    rows = []
    for name in names:
        path = EXAMPLES_DIR / f"{name}.toml"
        scenario = load_scenario(path)
        layouts, _ = seeded_layouts(scenario, args.layouts, args.seed)
        ref = run_probe(reference_root, path, layouts, workdir, f"{name}-ref")
        now = run_probe(REPOSITORY, path, layouts, workdir, f"{name}-now", engine=args.engine_params,
                        dynamics=args.dynamics_params, bare=True)
        same = compare(ref, now)
        n = len(layouts)
        steps_now = sum(o["steps"] for o in now["outcomes"])
        row = {
            "scenario": scenario.name, "file": name, "n": n,
            "sims_per_s_reference": n / ref["wall"], "sims_per_s_now": n / now["wall"],
            "ratio": ref["wall"] / now["wall"],
            "engine_share_reference": ref["engine"] / ref["wall"], "engine_share_now": now["engine"] / now["wall"],
            "steps_per_s_now": steps_now / now["wall"],
            "engine_steps_per_s_now": now["engine_steps"] / now["engine"] if now["engine"] else None,
            "bare_steps_per_s": now["bare_steps_per_s"],
            "steps_reference": sum(o["steps"] for o in ref["outcomes"]), "steps_now": steps_now,
            **same,
        }
        rows.append(row)
        print(f"{name[:24]:<24} {n:>3} {row['sims_per_s_reference']:>10.2f} {row['sims_per_s_now']:>10.2f} "
              f"{row['ratio']:>5.2f}x {row['engine_share_reference']:>10.0%} {row['engine_share_now']:>10.0%} "
              f"{row['steps_per_s_now']:>11.0f} {row['bare_steps_per_s']:>12.0f} "
              f"{row['steps_per_s_now'] / row['bare_steps_per_s']:>8.0%} {same['same_label']:>10.0%} "
              f"{same['times_within_step']:>11.0%}", flush=True)
    print("-" * len(header))
    ratios = [r["ratio"] for r in rows]
    if ratios:
        print(f"simulations per second, now / reference {args.reference}: geometric mean "
              f"{np.exp(np.mean(np.log(ratios))):.2f}x; 'of limit': a simulation's steps per second over the bare "
              "engine's on the same scenes")
    return rows


def equivalence(names, args, reference_root: Path, workdir: Path) -> list[dict]:
    against = "this tree without the candidate settings" if args.against == "current" else args.reference
    print(f"labels of {args.equivalence} random valid layouts per scenario (seed {args.seed}) against {against}; "
          f"engine {args.engine_params or '-'}, dynamics {args.dynamics_params or '-'}, layouts moved by "
          f"{args.moved:g} of each range", flush=True)
    rows = []
    for name in names:
        path = EXAMPLES_DIR / f"{name}.toml"
        scenario = load_scenario(path)
        layouts, n_success = seeded_layouts(scenario, args.equivalence, args.seed)
        base_root = REPOSITORY if args.against == "current" else reference_root
        base = start_probe(base_root, path, layouts, workdir, f"{name}-base")
        moved = layouts
        if args.moved:
            # The outcomes' own floor: the same layouts moved by a tiny fraction of each range (seeded signs).
            space = scenario.design_space
            width = np.asarray(space.upper) - np.asarray(space.lower)
            signs = np.random.default_rng(args.seed + 1).choice([-1.0, 1.0], size=(len(layouts), space.dim))
            moved = list(np.clip(np.asarray(layouts) + args.moved * width * signs, space.lower, space.upper))
        cand = start_probe(REPOSITORY, path, moved, workdir, f"{name}-candidate", engine=args.engine_params,
                           dynamics=args.dynamics_params)
        a, b = finish_probe(*base), finish_probe(*cand)
        same = compare(a, b)
        success_kept = all(o["success"] for o in b["outcomes"][:n_success])
        row = {"scenario": scenario.name, "file": name, **same, "success_layouts_succeed": success_kept,
               "base_wall": a["wall"], "candidate_wall": b["wall"],
               "base_steps": sum(o["steps"] for o in a["outcomes"]),
               "candidate_steps": sum(o["steps"] for o in b["outcomes"]),
               "candidate_engine_steps_per_s": b["engine_steps"] / b["engine"] if b["engine"] else None,
               "base_engine_steps_per_s": a["engine_steps"] / a["engine"] if a["engine"] else None}
        rows.append(row)
        verdict = "accept" if same["same_label"] >= 0.99 and success_kept else "REJECT"
        print(f"{name:<24} n={same['n']:>4} identical labels {same['same_label']:.1%} "
              f"(differ: {same['differing'][:10]}) event times within a step {same['times_within_step']:.1%} "
              f"success layouts succeed: {success_kept}; engine steps/s {row['base_engine_steps_per_s']:.0f} -> "
              f"{row['candidate_engine_steps_per_s']:.0f} (both run at once) -> {verdict}", flush=True)
    return rows


def parallel_table(names, args, reference_root: Path, workdir: Path) -> list[dict]:
    from design.robust.contraption import load_problem
    from design.robust.sampling import sobol_valid

    w = args.workers
    print(f"executor: {args.parallel} valid Sobol layouts per batch (seed {args.seed}) in this process, then on {w} "
          f"worker processes; efficiency = serial time / ({w} x pooled time); cold: the pool's start-up counted, "
          "warm: a second batch on the same pool", flush=True)
    header = (f"{'scenario':<24} {'code':<9} {'serial sims/s':>13} {'pooled sims/s':>13} {'tasks':>5} "
              f"{'efficiency cold':>15} {'efficiency warm':>15} {'same':>5}")
    print(header)
    print("-" * len(header))
    rows = []
    for name in names:
        path = EXAMPLES_DIR / f"{name}.toml"
        problem = load_problem(path)
        both = sobol_valid(problem, 2 * args.parallel, seed=args.seed)
        spec = {"parallel": w, "U": both[: args.parallel].tolist(), "U2": both[args.parallel:].tolist()}
        for code, root in (("reference", reference_root), ("now", REPOSITORY)):
            source = workdir / f"{name}-{code}-parallel.in.json"
            result = workdir / f"{name}-{code}-parallel.out.json"
            source.write_text(json.dumps({"scenario": str(path), **spec}), encoding="utf-8")
            process = subprocess.Popen([sys.executable, str(PROBE), "--root", str(root), "--input", str(source),
                                        "--output", str(result)], cwd=str(root))
            out = finish_probe(process, result)
            n = args.parallel
            row = {"scenario": problem.name, "file": name, "code": code, "n": n, "workers": w,
                   "serial_sims_per_s": 2 * n / (out["serial"] + out["serial2"]),
                   "pooled_sims_per_s": 2 * n / (out["pooled"] + out["pooled2"]),
                   "efficiency_cold": out["serial"] / (w * out["pooled"]),
                   "efficiency_warm": out["serial2"] / (w * out["pooled2"]),
                   "tasks": out["tasks"], "same": out["same"]}
            rows.append(row)
            tasks = "-" if row["tasks"] is None else row["tasks"]
            print(f"{name[:24]:<24} {code:<9} {row['serial_sims_per_s']:>13.1f} {row['pooled_sims_per_s']:>13.1f} "
                  f"{tasks:>5} {row['efficiency_cold']:>15.2f} {row['efficiency_warm']:>15.2f} "
                  f"{'yes' if row['same'] else 'NO':>5}", flush=True)
    print("-" * len(header))
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="bench_simulation", description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", default="", help="comma-separated example names (default: all)")
    parser.add_argument("--layouts", type=int, default=RANDOM_LAYOUTS, help="random layouts per scenario (speed)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--reference", default=REFERENCE, help="the commit to measure against")
    parser.add_argument("--equivalence", type=int, default=0, metavar="N",
                        help="check labels on N random layouts instead of measuring speed")
    parser.add_argument("--against", choices=("reference", "current"), default="reference")
    parser.add_argument("--moved", type=float, default=0.0, metavar="FRACTION",
                        help="with --equivalence: move the candidate side's layouts by this fraction of each range")
    parser.add_argument("--engine", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--dynamics", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--parallel", type=int, default=0, metavar="N",
                        help="measure the executor's efficiency on batches of N layouts instead")
    parser.add_argument("--workers", type=int, default=2, help="worker processes for --parallel")
    parser.add_argument("--early", action="store_true",
                        help="measure early termination on the recorded layouts instead (bench/simulation_early.py)")
    parser.add_argument("--limit", type=int, help="with --early: the first N recorded layouts of each scenario")
    parser.add_argument("--json", type=Path, help="write the figures here")
    args = parser.parse_args(argv if argv is not None else sys.argv[1:] if __name__ == "__main__" else [])
    if args.early:
        early = ["--scenarios", args.scenarios] + (["--limit", str(args.limit)] if args.limit else [])
        simulation_early.main(early + (["--json", str(args.json)] if args.json else []))
        return
    args.engine_params = _pairs(args.engine, "--engine")
    args.dynamics_params = _pairs(args.dynamics, "--dynamics")
    known = example_names()
    names = [n.strip() for n in args.scenarios.split(",") if n.strip()] or known
    unknown = sorted(set(names) - set(known))
    if unknown:
        raise SystemExit(f"bench_simulation: --scenarios: unknown {unknown}; expected some of {', '.join(known)}")
    needs_reference = not (args.equivalence and args.against == "current")
    reference_root = reference_tree(args.reference) if needs_reference else REPOSITORY
    with tempfile.TemporaryDirectory(prefix="bench-simulation-") as folder:
        workdir = Path(folder)
        if args.parallel:
            rows = parallel_table(names, args, reference_root, workdir)
        elif args.equivalence:
            rows = equivalence(names, args, reference_root, workdir)
        else:
            rows = speed_table(names, args, reference_root, workdir)
    if args.json:
        args.json.write_text(json.dumps({"arguments": {k: v for k, v in vars(args).items() if k != "json"},
                                         "rows": rows}, indent=1, default=str), encoding="utf-8")


if __name__ == "__main__":
    main()
