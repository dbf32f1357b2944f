"""Robust layouts: ours vs baselines B1-B3 at the same simulation budget (thesis Table 4.2, Figure 4.18).

For each scenario, ours runs T times (seeds 0..T-1) under a budget cap; the baselines then get B = the mean number
of simulations ours used, as in the thesis. Every result is scored by ρ_g on one shared Sobol evaluation set. The
thesis used B = 614 / 1120 simulations, T = 10 and 100K-1M evaluation layouts; on a 2-core machine shared with
others this bench uses smaller budgets and sets by default (QUICK below; ``CHAOS_BENCH_ROBUST=reduced`` for larger
ones, ``=full`` for the thesis budgets and T = 10, hours), so compare orderings, not absolute values.

Figures: the table (ρ_g mean ± standard error, time, simulations) beside the thesis's Table 4.2, the ratio of our
ρ_g to each baseline's, and a PNG of the mean ρ_l curves per scenario (path printed).

``CHAOS_BENCH_ROBUST=longchain1915`` and ``=teapot2420`` (LONGCHAIN and TEAPOTADVENTURE at the thesis budgets) take
hours, so they store each finished run under ~/.cache/chaos-station/bench_robust/ (``CHAOS_BENCH_ROBUST_STORE``);
the same command run again skips the stored runs and prints the table from them, and with
``CHAOS_BENCH_ROBUST_STORED=1`` it only prints what is stored.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import os
import shutil
import subprocess
import tempfile
import time
from collections.abc import Callable, Sequence
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import psutil

from design.contraption.catalog import EXAMPLES_DIR
from design.robust import PSPSettings, RobustnessSettings, SimulationCache, SimulationExecutor, compare_methods
from design.robust.contraption import load_problem
from design.robust.executor import cache_scope
from design.robust.pipeline import Comparison, MethodRun
from design.robust.plot import plot_robustness
from design.robust.robustness import RobustnessCurve, evaluation_layouts

#: Thesis Table 4.2: design dimensions d, ρ_g (B1, B2, B3, ours) and processing time in seconds (B1, B2, B3, ours,
#: on 6 cores); Table 4.1 budgets.
THESIS = {
    "CAUSALITYSWITCH": {"d": 4, "B": 614, "rho": (0.44, 0.59, 0.63, 0.65), "time": (263, 282, 463, 364)},
    "BALLRUN": {"d": 8, "B": 1120, "rho": (0.34, 0.35, 0.40, 0.48), "time": (59, 52, 786, 153)},
    "LONGCHAIN": {"d": 11, "B": 1915, "rho": (0.09, 0.13, 0.13, 0.16), "time": (1499, 1597, 1956, 636)},
    "TEAPOTADVENTURE": {"d": 16, "B": 2420, "rho": (0.16, 0.23, 0.14, 0.27), "time": (536, 536, 988, 779)},
}

#: (thesis name, scenario file stem, budget cap for ours, runs T, evaluation set size, local samples per result)
#: The default: about 10 minutes on 2 idle cores (a CAUSALITYSWITCH simulation takes about 1 s of one core).
QUICK = [
    ("BALLRUN", "ballrun", 240, 5, 1024, 30),
    ("CAUSALITYSWITCH", "causalityswitch_ball", 64, 5, 128, 8),
]
#: CHAOS_BENCH_ROBUST=reduced: about 40 minutes on 2 idle cores.
REDUCED = [
    ("BALLRUN", "ballrun", 240, 5, 1024, 30),
    ("CAUSALITYSWITCH", "causalityswitch_ball", 120, 5, 256, 16),
]
FULL = [
    ("BALLRUN", "ballrun", 1120, 10, 16384, 100),
    ("CAUSALITYSWITCH", "causalityswitch_ball", 614, 10, 8192, 100),
]
METHOD_ORDER = ("b1", "b2", "b3", "ours")
#: CHAOS_BENCH_PLACEMENT_ERROR: ours optimizes the mean energy under this uniform placement error (0: the thesis's).
PLACEMENT_ERROR = float(os.environ.get("CHAOS_BENCH_PLACEMENT_ERROR", "0"))
#: CHAOS_BENCH_SETTINGS=recommended|thesis: ours with PSPSettings.recommended() (the station's default) or with the
#: thesis's settings as published.
SETTINGS_NAME = os.environ.get("CHAOS_BENCH_SETTINGS", "recommended").lower()
if SETTINGS_NAME not in ("recommended", "thesis"):
    raise SystemExit(f"bench robust: CHAOS_BENCH_SETTINGS must be 'recommended' or 'thesis', got {SETTINGS_NAME!r}")
RECOMMENDED_SETTINGS = SETTINGS_NAME == "recommended"
#: CHAOS_BENCH_ROBUST=causality614: CAUSALITYSWITCH at the thesis budget, all four methods (about an hour).
CAUSALITY_AT_THESIS_BUDGET = [("CAUSALITYSWITCH", "causalityswitch_ball", 614, 5, 1024, 30)]
#: CHAOS_BENCH_ROBUST=causality614ours: the same, ours only (about 30 minutes; the evaluation set and each result's
#: local samples are seeded as in causality614, so the baselines' figures from that run compare).
CAUSALITY_OURS_AT_THESIS_BUDGET = [("CAUSALITYSWITCH", "causalityswitch_ball", 614, 5, 1024, 30, ("ours",))]
#: CHAOS_BENCH_ROBUST=ballrun1120: BALLRUN at the thesis budget, all four methods. Only 1.5 % of BALLRUN's layouts
#: succeed, so at the QUICK budget of 240 the baselines that search by ρ_l rarely find a success at all.
BALLRUN_AT_THESIS_BUDGET = [("BALLRUN", "ballrun", 1120, 5, 1024, 30)]
#: CHAOS_BENCH_ROBUST=ballrun1120ours: the same, ours only (seeded as in ballrun1120).
BALLRUN_OURS_AT_THESIS_BUDGET = [("BALLRUN", "ballrun", 1120, 5, 1024, 30, ("ours",))]
#: CHAOS_BENCH_ROBUST=longchain1915 / teapot2420: the other two scenarios of Table 4.2 at the thesis budgets, T = 3,
#: the evaluation protocol of causality614 and ballrun1120. Hours on a shared machine, so these are resumable: each
#: finished run is stored at once (see :class:`RunStore`) and a rerun of the same command continues where it stopped.
#: The example scenarios are reduced (LONGCHAIN d = 7, TEAPOTADVENTURE d = 6 against the thesis's 11 and 16).
LONGCHAIN_AT_THESIS_BUDGET = [("LONGCHAIN", "longchain", 1915, 3, 1024, 30)]
TEAPOT_AT_THESIS_BUDGET = [("TEAPOTADVENTURE", "teapotadventure", 2420, 3, 1024, 30)]
RESUMABLE = {"longchain1915": LONGCHAIN_AT_THESIS_BUDGET, "teapot2420": TEAPOT_AT_THESIS_BUDGET}


def bench_settings() -> PSPSettings:
    """Ours's settings as CHAOS_BENCH_SETTINGS and CHAOS_BENCH_PLACEMENT_ERROR choose them."""
    if RECOMMENDED_SETTINGS:
        return PSPSettings.recommended(placement_error=PLACEMENT_ERROR)
    return PSPSettings(placement_error=PLACEMENT_ERROR)


