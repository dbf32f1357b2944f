"""Guided exploration on the four machines: the issue's acceptance (Figure 3.15-like cases) and the Explorer API."""

from __future__ import annotations

import numpy as np
import pytest

from design.explore import (
    CURVATURE,
    INTERSECTION,
    Explorer,
    InvariantSpecError,
    OverConstrainedError,
    detect_pois,
    track_poi,
)
from design.explore.errors import ExploreError

#: A slider move "changes the drawing visibly" when the ink moves on average by 0.3 % of the drawing's diagonal
#: (0.6 mm on a 20 cm plot; the before/after PNGs of the bench make it plain to see).
VISIBLE = 0.003
#: The issue's limits on the invariant error after re-projection.
LIMITS = {"position": 0.01, "distance": 0.01, "radial": 0.01, "curvature": 0.02, "angle": 1.0}

MACHINES = ["elliptic_spirograph", "cycloid_drawing_machine", "hoot_nanny"]
#: The designs the cases start from (pinned, so that a change of the models' defaults does not change the tests).
DESIGNS = {
    "elliptic_spirograph": {"r_f": 5, "r_r": 3, "e": 0.4, "d": 1.5},
    "cycloid_drawing_machine": {"r_t": 7, "r_e": 4, "d_tf": 9.0, "theta_te": 2.4, "r_s": 3.5, "d_fh": 10.5},
    "hoot_nanny": {
        "r_t": 10, "r_g1": 3, "r_g2": 2, "theta_12": 1.2, "r_p1": 2.8, "r_p2": 1.8, "l1": 13.5, "l2": 7.2,
    },
}


