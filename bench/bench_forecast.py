"""Where the loop's per-attempt predictions go wrong: each prediction re-made with one ingredient replaced by the
world's truth.

The loop predicts each checked attempt (:meth:`station.services.assemble.Assembly.forecast`) from the check's
as-built layout, the check's residual error on what it measured, the error of how the guide told the maker to set
what it did not measure (:func:`station.services.world.guide_sigma`) and physics drawn from the loop's profile (loop 1:
the scenario's values and ranges; later loops: the calibrated values and intervals), with ``predict_samples``
simulations. This bench runs the loop (``bench_loop``'s service and sizes) with every attempt's prediction request,
the layout as the world's maker really placed it and the world's hidden physics written to a capture file (``run``;
only a bench may read those), then re-predicts every captured attempt (``decompose``) with:

- ``station``: the same request with ``--samples`` simulations (the station's own model without the sampling noise
  of its few simulations; ``as made`` repeats the loop's own count and seed, and must give the loop's figure);
- ``hidden physics``: the world's hidden material values, no draws (what the physics draws cost);
- ``profile centre``: the profile's values, no draws (what the width of the draws costs, apart from their centre);
- ``true unmeasured``: the parameters the check did not measure at their really placed values, no error;
- ``true measured``: the parameters the check measured at their really placed values, no error (what the check's
  measurement error and residual cost);
- ``true placement``: every parameter as really placed (physics still the profile's draws);
- ``truth``: as placed under the hidden physics: one simulation, which must repeat the attempt's outcome.

Every variant of an attempt draws the same placement noise and material draws (one seed), so their differences are
not sampling noise. For each variant: the mean probability and the Brier score against the attempts' outcomes, per
loop and overall.

``worlds`` scores one captured attempt's layout and placement error under many worlds' hidden physics (how its
success spreads over workshops, beside the station's prediction); ``replay`` forecasts attempts in those worlds the
station's way (the prediction as a Beta prior of the layout choice's weight, updated by the layout's record) and by
the record weighing the prediction's material draws (each simulated twice), beside the best any forecast could do
there (each world's own success); ``sensitivity`` splits the station's predicted successes by the thirds of each
drawn material value.

Run: ``python -m bench.bench_forecast run --scenario causalityswitch_ball --seeds 11-13 --jigs --database DB
--capture rows.jsonl [--workers 2]``, then ``python -m bench.bench_forecast decompose --capture rows.jsonl
[--samples 32] [--json out.json]``, ``... worlds --capture rows.jsonl --row 0 --seeds 100-129 --json worlds.json``,
``... replay --capture rows.jsonl --row 0 --worlds worlds.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from bench.bench_loop import FULL, _seeds, run_bench


def capture(path: Path):
    """Write every loop attempt's prediction request, as-placed layout, hidden physics and outcome to ``path``
    (JSON lines) by wrapping the two calls of :class:`station.services.assemble.Assembly` that see them."""
    import station.services.assemble as assemble

    original_run, original_predict = assemble.run_attempt, assemble.predict_layout
    state: dict = {}

    def run_attempt(scenario, x, guide, world, hidden=None):
        result = original_run(scenario, x, guide, world, hidden)
        state["run"] = {"world": world.url, "world_seed": world.seed, "attempt": world.attempt,
                        "success": bool(result.success), "as_placed": dict(result.as_placed),
                        "hidden": world.hidden_physics(), "settings": world.settings(),
                        "set_with": {p.name: {q.name: q.set_with for q in p.settings} for p in guide.parts}}
        return result

    def predict_layout(scenario, x, request, *, report=None):
        result = original_predict(scenario, x, request, report=report)
        run = state.pop("run", None)
        if run is not None:
            profile = request.profile
            row = {"scenario": str(scenario.source), "content_hash": scenario.content_hash,
                   "names": list(scenario.design_space.names), "x": [float(v) for v in x],
                   "values": dict(profile.values) if profile else None,
                   "intervals": {k: list(v) for k, v in profile.intervals.items()} if profile else None,
                   "position_sigma_m": request.position_sigma_m, "angle_sigma_deg": request.angle_sigma_deg,
                   "unmeasured": list(request.unmeasured), "set_sigma": dict(request.set_sigma or {}),
                   "samples": request.samples, "seed": request.seed, "probability": result.probability, **run}
            with path.open("a", encoding="utf-8") as out:
                out.write(json.dumps(row) + "\n")
        return result

    assemble.run_attempt, assemble.predict_layout = run_attempt, predict_layout


def read_rows(path: Path) -> list[dict]:
    """The captured attempts, the last capture of each (world, attempt) kept, in order."""
    rows: dict = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.strip():
            row = json.loads(line)
            rows[(row["world"], row["attempt"])] = row
    return [rows[k] for k in sorted(rows, key=lambda k: (k[0], k[1]))]


def variants(row: dict, samples: int) -> dict[str, dict]:
    """The predictions to re-make for one captured attempt: ``{name: predict_success keyword arguments}``."""
    names = row["names"]
    x = np.array(row["x"], dtype=float)
    placed = np.array([row["as_placed"][n] for n in names], dtype=float)
    unmeasured = tuple(row["unmeasured"])
    seen = np.array([n not in unmeasured for n in names])
    station = dict(layout=x, values=row["values"], intervals=row["intervals"],
                   position_sigma_m=row["position_sigma_m"], angle_sigma_deg=row["angle_sigma_deg"],
                   unmeasured=unmeasured, set_sigma=row["set_sigma"], samples=samples, seed=row["seed"])
    exact_unmeasured = {**row["set_sigma"], **{n: 0.0 for n in unmeasured}}
    hidden = row["hidden"]
    return {
        "as made": {**station, "samples": row["samples"]},
        "station": station,
        "hidden physics": {**station, "values": hidden, "intervals": None},
        "profile centre": {**station, "intervals": None},
        "true unmeasured": {**station, "layout": np.where(seen, x, placed), "set_sigma": exact_unmeasured},
        "true measured": {**station, "layout": np.where(seen, placed, x), "position_sigma_m": 0.0,
                          "angle_sigma_deg": 0.0},
        "true placement": {**station, "layout": placed, "position_sigma_m": 0.0, "angle_sigma_deg": 0.0,
                           "unmeasured": (), "set_sigma": None},
        "truth": {**station, "layout": placed, "position_sigma_m": 0.0, "angle_sigma_deg": 0.0, "unmeasured": (),
                  "set_sigma": None, "values": hidden, "intervals": None, "samples": 1},
    }


def decompose(rows: list[dict], samples: int, workers: int | None, log=print) -> dict:
    """Every variant of every captured attempt; per variant the mean probability and Brier score, per loop and in
    all."""
    from calibration.sim_predict import predict_success
    from station.services.contraption import open_scenario
    from station.services.loop import ATTEMPT_BLOCK
    from station.services.sim_calibration import station_runner

    scenarios: dict = {}
    table: list[dict] = []
    with station_runner(workers=workers) as run:
        for row in rows:
            scenario = scenarios.get(row["scenario"]) or open_scenario(row["scenario"])
            scenarios[row["scenario"]] = scenario
            if scenario.content_hash != row["content_hash"]:
                raise SystemExit(f"{row['scenario']}: the scenario changed since the capture")
            made = variants(row, samples)
            probabilities = {name: predict_success(scenario, run=run, **kwargs).probability
                             for name, kwargs in made.items()}
            entry = {"world": row["world"], "loop": row["attempt"] // ATTEMPT_BLOCK,
                     "attempt": row["attempt"] % ATTEMPT_BLOCK, "success": row["success"],
                     "captured": row["probability"], **probabilities}
            table.append(entry)
            log(json.dumps(entry))
    return {"samples": samples, "attempts": table, "summary": summarize(table)}


class _Kept:
    """A runner that keeps what it simulated (one call): the material values drawn (``names``), each simulation's
    values (real units) and whether it succeeded."""

    def __init__(self, run) -> None:
        self.run = run

    def expect(self, n: int) -> None:
        self.run.expect(n)

    def __call__(self, problem, rows: np.ndarray) -> np.ndarray:
        out = self.run(problem, rows)
        self.names, self.values = list(problem.physics), problem.to_real(rows)[:, :problem.n_physics]
        self.success = problem.split(out)[0] > 0.5
        return out


def sensitivity(rows: list[dict], samples: int, workers: int | None, log=print) -> dict:
    """Which drawn material value the station's predicted failures come from: for each captured attempt, ``samples``
    simulations drawn as :func:`calibration.sim_predict.predict_success` draws them (the station's placement noise,
    the profile's material draws), each simulation's draws and outcome; per material value, the success rate of the
    simulations in each third of its draws, beside where the world's hidden value lies."""
    from calibration.sim_predict import predict_success
    from station.services.contraption import open_scenario
    from station.services.sim_calibration import station_runner

    draws: list[np.ndarray] = []
    outcomes: list[np.ndarray] = []
    names: list[str] = []
    with station_runner(workers=workers) as run:
        for row in rows:
            kept = _Kept(run)
            predicted = predict_success(open_scenario(row["scenario"]), run=kept, **variants(row, samples)["station"])
            names = kept.names
            draws.append(kept.values)
            outcomes.append(kept.success)
            log(f"{row['world']} attempt {row['attempt']}: {predicted.successes}/{samples}")
    thetas, success = np.vstack(draws), np.concatenate(outcomes)
    result = {"samples": int(len(success)), "success_rate": float(success.mean()), "parameters": {}}
    hidden = [row["hidden"] for row in rows]
    for j, name in enumerate(names):
        cuts = np.quantile(thetas[:, j], [1 / 3, 2 / 3])
        third = np.digitize(thetas[:, j], cuts)
        result["parameters"][name] = {
            "thirds": [[float(thetas[third == t, j].min()), float(thetas[third == t, j].max()),
                        float(success[third == t].mean())] for t in range(3)],
            "hidden": sorted({round(float(h[name]), 4) for h in hidden if name in h})}
    return result


def worlds(row: dict, seeds: list[int], samples: int, station_samples: int, workers: int | None, log=print) -> dict:
    """One captured attempt's layout and placement error under the hidden physics of many worlds (``seeds``: each
    world's material values drawn as the loop's worlds draw them, ``samples`` simulations each), beside the
    station's prediction of it (its profile's draws, ``station_samples`` simulations): whether the station's physics
    draws are as wide as the worlds' and how the layout's success spreads over worlds (what a record of attempts in
    one world tells)."""
    from calibration.sim_predict import predict_success
    from drivers.sim.world import SimulatedWorld
    from station.services.contraption import open_scenario
    from station.services.sim_calibration import station_runner
    from station.services.world import prepare_world

    scenario = open_scenario(row["scenario"])
    station = variants(row, station_samples)["station"]
    per_world = {}
    with station_runner(workers=workers) as run:
        predicted = predict_success(scenario, run=run, **station).probability
        log(f"station: {predicted:.3f} ({station_samples} simulations)")
        for seed in seeds:
            hidden = prepare_world(SimulatedWorld(f"sim://world?seed={seed}"), scenario)
            kwargs = {**station, "values": hidden, "intervals": None, "samples": samples}
            per_world[seed] = predict_success(scenario, run=run, **kwargs).probability
            log(f"world {seed}: {per_world[seed]:.3f}")
    rates = np.array(list(per_world.values()))
    return {"station": predicted, "station_samples": station_samples, "samples": samples,
            "worlds": per_world, "mean": float(rates.mean()), "sd": float(rates.std()),
            "share_at_least_0.8": float(np.mean(rates >= 0.8)), "share_at_most_0.2": float(np.mean(rates <= 0.2))}


def given_record(physics_runs, successes: int, attempts: int) -> float:
    """The success of the next attempt given a layout's record, from material draws simulated a few times each
    (``physics_runs``: ``(successes, simulations)`` per draw): each draw weighted by the record's likelihood under it,
    ``p^k (1 - p)^(n - k)`` with ``p = (s + 1/2) / (r + 1)`` (never 0 or 1 from a few simulations). The alternative to
    the station's Beta update that ``replay`` measures."""
    runs = np.asarray(physics_runs, dtype=float).reshape(-1, 2)
    s, r = runs[:, 0], runs[:, 1]
    if not attempts:
        return float(s.sum() / r.sum())
    p = (s + 0.5) / (r + 1.0)
    log_w = successes * np.log(p) + (attempts - successes) * np.log1p(-p)
    w = np.exp(log_w - log_w.max())
    return float(np.sum(w * s / r) / np.sum(w))


def paired_pool(row: dict, pool: int, workers: int | None) -> np.ndarray:
    """``pool`` material draws of a captured attempt's profile, each simulated twice at the attempt's layout with its
    own placement error (:func:`calibration.sim_predict.predict_success`'s draws, each draw repeated): ``(pool, 2)``
    of ``(successes, simulations)``."""
    from calibration.sim_runs import OutcomeProblem, noisy_layouts
    from design.contraption.validation import with_physics
    from station.services.contraption import open_scenario
    from station.services.sim_calibration import station_runner

    scenario = open_scenario(row["scenario"])
    known = scenario.physics_parameters()
    uncertain = scenario.uncertain_parameters()
    centres = {k: float(v) for k, v in (row["values"] or {}).items() if k in known}
    spread = {k: v for k, v in (row["intervals"] or {}).items() if k in centres and v[1] > v[0]}
    names = list(spread)
    ranges = {k: uncertain[k][1] if k in uncertain else (0.0, max(2.0 * centres[k], 1.0)) for k in names}
    rng = np.random.default_rng(row["seed"])
    layouts = noisy_layouts(scenario, np.array(row["x"]), 2 * pool, row["position_sigma_m"], row["angle_sigma_deg"],
                            rng, tuple(row["unmeasured"]), row["set_sigma"])
    thetas = np.column_stack([np.clip(np.repeat(rng.normal(centres[n], (spread[n][1] - spread[n][0]) / 3.919928,
                                                           pool), 2), *ranges[n]) for n in names])
    problem = OutcomeProblem(with_physics(scenario, {k: v for k, v in centres.items() if k not in spread}), names,
                             ranges)
    with station_runner(workers=workers) as run:
        run.expect(2 * pool)
        success, _, _ = problem.split(run(problem, problem.rows(thetas, layouts)))
    pairs = (success > 0.5).reshape(pool, 2).sum(axis=1)
    return np.column_stack([pairs, np.full(pool, 2)]).astype(float)


def replay(row: dict, per_world: dict, attempts: int, samples: int, pool: int, repeats: int, workers: int | None,
           seed: int = 0, log=print) -> dict:
    """Forecasts of ``attempts`` attempts in each world of ``per_world`` (``{seed: the layout's success there}``,
    from :func:`worlds`): the outcomes drawn from each world's success (``repeats`` times, seeded); each attempt's
    prediction ``samples`` simulations (``samples / 2`` material draws of a pool of ``pool`` drawn from the station's
    profile, each simulated twice); its forecast the station's (the plain prediction as a Beta prior of
    :data:`station.services.layout_choice.PREDICTION_WEIGHT` attempts, updated by the layout's record before it),
    the draws weighted by that record (:func:`given_record`), and the best any forecast could do (the world's own
    success). The Brier scores over every attempt."""
    from station.services.layout_choice import expected_success

    runs = paired_pool(row, pool, workers)
    log(f"pool: {len(runs)} material draws, success {runs[:, 0].sum() / runs[:, 1].sum():.3f}")
    rng = np.random.default_rng(seed)
    squares: dict[str, list[float]] = {"predicted": [], "forecast (Beta)": [], "forecast (draws weighted)": [],
                                       "the world's own success": []}
    for rate in per_world.values():
        for _ in range(repeats):
            successes = 0
            for a in range(attempts):
                drawn = runs[rng.choice(len(runs), samples // 2, replace=False)]
                plain = drawn[:, 0].sum() / drawn[:, 1].sum()
                outcome = float(rng.random() < rate)
                for name, forecast in (("predicted", plain),
                                       ("forecast (Beta)", expected_success(plain, successes, a)),
                                       ("forecast (draws weighted)", given_record(drawn, successes, a)),
                                       ("the world's own success", rate)):
                    squares[name].append((forecast - outcome) ** 2)
                successes += int(outcome)
    return {"worlds": len(per_world), "attempts": attempts, "repeats": repeats, "samples": samples, "pool": pool,
            "world_mean": float(np.mean(list(per_world.values()))),
            "pool_success": float(runs[:, 0].sum() / runs[:, 1].sum()),
            "draws": {f"{k} of 2": float(np.mean(runs[:, 0] == k)) for k in (0, 1, 2)},
            "brier": {name: float(np.mean(v)) for name, v in squares.items()}}


def summarize(table: list[dict]) -> dict:
    """Per variant and per loop (and ``all``): the mean probability, the success rate, the Brier score."""
    skip = {"world", "loop", "attempt", "success"}
    names = [k for k in table[0] if k not in skip] if table else []
    groups = {"all": table}
    for entry in table:
        groups.setdefault(f"loop {entry['loop']}", []).append(entry)
    summary = {}
    for group, entries in groups.items():
        outcomes = np.array([float(e["success"]) for e in entries])
        summary[group] = {"attempts": len(entries), "success_rate": float(outcomes.mean()),
                          **{name: {"mean": float(np.mean([e[name] for e in entries])),
                                    "brier": float(np.mean([(e[name] - s) ** 2 for e, s in zip(entries, outcomes)]))}
                             for name in names}}
    return summary


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    # every command reads or writes a capture, runs on workers and may write its result as JSON
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--capture", required=True)
    common.add_argument("--workers", type=int, default=2)
    common.add_argument("--json", default=None)
    run = sub.add_parser("run", parents=[common], help="run the loop with every attempt captured")
    run.add_argument("--scenario", default="causalityswitch_ball")
    run.add_argument("--seeds", default="11")
    run.add_argument("--jigs", action="store_true")
    run.add_argument("--database", required=True)
    again = sub.add_parser("decompose", parents=[common],
                           help="re-predict every captured attempt with one ingredient made true")
    again.add_argument("--samples", type=int, default=48)
    shape = sub.add_parser("sensitivity", parents=[common],
                           help="which drawn material value the predicted failures come from")
    shape.add_argument("--samples", type=int, default=64)
    shape.add_argument("--loop", type=int, default=None, help="only this loop's attempts")
    spread = sub.add_parser("worlds", parents=[common], help="one captured attempt under many worlds' hidden physics")
    spread.add_argument("--row", type=int, default=0, help="which captured attempt (0: the first)")
    spread.add_argument("--seeds", default="100-129")
    spread.add_argument("--samples", type=int, default=8)
    spread.add_argument("--station-samples", type=int, default=128)
    again_worlds = sub.add_parser("replay", parents=[common],
                                  help="old and new forecasts of attempts in worlds scored by `worlds`")
    again_worlds.add_argument("--row", type=int, default=0)
    again_worlds.add_argument("--worlds", required=True, help="the JSON `worlds --json` wrote")
    again_worlds.add_argument("--attempts", type=int, default=10)
    again_worlds.add_argument("--samples", type=int, default=16)
    again_worlds.add_argument("--pool", type=int, default=64)
    again_worlds.add_argument("--repeats", type=int, default=200)
    args = parser.parse_args(argv)
    log = lambda line: print(line, flush=True)  # noqa: E731
    if args.command == "run":
        capture(Path(args.capture))
        result = run_bench([args.scenario], _seeds(args.seeds), dict(FULL), workers=args.workers,
                           database=args.database, jigs=args.jigs, log=log)
        print(json.dumps({k: {"brier": v["brier"], "brier_forecast": v["brier_forecast"]} for k, v in result.items()}))
    elif args.command == "decompose":
        result = decompose(read_rows(Path(args.capture)), args.samples, args.workers, log=log)
        print(json.dumps(result["summary"], indent=2))
    else:
        rows = read_rows(Path(args.capture))
        if args.command == "sensitivity":
            from station.services.loop import ATTEMPT_BLOCK

            rows = [r for r in rows if args.loop is None or r["attempt"] // ATTEMPT_BLOCK == args.loop]
            result = sensitivity(rows, args.samples, args.workers, log=log)
        elif args.command == "worlds":
            result = worlds(rows[args.row], _seeds(args.seeds), args.samples, args.station_samples, args.workers,
                            log=log)
        else:  # replay
            per_world = json.loads(Path(args.worlds).read_text(encoding="utf-8"))["worlds"]
            result = replay(rows[args.row], per_world, args.attempts, args.samples, args.pool, args.repeats,
                            args.workers, log=log)
        print(json.dumps(result, indent=2))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2, default=str) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