def run_scenario(thesis_name, stem, budget, runs, n_eval, n_local, out_dir: Path, methods=METHOD_ORDER) -> None:
    path = EXAMPLES_DIR / f"{stem}.toml"
    if not path.exists():
        print(f"{thesis_name}: scenario file {path} is missing; skipped")
        return
    problem = load_problem(path)
    robustness = RobustnessSettings(n_evaluation=n_eval, n_local=n_local)
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as cache_dir:
        # A fresh cache: every method pays for its own simulations (honest times); the evaluation set is
        # simulated once and shared by all methods within the run.
        with SimulationExecutor(problem, workers=None, cache_path=Path(cache_dir) / "sims.sqlite3") as executor:
            comparison = compare_methods(
                problem, executor, list(methods), runs, budget, seed=0, robustness=robustness,
                settings=bench_settings(),
            )
    wall = time.perf_counter() - started
    print_comparison(thesis_name, stem, problem, comparison, budget, runs, n_local, f"wall {wall:.0f} s", out_dir)


def print_comparison(thesis_name, stem, problem, comparison: Comparison, budget, runs, n_local, note,
                     out_dir: Path) -> None:
    """Table 4.2's row of one scenario beside the thesis's, the per-seed ρ_g, the ratios and the ρ_l plot."""
    rows = {r["method"]: r for r in comparison.table()}
    thesis = THESIS[thesis_name]
    print(
        f"{thesis_name} ({stem}): d = {problem.dim} (thesis {thesis['d']}), {len(problem.event_names)} events; our "
        f"budget cap {budget}, baselines' B = {comparison.budget} (thesis B = {thesis['B']}); T = {runs} seeds; "
        f"evaluation set {comparison.evaluation_size} layouts (+{n_local} local per result); {note}"
    )
    if not rows:
        return
    print(f"  {'method':6s} {'rho_g mean ± s.e.':>19s} {'thesis':>7s} {'time (s)':>9s} {'thesis':>7s} {'sims':>6s}")
    for method in (m for m in METHOD_ORDER if m in rows):
        row = rows[method]
        index = METHOD_ORDER.index(method)
        print(
            f"  {method:6s} {row['rho_g_mean']:11.3f} ± {row['rho_g_sem']:.3f} {thesis['rho'][index]:7.2f} "
            f"{row['seconds_mean']:9.1f} {thesis['time'][index]:7d} {row['simulations_mean']:6.0f}"
        )
    for method in (m for m in METHOD_ORDER if m in rows):
        per_seed = ", ".join(f"{r.curve.global_robustness:.3f}" for r in comparison.runs if r.method == method)
        print(f"  {method} per seed: {per_seed}")
    if "ours" in rows:
        ours = rows["ours"]["rho_g_mean"]
        ratios = ", ".join(
            f"ours/{m} = {ours / rows[m]['rho_g_mean']:.2f}" if rows[m]["rho_g_mean"] > 0 else f"ours/{m} = inf"
            for m in ("b1", "b2", "b3") if m in rows
        )
        thesis_ratios = ", ".join(f"{thesis['rho'][3] / thesis['rho'][i]:.2f}" for i in range(3)
                                  if METHOD_ORDER[i] in rows)
        print(f"  ratios: {ratios}  (thesis: {thesis_ratios})")
    best = max(rows, key=lambda m: rows[m]["rho_g_mean"])
    print(f"  highest mean rho_g: {best}")
    picture = plot_robustness(
        {m: comparison.mean_curves()[m] for m in METHOD_ORDER if m in rows},
        out_dir / f"robustness-{stem}.png",
        f"{thesis_name}: mean local robustness (T = {runs}, B = {comparison.budget})",
    )
    print(f"  local robustness plot: {picture}")