def pick(explorer: Explorer, kind: str) -> list[int]:
    """The PoIs a user would click: the first curvature maximum (two for a distance), the widest crossing."""
    maxima = [p for p in explorer.pois if p.kind == CURVATURE]
    crossings = [p for p in explorer.pois if p.kind == INTERSECTION]
    if kind == "angle":
        return [max(crossings, key=lambda p: p.angle).id]
    if kind == "distance":
        return [maxima[0].id, maxima[len(maxima) // 2].id]
    return [maxima[0].id]


def move_one(explorer: Explorer, slider: int = 0):
    """Move a slider by 1.0 (up if its bounds allow, else down) and release it."""
    s = explorer.sliders[slider]
    value = 1.0 if s.upper >= 1.0 else -1.0
    assert s.lower <= value <= s.upper, f"slider {s.name} cannot move by 1: bounds [{s.lower}, {s.upper}]"
    moved = explorer.move(slider, value)
    assert explorer.sliders[slider].value == value
    return moved, explorer.release()


def independent_error(kind, before_pois, ids, invariant, explorer: Explorer) -> float:
    """The invariant's error measured again from scratch: full detection on a finer sampling of the new design and
    Eq. 3.14 tracking of the PoIs picked on the old design."""
    t = np.linspace(0.0, explorer.period, 16385)
    pois = detect_pois(explorer.machine.curve(explorer.design, t), t)
    matched = []
    for i in ids:
        result = track_poi(before_pois[i], pois, sigma_poi=0.25 * explorer.size, sigma_arclength=0.05)
        assert not result.lost, result.reason
        matched.append(result.match)
    size = invariant.size
    target = invariant.target
    if kind == "position":
        return float(np.hypot(matched[0].xy[0] - target[0], matched[0].xy[1] - target[1]) / size)
    if kind == "radial":
        u = np.array(target) / np.hypot(*target)
        return float(abs(matched[0].xy[0] * u[1] - matched[0].xy[1] * u[0]) / size)
    if kind == "distance":
        d = np.hypot(matched[0].xy[0] - matched[1].xy[0], matched[0].xy[1] - matched[1].xy[1])
        return float(abs(d - target[0]) / size)
    if kind == "curvature":
        return float(abs(matched[0].curvature / target[0] - 1))
    return float(np.degrees(abs(matched[0].angle - target[0])))


@pytest.mark.parametrize("kind", ["position", "curvature", "angle", "radial", "distance"])
@pytest.mark.parametrize("machine", MACHINES)
def test_a_slider_move_changes_the_drawing_and_keeps_the_invariant(machine, kind):
    explorer = Explorer(machine, DESIGNS[machine])
    ids = pick(explorer, kind)
    before_pois = explorer.pois
    invariant = explorer.add_invariant(kind, ids)
    _, result = move_one(explorer)
    assert result.converged, result.warning
    assert result.lost == []
    assert result.shape_change > VISIBLE
    assert result.errors_after[invariant.label] < LIMITS[kind]
    assert independent_error(kind, before_pois, ids, invariant, explorer) < LIMITS[kind]
    explorer.machine.validate(result.params)


@pytest.mark.parametrize(
    ("machine", "kinds"),
    [("cycloid_drawing_machine", ["radial", "curvature"]), ("hoot_nanny", ["curvature", "radial"])],
)
def test_combined_invariants_all_hold(machine, kinds):
    explorer = Explorer(machine, DESIGNS[machine])
    ids = pick(explorer, kinds[0])
    invariants = [explorer.add_invariant(kind, ids) for kind in kinds]
    assert len(explorer.sliders) < len(explorer.names)
    _, result = move_one(explorer)
    assert result.converged and result.lost == []
    assert result.shape_change > VISIBLE
    for inv in invariants:
        assert result.errors_after[inv.label] < LIMITS[inv.kind]


def test_spirograph_has_one_parameter_so_most_invariants_are_over_constrained():
    explorer = Explorer("spirograph", {"r_f": 7, "r_r": 3, "d": 2.0})
    for kind in ("position", "curvature", "angle", "distance"):
        ids = pick(explorer, kind)
        with pytest.raises(OverConstrainedError, match=f"{kind}:") as info:
            explorer.add_invariant(kind, ids)
        assert info.value.invariants == (f"{kind}:{','.join(map(str, ids))}",)
        assert explorer.invariants == []  # refused invariants leave the session as it was
    # A lobe tip moves along its symmetry axis when d changes: the radial invariant is redundant,
    # so the base slider stays, and a move keeps the invariant.
    invariant = explorer.add_invariant("radial", pick(explorer, "radial"))
    assert explorer.subspace.redundant
    assert [s.name for s in explorer.sliders] == ["d"]
    _, result = move_one(explorer)
    assert result.shape_change > VISIBLE
    assert result.errors_after[invariant.label] < LIMITS["radial"]


def test_dimension_is_at_most_what_the_constraints_leave():
    # sigma_var may drop a free direction along which the samples spread little (a tight feasible range, or a
    # strongly non-linear invariant), as in the thesis; it never keeps more than the constraints leave.
    explorer = Explorer("hoot_nanny", DESIGNS["hoot_nanny"])
    maxima = [p.id for p in explorer.pois if p.kind == CURVATURE]
    explorer.add_invariant("position", [maxima[0]])
    assert 1 <= len(explorer.sliders) <= len(explorer.names) - 2
    explorer.add_invariant("curvature", [maxima[0]])
    assert 1 <= len(explorer.sliders) <= len(explorer.names) - 3
    assert [s.name for s in explorer.sliders] == [f"axis {k + 1}" for k in range(len(explorer.sliders))]


def assert_bounds_are_the_feasible_run(explorer: Explorer, past: float = 1e-3) -> None:
    """Each slider's bounds, from the current design, are where it stops being feasible: the design is feasible at
    the bound and, unless the bound is the slider's end (±2), not ``past`` beyond it."""
    for k, s in enumerate(explorer.sliders):
        assert -2.0 <= s.lower <= s.value <= s.upper <= 2.0
        for v, outward in ((s.lower, -past), (s.upper, past)):
            probe = explorer.values.copy()
            probe[k] = v
            assert explorer.machine.is_feasible(explorer._design_at(probe @ explorer.basis)), (k, v)
            if abs(v) < 2.0 - past:
                probe[k] = v + outward
                assert not explorer.machine.is_feasible(explorer._design_at(probe @ explorer.basis)), (k, v)


def test_bounds_are_recomputed_on_every_move_and_stay_feasible():
    explorer = Explorer("cycloid_drawing_machine", DESIGNS["cycloid_drawing_machine"])
    explorer.add_invariant("curvature", pick(explorer, "curvature"))
    assert len(explorer.sliders) >= 2
    first = [(s.lower, s.upper) for s in explorer.sliders]
    assert_bounds_are_the_feasible_run(explorer)
    explorer.move(0, explorer.sliders[0].upper)
    after = [(s.lower, s.upper) for s in explorer.sliders]
    # This move changes where the other sliders hit a constraint (slider 2's upper bound drops from about 0.9 to
    # about 0): bounds kept from before the move would be off, and the check below would find it.
    assert after[1:] != first[1:]
    assert_bounds_are_the_feasible_run(explorer)
    assert explorer.machine.is_feasible(explorer.design)
    # Past the bound, a slider is clamped to it.
    explorer.move(0, 10.0)
    assert explorer.sliders[0].value == pytest.approx(explorer.sliders[0].upper)
    assert_bounds_are_the_feasible_run(explorer)


def test_release_without_invariants_is_a_plain_parameter_move():
    explorer = Explorer("elliptic_spirograph", DESIGNS["elliptic_spirograph"])
    assert [s.name for s in explorer.sliders] == list(explorer.names)
    moved = explorer.move(1, 1.0)
    d0 = explorer.base_design["d"]
    assert moved.params["d"] == pytest.approx(d0 + explorer.scale[1])
    result = explorer.release()
    assert result.params == moved.params
    assert explorer.values.tolist() == [0.0, 0.0]


def test_basis_stays_consistent_across_releases():
    explorer = Explorer("cycloid_drawing_machine", DESIGNS["cycloid_drawing_machine"])
    explorer.add_invariant("position", pick(explorer, "position"))
    for _ in range(2):
        previous = explorer.basis
        move_one(explorer)
        now = explorer.basis
        assert now.shape == previous.shape
        # Each slider keeps pointing roughly the same way (no flips, no swaps).
        assert np.all(np.einsum("ij,ij->i", now, previous) > 0.5)


def test_bad_invariants_and_moves_are_refused_clearly():
    explorer = Explorer("elliptic_spirograph", DESIGNS["elliptic_spirograph"])
    maxima = [p.id for p in explorer.pois if p.kind == CURVATURE]
    crossings = [p.id for p in explorer.pois if p.kind == INTERSECTION]
    with pytest.raises(InvariantSpecError, match="type must be one of"):
        explorer.add_invariant("colour", [0])
    with pytest.raises(InvariantSpecError, match="must be an intersection PoI, got a curvature PoI"):
        explorer.add_invariant("angle", [maxima[0]])
    with pytest.raises(InvariantSpecError, match="must be a curvature PoI, got an intersection PoI"):
        explorer.add_invariant("curvature", [crossings[0]])
    with pytest.raises(InvariantSpecError, match=r"PoI id must be one of 0\.\."):
        explorer.add_invariant("position", [999])
    with pytest.raises(InvariantSpecError, match="takes 2 PoI"):
        explorer.add_invariant("distance", [maxima[0]])
    with pytest.raises(InvariantSpecError, match="two different PoIs"):
        explorer.add_invariant("distance", [maxima[0], maxima[0]])
    with pytest.raises(ExploreError, match="slider index"):
        explorer.move(5, 1.0)
    with pytest.raises(ExploreError, match="finite"):
        explorer.move(0, float("nan"))
    assert explorer.invariants == []


def random_feasible_design(model, rng) -> dict:
    while True:
        params = {}
        for p in model.parameters:
            if p.kind == "discrete":
                params[p.name] = int(rng.integers(max(1, p.lower), 11))
            else:
                params[p.name] = float(rng.uniform(p.lower, min(p.upper, 20.0)))
        if model.is_feasible(params):
            return params


@pytest.mark.parametrize("machine", [pytest.param(m, marks=[pytest.mark.slow] if m == "hoot_nanny" else [])
                                     for m in MACHINES])
def test_random_designs_a_release_is_never_silently_wrong(machine):
    # HOOT-NANNY's random designs draw long curves (the slowest case by far): with the slow tests; its pinned design
    # keeps every kind of invariant in test_a_slider_move_changes_the_drawing_and_keeps_the_invariant.
    """On seeded random designs and PoIs: a converged release keeps every invariant within the limits; a failed one
    leaves the design where it was and says so. Over-constrained invariants are refused."""
    rng = np.random.default_rng(7)
    model = Explorer(machine, DESIGNS[machine]).machine
    checked = 0
    for _ in range(2):
        params = random_feasible_design(model, rng)
        for kind in ("position", "curvature", "angle", "radial", "distance"):
            explorer = Explorer(machine, params)
            maxima = [p.id for p in explorer.pois if p.kind == CURVATURE]
            crossings = [p.id for p in explorer.pois if p.kind == INTERSECTION]
            pool = crossings if kind == "angle" else maxima
            if len(pool) < 2:
                continue
            ids = [int(i) for i in rng.choice(pool, 2 if kind == "distance" else 1, replace=False)]
            try:
                invariant = explorer.add_invariant(kind, ids)
            except OverConstrainedError:
                continue
            s = explorer.sliders[0]
            value = 1.0 if s.upper >= 1.0 else max(s.lower, -1.0)
            base = explorer.base_design
            explorer.move(0, value)
            result = explorer.release()
            if result.converged:
                assert result.errors_after[invariant.label] < LIMITS[kind], (params, kind, ids)
                checked += 1
            else:
                assert result.params == base and result.warning
    assert checked >= 4
