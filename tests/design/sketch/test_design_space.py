"""Retrieval over the machines' whole design space: maker-like sketches of designs drawn uniformly from
the feasible space (bench.sketch_space), uniform feasible sampling, sector chaining, refinement, the cache format."""

from __future__ import annotations

import json

import numpy as np
import pytest

import design.sketch.candidates as candidates_module
from bench.sketch_space import HIT_DISTANCE, feasible_designs, is_hit, make_space_case, pattern, shape_distance
from design.machines import get_machine
from design.machines.feasible_sampling import uniform_feasible
from design.sketch import SketchRetriever
from design.sketch.candidates import DatabaseSettings, cache_path, load_database, radius_roles, version_key
from design.sketch.errors import RetrievalSettingError
from design.sketch.refine import refine_many
from design.sketch.retrieval import Candidate, prepare_variants
from design.sketch.spline import resample_closed

#: Small uniform databases (a few seconds to build) that still hold every radii combination the tests need.
SMALL = {
    "cycloid_drawing_machine": DatabaseSettings(max_radius=10, sampling="uniform", samples=24, harmonics=64,
                                                points=256),
    "hoot_nanny": DatabaseSettings(max_radius=6, sampling="uniform", samples=48, harmonics=64, points=256),
}


@pytest.fixture(scope="module")
def retriever(tmp_path_factory):
    instance = SketchRetriever(list(SMALL), cache_dir=tmp_path_factory.mktemp("space-cache"), settings=SMALL)
    instance.load_all()
    return instance


def _case(name: str, lead: int, seed: int, sector: bool):
    """A maker-like sketch of a design drawn uniformly from the feasible space with the leading radius ``lead``.

    The other radii are uniform among those feasible with it, up to the small database's largest; the design is
    drawn within the machine's sampling box, which holds every feasible design (see
    test_sampling_box_holds_every_feasible_design).
    """
    machine = get_machine(name)
    rng = np.random.default_rng(seed)
    roles = radius_roles(machine)
    top = SMALL[name].max_radius
    others = [(a, b) for a in range(1, top + 1) for b in range(1, top + 1)] if len(roles) == 3 else \
        [(a,) for a in range(1, top + 1)]
    combos = np.array([(lead, *o) for o in others])
    params, owner = uniform_feasible(machine, combos, roles, 1, rng, pilot=2048)
    for row in rng.permutation(len(params)):
        design = {n: (int(round(v)) if n in roles else float(v)) for n, v in zip(machine.parameter_names, params[row])}
        if sector and machine.symmetry_order(design) == 1:
            continue
        case = make_space_case(machine, design, rng, sector_probability=1.0 if sector else 0.0)
        if case is not None and case.sector == sector:
            return case
    raise AssertionError(f"no {name} design with leading radius {lead}")


def test_sampling_box_holds_every_feasible_design():
    # designs found by rejection from the parameters' whole boxes (the bench's way) all lie in the sampling box
    for name in ("cycloid_drawing_machine", "hoot_nanny"):
        machine = get_machine(name)
        designs = feasible_designs(machine, 60, np.random.default_rng(8))
        box = machine.sampling_box({r: np.array([d[r] for d in designs], float) for r in machine.discrete_names})
        for n in machine.continuous_names:
            values = np.array([d[n] for d in designs])
            assert ((box[n][0] <= values) & (values <= box[n][1])).all(), n


@pytest.mark.parametrize(("name", "lead", "seed", "sector"), [
    ("cycloid_drawing_machine", 9, 3, False),
    ("cycloid_drawing_machine", 9, 4, True),
    ("hoot_nanny", 5, 5, False),
    ("hoot_nanny", 5, 6, True),
])
def test_sketch_finds_a_design_that_draws_it(retriever, name, lead, seed, sector):
    case = _case(name, lead, seed, sector)
    result = retriever.query(case.sketch, top=5)
    draws, _ = is_hit(case, [c for c in result.candidates if c.machine == name])
    best = min(shape_distance(case.curve, pattern(get_machine(c.machine), c.params)) for c in result.candidates)
    assert draws, (case.radii, case.params, best, [(c.machine, c.radii, c.distance) for c in result.candidates])
    assert best <= HIT_DISTANCE
    for candidate in result.candidates:
        assert get_machine(candidate.machine).is_feasible(candidate.params)


