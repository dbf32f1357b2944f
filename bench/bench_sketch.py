"""Sketch retrieval benchmark (thesis 3.4, Table 3.1): stroke ordering, distance timings, hit rates, query time.

Run with ``.venv/bin/python -m bench sketch``. Environment: ``SKETCH_BENCH_CASES`` (cases per machine, default 40),
``SKETCH_BENCH_SEED`` (default 2026). Candidate databases are cached in the station's cache directory, so the
first run also builds them (about two minutes on 2 cores) and later runs only load them.
"""

from __future__ import annotations

import math
import os
import time

import numpy as np

from common.progress import Reporter
from design.machines import get_machine
from design.sketch.candidates import radius_roles
from design.sketch.distance import SpectrumBank, low_spectrum, procrustes_distance_direct
from design.sketch.ordering import EXACT_MAX_STROKES, order_strokes
from design.sketch.retrieval import SketchRetriever
from design.sketch.synthetic import SyntheticCase, make_case

MACHINES = ("spirograph", "elliptic_spirograph", "cycloid_drawing_machine", "hoot_nanny")


def benchmark_set(retriever: SketchRetriever, cases_per_machine: int, seed: int) -> list[SyntheticCase]:
    """The seeded benchmark set: for each machine, random radii among its database's combinations."""
    rng = np.random.default_rng(seed)
    cases = []
    for name in retriever.machine_names:
        machine = get_machine(name)
        combos = retriever.database(name).combinations()
        roles = radius_roles(machine)
        made = 0
        while made < cases_per_machine:
            combo = [int(r) for r in combos[rng.integers(len(combos))]]
            # the pattern's symmetry order: the leading radius over its gcd with the others' lcm (a Hoot-Nanny
            # 6 / 4 / 3 has none)
            symmetry = combo[0] // math.gcd(combo[0], math.lcm(*combo[1:]))
            case = make_case(machine, dict(zip(roles, combo)), rng, symmetry=symmetry)
            if case is not None:
                cases.append(case)
                made += 1
    return cases


def bench_ordering(rng: np.random.Generator) -> None:
    print("stroke ordering (exact MILP with lazy subtour cuts vs 2-opt/Or-opt heuristic), median of 3 random sets")
    print(f"  {'strokes':>7} {'exact s':>9} {'heur. s':>9} {'heur./exact gap':>16}")
    for n in (4, 8, 16, 24, 32, 48, 64):
        exact_times, heuristic_times, ratios = [], [], []
        for _ in range(3):
            strokes = [rng.random((2, 2)) for _ in range(n)]
            start = time.perf_counter()
            exact = order_strokes(strokes, method="exact", time_limit=20.0)
            exact_times.append(time.perf_counter() - start)
            start = time.perf_counter()
            heuristic = order_strokes(strokes, method="heuristic")
            heuristic_times.append(time.perf_counter() - start)
            ratios.append(heuristic.gap_length / max(exact.gap_length, 1e-12))
        print(f"  {n:7d} {np.median(exact_times):9.3f} {np.median(heuristic_times):9.3f} {np.median(ratios):16.3f}")
    print(f"  (auto uses the exact MILP up to {EXACT_MAX_STROKES} strokes)")


def bench_distance(rng: np.random.Generator) -> None:
    print("curve distance (symmetric Procrustes, both directions, all start points)")
    machine = get_machine("spirograph")
    rows = [{"r_f": 7, "r_r": 3, "d": d} for d in np.linspace(0.2, 2.9, 1000)]
    curves = machine.sample_many(rows, n=1025, spacing="arclength")[:, :-1]
    query = curves[417] + rng.normal(0, 0.01, curves[417].shape)
    start = time.perf_counter()
    for i in range(100):
        procrustes_distance_direct(query, curves[i : i + 1])
    one = (time.perf_counter() - start) / 100
    start = time.perf_counter()
    procrustes_distance_direct(query, curves)
    batch = (time.perf_counter() - start) / len(curves)
    bank = SpectrumBank(low_spectrum(curves))
    q = low_spectrum(query)
    bank.match(q)
    start = time.perf_counter()
    for _ in range(5):
        bank.match(q)
    banked = (time.perf_counter() - start) / 5 / len(curves)
    print(f"  1024 points, one candidate at a time:   {1e3 * one:8.4f} ms per candidate (thesis: 0.7 ms)")
    print(
        f"  1024 points, 1000 candidates batched:   {1e3 * batch:8.4f} ms per candidate ({0.7e-3 / batch:.0f}x thesis)"
    )
    print(
        f"  spectrum bank, K={bank.harmonics} harmonics, {bank.shifts} shifts: {1e3 * banked:8.4f} ms per candidate "
        f"({0.7e-3 / banked:.0f}x thesis)"
    )


