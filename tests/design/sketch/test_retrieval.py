"""Candidate database (Farey radii, feasible grid, cache with version key) and the retrieval pipeline."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import design.sketch.candidates as candidates_module
from design.machines import get_machine
from design.sketch import SketchRetriever, load_sketch, make_sketch
from design.sketch.candidates import (
    DatabaseSettings,
    cache_path,
    farey,
    feasible_grid,
    load_database,
    radius_combinations,
    radius_roles,
    version_key,
)
from design.sketch.errors import RetrievalSettingError
from design.sketch.retrieval import curve_distance, refine_candidate
from design.sketch.synthetic import make_case

EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "sketches"

#: Small databases so that the tests build them in about two seconds.
SMALL = {
    "spirograph": DatabaseSettings(max_radius=7, values_per_dimension=3, harmonics=48, points=256),
    "elliptic_spirograph": DatabaseSettings(max_radius=4, values_per_dimension=2, harmonics=48, points=256),
    "cycloid_drawing_machine": DatabaseSettings(max_radius=4, values_per_dimension=2, harmonics=48, points=256),
    "hoot_nanny": DatabaseSettings(max_radius=7, max_other_radius=3, values_per_dimension=2, harmonics=48, points=256),
}


@pytest.fixture(scope="module")
def retriever(tmp_path_factory):
    cache = tmp_path_factory.mktemp("sketch-cache")
    instance = SketchRetriever(list(SMALL), cache_dir=cache, settings=SMALL)
    instance.load_all()
    return instance


def test_farey_sequence():
    assert farey(5) == [(1, 5), (1, 4), (1, 3), (2, 5), (1, 2), (3, 5), (2, 3), (3, 4), (4, 5), (1, 1)]
    assert len(farey(7)) == 1 + sum(1 for b in range(1, 8) for a in range(1, b + 1) if math.gcd(a, b) == 1) - 1


def test_radius_combinations_are_coprime_and_in_role_order():
    spiro = get_machine("spirograph")
    assert radius_roles(spiro) == ("r_f", "r_r")
    combos = radius_combinations(spiro, 6)
    assert (5, 3) in combos and (3, 5) in combos and (4, 2) not in combos
    assert all(math.gcd(*c) == 1 for c in combos)
    hoot = get_machine("hoot_nanny")
    assert radius_roles(hoot)[0] == hoot.symmetry_gear
    triples = radius_combinations(hoot, 7, max_other_radius=3)
    # A.62: the three radii share no divisor as a whole; a pair may (6 / 2 / 3 draws its own pattern)
    assert triples and all(math.gcd(*t) == 1 for t in triples)
    assert (6, 2, 3) in triples and (6, 2, 2) not in triples
    assert all(max(t[1:]) <= 3 for t in triples)


def test_feasible_grid_points_are_all_feasible():
    machine = get_machine("cycloid_drawing_machine")
    grid = feasible_grid(machine, machine.defaults(), 3)
    assert len(grid) == 3 ** len(machine.continuous_names)
    assert all(machine.is_feasible(point) for point in grid)
    values = {round(p["d_tf"], 9) for p in grid}
    assert len(values) == 3


def test_database_is_cached_under_a_version_key(tmp_path, monkeypatch):
    machine = get_machine("spirograph")
    settings = SMALL["spirograph"]
    first = load_database(machine, tmp_path, settings)
    path = cache_path(tmp_path, machine.name, version_key(machine, settings))
    assert path.exists()

    def no_build(*args, **kwargs):
        raise AssertionError("the cached database should have been loaded")

    monkeypatch.setattr(candidates_module, "build_database", no_build)
    second = load_database(machine, tmp_path, settings)
    assert np.array_equal(first.params, second.params)
    assert np.array_equal(first.bank.spectra, second.bank.spectra)
    monkeypatch.undo()
    # other settings (or a changed model) give another key, and the stale file is replaced
    other = DatabaseSettings(max_radius=5, values_per_dimension=2, harmonics=48, points=256)
    assert version_key(machine, other) != version_key(machine, settings)
    load_database(machine, tmp_path, other)
    assert not path.exists()
    # a damaged cache file is rebuilt, not an error
    damaged = cache_path(tmp_path, machine.name, version_key(machine, other))
    damaged.write_bytes(b"not a database")
    assert len(load_database(machine, tmp_path, other)) > 0


def test_bad_database_settings():
    with pytest.raises(RetrievalSettingError, match="values_per_dimension"):
        DatabaseSettings(values_per_dimension=0)
    with pytest.raises(RetrievalSettingError, match="harmonics"):
        DatabaseSettings(points=128, harmonics=100)


def test_database_rows_are_feasible_and_match_their_radii(retriever):
    for name in SMALL:
        database = retriever.database(name)
        machine = get_machine(name)
        rows = np.random.default_rng(0).choice(len(database), size=min(10, len(database)), replace=False)
        for row in rows:
            design = database.design(int(row))
            assert machine.is_feasible(design), (name, design)
            assert tuple(design[r] for r in database.roles) == tuple(database.radii[row])


@pytest.mark.parametrize(("radii", "seed"), [((5, 2), 0), ((7, 3), 1), ((4, 1), 2)])
def test_synthetic_spirograph_sketch_retrieves_its_radii(retriever, radii, seed):
    machine = get_machine("spirograph")
    rng = np.random.default_rng(seed)
    case = None
    while case is None:
        case = make_case(machine, dict(zip(radius_roles(machine), radii)), rng, symmetry=radii[0])
    result = retriever.query(case.sketch, top=5)
    found = [(c.machine, c.radii) for c in result.candidates]
    assert ("spirograph", radii) in found
    assert len(set(found)) == len(found)  # one candidate per (machine, radii)
    distances = [c.distance for c in result.candidates]
    assert distances == sorted(distances)
    for candidate in result.candidates:
        assert get_machine(candidate.machine).is_feasible(candidate.params)


def test_sector_sketch_with_symmetry_prunes_to_the_leading_radius(retriever):
    sketch = load_sketch(EXAMPLES / "trefoil-sector.json")
    result = retriever.query(sketch, top=3)
    assert result.candidates[0].radii[0] == 3
    assert all(report.pruned for report in result.reports)
    assert result.prepared.order.method == "exact"
    assert len(result.prepared.strokes) == 3
    pruned = sum(r.candidates_compared for r in result.reports)
    assert pruned < sum(r.candidates_total for r in result.reports)
    unpruned = retriever.query(sketch, top=3, prune=False)
    assert sum(r.candidates_compared for r in unpruned.reports) == sum(r.candidates_total for r in unpruned.reports)


def test_refinement_never_worsens_and_stays_feasible(retriever):
    sketch = load_sketch(EXAMPLES / "seven-star.json")
    result = retriever.query(sketch, top=3)
    best = result.candidates[0]
    machine = get_machine(best.machine)
    refined = refine_candidate(machine, best, result.prepared.coefficients, evaluations=40)
    assert refined.distance <= best.distance + 1e-12
    assert machine.is_feasible(refined.params)
    assert refined.radii == best.radii
    assert curve_distance(machine, refined.params, result.prepared.coefficients) == pytest.approx(
        refined.distance, abs=1e-6
    )


def test_query_settings_are_checked(retriever):
    sketch = make_sketch([[[0, 0], [1, 0], [1, 1], [0, 1]]])
    with pytest.raises(RetrievalSettingError, match="top"):
        retriever.query(sketch, top=0)
    with pytest.raises(RetrievalSettingError, match="refine"):
        retriever.query(sketch, refine=-1)
    with pytest.raises(RetrievalSettingError, match="unknown machine"):
        SketchRetriever(["harmonograph"])