def store_directory() -> Path:
    """Where resumable configurations keep their runs: CHAOS_BENCH_ROBUST_STORE, else the user's cache folder."""
    override = os.environ.get("CHAOS_BENCH_ROBUST_STORE")
    if override:
        return Path(override)
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "chaos-station" / "bench_robust"


def code_version() -> str:
    """The commit the bench runs from, with "+changes" when the simulating and optimizing code differs from it
    (a resumed configuration may span sessions and commits; each run says which code it timed)."""
    root = Path(__file__).resolve().parent.parent
    try:
        commit = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, timeout=10).stdout.strip()
        changed = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--", "design", "bench"],
                                 capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return f"{commit or 'unknown'}{'+changes' if changed else ''}"


class RunStore:
    """The finished runs of one configuration: a JSON file rewritten (atomically) as each run ends.

    The file is named by the scenario's stem and a digest of the configuration (the scenario's content hash and
    simulator revision, ours's budget cap, the evaluation set's size, the local samples, ours's settings), so a
    changed scenario, simulator or protocol starts a new file instead of mixing results. Beside it,
    ``evaluation_cache`` holds the shared evaluation set's simulations.
    """

    def __init__(self, directory: Path, stem: str, config: dict, details: dict | None = None) -> None:
        digest = hashlib.sha256(json.dumps(config, sort_keys=True).encode()).hexdigest()[:12]
        directory.mkdir(parents=True, exist_ok=True)
        self.path = directory / f"{stem}-{digest}.json"
        self.evaluation_cache = directory / f"{stem}-{digest}-evaluation.sqlite3"
        self.config = config
        # kept for the record, not part of the name (e.g. every settings field); as JSON reads it back
        self.details = json.loads(json.dumps(details or {}))
        stored = json.loads(self.path.read_text()) if self.path.exists() else {}
        self.runs: dict[str, dict] = stored.get("runs", {})
        #: the stored details when they differ from these (the settings behind a name changed between sessions)
        self.stored_details: dict | None = (stored.get("details") if stored and stored.get("details") != self.details
                                            else None)

    @staticmethod
    def key(method: str, seed: int, budget: int) -> str:
        # a baseline's result holds for one B (the mean of ours's simulations over the seeds compared)
        return f"ours/seed{seed}" if method == "ours" else f"{method}/B{budget}/seed{seed}"

    def get(self, method: str, seed: int, budget: int) -> dict | None:
        return self.runs.get(self.key(method, seed, budget))

    def put(self, run: MethodRun, budget: int, evaluation_size: int, cpu: float | None = None) -> dict:
        record = {
            "method": run.method, "seed": run.seed, "budget": int(budget), "u": np.asarray(run.u).tolist(),
            "rho_g": float(run.curve.global_robustness), "simulations": int(run.n_simulations),
            "seconds": float(run.seconds), "cpu_seconds": cpu, "epsilon": np.asarray(run.curve.epsilon).tolist(),
            "local": np.asarray(run.curve.local).tolist(), "valid": bool(run.curve.valid),
            "evaluation_size": int(evaluation_size),
            "finished": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "load_average": [round(v, 2) for v in os.getloadavg()],
            "code": code_version(),
        }
        self.runs[self.key(run.method, run.seed, budget)] = record
        scratch = self.path.with_name(self.path.name + ".tmp")
        scratch.write_text(json.dumps({"config": self.config, "details": self.details, "runs": self.runs}, indent=1))
        os.replace(scratch, self.path)
        return record

    @staticmethod
    def method_run(record: dict) -> MethodRun:
        curve = RobustnessCurve(np.array(record["epsilon"]), np.array(record["local"]), record["rho_g"],
                                record["valid"])
        return MethodRun(record["method"], record["seed"], np.array(record["u"]), record["simulations"],
                         record["seconds"], curve)


