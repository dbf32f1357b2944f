"""The drawing-machine API, checked the same way on every built-in machine."""

from __future__ import annotations

import numpy as np
import pytest

from design.errors import ConstraintViolation, ParameterError
from design.machines import Circle, Point, get_machine, machine_names
from design.machines.parameters import random_in_boxes

BUILTINS = [
    n for n in ("spirograph", "elliptic_spirograph", "cycloid_drawing_machine", "hoot_nanny") if n in machine_names()
]

#: Extra feasible designs per machine (besides the defaults) with coprime radii and a long period.
DESIGNS = {
    "spirograph": [{"r_f": 7, "r_r": 5, "d": 3.1}, {"r_f": 13, "r_r": 8, "d": 8.0}, {"r_f": 9, "r_r": 2, "d": 0.7}],
    "elliptic_spirograph": [{"r_f": 7, "r_r": 5, "e": 0.3, "d": 3.1}, {"r_f": 11, "r_r": 4, "e": 0.7, "d": 2.0}],
    "cycloid_drawing_machine": [
        {"r_t": 10, "r_e": 3, "d_tf": 12.0, "theta_te": 2.1, "r_s": 2.8, "d_fh": 15.5},
        {"r_t": 11, "r_e": 4, "d_tf": 13.0, "theta_te": 1.9, "r_s": 3.2, "d_fh": 12.5},
    ],
    "hoot_nanny": [
        {"r_t": 4, "r_g1": 3, "r_g2": 2, "theta_12": 1.38, "r_p1": 2.8, "r_p2": 1.85, "l1": 7.32, "l2": 6.69},
        {"r_t": 9, "r_g1": 4, "r_g2": 5, "theta_12": 1.53, "r_p1": 3.98, "r_p2": 4.78, "l1": 15.57, "l2": 14.8},
    ],
}


def designs(name):
    machine = get_machine(name)
    return [machine.defaults()] + DESIGNS.get(name, [])


def test_the_four_builtins_are_registered():
    assert BUILTINS[0] == "spirograph"
    assert machine_names()[: len(BUILTINS)] == BUILTINS


@pytest.mark.parametrize("name", BUILTINS)
def test_parameters_and_defaults(name):
    machine = get_machine(name)
    assert machine.name == name and machine.title
    defaults = machine.defaults()
    assert list(defaults) == [p.name for p in machine.parameters]
    for parameter in machine.parameters:
        assert parameter.kind in ("discrete", "continuous")
        assert parameter.lower <= parameter.default <= parameter.upper
        if parameter.kind == "discrete":
            assert isinstance(defaults[parameter.name], int)
    assert machine.is_feasible(defaults)
    assert machine.validate({}) == defaults
    for design in designs(name):
        assert machine.violations(design) == []


@pytest.mark.parametrize("name", BUILTINS)
def test_closes_after_exactly_one_period_and_not_before(name):
    machine = get_machine(name)
    for design in designs(name):
        period = machine.period(design)
        turns = machine.turns(design)
        assert period == pytest.approx(2 * np.pi * turns)
        start, end = machine.curve(design, [0.0, period])
        scale = np.abs(machine.sample(design, 512)).max()
        assert np.linalg.norm(end - start) < 1e-9 * scale
        earlier = machine.curve(design, 2 * np.pi * np.arange(1, turns))
        assert turns >= 2
        assert np.linalg.norm(earlier - start, axis=1).min() > 1e-6 * scale


@pytest.mark.parametrize("name", BUILTINS)
@pytest.mark.parametrize("spacing", ["time", "arclength"])
def test_sample_is_closed_and_spaced(name, spacing):
    machine = get_machine(name)
    for design in designs(name):
        points = machine.sample(design, n=2001, spacing=spacing)
        assert points.shape == (2001, 2)
        assert np.array_equal(points[-1], points[0])
        assert np.isfinite(points).all()
        if spacing == "arclength":
            steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
            # Chords equal arcs except across cusps (d = r_r), where a chord is shorter than its arc.
            close = np.abs(steps / np.median(steps) - 1) < 0.02
            assert close.mean() > 0.95
            assert steps.max() < 1.02 * np.median(steps)
        else:
            t = np.linspace(0, machine.period(design), 2001)
            np.testing.assert_allclose(points[:-1], machine.curve(design, t)[:-1], atol=1e-9)


@pytest.mark.parametrize("name", BUILTINS)
def test_arclength_times_split_the_curve_into_equal_lengths(name):
    machine = get_machine(name)
    for design in designs(name):
        P = {k: np.array([[float(v)]]) for k, v in machine.validate(design).items()}
        period = machine._period(P).reshape(1, 1)
        times = machine._arclength_times(P, period, 129)[0]
        assert times[0] == 0 and times[-1] == pytest.approx(period[0, 0])
        fine = times[:-1, None] + (times[1:] - times[:-1])[:, None] * np.linspace(0, 1, 400)[None, :]
        z = machine._positions(P, fine)
        lengths = np.abs(np.diff(z, axis=-1)).sum(axis=-1).ravel()
        assert lengths.std() / lengths.mean() < 2e-3


