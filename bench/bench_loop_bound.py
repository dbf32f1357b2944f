"""What a scenario's design space allows in a simulated world: the loop's success with the world's physics known.

An upper bound for ``bench_loop``: for each scenario and world seed, the world's hidden material values
are read (as no station service may) and taken as exact, and a layout is scored under them with the placement error
the loop's maker is left with (``--precision``). No calibration can do better than knowing the physics, so where
this bound is under the loop's goal (90 %) the shortfall is the design space's and the placing's, not the
calibration's.

**The placement precision** (``--precision loop``, the default) is, per design parameter, what the world twin's maker
achieves for it at best in the loop's workflow (:func:`loop_precision`): a parameter the camera check measures (the
top camera; with jigs also the side camera, which reads the jigs' face tags) and the maker then corrects is left with
the check's move error (the world's ``fix_mm`` / ``fix_deg``), unless how the guide sets it is already finer (a jig's
0.2 mm: the check then asks for no move); every other parameter keeps the error of how the guide tells the maker to
set it (:func:`station.services.world.guide_sigma`, highlighted as in the loop: on a jig, with a ruler, by eye on the
sheet, guessed over its range when the guide does not state it). The guide is the layout's own, with the laser-cut
jigs (``--jigs yes``) or without (``no``; ``both``, the default, measures each). ``--precision flat`` is every
parameter at one error, 0.5 mm / 0.5 deg (a checked part), and the best layout also at 1 mm / 1 deg (by eye).

**The limits**: the best layout is measured again with each parameter alone placed exactly (the others at their
errors, the same placement draws), so the gain each would bring shows which parameters hold the bound down, and
how each is set says why they cannot be placed better.

The layouts: by default ``station optimize``'s service (the scenario's default budget unless ``--budget``) under the
known physics, its layout and verified runners-up (``--candidates``) scored with 16 simulations each, the best
measured again with ``--samples`` fresh simulations (default 64; a fresh measurement, so the choice's luck is not
counted). ``--scan N`` leaves the optimizer out (so its search is not what limits the bound): N layouts of a
scrambled Sobol design over the whole design space (seeded), with the scenario's own layouts (not with ``--precision
flat``, which measures as the 2026-12-04 results did) and (``--loop-database``) every layout ``bench_loop`` placed in
the same world, each scored with ``--scan-samples`` simulations at the
precision of the scenario's own layout's guide, and the best ``--scan-top`` whose guide the station can make measured
again with ``--samples`` simulations at the precision of their own guides, with every layout the loop placed and
(``--jigs both``) the best layout without jigs measured with jigs whatever their screening; the bound is the best of
those (a little generous: the best of a few noisy measurements).

Simulations go through the station's cache (``CHAOS_STATION_HOME`` moves it): a run stopped and started again
reuses every simulation it made. ``--out FILE`` appends each world's row as a JSON line.

Run: ``python -m bench.bench_loop_bound [--scenarios branching,longchain] [--seeds 1-5] [--budget N]
[--workers 2] [--scan 96] [--jigs both|yes|no] [--precision loop|flat] [--out rows.jsonl]`` or
``python -m bench loop_bound`` (BRANCHING, seeds 1-2, budget 200); ``--table rows.jsonl`` prints the table of the
rows stored there (no simulation).
"""

from __future__ import annotations

import argparse
import json
import math
import sqlite3
import tempfile
import time
from collections.abc import Sequence
from contextlib import closing
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.bench_loop import _seeds
from calibration.sim_runs import wilson_interval
from design.contraption.schema import ANGLE_KEYS
from drivers.sim.world import parse_world_options
from station.errors import ServiceError
from station.services.check_cameras import camera_names, check_views, reads_side
from station.services.loop import LoopSettings

POSITION_SIGMA_M, ANGLE_SIGMA_DEG = 0.0005, 0.5  # --precision flat: a checked and corrected placement
BY_EYE_SIGMA_M, BY_EYE_SIGMA_DEG = 0.001, 1.0  # --precision flat: a part the check does not measure, highlighted
#: The loop's cameras, as its attempts check with them (the side one, with jigs, faces the board).
LOOP_CAMERAS = LoopSettings()
PRECISIONS = ("loop", "flat")
JIGS = {"both": (False, True), "yes": (True,), "no": (False,)}


