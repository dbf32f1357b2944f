"""Robust layouts: ours vs baselines B1-B3 at the same simulation budget (thesis Table 4.2, Figure 4.18).

For each scenario, ours runs T times (seeds 0..T-1) under a budget cap; the baselines then get B = the mean number
of simulations ours used, as in the thesis. Every result is scored by ρ_g on one shared Sobol evaluation set. The
thesis used B = 614 / 1120 simulations, T = 10 and 100K-1M evaluation layouts; on a 2-core machine shared with
others this bench uses smaller budgets and sets by default (QUICK below; ``CHAOS_BENCH_ROBUST=reduced`` for larger
ones, ``=full`` for the thesis budgets and T = 10, hours), so compare orderings, not absolute values.

Figures: the table (ρ_g mean ± standard error, time, simulations) beside the thesis's Table 4.2, the ratio of our
ρ_g to each baseline's, and a PNG of the mean ρ_l curves per scenario (path printed).
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

from design.contraption.catalog import EXAMPLES_DIR
from design.robust import PSPSettings, RobustnessSettings, SimulationExecutor, compare_methods
from design.robust.contraption import load_problem
from design.robust.plot import plot_robustness

#: Thesis Table 4.2: ρ_g (B1, B2, B3, ours) and processing time in seconds (B1, B2, B3, ours); Table 4.1 budgets.
THESIS = {
    "CAUSALITYSWITCH": {"B": 614, "rho": (0.44, 0.59, 0.63, 0.65), "time": (263, 282, 463, 364)},
    "BALLRUN": {"B": 1120, "rho": (0.34, 0.35, 0.40, 0.48), "time": (59, 52, 786, 153)},
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
                settings=(PSPSettings.recommended(placement_error=PLACEMENT_ERROR) if RECOMMENDED_SETTINGS
                          else PSPSettings(placement_error=PLACEMENT_ERROR)),
            )
    rows = {r["method"]: r for r in comparison.table()}
    thesis = THESIS[thesis_name]
    wall = time.perf_counter() - started
    print(
        f"{thesis_name} ({stem}): d = {problem.dim}, {len(problem.event_names)} events; our budget cap {budget}, "
        f"baselines' B = {comparison.budget} (thesis B = {thesis['B']}); T = {runs} seeds; evaluation set "
        f"{comparison.evaluation_size} layouts (+{n_local} local per result); wall {wall:.0f} s"
    )
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


def main() -> None:
    mode = os.environ.get("CHAOS_BENCH_ROBUST", "quick").lower()
    configs = {"full": FULL, "reduced": REDUCED, "causality614": CAUSALITY_AT_THESIS_BUDGET,
               "causality614ours": CAUSALITY_OURS_AT_THESIS_BUDGET, "ballrun1120": BALLRUN_AT_THESIS_BUDGET,
               "ballrun1120ours": BALLRUN_OURS_AT_THESIS_BUDGET}.get(mode, QUICK)
    out_dir = Path(os.environ.get("CHAOS_BENCH_OUT", tempfile.gettempdir())) / "chaos-bench-robust"
    out_dir.mkdir(parents=True, exist_ok=True)
    words = {"full": "FULL (thesis budgets, T = 10)", "reduced": "REDUCED (smaller budgets and evaluation sets)",
             "causality614": "CAUSALITYSWITCH at the thesis budget",
             "causality614ours": "CAUSALITYSWITCH at the thesis budget, ours only",
             "ballrun1120": "BALLRUN at the thesis budget",
             "ballrun1120ours": "BALLRUN at the thesis budget, ours only"}
    print(
        f"configuration: {words.get(mode, 'QUICK (small budgets and evaluation sets)')} "
        f"(CHAOS_BENCH_ROBUST=quick|reduced|full|causality614|causality614ours|ballrun1120|ballrun1120ours); ours with "
        f"{'PSPSettings.recommended()' if RECOMMENDED_SETTINGS else 'the thesis settings'} "
        f"(CHAOS_BENCH_SETTINGS), placement error "
        f"{PLACEMENT_ERROR}; {os.cpu_count()} cores"
    )
    for config in configs:
        run_scenario(*config[:6], out_dir=out_dir, **({"methods": config[6]} if len(config) > 6 else {}))
