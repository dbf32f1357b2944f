"""What a scenario's design space allows in a simulated world: the loop's success with the world's physics known.

An upper bound for ``bench_loop``: for each scenario and world seed, the world's hidden material values
are read (as no station service may) and taken as exact: the layout is optimized under them (``station optimize``'s
service, the scenario's default budget unless ``--budget``), the optimizer's layout and its verified runners-up
(``--candidates``) are scored under them with the placement error left after a check (0.5 mm, 0.5 deg; 16
simulations each), and the best is measured again with other placement draws (``--samples``, default 64; a fresh
measurement, so the choice's luck is not counted). No calibration can do better than knowing the physics, so where
this bound is under the loop's goal (90 %) the shortfall is the design space's, not the calibration's.

``--scan N`` leaves the optimizer out (so its search is not what limits the bound): N layouts of a scrambled Sobol
design over the whole design space (seeded), each scored with ``--scan-samples`` simulations under the world's
physics, and the best ``--scan-top`` of them measured again with ``--samples`` fresh simulations; the bound is the
best of those (a little generous: the best of a few noisy measurements). The best is also measured with the
placement of a part no check measures (1 mm, 1 deg: the world's with the projector's highlight), which is what
CAUSALITYSWITCH's parts get: its check measures none of its four parameters.

Simulations go through the station's cache: a second run (or a run after ``bench_loop`` in the same worlds) reuses
what was simulated.

Run: ``python -m bench.bench_loop_bound [--scenarios branching,longchain] [--seeds 1-5] [--budget N]
[--workers 2] [--scan 96]`` or ``python -m bench loop_bound`` (BRANCHING, seeds 1-2, budget 200).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bench.bench_loop import _seeds

POSITION_SIGMA_M, ANGLE_SIGMA_DEG = 0.0005, 0.5  # a checked and corrected placement (the world's defaults)
BY_EYE_SIGMA_M, BY_EYE_SIGMA_DEG = 0.001, 1.0  # a part the check does not measure, placed with the highlight


def _known_world(name: str, seed: int):
    """``(scenario, hidden, known)``: the example scenario, world ``seed``'s hidden material values (read as no
    station service may) and the scenario with them."""
    from design.contraption.physics_profile import PhysicsProfile, apply_profile
    from station.services import world as worlds
    from station.services.trials import load_trial_scenario

    scenario = load_trial_scenario(name)
    hidden = worlds.prepare_world(worlds.open_world(f"sim://world?seed={seed}"), scenario)
    known = apply_profile(scenario, PhysicsProfile(name=f"world {seed}'s hidden physics", values=hidden, intervals={}))
    return scenario, hidden, known


def _success(known, hidden, run, x: np.ndarray, n: int, draw_seed: int, *, position_sigma_m: float = POSITION_SIGMA_M,
             angle_sigma_deg: float = ANGLE_SIGMA_DEG):
    """The success of layout ``x`` over ``n`` simulations under the world's physics (no material draws)."""
    from calibration.sim_predict import predict_success

    return predict_success(known, x, values=hidden, position_sigma_m=position_sigma_m, angle_sigma_deg=angle_sigma_deg,
                           samples=n, seed=draw_seed, run=run)


def world_bound(name: str, seed: int, *, budget: int | None, candidates: int, samples: int, workers: int) -> dict:
    """The best candidate's success in world ``seed`` with its physics known: ``{"seed", "hidden", "candidates",
    "best", "success", "events", "budget"}``."""
    from design.contraption.layout_io import layout_from_data
    from design.robust.contraption import ContraptionProblem
    from station.services import robust
    from station.services.layout_choice import candidate_layouts
    from station.services.sim_calibration import station_runner

    scenario, hidden, known = _known_world(name, seed)
    problem = ContraptionProblem(robust.load_problem(scenario.source).path, known)
    budget = robust.default_budget(problem, budget)
    result = robust.optimize(problem, budget, 0, robust.psp_settings("recommended"), workers=workers)
    layouts = [np.asarray(layout_from_data(data, known, file="<candidate>").x, dtype=float)
               for data in candidate_layouts(result.to_json(problem), candidates)]
    with station_runner(workers=workers) as run:  # one pool for every layout: a pool per layout costs seconds
        scores = [_success(known, hidden, run, x, 16, 1).probability for x in layouts]
        best = int(np.argmax(scores))
        measured = _success(known, hidden, run, layouts[best], samples, 7)
    return {"seed": seed, "budget": budget, "candidates": scores, "best": best, "success": measured.probability,
            "interval": list(measured.interval), "events": dict(measured.events), "hidden": hidden}