def main() -> None:
    from station.commands.sketch import describe_progress
    from station.paths import cache_dir
    from station.progress_view import ProgressView

    cases_per_machine = int(os.environ.get("SKETCH_BENCH_CASES", "40"))
    seed = int(os.environ.get("SKETCH_BENCH_SEED", "2026"))
    rng = np.random.default_rng(seed)
    bench_ordering(rng)
    bench_distance(rng)

    report = Reporter(ProgressView(describe=describe_progress))
    retriever = SketchRetriever(MACHINES, cache_dir=cache_dir(), report=report)
    print("candidate databases (Farey radii x feasible grid, 4 values per continuous parameter)")
    for name in MACHINES:
        start = time.perf_counter()
        database = retriever.database(name)
        seconds = time.perf_counter() - start
        print(
            f"  {name:24s} {len(database):6d} designs, {len(database.combinations()):3d} radii combinations, "
            f"built in {database.build_seconds:5.1f} s, loaded in {seconds:5.2f} s"
        )
    start = time.perf_counter()
    SketchRetriever(MACHINES, cache_dir=cache_dir()).load_all()
    print(f"  all four loaded from the cache in {time.perf_counter() - start:.2f} s")

    cases = benchmark_set(retriever, cases_per_machine, seed)
    print(
        f"benchmark set: {len(cases)} sketches (seed {seed}): noise, uneven subsampling, 1-4 strokes with gaps, "
        f"{sum(c.sector for c in cases)} drawn as one symmetric sector with k given; "
        f"{sum(c.rejected for c in cases)} near-circle designs (detail < 2 %, radii not identifiable) drawn again"
    )
    modes = {"pruned": {"prune": True}, "unpruned": {"prune": False}, "pruned+refine3": {"prune": True, "refine": 3}}
    for mode, options in modes.items():
        hits: dict[str, list[bool]] = {n: [] for n in MACHINES}
        firsts: dict[str, list[bool]] = {n: [] for n in MACHINES}
        times = []
        compared = []
        stages: dict[str, int] = {}
        for case in cases:
            result = retriever.query(case.sketch, top=5, **options)
            times.append(result.timings["total"])
            compared.append(sum(r.candidates_compared for r in result.reports))
            for report in result.reports:
                if report.machine == case.machine:
                    stages[report.stage] = stages.get(report.stage, 0) + 1
            found = [(c.machine, c.radii) for c in result.candidates]
            hits[case.machine].append((case.machine, case.radii) in found)
            firsts[case.machine].append(bool(found) and found[0] == (case.machine, case.radii))
        print(f"  {mode}: true machine and radii in the top 5 (top 1)")
        for name in MACHINES:
            rate = np.mean(hits[name]) if hits[name] else float("nan")
            top1 = np.mean(firsts[name]) if firsts[name] else float("nan")
            flag = "ok" if rate >= 0.9 else "BELOW 90%"
            print(f"    {name:24s} {100 * rate:5.1f} % ({100 * top1:5.1f} %) of {len(hits[name])}  {flag}")
        print(
            f"    query time over all four machines: median {np.median(times):.3f} s, 90th percentile "
            f"{np.percentile(times, 90):.3f} s, max {np.max(times):.3f} s; candidates compared: median "
            f"{int(np.median(compared))} of {sum(len(retriever.database(n)) for n in MACHINES)}"
        )
        if options.get("prune"):
            print(f"    candidates of the true machine ranked from: {stages}")