def test_uniform_feasible_designs_are_feasible_keep_their_radii_and_spread():
    machine = get_machine("hoot_nanny")
    roles = radius_roles(machine)
    radii = np.array([[5, 3, 2], [10, 8, 1], [6, 4, 3]])
    params, owner = uniform_feasible(machine, radii, roles, 32, np.random.default_rng(0))
    assert set(owner.tolist()) == {0, 1, 2}  # pairs sharing a divisor (10 / 8, 6 / 4 / 3) are designs too
    assert machine.feasible_mask(params).all()
    names = list(machine.parameter_names)
    for i, combo in enumerate(radii):
        rows = params[owner == i]
        assert np.array_equal(rows[:, [names.index(r) for r in roles]], np.repeat(combo[None], len(rows), axis=0))
        spread = rows[:, [names.index(n) for n in machine.continuous_names]].std(axis=0)
        assert (spread > 0.05).all(), spread  # chains moved away from their few pilot designs


def test_database_symmetry_is_the_patterns_not_the_leading_radius(retriever):
    database = retriever.database("hoot_nanny")
    machine = get_machine("hoot_nanny")
    rows = np.random.default_rng(1).choice(len(database), 40, replace=False)
    for row in rows:
        assert database.symmetry[row] == machine.symmetry_order(database.design(int(row)))
    assert (database.symmetry != database.radii[:, 0]).any()


def test_sector_of_a_ring_is_read_by_chaining_its_copies():
    # Cycloid Drawing Machine 9 / 5 sectors: one of the readings follows the pattern; on a ring-like pattern the
    # copies overlap and the closed tour through them goes round in the wrong order, the chained copies do not
    machine = get_machine("cycloid_drawing_machine")
    rng = np.random.default_rng(2)
    params, _ = uniform_feasible(machine, np.array([[9, 5]]), radius_roles(machine), 3, rng)
    tour, chained = [], []
    for row in params:
        design = {n: (int(round(v)) if n in ("r_t", "r_e") else float(v)) for n, v in zip(machine.parameter_names, row)}
        case = make_space_case(machine, design, rng, sector_probability=1.0)
        assert case.sector
        readings = prepare_variants(case.sketch)
        assert [r.order.method for r in readings][-1] == "sector"
        distances = [shape_distance(case.curve, resample_closed(r.curve, len(case.curve))) for r in readings]
        assert min(distances) < 0.02, distances
        tour.append(distances[0])
        chained.append(distances[-1])
    assert any(t > 0.5 and c < 0.02 for t, c in zip(tour, chained)), (tour, chained)


def test_refinement_never_worsens_and_stays_feasible(retriever):
    case = _case("cycloid_drawing_machine", 9, 3, False)
    result = retriever.query(case.sketch, top=3, refine=0)
    machine = get_machine("cycloid_drawing_machine")
    mine = [c for c in result.candidates if c.machine == machine.name]
    targets = np.stack([v.coefficients for v in prepare_variants(case.sketch, harmonics=64)])
    refined = refine_many(machine, mine, targets, rounds=3, offspring=6, points=256)
    for before, after in zip(mine, refined):
        assert after.distance <= before.distance
        assert after.radii == before.radii
        assert machine.is_feasible(after.params)
    assert isinstance(refined[0], Candidate)


def test_a_database_of_another_format_is_rebuilt_not_read(tmp_path, monkeypatch):
    machine = get_machine("spirograph")
    settings = DatabaseSettings(max_radius=4, values_per_dimension=2, harmonics=16, points=64)
    first = load_database(machine, tmp_path, settings)
    path = cache_path(tmp_path, machine.name, version_key(machine, settings))
    # an older format gets another key (the format is part of it): the old file is replaced
    monkeypatch.setattr(candidates_module, "DATABASE_FORMAT", candidates_module.DATABASE_FORMAT - 1)
    old_key = version_key(machine, settings)
    assert old_key != first.key
    # a file under the current name whose content says another key is not trusted either
    data = dict(np.load(path, allow_pickle=False))
    meta = json.loads(str(data["meta"]))
    meta["key"] = old_key
    data["meta"] = np.array(json.dumps(meta))
    with open(path, "wb") as stream:
        np.savez(stream, **data)
    monkeypatch.undo()
    built = []
    original = candidates_module.build_database
    monkeypatch.setattr(candidates_module, "build_database", lambda *a, **k: built.append(1) or original(*a, **k))
    again = load_database(machine, tmp_path, settings)
    assert built and again.key == first.key
    assert candidates_module.read_database(path).key == first.key


def test_a_query_can_search_some_of_the_retrievers_machines(retriever):
    case = _case("cycloid_drawing_machine", 9, 3, False)
    result = retriever.query(case.sketch, top=5, refine=0, machines=["hoot_nanny"])
    assert result.candidates and {c.machine for c in result.candidates} == {"hoot_nanny"}
    assert [r.machine for r in result.reports] == ["hoot_nanny"]
    with pytest.raises(RetrievalSettingError, match="spirograph"):
        retriever.query(case.sketch, machines=["spirograph"])
