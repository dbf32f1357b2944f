"""The acceptance benchmark in small (slow: builds the default databases, ~15 s, and runs 24 queries)."""

from __future__ import annotations

import importlib

import pytest

from design.sketch import SketchRetriever

MACHINES = ("spirograph", "elliptic_spirograph", "cycloid_drawing_machine", "hoot_nanny")


@pytest.mark.slow
def test_true_design_in_top_five_on_a_small_seeded_set(tmp_path):
    bench = importlib.import_module("bench.bench_sketch")
    retriever = SketchRetriever(MACHINES, cache_dir=tmp_path)
    cases = bench.benchmark_set(retriever, 6, seed=11)
    hits: dict[str, int] = dict.fromkeys(MACHINES, 0)
    for case in cases:
        found = [(c.machine, c.radii) for c in retriever.query(case.sketch, top=5).candidates]
        hits[case.machine] += (case.machine, case.radii) in found
    assert all(count >= 5 for count in hits.values()), hits