@pytest.mark.parametrize("name", BUILTINS)
def test_sample_many_matches_sample(name):
    machine = get_machine(name)
    rows = designs(name)
    for spacing in ("time", "arclength"):
        batch = machine.sample_many(rows, n=300, spacing=spacing)
        assert batch.shape == (len(rows), 300, 2)
        for row, points in zip(rows, batch):
            np.testing.assert_allclose(points, machine.sample(row, 300, spacing), atol=1e-9)
    array = np.array([[row[p] for p in machine.parameter_names] for row in rows], dtype=float)
    np.testing.assert_allclose(machine.sample_many(array, n=64), machine.sample_many(rows, n=64))
    assert machine.feasible_mask(array).all()


@pytest.mark.parametrize("name", BUILTINS)
def test_curve_many_and_period_many(name):
    machine = get_machine(name)
    rows = designs(name)
    periods = machine.period_many(rows)
    np.testing.assert_allclose(periods, [machine.period(row) for row in rows])
    fractions = np.linspace(0, 1, 50)
    batch = machine.curve_many(rows, fractions[None, :] * periods[:, None])
    shared = machine.curve_many(rows, fractions * 3.0)
    assert batch.shape == shared.shape == (len(rows), 50, 2)
    for row, period, points, common in zip(rows, periods, batch, shared):
        np.testing.assert_allclose(points, machine.curve(row, fractions * period), atol=1e-12)
        np.testing.assert_allclose(common, machine.curve(row, fractions * 3.0), atol=1e-12)
    with pytest.raises(ParameterError, match="shape"):
        machine.curve_many(rows, np.zeros((len(rows) + 1, 3)))


@pytest.mark.parametrize("name", BUILTINS)
def test_sample_many_names_the_infeasible_row(name):
    machine = get_machine(name)
    bad = dict(machine.defaults())
    first = machine.discrete_names[0]
    bad[first] = machine.parameter(first).upper + 1
    assert not machine.feasible_mask([machine.defaults(), bad]).all()
    with pytest.raises(ParameterError, match="row 1"):
        machine.sample_many([machine.defaults(), bad], n=16)


@pytest.mark.parametrize("name", BUILTINS)
def test_feasible_interval_ends_are_feasible_and_just_outside_is_not(name):
    machine = get_machine(name)
    for design in designs(name):
        for parameter in machine.continuous_names:
            lo, hi = machine.feasible_interval(design, parameter)
            box = machine.parameter(parameter)
            assert lo <= design[parameter] <= hi
            assert machine.is_feasible(design | {parameter: lo}), (parameter, lo)
            assert machine.is_feasible(design | {parameter: hi}), (parameter, hi)
            step = 1e-6 * (box.upper - box.lower)
            if lo > box.lower:
                assert not machine.is_feasible(design | {parameter: lo - step}), (parameter, lo)
            if hi < box.upper:
                assert not machine.is_feasible(design | {parameter: hi + step}), (parameter, hi)
            middle = np.linspace(lo, hi, 7)
            assert machine.feasible_mask({**{k: v for k, v in design.items()}, parameter: middle}).all()


@pytest.mark.parametrize("name", BUILTINS)
def test_feasible_interval_rejects_discrete_and_unknown(name):
    machine = get_machine(name)
    with pytest.raises(ParameterError, match="continuous"):
        machine.feasible_interval(None, machine.discrete_names[0])
    with pytest.raises(ParameterError, match="nope"):
        machine.feasible_interval(None, "nope")


@pytest.mark.parametrize("name", BUILTINS)
def test_bad_parameters_raise_parameter_error_with_one_template(name):
    machine = get_machine(name)
    with pytest.raises(ParameterError, match=rf"{name}: parameter 'bogus' must be one of"):
        machine.validate({"bogus": 1})
    gear = machine.discrete_names[0]
    with pytest.raises(ParameterError, match=rf"parameter '{gear}' must be an integer gear radius.*got 2.5"):
        machine.validate({gear: 2.5})
    with pytest.raises(ParameterError, match=rf"parameter '{gear}' must be an integer gear radius"):
        machine.validate({gear: 1000})
    with pytest.raises(ParameterError, match="must be a finite real number"):
        machine.validate({machine.continuous_names[0]: "abc"})
    with pytest.raises(ParameterError, match="must be a finite real number"):
        machine.validate({machine.continuous_names[0]: float("nan")})
    continuous = machine.parameter(machine.continuous_names[0])
    with pytest.raises(ParameterError, match=rf"parameter '{continuous.name}' must be in \["):
        machine.validate({continuous.name: continuous.upper + 1})