@dataclass(frozen=True)
class Precision:
    """Each design parameter's placement error (one standard deviation, m or deg) and how it is reached."""

    sigma: dict[str, float]
    how: dict[str, str]  #: per parameter: "check (top)", "check (side)", "jig", "ruler", "sheet", "guess", "flat"
    jigs: bool = False

    def exact(self, name: str) -> Precision:
        """The same with ``name`` placed exactly."""
        return Precision({**self.sigma, name: 0.0}, self.how, self.jigs)

    def words(self) -> str:
        return ", ".join(f"{n} {_amount(n, s)} ({self.how[n]})" for n, s in self.sigma.items())


def _is_angle(name: str) -> bool:
    return name.rsplit(".", 1)[-1] in ANGLE_KEYS


def _amount(name: str, sigma: float) -> str:
    return f"{sigma:.2g} deg" if _is_angle(name) else f"{sigma * 1000:.2g} mm"


def flat_precision(scenario, position_sigma_m: float = POSITION_SIGMA_M,
                   angle_sigma_deg: float = ANGLE_SIGMA_DEG) -> Precision:
    """Every parameter at one error (``--precision flat``)."""
    names = list(scenario.design_space.names)
    return Precision({n: angle_sigma_deg if _is_angle(n) else position_sigma_m for n in names},
                     dict.fromkeys(names, "flat"))


def guide_job(scenario, x: np.ndarray | None, *, jigs: bool):
    """The guide the loop makes for layout ``x`` (None: the scenario's own layout), with its jigs or without."""
    from station.services.guide import GuideRequest, make_guide

    with tempfile.TemporaryDirectory() as folder:
        layout = None
        if x is not None:
            layout = str(Path(folder) / "LAYOUT.json")
            Path(layout).write_text(json.dumps({"x": [float(v) for v in x]}), encoding="utf-8")
        # the tolerance map changes no set_with and no tag: left out, it costs seconds per layout
        return make_guide(GuideRequest(scenario.source, layout, jigs=True if jigs else None, tolerances=False))


def checked_by(job, *, jigs: bool, seed: int = 0) -> dict[str, str]:
    """``{parameter: "top" | "side"}``: what the loop's camera check measures of ``job``'s parts, placed as
    designed: the top camera's frame, and with jigs the side camera's (the jigs' face tags), through the loop's own
    check (:func:`station.services.check_cameras.check_views`'s ``measured_by``)."""
    cameras = camera_names([LOOP_CAMERAS.camera])
    if jigs and reads_side(job):
        cameras = camera_names([LOOP_CAMERAS.camera, LOOP_CAMERAS.side_camera])
    return dict(check_views(job, cameras, seed=seed, station_cameras=False).report.measured_by)


def loop_precision(scenario, x: np.ndarray | None, *, jigs: bool, world: str = "sim://world") -> Precision:
    """What the loop's maker achieves per parameter at best for layout ``x`` (None: the scenario's own) in
    ``world`` (its URL options: ``fix_mm``, ``fix_deg``): a parameter the check measures at the check's move error
    or how the guide sets it, whichever is finer (a finer one is within tolerance: the check moves nothing); every
    other one as the guide sets it (:func:`station.services.world.guide_sigma`, highlighted as in the loop)."""
    from station.services.world import guide_sigma

    job = guide_job(scenario, x, jigs=jigs)
    set_sigma = guide_sigma(job.guide, scenario, highlighted=True)
    set_with = {q.name: q.set_with for part in job.guide.parts for q in part.settings}
    for by_hand in job.jigs.plan.by_hand if job.jigs is not None else ():  # the plan says why it made no jig
        for part in job.guide.parts:
            if part.name == by_hand.part:
                set_with.update({q.name: f"{q.set_with}, no jig: {by_hand.reason}" for q in part.settings
                                 if q.set_with != "jig"})
    measured = checked_by(job, jigs=jigs)
    options = parse_world_options(world)
    sigma, how = {}, {}
    for name in scenario.design_space.names:
        sigma[name], how[name] = float(set_sigma[name]), set_with.get(name, "guess")
        fix = options["fix_deg"] if _is_angle(name) else options["fix_mm"] / 1000.0
        if name in measured and fix < sigma[name]:
            sigma[name], how[name] = float(fix), f"check ({measured[name]})"
        elif how[name] == "check" and name not in measured:  # the guide counts on a check that sees nothing of it
            how[name] = "check, not measured: by eye"
    return Precision(sigma, how, jigs)


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


