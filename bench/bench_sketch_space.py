"""Sketch retrieval over each machine's whole design space: hit rates on held-out maker-like sketches.

Run with ``.venv/bin/python -m bench sketch_space``. The sets are made by :mod:`bench.sketch_space` (designs uniform
over each machine's feasible space, radii up to 10; hand-drawn strokes): the tuning set (seed
:data:`~bench.sketch_space.TUNING_SEED`) and the held-out evaluation set (seed
:data:`~bench.sketch_space.EVALUATION_SEED`). Databases are built afresh in a temporary folder, so their build time
is measured. Queries use the station's default options (:class:`station.services.sketch.RetrieveOptions`).

Environment: ``SKETCH_SPACE_CASES`` (sketches per machine and set, default 40), ``SKETCH_SPACE_SETS``
(``evaluation,tuning`` by default).
"""

from __future__ import annotations

import os
import tempfile
import time

import numpy as np

from bench.sketch_space import (
    EVALUATION_SEED,
    HIT_DISTANCE,
    STRICT_DISTANCE,
    TUNING_SEED,
    closest_shape,
    is_hit,
    space_set,
)

MACHINES = ("spirograph", "elliptic_spirograph", "cycloid_drawing_machine", "hoot_nanny")


def evaluate(retriever, alone, cases, options) -> dict[str, dict[str, list]]:
    """Per machine: pattern hits, radii hits, hits (either) with the machine given (``alone``: a retriever per
    machine); true machine in the top 5 and hits without it; query times over all four machines."""
    from station.services.sketch import retrieve

    keys = ("pattern", "strict", "radii", "hit", "machine", "any_hit", "seconds", "given_seconds")
    rows: dict[str, dict[str, list]] = {n: {k: [] for k in keys} for n in MACHINES}
    for case in cases:
        row = rows[case.machine]
        begin = time.perf_counter()
        given = retrieve(case.sketch, options, retriever=alone[case.machine])
        row["given_seconds"].append(time.perf_counter() - begin)
        pattern, radii = is_hit(case, given.candidates)
        row["pattern"].append(pattern)
        row["strict"].append(closest_shape(case, given.candidates) <= STRICT_DISTANCE)
        row["radii"].append(radii)
        row["hit"].append(pattern or radii)
        begin = time.perf_counter()
        blind = retrieve(case.sketch, options, retriever=retriever)
        row["seconds"].append(time.perf_counter() - begin)
        row["machine"].append(any(c.machine == case.machine for c in blind.candidates[:5]))
        row["any_hit"].append(any(is_hit(case, blind.candidates)))
    return rows


def print_table(title: str, rows: dict[str, dict[str, list]]) -> None:
    print(f"  {title}: hits among the top 5 (pattern within {HIT_DISTANCE} shape distance, or the true radii; "
          f"'strict': within {STRICT_DISTANCE}); blind: the machine not given")
    print(f"    {'machine':24s} {'n':>3s} {'pattern':>8s} {'strict':>8s} {'radii':>8s} {'hit':>8s} {'| blind:':>9s} "
          f"{'machine':>8s} {'hit':>6s} {'query s':>8s}")
    for name in MACHINES:
        row = rows[name]
        n = len(row["hit"])
        if not n:
            continue
        pct = {k: 100 * np.mean(row[k]) for k in ("pattern", "strict", "radii", "hit", "machine", "any_hit")}
        flag = "" if pct["hit"] >= 90 else "  BELOW 90%"
        print(f"    {name:24s} {n:3d} {pct['pattern']:7.1f}% {pct['strict']:7.1f}% {pct['radii']:7.1f}% "
              f"{pct['hit']:7.1f}% {'|':>9s} "
              f"{pct['machine']:7.1f}% {pct['any_hit']:5.1f}% {np.median(row['seconds']):8.3f}{flag}")
    seconds = np.concatenate([rows[n]["seconds"] for n in MACHINES])
    print(f"    query over all four machines: median {np.median(seconds):.3f} s, 90th percentile "
          f"{np.percentile(seconds, 90):.3f} s, max {seconds.max():.3f} s")


def main() -> None:
    from design.sketch.retrieval import SketchRetriever
    from station.services.sketch import RetrieveOptions

    per_machine = int(os.environ.get("SKETCH_SPACE_CASES", "40"))
    sets = os.environ.get("SKETCH_SPACE_SETS", "evaluation,tuning").split(",")
    options = RetrieveOptions()
    print(f"options: {options}; load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    with tempfile.TemporaryDirectory() as cache:
        retriever = SketchRetriever(MACHINES, cache_dir=cache)
        print("candidate databases, built afresh")
        total = 0.0
        for name in MACHINES:
            begin = time.perf_counter()
            database = retriever.database(name)
            seconds = time.perf_counter() - begin
            total += seconds
            print(f"    {name:24s} {len(database):7d} designs, {len(database.combinations()):4d} radii "
                  f"combinations, {seconds:5.1f} s")
        print(f"    all four built in {total:.1f} s (load average now {os.getloadavg()[0]:.2f})")
        begin = time.perf_counter()
        SketchRetriever(MACHINES, cache_dir=cache).load_all()
        print(f"    all four loaded from the cache in {time.perf_counter() - begin:.2f} s")
        alone = {name: SketchRetriever([name], cache_dir=cache) for name in MACHINES}
        for single in alone.values():
            single.load_all()
        for which in sets:
            seed = {"evaluation": EVALUATION_SEED, "tuning": TUNING_SEED}[which.strip()]
            cases = space_set(MACHINES, per_machine, seed)
            sectors = sum(c.sector for c in cases)
            print(f"{which} set (seed {seed}): {len(cases)} sketches, {sectors} drawn as one sector with --symmetry")
            print_table(which, evaluate(retriever, alone, cases, options))