def cpu_seconds() -> float:
    """CPU seconds (user + system) used so far by this process and its living descendants (the executor's worker
    processes and their forkserver): on a machine shared with other work, what a run costs apart from waiting."""
    me = psutil.Process()
    total = sum(me.cpu_times()[:2])
    for child in me.children(recursive=True):
        with contextlib.suppress(psutil.Error):
            total += sum(child.cpu_times()[:2])
    return total


def _run_alone(problem, executor: SimulationExecutor, evaluation_cache: Path, method: str, seed: int, budget: int,
               settings: PSPSettings, robustness: RobustnessSettings) -> tuple[MethodRun, int, float]:
    """One method's run on one seed, paying for all its own simulations: the executor's cache is swapped for a
    copy of the evaluation set's (what a fresh cache holds in :func:`run_scenario` when the methods start).
    Returns the run, the evaluation set's size and the CPU seconds of the run's timed part."""
    marks: dict[bool, float] = {}

    def mark(_method: str, _seed: int, running: bool) -> None:
        marks[running] = cpu_seconds()

    with tempfile.TemporaryDirectory() as scratch:
        fresh = Path(scratch) / "run.sqlite3"
        executor.cache.close()
        shutil.copyfile(evaluation_cache, fresh)
        executor.cache = SimulationCache(fresh)
        try:
            comparison = compare_methods(problem, executor, [method], 1, budget, seed, settings, robustness,
                                         on_timed=mark)
        finally:
            executor.cache.close()
            executor.cache = SimulationCache(evaluation_cache)
    return comparison.runs[0], comparison.evaluation_size, marks[False] - marks[True]