def _success(known, hidden, run, x: np.ndarray, n: int, draw_seed: int, precision: Precision):
    """The success of layout ``x`` over ``n`` simulations under the world's physics (no material draws), each
    parameter placed with ``precision``'s error."""
    from calibration.sim_predict import predict_success

    names = tuple(known.design_space.names)
    return predict_success(known, x, values=hidden, unmeasured=names, set_sigma=precision.sigma, samples=n,
                           seed=draw_seed, run=run)


def _precision_of(kind: str, scenario, x, jigs: bool) -> Precision:
    return flat_precision(scenario) if kind == "flat" else loop_precision(scenario, x, jigs=jigs)


def _limits(known, hidden, run, x, samples: int, precision: Precision, bound: float) -> dict[str, dict]:
    """Per parameter placed with an error: the success with it alone placed exactly (the same draws, seed 7)."""
    limits = {}
    for name, sigma in precision.sigma.items():
        if sigma > 0:
            measured = _success(known, hidden, run, x, samples, 7, precision.exact(name))
            limits[name] = {"exact": measured.probability, "gain": measured.probability - bound,
                            "sigma": sigma, "how": precision.how[name]}
    return limits


def _measured_row(seed, known, hidden, run, layouts, scores, precisions, samples, *, limits: bool) -> dict:
    """The best of ``layouts`` by ``scores`` measured again with ``samples`` simulations at its own precision."""
    best = int(np.argmax(scores))
    measured = _success(known, hidden, run, layouts[best], samples, 7, precisions[best])
    row = {"seed": seed, "best": best, "success": measured.probability, "interval": list(measured.interval),
           "successes": measured.successes, "samples": samples, "events": dict(measured.events), "hidden": hidden,
           "layout": dict(zip(known.design_space.names, map(float, layouts[best]))),
           "sigma": precisions[best].sigma, "how": precisions[best].how, "jigs": precisions[best].jigs}
    if limits:
        row["limits"] = _limits(known, hidden, run, layouts[best], samples, precisions[best], measured.probability)
    return row


def world_bound(name: str, seed: int, *, budget: int | None, candidates: int, samples: int, workers: int,
                precision: str = "loop", jigs: bool = False, limits: bool = True) -> dict:
    """The best optimizer candidate's success in world ``seed`` with its physics known: ``{"seed", "hidden",
    "candidates", "best", "success", "interval", "events", "budget", "layout", "sigma", "how", "jigs",
    "limits"}``."""
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
    precisions = [_precision_of(precision, scenario, x, jigs) for x in layouts]
    with station_runner(workers=workers) as run:  # one pool for every layout: a pool per layout costs seconds
        scores = [_success(known, hidden, run, x, 16, 1, p).probability for x, p in zip(layouts, precisions)]
        row = _measured_row(seed, known, hidden, run, layouts, scores, precisions, samples, limits=limits)
    return {**row, "budget": budget, "candidates": scores}


def loop_layouts(database: str, scenario, seed: int) -> list[np.ndarray]:
    """Every layout ``bench_loop`` placed for ``scenario`` in world ``seed`` (any settings), from its database
    (opened read-only)."""
    from design.contraption.layout_io import layout_from_data

    with closing(sqlite3.connect(f"file:{database}?mode=ro", uri=True)) as connection:
        rows = connection.execute("SELECT l.layout FROM loop_loops l JOIN loop_runs r ON r.id = l.run_id "
                                  "WHERE r.scenario_name = ? AND r.world = ? ORDER BY r.id, l.loop_number",
                                  (scenario.name, f"sim://world?seed={seed}")).fetchall()
    layouts: list[np.ndarray] = []
    for (text,) in rows:
        x = np.asarray(layout_from_data(json.loads(text), scenario, file=database).x, dtype=float)
        if not any(np.allclose(x, y) for y in layouts):
            layouts.append(x)
    return layouts


