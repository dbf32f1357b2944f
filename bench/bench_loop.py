"""Acceptance bench of the station loop on the simulated world (thesis 5.2.3 and 4.8).

For each example scenario and each world seed: ``station loop``'s service (:func:`station.services.loop.run_loop`)
with hidden physics (friction x U(0.7, 1.3), restitution +- 0.15, damping x U(0.5, 2)) and a simulated maker who
knows only what the guide says (:mod:`drivers.sim.world`: each parameter set as the guide tells, by eye on the sheet
2 mm, 2 deg, half when highlighted; with a ruler 1.5 mm, 2 deg; on a laser-cut jig 0.2 mm, 0.2 deg, the jig laid by
eye; after a check's instruction 0.5 mm, 0.5 deg), and the thesis's workflow (the optimizer's own loop-1 layout from
the printed sheet: no highlight, no check, no calibration, no jigs) in the same world. With ``--jigs`` the loop's
attempts use the layout's laser-cut jigs (cut on the laser twin per loop); the baseline is the same either way.
Default sizes (``FULL``): 5 attempts x 2 loops, loop 1 optimized at ``station optimize``'s default budget (the
thesis's per scenario, cached across worlds), later loops at the same default (per world: the calibrated physics
differ), 6 candidates compared, 16 simulations per prediction, a fit of 16 Sobol candidates + 2 rounds with 4 draws
per trial. Per scenario:

- the success rate of the attempts after the first calibration (loops >= 2; goal >= 90 %), with Wilson's interval;
- the median number of attempts to the first success (loop 1's first attempt is 1; goal <= 2), and the baseline's;
- the baseline's success rate;
- the Brier score of the predicted success over every loop attempt (goal <= 0.15), and of the forecast (the
  prediction updated by the layout's record before the attempt, :func:`station.services.loop.record_forecasts`);
- how many loops' predicted (and forecast) rates fall within Wilson's interval of their measured rate.

CAUSALITYSWITCH has two files (the ball or the dominoes faster); this bench uses ``causalityswitch_ball.toml``
unless ``--scenarios`` names the other. Everything is stored in one bench database (default under the station's
cache folder): a stopped bench resumes where it stopped (each run keyed by its arguments), and a run with more seeds
reuses the runs already made.

Run: ``python -m bench.bench_loop [--scenarios simple,ballrun] [--seeds 1-5] [--quick] [--loops K] [--jigs]
[--world '&ruler_mm=1'] [--prediction-weight W] [--workers 2] [--database DB] [--json OUT.json]`` or
``python -m bench loop`` (quick, SIMPLE and CAUSALITYSWITCH, 5 seeds).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

ALL = ("simple", "ballrun", "causalityswitch_ball", "longchain", "teapotadventure", "branching")
QUICK = dict(attempts=4, loops=2, budget=120, reoptimize_budget=120, candidates=4, rounds=2, predict_samples=12,
             fit_draws=3, fit_sobol=8, fit_rounds=1)
#: Loop 1's budget None: ``station optimize``'s default, the thesis's budget per scenario (made once, cached).
FULL = dict(attempts=5, loops=2, budget=None, reoptimize_budget=None, candidates=6, rounds=3, predict_samples=16,
            fit_draws=4, fit_sobol=16, fit_rounds=2)


def _seeds(text: str) -> list[int]:
    seeds: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        seeds += list(range(int(lo), int(hi or lo) + 1))
    return seeds


def first_success(successes: list[bool]) -> float:
    """The 1-based number of the first successful attempt (inf when none)."""
    return float(next((i for i, s in enumerate(successes, start=1) if s), math.inf))


def scenario_figures(results: list) -> dict:
    """The acceptance figures of one scenario's runs (one per world seed)."""
    from calibration.sim_runs import wilson_interval

    later = [s for r in results for (k, _, s, _, _) in r.outcomes if k >= 2]
    predictions = [(p, s) for r in results for (_, _, s, p, _) in r.outcomes if p is not None]
    forecasts = [(f, s) for r in results for (_, _, s, _, f) in r.outcomes if f is not None]
    firsts = [first_success([s for (_, _, s, _, _) in r.outcomes]) for r in results]
    within = [0, 0]  # predicted, forecast
    total = 0
    for r in results:
        for loop in r.loops:
            if loop.predicted_success is None:
                continue
            lo, hi = loop.interval
            total += 1
            for i, rate in enumerate((loop.predicted_success, loop.forecast_success)):
                within[i] += lo - 1e-9 <= rate <= hi + 1e-9  # Wilson's ends carry rounding
    baseline = [r.baseline_successes / r.baseline_attempts for r in results if r.baseline_attempts]
    baseline_n = sum(r.baseline_attempts for r in results)
    baseline_k = sum(r.baseline_successes for r in results)
    k = sum(later)
    return {
        "seeds": len(results),
        "after_calibration": {"attempts": len(later), "successes": k,
                              "success_rate": k / len(later) if later else None,
                              "interval": list(wilson_interval(k, len(later))) if later else None},
        "loop1_success_rate": float(np.mean([s for r in results for (kk, _, s, _, _) in r.outcomes if kk == 1])),
        "median_attempts_to_first_success": float(np.median(firsts)) if firsts else None,
        "baseline": {"attempts": baseline_n, "success_rate": baseline_k / baseline_n if baseline_n else None,
                     "median_attempts_to_first_success":
                         float(np.median([first_success(r.baseline) for r in results if r.baseline]))
                         if any(r.baseline for r in results) else None},
        "brier": _brier(predictions),
        "brier_forecast": _brier(forecasts),
        "predicted_within_interval": [within[0], total],
        "forecast_within_interval": [within[1], total],
        "per_seed": [{"run": r.run_id, **r.to_json(), "hidden": r.hidden} for r in results],
        "baseline_rates": baseline,
    }