def run_resumable(problem, stem: str, budget: int, runs: int, n_eval: int, n_local: int,
                  methods: Sequence[str] = METHOD_ORDER, *, settings: PSPSettings, settings_name: str,
                  directory: Path, run_missing: bool = True, backend: str = "auto", workers: int | None = None,
                  log: Callable[[str], None] = print) -> tuple[Comparison, RunStore, list[str]]:
    """Ours and the baselines on seeds 0..runs-1 as :func:`compare_methods` runs them, one run at a time, each
    stored as it ends; the runs already stored are skipped. Returns the comparison of the stored runs, the store
    and the runs still missing (``run_missing=False`` only reads what is stored).

    The baselines' B is the mean number of simulations of ours's stored seeds, so they start once ours has run on
    every seed. The evaluation set's simulations are kept beside the store and shared; each run starts from a copy
    of them alone, so its time is that of its own simulations (plus its share of the evaluation set it happens to
    draw, as in :func:`run_scenario`).
    """
    robustness = RobustnessSettings(n_evaluation=n_eval, n_local=n_local)
    config = {"scenario": problem.name, "scope": cache_scope(problem), "budget_cap": int(budget),
              "n_evaluation": int(n_eval), "n_local": int(n_local), "settings": settings_name,
              "placement_error": float(settings.placement_error)}
    store = RunStore(directory, stem, config, {"settings_fields": dataclasses.asdict(settings)})
    if store.stored_details is not None:
        log(f"{stem}: warning: the stored runs in {store.path} were made with other {settings_name!r} settings "
            f"({store.stored_details}); new runs use {store.details}")
    # ours first: the baselines' budget is what ours used
    ordered = [m for m in ("ours", *METHOD_ORDER[:3]) if m in methods]

    def budget_of(method: str) -> int | None:
        if method == "ours" or "ours" not in ordered:
            return int(budget)
        used = [store.get("ours", seed, budget) for seed in range(runs)]
        return None if None in used else int(round(np.mean([r["simulations"] for r in used])))

    def missing() -> list[str]:
        return [f"{m} seed {s}" for m in ordered for s in range(runs)
                if budget_of(m) is None or store.get(m, s, budget_of(m)) is None]

    if run_missing and missing():
        with SimulationExecutor(problem, backend=backend, workers=workers,
                                cache_path=store.evaluation_cache) as executor:
            layouts = evaluation_layouts(problem, n_eval)
            log(f"{stem}: evaluation set, {executor.count_new(layouts)} of {len(layouts)} layouts to simulate "
                f"(kept in {store.evaluation_cache})")
            executor.run(layouts)
            # start the workers outside any run's time, as the evaluation set does in run_scenario
            executor.cache.close()
            executor.cache = SimulationCache(None)
            executor.run(layouts[: executor.workers])
            executor.cache.close()
            executor.cache = SimulationCache(store.evaluation_cache)
            for method in ordered:
                method_budget = budget_of(method)
                for seed in range(runs):
                    if store.get(method, seed, method_budget) is not None:
                        continue
                    run, size, cpu = _run_alone(problem, executor, store.evaluation_cache, method, seed,
                                                method_budget, settings, robustness)
                    record = store.put(run, method_budget, size, cpu)
                    log(f"{stem}: {method} seed {seed} (B = {method_budget}): rho_g {record['rho_g']:.3f}, "
                        f"{record['simulations']} simulations, {record['seconds']:.0f} s, CPU {cpu:.0f} s; stored in "
                        f"{store.path}")
    records = [r for m in ordered if budget_of(m) is not None for s in range(runs)
               if (r := store.get(m, s, budget_of(m))) is not None]
    baseline = next((budget_of(m) for m in ordered if m != "ours"), budget)
    size = records[0]["evaluation_size"] if records else 0
    comparison = Comparison(problem.name, int(baseline or 0), size, [RunStore.method_run(r) for r in records])
    return comparison, store, missing()