def world_scan(name: str, seed: int, *, layouts: int, scan_samples: int, top: int, samples: int, workers: int,
               precision: str = "loop", jigs: bool = False, limits: bool = True,
               loop_database: str | None = None, carried: Sequence[np.ndarray] = ()) -> dict:
    """The best of a Sobol design's ``layouts``, the scenario's own layouts, (``loop_database``) those the loop
    placed in world ``seed`` and the ``carried`` ones (another precision's best in this world), with its physics
    known (:func:`world_bound`'s keys; ``"budget"`` is the simulations spent, ``"candidates"`` the measured layouts'
    fresh measurements, ``"by_eye"`` with ``precision`` flat). The loop's and the carried layouts are measured
    whatever their screening: the bound is never under what a layout the loop placed allows."""
    from scipy.stats import qmc

    from station.services.sim_calibration import station_runner

    scenario, hidden, known = _known_world(name, seed)
    space = known.design_space
    lower, upper = np.asarray(space.lower, dtype=float), np.asarray(space.upper, dtype=float)
    scanned = lower + qmc.Sobol(d=len(lower), scramble=True, seed=seed).random(layouts) * (upper - lower)
    own = [] if precision == "flat" else [np.asarray(x, dtype=float) for x in scenario.layouts.values()]
    kept: list[np.ndarray] = []
    for x in [*(loop_layouts(loop_database, known, seed) if loop_database else []), *carried]:
        if not any(np.allclose(x, y) for y in kept):
            kept.append(np.asarray(x, dtype=float))
    sources = ["scanned"] * layouts + ["the scenario's"] * len(own) + ["the loop's or carried"] * len(kept)
    xs = np.vstack([scanned, *own, *kept])
    must = list(range(layouts + len(own), len(xs)))
    screening = _precision_of(precision, scenario, None, jigs)
    with station_runner(workers=workers) as run:
        screened = np.array([_success(known, hidden, run, x, scan_samples, 1, screening).probability for x in xs])
        # best screened first; among equal scores the scenario's own layouts before the scanned ones
        ranked = sorted((i for i in range(len(xs)) if i not in must), key=lambda i: (-screened[i], i < layouts, i))
        order, precisions, unguided, best_screened = [], [], [], 0
        for i in [*must, *ranked]:  # the must-measure ones, then the best screened whose guide the station can make
            if i not in must and best_screened == top:
                break
            try:
                precisions.append(_precision_of(precision, scenario, xs[i], jigs))
                order.append(i)
                best_screened += i not in must
            except ServiceError as error:  # no guide: the loop cannot place it either
                unguided.append({"layout": dict(zip(space.names, map(float, xs[i]))), "error": str(error)})
        measured = [_success(known, hidden, run, xs[i], samples, 7, p) for i, p in zip(order, precisions)]
        scores = [m.probability for m in measured]
        row = _measured_row(seed, known, hidden, run, [xs[i] for i in order], scores, precisions, samples,
                            limits=limits)
        best = order[row["best"]]
        row.update(budget=len(xs) * scan_samples + len(order) * samples, candidates=scores, unguided=unguided,
                   given=len(own) + len(kept), screened=float(screened[best]), best=best, chosen=sources[best])
        if precision == "flat":
            by_eye = _success(known, hidden, run, xs[row["best"]], samples, 11,
                              flat_precision(scenario, BY_EYE_SIGMA_M, BY_EYE_SIGMA_DEG))
            row.update(by_eye=by_eye.probability, by_eye_interval=list(by_eye.interval))
    return row


def limiting(rows: list[dict], *, least_gain: float = 0.02) -> list[tuple[str, float, str, str]]:
    """The parameters that hold the bound down over ``rows`` (one scenario's worlds, one precision): ``(name, mean
    gain when placed exactly, its error in words, how it is set)``, largest gain first, those gaining at least
    ``least_gain``."""
    gains: dict[str, list[float]] = {}
    info: dict[str, tuple[str, str]] = {}
    for row in rows:
        for name, limit in row.get("limits", {}).items():
            gains.setdefault(name, []).append(limit["gain"])
            info[name] = (_amount(name, limit["sigma"]), limit["how"])
    means = [(name, float(np.mean(g)), *info[name]) for name, g in gains.items()]
    return sorted((m for m in means if m[1] >= least_gain), key=lambda m: -m[1])