@pytest.mark.parametrize("name", BUILTINS)
def test_every_constraint_has_a_name_category_and_message(name):
    machine = get_machine(name)
    from design.machines import CATEGORIES

    for constraint in machine.all_constraints():
        assert constraint.category in CATEGORIES, constraint.name
        assert constraint.message(machine.defaults())


@pytest.mark.parametrize("name", BUILTINS)
def test_mechanism_pen_is_on_the_curve(name):
    machine = get_machine(name)
    for design in designs(name):
        for t in (0.0, 0.7, 3.1, machine.period(design) * 0.61):
            shapes = machine.mechanism(design, t)
            pens = [s for s in shapes if isinstance(s, Point) and s.label == "pen"]
            assert len(pens) == 1
            np.testing.assert_allclose(pens[0].position, machine.curve(design, [t])[0], atol=1e-9)
            assert any(isinstance(s, Circle) for s in shapes)
            labels = [s.label for s in shapes]
            assert len(labels) == len(set(labels))


@pytest.mark.parametrize("name", BUILTINS)
def test_describe_is_plain_json(name):
    import json

    description = get_machine(name).describe()
    assert json.loads(json.dumps(description))["name"] == name
    assert {p["name"] for p in description["parameters"]} == set(get_machine(name).parameter_names)


def test_validate_reports_constraint_name_and_margin():
    machine = get_machine("spirograph")
    with pytest.raises(ConstraintViolation) as info:
        machine.validate({"r_f": 7, "r_r": 3, "d": 4.5})
    assert info.value.constraint == "pen_inside_gear"
    assert info.value.margin == pytest.approx(-1.5)
    assert "d must be at most r_r = 3, got 4.5" in str(info.value)


def random_feasible_designs(machine, k, seed):
    """``k`` feasible designs by rejection sampling in the boxes (gear radii 1..12, lengths up to 25)."""
    rows = random_in_boxes(machine.parameters, 200_000, np.random.default_rng(seed))
    ok = np.flatnonzero(machine.feasible_mask(rows))[:k]
    assert ok.size == k
    discrete = set(machine.discrete_names)
    return [{name: (int(v[i]) if name in discrete else float(v[i])) for name, v in rows.items()} for i in ok]


@pytest.mark.parametrize("name", BUILTINS)
def test_feasible_interval_on_random_feasible_designs(name):
    machine = get_machine(name)
    for design in random_feasible_designs(machine, 12, seed=11):
        for parameter in machine.continuous_names:
            lo, hi = machine.feasible_interval(design, parameter)
            box = machine.parameter(parameter)
            assert lo <= design[parameter] <= hi
            inside = np.linspace(lo, hi, 41)
            assert machine.feasible_mask({**design, parameter: inside}).all(), (design, parameter)
            step = 1e-7 * (box.upper - box.lower)
            outside = [x for x, edge in ((lo - step, lo > box.lower), (hi + step, hi < box.upper)) if edge]
            if outside:
                assert not machine.feasible_mask({**design, parameter: np.array(outside)}).any(), (design, parameter)


@pytest.mark.parametrize("name", BUILTINS)
def test_mechanism_frames(name):
    machine = get_machine(name)
    design = machine.defaults()
    drawing = machine.mechanism(design, 1.3)
    fixed = machine.mechanism(design, 1.3, frame="fixed")
    assert [s.label for s in drawing] == [s.label for s in fixed]
    pen_drawing = next(s.position for s in drawing if s.label == "pen")
    pen_fixed = next(s.position for s in fixed if s.label == "pen")
    assert np.hypot(*pen_drawing) == pytest.approx(np.hypot(*pen_fixed))  # same point, frames differ by a rotation
    with pytest.raises(ParameterError, match="frame"):
        machine.mechanism(design, 1.3, frame="paper")


@pytest.mark.parametrize("name", BUILTINS)
def test_every_box_and_integrality_constraint_is_a_parameter_error(name):
    machine = get_machine(name)
    for parameter in machine.parameters:
        cases = [(f"{parameter.name}_max", parameter.upper + 1), (f"{parameter.name}_min", parameter.lower - 1)]
        if parameter.kind == "discrete":
            cases.append((f"{parameter.name}_integer", parameter.default + 0.5))
        for constraint, value in cases:
            assert constraint in [v.constraint for v in machine.violations({parameter.name: value})]
            with pytest.raises(ParameterError, match=f"parameter '{parameter.name}' must be"):
                machine.validate({parameter.name: value})