def run_stored_scenario(thesis_name, stem, budget, runs, n_eval, n_local, out_dir: Path, methods=METHOD_ORDER,
                        run_missing: bool = True) -> None:
    """:func:`run_scenario` one stored run at a time: resumes where an interrupted run stopped."""
    path = EXAMPLES_DIR / f"{stem}.toml"
    if not path.exists():
        print(f"{thesis_name}: scenario file {path} is missing; skipped")
        return
    problem = load_problem(path)
    comparison, store, missing = run_resumable(
        problem, stem, budget, runs, n_eval, n_local, methods, settings=bench_settings(), settings_name=SETTINGS_NAME,
        directory=store_directory(), run_missing=run_missing,
        log=lambda line: print(f"  [{time.strftime('%H:%M:%S')}] {line}", flush=True),
    )
    own = sum(r.seconds for r in comparison.runs)
    state = f"in progress, missing: {', '.join(missing)}" if missing else "complete"
    print_comparison(thesis_name, stem, problem, comparison, budget, runs, n_local,
                     f"{len(comparison.runs)} runs stored ({state}), their own time {own:.0f} s; {store.path}",
                     out_dir)
    for run in comparison.runs:
        record = store.get(run.method, run.seed, budget if run.method == "ours" else comparison.budget)
        cpu = "?" if record.get("cpu_seconds") is None else f"{record['cpu_seconds']:.0f}"
        print(f"    {run.method} seed {run.seed}: rho_g {run.curve.global_robustness:.3f}, {run.n_simulations} "
              f"simulations, {run.seconds:.0f} s, CPU {cpu} s (finished {record['finished']}, load "
              f"{record['load_average']}, code {record.get('code', 'unknown')})")


def main() -> None:
    mode = os.environ.get("CHAOS_BENCH_ROBUST", "quick").lower()
    configs = {"full": FULL, "reduced": REDUCED, "causality614": CAUSALITY_AT_THESIS_BUDGET,
               "causality614ours": CAUSALITY_OURS_AT_THESIS_BUDGET, "ballrun1120": BALLRUN_AT_THESIS_BUDGET,
               "ballrun1120ours": BALLRUN_OURS_AT_THESIS_BUDGET, **RESUMABLE}.get(mode, QUICK)
    out_dir = Path(os.environ.get("CHAOS_BENCH_OUT", tempfile.gettempdir())) / "chaos-bench-robust"
    out_dir.mkdir(parents=True, exist_ok=True)
    words = {"full": "FULL (thesis budgets, T = 10)", "reduced": "REDUCED (smaller budgets and evaluation sets)",
             "causality614": "CAUSALITYSWITCH at the thesis budget",
             "causality614ours": "CAUSALITYSWITCH at the thesis budget, ours only",
             "ballrun1120": "BALLRUN at the thesis budget",
             "ballrun1120ours": "BALLRUN at the thesis budget, ours only",
             "longchain1915": "LONGCHAIN at the thesis budget (resumable)",
             "teapot2420": "TEAPOTADVENTURE at the thesis budget (resumable)"}
    print(
        f"configuration: {words.get(mode, 'QUICK (small budgets and evaluation sets)')} "
        f"(CHAOS_BENCH_ROBUST=quick|reduced|full|causality614|causality614ours|ballrun1120|ballrun1120ours|"
        f"longchain1915|teapot2420); ours with "
        f"{'PSPSettings.recommended()' if RECOMMENDED_SETTINGS else 'the thesis settings'} "
        f"(CHAOS_BENCH_SETTINGS), placement error "
        f"{PLACEMENT_ERROR}; {os.cpu_count()} cores"
    )
    stored_only = os.environ.get("CHAOS_BENCH_ROBUST_STORED", "") == "1"
    for config in configs:
        methods = {"methods": config[6]} if len(config) > 6 else {}
        if mode in RESUMABLE:
            run_stored_scenario(*config[:6], out_dir=out_dir, run_missing=not stored_only, **methods)
        else:
            run_scenario(*config[:6], out_dir=out_dir, **methods)