def pooled(rows: list[dict]) -> tuple[float, tuple[float, float]]:
    """The bound over ``rows``' worlds: their successes pooled, with Wilson's 95 % interval."""
    k = sum(int(r["successes"]) for r in rows)
    n = sum(int(r["samples"]) for r in rows)
    return (k / n if n else math.nan), wilson_interval(k, n)


def _world_lines(name: str, row: dict, scan: bool, seconds: float) -> list[str]:
    weakest = sorted(row["events"].items(), key=lambda item: item[1])[:2]
    jigs = "with jigs" if row["jigs"] else "without jigs"
    lines = [f"  {name} world {row['seed']} {jigs}: best of {len(row['candidates'])} "
             f"{'measured layouts' if scan else 'candidates'} {row['success']:.2f} "
             f"[{row['interval'][0]:.2f}, {row['interval'][1]:.2f}] (budget {row['budget']}; weakest events "
             f"{', '.join(f'{e} {p:.2f}' for e, p in weakest)}; {seconds:.0f} s)",
             f"    its layout {', '.join(f'{k} {v:.4g}' for k, v in row['layout'].items())}"
             + (f" ({row['chosen']}, screened {row['screened']:.2f})" if "screened" in row else "")
             + f"; the top {len(row['candidates'])} again: {', '.join(f'{c:.2f}' for c in row['candidates'])}",
             "    placed with " + Precision(row["sigma"], row["how"]).words()]
    for skipped in row.get("unguided", []):
        lines.append(f"    no guide for layout {', '.join(f'{k} {v:.4g}' for k, v in skipped['layout'].items())}: "
                     f"{skipped['error'][:120]}")
    if row.get("limits"):
        lines.append("    each placed exactly: " + ", ".join(
            f"{n} {lim['exact']:.2f} ({lim['gain']:+.2f})" for n, lim in row["limits"].items()))
    if "by_eye" in row:
        lines.append(f"    placed by eye ({BY_EYE_SIGMA_M * 1000:g} mm / {BY_EYE_SIGMA_DEG:g} deg) "
                     f"{row['by_eye']:.2f} [{row['by_eye_interval'][0]:.2f}, {row['by_eye_interval'][1]:.2f}]")
    return lines


def print_table(table: list[tuple[str, bool | None, list[dict]]]) -> None:
    """The markdown table of ``(scenario, jigs (None: flat precision), rows)``."""
    print("| scenario | jigs | success with the physics known, per world | pooled (95 % interval) | worlds >= 0.90 "
          "| held down by (mean gain placed exactly) |")
    print("|---|---|---|---|---|---|")
    for name, jigs, rows in table:
        bound, (low, high) = pooled(rows)
        held = "; ".join(f"{n} {g:+.2f} ({amount}, {how})" for n, g, amount, how in limiting(rows)) or "-"
        per_world = " / ".join(f"{r['seed']}: {r['success']:.2f}" for r in rows)
        print(f"| {name} | {'flat' if jigs is None else 'yes' if jigs else 'no'} | {per_world} | {bound:.2f} "
              f"[{low:.2f}, {high:.2f}] | {sum(r['success'] >= 0.9 for r in rows)}/{len(rows)} | {held} |")
        if rows and "by_eye" in rows[0]:
            by_eye = [r["by_eye"] for r in rows]
            print(f"| {name}, placed by eye | flat | {' / '.join(f'{b:.2f}' for b in by_eye)} | "
                  f"{np.mean(by_eye):.2f} | {sum(b >= 0.9 for b in by_eye)}/{len(by_eye)} | - |")


def flat_row(row: dict) -> bool:
    """Whether an ``--out`` row was measured at ``--precision flat``: its ``"precision"`` label, or for a row whose
    ``"precision"`` is no label (the per-parameter errors), every parameter's ``"how"`` being ``"flat"``."""
    label = row.get("precision")
    return label == "flat" if isinstance(label, str) else set(row.get("how", {}).values()) == {"flat"}