def _brier(pairs: list) -> float | None:
    return float(np.mean([(p - s) ** 2 for p, s in pairs])) if pairs else None


def run_bench(scenarios, seeds, sizes: dict, *, workers: int | None, database: str, world: str = "",
              jigs: bool = False, log=print) -> dict:
    """Every scenario over every seed; the figures per scenario (and the seconds each took)."""
    from station.services.loop import LoopSettings, run_loop

    figures = {}
    for name in scenarios:
        started = time.perf_counter()
        results = []
        for seed in seeds:
            t0 = time.perf_counter()
            url = f"sim://world?seed={seed}{world}"
            result = run_loop(name, url, LoopSettings(**sizes, jigs=jigs, workers=workers), database=database)
            results.append(result)
            rates = ", ".join(f"loop {s.loop} {s.successes}/{s.attempts} (pred {_f(s.predicted_success)}, "
                              f"forecast {_f(s.forecast_success)})"
                              for s in result.loops)
            log(f"  {name}{' (jigs)' if jigs else ''} seed {seed}: {rates}; "
                f"baseline {result.baseline_successes}/{result.baseline_attempts} "
                f"({time.perf_counter() - t0:.0f} s)")
        figures[name] = {**scenario_figures(results), "jigs": jigs,
                         "seconds": round(time.perf_counter() - started, 1)}
    return figures


def _f(value, digits: int = 2) -> str:
    if value is None:
        return "-"
    if isinstance(value, float) and math.isinf(value):
        return "none"
    return f"{value:.{digits}f}"