def world_scan(name: str, seed: int, *, layouts: int, scan_samples: int, top: int, samples: int,
               workers: int) -> dict:
    """The best of a Sobol design's ``layouts`` in world ``seed`` with its physics known (:func:`world_bound`'s
    keys; ``"budget"`` is the simulations spent, ``"candidates"`` the top layouts' fresh measurements)."""
    from scipy.stats import qmc

    from station.services.sim_calibration import station_runner

    _, hidden, known = _known_world(name, seed)
    space = known.design_space
    lower, upper = np.asarray(space.lower, dtype=float), np.asarray(space.upper, dtype=float)
    xs = lower + qmc.Sobol(d=len(lower), scramble=True, seed=seed).random(layouts) * (upper - lower)
    with station_runner(workers=workers) as run:
        screened = np.array([_success(known, hidden, run, x, scan_samples, 1).probability for x in xs])
        order = np.argsort(-screened, kind="stable")[:top]
        measured = [_success(known, hidden, run, xs[i], samples, 7) for i in order]
        best = int(np.argmax([m.probability for m in measured]))
        by_eye = _success(known, hidden, run, xs[order[best]], samples, 11, position_sigma_m=BY_EYE_SIGMA_M,
                          angle_sigma_deg=BY_EYE_SIGMA_DEG)
    return {"seed": seed, "budget": layouts * scan_samples + top * samples,
            "candidates": [m.probability for m in measured], "best": int(order[best]),
            "success": measured[best].probability, "interval": list(measured[best].interval),
            "events": dict(measured[best].events), "hidden": hidden,
            "layout": dict(zip(space.names, map(float, xs[order[best]]))),
            "screened": float(screened[order[best]]), "by_eye": by_eye.probability,
            "by_eye_interval": list(by_eye.interval)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", default="branching,causalityswitch_ball,longchain")
    parser.add_argument("--seeds", default="1-5")
    parser.add_argument("--budget", type=int, default=None, help="the optimizer's budget (default: the scenario's)")
    parser.add_argument("--candidates", type=int, default=6)
    parser.add_argument("--samples", type=int, default=64)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--scan", type=int, default=0,
                        help="score this many Sobol layouts instead of optimizing (0: optimize)")
    parser.add_argument("--scan-samples", type=int, default=12, help="simulations per scanned layout")
    parser.add_argument("--scan-top", type=int, default=4, help="scanned layouts measured again")
    args = parser.parse_args([] if argv is None else argv)
    if argv is None:  # python -m bench: a small version
        args.scenarios, args.seeds, args.budget = "branching", "1-2", 200
    names = [s.strip() for s in args.scenarios.split(",") if s.strip()]
    search = (f"a scan of {args.scan} Sobol layouts ({args.scan_samples} simulations each), the best "
              f"{args.scan_top} measured again" if args.scan else
              f"budget {args.budget or 'the scenario default'}, {args.candidates} candidates")
    print(f"bench_loop_bound: {', '.join(names)} over world seeds {args.seeds}; {search}, {args.samples} "
          f"simulations for the best, placement {POSITION_SIGMA_M * 1000:g} mm / {ANGLE_SIGMA_DEG:g} deg", flush=True)
    rows = []
    for name in names:
        bounds, by_eye = [], []
        for seed in _seeds(args.seeds):
            started = time.perf_counter()
            if args.scan:
                row = world_scan(name, seed, layouts=args.scan, scan_samples=args.scan_samples, top=args.scan_top,
                                 samples=args.samples, workers=args.workers)
            else:
                row = world_bound(name, seed, budget=args.budget, candidates=args.candidates,
                                  samples=args.samples, workers=args.workers)
            weakest = sorted(row["events"].items(), key=lambda item: item[1])[:2]
            print(f"  {name} world {seed}: best of {len(row['candidates'])} "
                  f"{'scanned layouts' if args.scan else 'candidates'} "
                  f"{row['success']:.2f} [{row['interval'][0]:.2f}, {row['interval'][1]:.2f}] "
                  f"(budget {row['budget']}; weakest events "
                  f"{', '.join(f'{e} {p:.2f}' for e, p in weakest)}; {time.perf_counter() - started:.0f} s)",
                  flush=True)
            if "layout" in row:
                print(f"    its layout {', '.join(f'{k} {v:.4g}' for k, v in row['layout'].items())} "
                      f"(screened {row['screened']:.2f}); the top {len(row['candidates'])} again: "
                      f"{', '.join(f'{c:.2f}' for c in row['candidates'])}; placed by eye "
                      f"({BY_EYE_SIGMA_M * 1000:g} mm / {BY_EYE_SIGMA_DEG:g} deg) {row['by_eye']:.2f} "
                      f"[{row['by_eye_interval'][0]:.2f}, {row['by_eye_interval'][1]:.2f}]", flush=True)
            bounds.append(row["success"])
            by_eye.append(row.get("by_eye"))
        rows.append((name, bounds))
        if args.scan:
            rows.append((f"{name}, placed by eye", by_eye))
    print("| scenario | success with the physics known, per world | mean | worlds >= 0.90 |")
    print("|---|---|---|---|")
    for name, bounds in rows:
        print(f"| {name} | {' / '.join(f'{b:.2f}' for b in bounds)} | {np.mean(bounds):.2f} | "
              f"{sum(b >= 0.9 for b in bounds)}/{len(bounds)} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(__import__("sys").argv[1:]))
