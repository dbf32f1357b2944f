"""Is the predicted PSP honest? Brier score and reliability on held-out simulations, per scenario, with and without
the probability calibration.

For every example scenario (examples/scenarios/*.toml) and the tilted plank (tests/data/robust/tilted_plank.toml, a
scenario nobody tuned on), ``station optimize``'s pipeline runs with a simulation budget and seed 0, under the
station's recommended settings without their probability calibration ("uncalibrated": :data:`UNCALIBRATED`) and as
they are ("recommended"). Each fitted model is then scored on held-out simulations it never saw: a Sobol sample of the
whole design space (its own seed) and layouts in balls of radius 0.02-0.2 around the layout the run returned (where
a maker builds). Printed per scenario and settings: the predicted PSP of the returned layout beside the success rate
simulated within 0.05 of it, then the Brier score of the whole success (uniform and near the optimum) against the
Brier score of the held-out base rate (a useful model scores below it), the expected calibration error, and the
Brier score per event (each factor on the held-out rows where its parents happened). Reliability curves (binned
predicted vs observed success) are drawn to docs/psp_reliability.png.

Sizes: the quick plan (default) uses small budgets on the slow scenarios (CAUSALITYSWITCH, LONGCHAIN and
TEAPOTADVENTURE simulate in about 1 s each): each of those takes 10-20 minutes of one core, the whole run about an
hour on 2 cores;
``CHAOS_BENCH_PSP=full`` uses the station's default budgets (the thesis's Table 4.1 where it gives one; hours).
``CHAOS_BENCH_PSP_CACHE=FILE.sqlite3`` keeps the simulations between runs (default: a temporary file);
``CHAOS_BENCH_PSP_ONLY=simple,ballrun`` runs those scenarios only (file stems); ``CHAOS_BENCH_WORKERS=N``.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import numpy as np

from design.contraption.catalog import EXAMPLES_DIR
from design.robust.contraption import load_problem
from design.robust.executor import SimulationExecutor
from design.robust.pipeline import optimize_robust_layout
from design.robust.plot import plot_reliability
from design.robust.reliability import held_out_layouts, psp_reliability
from design.robust.settings import PSPSettings

ROOT = Path(__file__).resolve().parents[1]
TILTED_PLANK = ROOT / "tests" / "data" / "robust" / "tilted_plank.toml"
#: The held-out Sobol sample's seed: not 0.. (the runs' seeds), not the robustness evaluation set's 12345.
HELD_OUT_SEED = 20_2020
#: Per scenario: (budget, held-out uniform layouts, held-out layouts near the returned layout) of the QUICK run
#: (default) and of the full one.
PLAN = {
    TILTED_PLANK: ((100, 128, 64), (600, 512, 256)),
    EXAMPLES_DIR / "simple.toml": ((300, 256, 128), (600, 1024, 256)),
    EXAMPLES_DIR / "ballrun.toml": ((600, 512, 128), (1120, 2048, 256)),
    EXAMPLES_DIR / "branching.toml": ((200, 128, 64), (600, 512, 256)),
    EXAMPLES_DIR / "causalityswitch_ball.toml": ((150, 96, 48), (614, 512, 256)),
    EXAMPLES_DIR / "causalityswitch_dominoes.toml": ((150, 96, 48), (614, 512, 256)),
    EXAMPLES_DIR / "longchain.toml": ((150, 96, 48), (1915, 512, 256)),
    EXAMPLES_DIR / "teapotadventure.toml": ((150, 96, 48), (2420, 512, 256)),
}
#: CHAOS_BENCH_WORKERS: local simulation processes (default: one per core).
WORKERS = int(os.environ["CHAOS_BENCH_WORKERS"]) if os.environ.get("CHAOS_BENCH_WORKERS") else None
#: The recommended settings' probability calibration taken away: cross-validation scored by ROC AUC (which ranks
#: layouts but never checks a probability), the product of the factors left uncalibrated, no check of the parameter
#: subspaces an event needs together. What the comparison shows is what these three do.
UNCALIBRATED = {"cv_scoring": "roc_auc", "calibrate_product": False, "subspace_check": False}
#: The settings compared.
VARIANTS = {"uncalibrated": PSPSettings.recommended(**UNCALIBRATED), "recommended": PSPSettings.recommended()}


def evaluate(problem, executor, budget: int, n_uniform: int, n_near: int, settings: PSPSettings, seed: int = 0):
    """One run of the pipeline and its model's scores on held-out simulations (a dict of figures)."""
    layout = optimize_robust_layout(problem, executor, budget, seed, settings)
    U, groups = held_out_layouts(problem, n_uniform, HELD_OUT_SEED, layout.u, n_near)
    events = executor.run(U)
    scores = psp_reliability(layout.model, U, events)
    near = np.array([g != "uniform" for g in groups])
    close = np.array([g in ("near 0.02", "near 0.05") for g in groups])
    success = events.all(axis=1)
    predicted = layout.model.predict_proba(U)
    near_score = psp_reliability(layout.model, U[near], events[near])[-1]
    return {
        "psp": layout.psp, "factors": dict(zip(layout.factor_names, layout.factor_probabilities)),
        "simulated_near": float(success[close].mean()) if close.any() else float("nan"),
        "predicted_near": float(predicted[close].mean()) if close.any() else float("nan"),
        "scores": scores, "near": near_score, "n_train": layout.n_simulations, "n_held_out": len(U),
    }


def main() -> None:
    full = os.environ.get("CHAOS_BENCH_PSP", "").lower() == "full"
    only = [s.strip() for s in os.environ.get("CHAOS_BENCH_PSP_ONLY", "").split(",") if s.strip()]
    plan = [(path, *sizes[full]) for path, sizes in PLAN.items() if not only or path.stem in only]
    cache = os.environ.get("CHAOS_BENCH_PSP_CACHE")
    curves: dict[str, dict[str, object]] = {}
    with tempfile.TemporaryDirectory() as scratch:
        cache_path = Path(cache) if cache else Path(scratch) / "sims.sqlite3"
        print(f"{'scenario file':24} settings      PSP(u*)  sim(u*)  Brier all  ref    ECE    Brier near  ref    "
              "per-event Brier (held-out rows)")
        for path, budget, n_uniform, n_near in plan:
            problem = load_problem(path)
            started = time.perf_counter()
            with SimulationExecutor(problem, workers=WORKERS, cache_path=cache_path) as executor:
                for variant, settings in VARIANTS.items():
                    r = evaluate(problem, executor, budget, n_uniform, n_near, settings)
                    whole, near = r["scores"][-1], r["near"]
                    events = "  ".join(f"{s.name}={s.brier:.3f}({s.n})" for s in r["scores"][:-1]
                                       if np.isfinite(s.brier))
                    # The file's stem: both CAUSALITYSWITCH variants are named CAUSALITYSWITCH (...).
                    print(f"{path.stem[:24]:24} {variant:12}  {r['psp']:.3f}    {r['simulated_near']:.3f}    "
                          f"{whole.brier:.3f}     {whole.reference_brier:.3f}  {whole.ece:.3f}  {near.brier:.3f}"
                          f"       {near.reference_brier:.3f}  {events}", flush=True)
                    curves.setdefault(path.stem, {})[variant] = whole
            print(f"   {problem.name}: budget {budget}, held-out {n_uniform} uniform + {n_near} near the "
                  f"result, {time.perf_counter() - started:.0f} s", flush=True)
    out = ROOT / "docs" / "psp_reliability.png"
    plot_reliability(curves, out, title="PSP reliability on held-out simulations (seed 0)")
    print(f"reliability curves: {out}")


if __name__ == "__main__":
    main()