def table(figures: dict) -> list[str]:
    """The results page's table (docs/results/2026-12-04-the-loop.md)."""
    rows = ["| scenario | seeds | success after calibration (goal >= 0.90) | loop 1 | median attempts to 1st "
            "success (goal <= 2) | baseline success | baseline median attempts | Brier (goal <= 0.15): "
            "predicted, forecast | within the interval: predicted, forecast |", "|---|---|---|---|---|---|---|---|---|"]
    for name, f in figures.items():
        after = f["after_calibration"]
        interval = after["interval"] or [math.nan, math.nan]
        within, total = f["predicted_within_interval"]
        within_forecast = f["forecast_within_interval"][0]
        label = f"{name} with jigs" if f.get("jigs") else name
        rows.append(f"| {label} | {f['seeds']} | {_f(after['success_rate'])} ({after['successes']}/{after['attempts']}"
                    f"; 95 % {_f(interval[0])}-{_f(interval[1])}) | {_f(f['loop1_success_rate'])} | "
                    f"{_f(f['median_attempts_to_first_success'], 1)} | {_f(f['baseline']['success_rate'])} "
                    f"({f['baseline']['attempts']}) | {_f(f['baseline']['median_attempts_to_first_success'], 1)} | "
                    f"{_f(f['brier'], 3)}, {_f(f['brier_forecast'], 3)} | {within}/{total}, "
                    f"{within_forecast}/{total} |")
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", default="simple,causalityswitch_ball",
                        help=f"comma-separated example names (all: {','.join(ALL)})")
    parser.add_argument("--seeds", default="1-5", help="world seeds, e.g. 1-5 or 1,3,7")
    parser.add_argument("--quick", action="store_true", help="small budgets (the default under `python -m bench`)")
    parser.add_argument("--budget", type=int, default=None, help="the optimizer's budget instead of the sizes'")
    parser.add_argument("--loops", type=int, default=None, help="loops instead of the sizes' (a run carries on)")
    parser.add_argument("--reoptimize-budget", type=int, default=None,
                        help="later loops' optimizer budget instead of the sizes'")
    parser.add_argument("--prediction-weight", type=float, default=None,
                        help="what a prediction is worth against a placed layout's record, in attempts, instead of "
                        "the loop's default")
    parser.add_argument("--jigs", action="store_true",
                        help="the loop's attempts use the layouts' laser-cut jigs (the baseline never does)")
    parser.add_argument("--world", default="", metavar="OPTIONS",
                        help="more sim://world options after the seed, e.g. '&ruler_mm=1&jig_mm=0.3'")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--database", default=None, help="the bench database (default: the station cache folder)")
    parser.add_argument("--json", default=None, help="write the figures there")
    args = parser.parse_args([] if argv is None else argv)
    if argv is None:  # python -m bench: the quick version
        args.quick = True
    from station.loopstore import station_commit
    from station.paths import cache_dir

    names = ALL if args.scenarios == "all" else tuple(s.strip() for s in args.scenarios.split(",") if s.strip())
    sizes = dict(QUICK if args.quick else FULL)
    if args.budget is not None:
        sizes["budget"] = args.budget
    if args.loops is not None:
        sizes["loops"] = args.loops
    if args.reoptimize_budget is not None:
        sizes["reoptimize_budget"] = args.reoptimize_budget
    if args.prediction_weight is not None:
        sizes["prediction_weight"] = args.prediction_weight
    database = args.database or str(cache_dir() / f"bench_loop{'_quick' if args.quick else ''}.sqlite3")
    world = args.world if not args.world or args.world.startswith("&") else f"&{args.world}"
    commit = station_commit()
    print(f"bench_loop: {', '.join(names)} over world seeds {args.seeds}{' with jigs' if args.jigs else ''}"
          f"{f' (world {world})' if world else ''}; sizes {sizes}; database {database}; station "
          f"{commit or 'not a git checkout'}", flush=True)
    figures = run_bench(names, _seeds(args.seeds), sizes, workers=args.workers, database=database, world=world,
                        jigs=args.jigs, log=lambda line: print(line, flush=True))
    for line in table(figures):
        print(line)
    if args.json:
        Path(args.json).write_text(json.dumps({"sizes": sizes, "seeds": args.seeds, "jigs": args.jigs, "world": world,
                                               "station_commit": commit, "figures": figures}, indent=2,
                                              default=str) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