def stored_table(path: str) -> list[tuple[str, bool | None, list[dict]]]:
    """The rows ``--out`` appended to ``path``, per scenario and precision (a world measured again: its last row)."""
    rows: dict[tuple, dict] = {}
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        if line.strip():
            row = json.loads(line)
            jigs = None if flat_row(row) else bool(row["jigs"])
            rows[(row["scenario"], jigs, row["seed"])] = row
    table: dict[tuple, list[dict]] = {}
    for (name, jigs, _), row in sorted(rows.items(), key=lambda item: (item[0][0], item[0][1] is True, item[0][2])):
        table.setdefault((name, jigs), []).append(row)
    return [(name, jigs, found) for (name, jigs), found in table.items()]


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
    parser.add_argument("--precision", choices=PRECISIONS, default="loop",
                        help="loop: each parameter as the loop's maker sets it at best; flat: 0.5 mm / 0.5 deg")
    parser.add_argument("--jigs", choices=tuple(JIGS), default="both",
                        help="the loop's guide with its laser-cut jigs, without, or both (--precision loop)")
    parser.add_argument("--no-limits", action="store_true",
                        help="skip measuring the best layout with each parameter placed exactly")
    parser.add_argument("--loop-database", default=None,
                        help="also measure the layouts bench_loop placed in the same worlds (its database; --scan)")
    parser.add_argument("--out", default=None, help="append each world's row to this file (JSON lines)")
    parser.add_argument("--table", default=None, help="only print the table of the rows --out wrote to this file")
    args = parser.parse_args([] if argv is None else argv)
    if args.table:
        try:
            table = stored_table(args.table)
        except (OSError, ValueError, KeyError) as error:
            print(f"bench_loop_bound: --table {args.table}: expected the JSON lines --out writes ({error})")
            return 2
        print_table(table)
        return 0
    if argv is None:  # python -m bench: a small version
        args.scenarios, args.seeds, args.budget, args.jigs = "branching", "1-2", 200, "no"
    names = [s.strip() for s in args.scenarios.split(",") if s.strip()]
    modes = JIGS[args.jigs] if args.precision == "loop" else (False,)
    search = (f"a scan of {args.scan} Sobol layouts ({args.scan_samples} simulations each), the best "
              f"{args.scan_top} measured again" if args.scan else
              f"budget {args.budget or 'the scenario default'}, {args.candidates} candidates")
    placement = (f"placement {POSITION_SIGMA_M * 1000:g} mm / {ANGLE_SIGMA_DEG:g} deg" if args.precision == "flat"
                 else "placement as the loop's maker sets each parameter at best "
                      f"({' and '.join('with jigs' if j else 'without jigs' for j in modes)})")
    print(f"bench_loop_bound: {', '.join(names)} over world seeds {args.seeds}; {search}, {args.samples} "
          f"simulations for the best, {placement}", flush=True)
    table = []
    for name in names:
        best_without: dict[int, np.ndarray] = {}  # per world: the best layout without jigs, measured with them too
        for jigs in modes:
            rows = []
            for seed in _seeds(args.seeds):
                started = time.perf_counter()
                common = {"samples": args.samples, "workers": args.workers, "precision": args.precision,
                          "jigs": jigs, "limits": not args.no_limits}
                if args.scan:
                    row = world_scan(name, seed, layouts=args.scan, scan_samples=args.scan_samples,
                                     top=args.scan_top, loop_database=args.loop_database,
                                     carried=[best_without[seed]] if jigs and seed in best_without else [],
                                     **common)
                    if not jigs:
                        best_without[seed] = np.array(list(row["layout"].values()), dtype=float)
                else:
                    row = world_bound(name, seed, budget=args.budget, candidates=args.candidates, **common)
                print("\n".join(_world_lines(name, row, bool(args.scan), time.perf_counter() - started)),
                      flush=True)
                if args.out:
                    with open(args.out, "a", encoding="utf-8") as out:
                        out.write(json.dumps({"scenario": name, "precision": args.precision, "scan": args.scan,
                                              "scan_samples": args.scan_samples, "scan_top": args.scan_top,
                                              **row}) + "\n")
                rows.append(row)
            table.append((name, jigs, rows))
    print_table([(name, None if args.precision == "flat" else jigs, rows) for name, jigs, rows in table])
    return 0


if __name__ == "__main__":
    raise SystemExit(main(__import__("sys").argv[1:]))
