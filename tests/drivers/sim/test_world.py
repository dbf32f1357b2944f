"""The simulated world (sim://world): options, hidden physics, the maker's placing and correcting errors, seeds."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.devices import probe, resolve
from drivers.errors import SimConfigError
from drivers.sim.world import SimulatedWorld, forget_worlds, sim_world

PARTS = [{"name": f"p{i}", "center_mm": [10.0 * i, -5.0 * i], "heading_deg": 15.0 * i} for i in range(40)]
NOMINAL = {"wood.friction": 0.5, "wood.rolling_friction": 0.01, "steel.restitution": 0.8,
           "domino.angular_damping": 0.087, "domino.linear_damping": 0.04}


def _errors(world: SimulatedWorld) -> np.ndarray:
    placed = world.placed()
    return np.array([[placed[p["name"]]["center_mm"][0] - p["center_mm"][0],
                      placed[p["name"]]["center_mm"][1] - p["center_mm"][1],
                      placed[p["name"]]["heading_deg"] - p["heading_deg"]] for p in PARTS])


@pytest.mark.parametrize("url, words", [
    ("sim://world?place_mm=-1", "place_mm"),
    ("sim://world?seed=x", "seed"),
    ("sim://world?friction=1.3,0.7", "friction"),
    ("sim://world?damping=2", "damping"),
    ("sim://world?highlight=2", "highlight"),
    ("sim://world?ruler_mm=-1", "ruler_mm"),
    ("sim://world?jig_deg=x", "jig_deg"),
    ("sim://world?colour=red", "colour"),
    ("sim://world?name=", "name"),
    ("sim://camera", "sim://world"),
])
def test_bad_options_are_one_line_naming_them(url, words):
    with pytest.raises(SimConfigError) as caught:
        SimulatedWorld(url)
    message = str(caught.value)
    assert words in message and "\n" not in message


def test_registry_kind_world_and_probe():
    info = resolve("sim://world?seed=3")
    assert (info.kind, info.simulated, info.available) == ("world", True, True)
    assert probe("sim://world?seed=3") == "open: simulated world, seed 3"
    assert probe("sim://world?seed=-3").startswith("not available: sim world option seed")


def test_hidden_physics_drawn_in_ranges_per_seed_and_independent_of_order():
    a, b = SimulatedWorld("sim://world?seed=1"), SimulatedWorld("sim://world?seed=2")
    a.draw_physics(NOMINAL)
    b.draw_physics(NOMINAL)
    assert a.hidden_physics() != b.hidden_physics()
    hidden = a.hidden_physics()
    assert 0.35 <= hidden["wood.friction"] <= 0.65
    assert 0.65 <= hidden["steel.restitution"] <= 0.95
    assert 0.0435 <= hidden["domino.angular_damping"] <= 0.174
    again = SimulatedWorld("sim://world?seed=1")
    again.draw_physics(dict(reversed(list(NOMINAL.items()))))  # another order, one value alone
    assert again.hidden_physics() == hidden
    again.draw_physics({"wood.friction": 0.5})
    assert again.hidden_physics() == {"wood.friction": hidden["wood.friction"]}
    # bounds (a scenario's uncertain range) clip; sane bounds too: no restitution of 1
    again.draw_physics({"steel.restitution": 0.95, "wood.friction": 0.5}, bounds={"wood.friction": (0.3, 0.4)})
    assert again.hidden_physics()["steel.restitution"] <= 0.99
    assert 0.3 <= again.hidden_physics()["wood.friction"] <= 0.4
    with pytest.raises(SimConfigError, match="wood.colour"):
        again.draw_physics({"wood.colour": 1.0})


def test_many_worlds_spread_hidden_values_over_the_whole_range():
    values = []
    for seed in range(200):
        world = SimulatedWorld(f"sim://world?seed={seed}&friction=0.7,1.3")
        world.draw_physics({"wood.friction": 1.0})
        values.append(world.hidden_physics()["wood.friction"])
    assert 0.7 <= min(values) < 0.75 and 1.25 < max(values) <= 1.3
    assert abs(np.mean(values) - 1.0) < 0.03


def test_placing_error_has_the_asked_spread_and_is_seeded_per_attempt_and_part():
    world = SimulatedWorld("sim://world?seed=5&place_mm=2&place_deg=3")
    world.place(PARTS, attempt=0)
    first = _errors(world)
    assert first[:, :2].std() == pytest.approx(2.0, rel=0.3)
    assert first[:, 2].std() == pytest.approx(3.0, rel=0.3)
    world.place(PARTS, attempt=1)
    assert not np.allclose(_errors(world), first)
    world.place(PARTS[::-1], attempt=0)  # another order: each part's error is its own
    assert np.allclose(_errors(world), first)
    world.place(PARTS, attempt=0, highlighted=True)  # the projector halves it (highlight=0.5)
    assert np.allclose(_errors(world), first * 0.5)
    other = SimulatedWorld("sim://world?seed=6&place_mm=2&place_deg=3")
    other.place(PARTS, attempt=0)
    assert not np.allclose(_errors(other), first)


def test_apply_moves_parts_by_the_instruction_with_the_fixing_error():
    world = SimulatedWorld("sim://world?seed=5&fix_mm=0.5&fix_deg=0.5")
    with pytest.raises(SimConfigError, match="place"):
        world.apply([], round=1)
    world.place(PARTS, attempt=2)
    errors = _errors(world)
    moves = [{"name": p["name"], "du_mm": -e[0], "dv_mm": -e[1], "dheading_deg": -e[2]} for p, e in zip(PARTS, errors)]
    world.apply(moves, round=1)
    after = _errors(world)
    assert after[:, :2].std() == pytest.approx(0.5, rel=0.35)
    assert np.abs(after).max() < np.abs(errors).max()
    replay = SimulatedWorld("sim://world?seed=5&fix_mm=0.5&fix_deg=0.5")
    replay.place(PARTS, attempt=2)
    assert replay.run_seed() == world.run_seed()  # the world seed and the attempt
    replay.place(PARTS, attempt=3)
    assert replay.run_seed() != world.run_seed()
    replay.place(PARTS, attempt=2)
    replay.apply(moves, round=1)
    assert replay.placed() == world.placed()
    with pytest.raises(SimConfigError, match="nope"):
        world.apply([{"name": "nope", "du_mm": 1}], round=2)
    with pytest.raises(SimConfigError, match="center_mm"):
        world.place([{"name": "x"}], attempt=0)


def test_named_worlds_are_shared():
    forget_worlds()
    try:
        a = sim_world("sim://world?name=bench&seed=4")
        b = sim_world("sim://world?name=bench&seed=4")
        assert a is b
        assert sim_world("sim://world?seed=4") is not a
    finally:
        forget_worlds()


def _stated(count: int, how: str, unit: str, role: str = "height") -> list[dict]:
    """``count`` parts each stating one parameter of its own, set ``how``."""
    return [{"name": f"q{i}", "center_mm": [5.0 * i, 0.0], "heading_deg": 0.0,
             "parameters": [{"name": f"q{i}.{'roll' if unit == 'deg' else 'z'}", "value": 10.0 + i, "unit": unit,
                             "role": role, "set_with": how}]} for i in range(count)]


def _set_errors(world: SimulatedWorld, parts: list[dict]) -> np.ndarray:
    settings = world.settings()
    return np.array([settings[p["parameters"][0]["name"]]["value"] - p["parameters"][0]["value"] for p in parts])


URL = "sim://world?seed=9&place_mm=2&place_deg=3&ruler_mm=1.5&ruler_deg=2&jig_mm=0.2&jig_deg=0.3&fix_mm=0.5&fix_deg=0.7"


@pytest.mark.parametrize("how, unit, highlighted, sigma", [
    ("ruler", "mm", False, 1.5), ("ruler", "deg", False, 2.0), ("ruler", "mm", True, 1.5),  # a ruler is not lit
    ("jig", "mm", False, 0.2), ("jig", "deg", True, 0.3),
    ("sheet", "mm", False, 2.0), ("sheet", "mm", True, 1.0), ("sheet", "deg", False, 3.0),
    ("check", "mm", True, 1.0),  # by eye until a check's instruction moves it
])
def test_each_way_of_setting_a_parameter_has_its_own_spread(how, unit, highlighted, sigma):
    world = SimulatedWorld(URL)
    parts = _stated(600, how, unit)
    world.place(parts, attempt=1, highlighted=highlighted)
    errors = _set_errors(world, parts)
    assert errors.std() == pytest.approx(sigma, rel=0.1)
    assert abs(errors.mean()) < 4 * sigma / np.sqrt(len(errors))
    assert {s["set_with"] for s in world.settings().values()} == {how}
    world.place(parts, attempt=2, highlighted=highlighted)  # a new attempt, new errors; the same attempt, the same
    assert not np.allclose(_set_errors(world, parts), errors)
    world.place(parts[::-1], attempt=1, highlighted=highlighted)
    assert np.allclose(_set_errors(world, parts), errors)


def test_a_checks_instruction_sets_a_parameter_with_the_correcting_error():
    world = SimulatedWorld(URL)
    parts = _stated(600, "check", "mm")
    world.place(parts, attempt=1)
    errors = _set_errors(world, parts)
    world.apply([{"name": p["name"], "parameters": {p["parameters"][0]["name"]: -e}} for p, e in zip(parts, errors)],
                round=1)
    assert _set_errors(world, parts).std() == pytest.approx(0.5, rel=0.1)
    with pytest.raises(SimConfigError, match="parameters"):
        world.apply([{"name": "q0", "parameters": {"q1.nope": 1.0}}], round=2)


def test_a_parameter_the_guide_does_not_state_is_guessed_uniformly_over_its_range():
    world = SimulatedWorld(URL)
    parts = _stated(1, "ruler", "mm")
    ranges = {"q0.z": [0.0, 45.0, "mm"], "a.roll": [-18.0, 0.0, "deg"], "b.x": [-200.0, 100.0, "mm"]}
    guesses = {name: [] for name in ranges}
    for attempt in range(800):
        world.place(parts, attempt=attempt, ranges=ranges)
        settings = world.settings()
        assert settings["q0.z"]["set_with"] == "ruler"  # stated: set as the guide says, not guessed
        for name in ("a.roll", "b.x"):
            assert settings[name]["set_with"] == "guess"
            guesses[name].append(settings[name]["value"])
    for name in ("a.roll", "b.x"):
        lower, upper, _ = ranges[name]
        values = np.array(guesses[name])
        assert lower <= values.min() < lower + 0.02 * (upper - lower)
        assert upper - 0.02 * (upper - lower) < values.max() <= upper
        assert values.std() == pytest.approx((upper - lower) / np.sqrt(12.0), rel=0.08)  # a uniform's spread
        assert np.mean(values) == pytest.approx((lower + upper) / 2, abs=0.05 * (upper - lower))
    with pytest.raises(SimConfigError, match="ranges"):
        world.place(parts, attempt=0, ranges={"c.x": [1.0, 0.0, "mm"]})


def test_a_part_on_a_jig_takes_the_jigs_placement_by_eye_plus_its_seating():
    parts = [{"name": f"p{i}", "center_mm": [10.0 * i, 0.0], "heading_deg": 0.0,
              "parameters": [{"name": f"p{i}.x", "value": 10.0 * i, "unit": "mm", "role": "u", "set_with": "jig"}]}
             for i in range(600)]
    jigs = [{"id": f"J{i}", "part": f"p{i}", "parameters": [f"p{i}.x"]} for i in range(600)]

    def pose_errors(url: str, highlighted: bool) -> np.ndarray:
        world = SimulatedWorld(url)
        world.place(parts, attempt=1, highlighted=highlighted, jigs=jigs)
        placed = world.placed()
        return np.array([[placed[p["name"]]["center_mm"][0] - p["center_mm"][0],
                          placed[p["name"]]["heading_deg"]] for p in parts])

    # the jig laid by eye over its footprint (the sheet's error, lit or not), the part seated on it
    by_eye = pose_errors("sim://world?seed=3&place_mm=2&place_deg=3&jig_mm=0&jig_deg=0", False)
    assert by_eye[:, 0].std() == pytest.approx(2.0, rel=0.1) and by_eye[:, 1].std() == pytest.approx(3.0, rel=0.1)
    assert np.allclose(pose_errors("sim://world?seed=3&place_mm=2&place_deg=3&jig_mm=0&jig_deg=0", True), by_eye / 2)
    seated = pose_errors("sim://world?seed=3&place_mm=0&place_deg=0&jig_mm=0.2&jig_deg=0.3", False)
    assert seated[:, 0].std() == pytest.approx(0.2, rel=0.1) and seated[:, 1].std() == pytest.approx(0.3, rel=0.1)
    both = pose_errors("sim://world?seed=3&place_mm=2&place_deg=3&jig_mm=0.2&jig_deg=0.3", False)
    assert np.allclose(both, by_eye + seated)
    # without its jig the same part is placed by eye with its own error
    world = SimulatedWorld("sim://world?seed=3&place_mm=2&place_deg=3&jig_mm=0&jig_deg=0")
    world.place(parts, attempt=1)
    alone = np.array([world.placed()[p["name"]]["center_mm"][0] - p["center_mm"][0] for p in parts])
    assert alone.std() == pytest.approx(2.0, rel=0.1) and not np.allclose(alone, by_eye[:, 0])


def test_a_part_set_with_a_ruler_in_the_plane_has_the_rulers_error():
    parts = _stated(600, "ruler", "mm", role="u")
    world = SimulatedWorld("sim://world?seed=4&place_mm=5&ruler_mm=1.5")
    world.place(parts, attempt=1, highlighted=True)
    errors = np.array([world.placed()[p["name"]]["center_mm"] for p in parts]) - [p["center_mm"] for p in parts]
    assert errors.std() == pytest.approx(1.5, rel=0.1)


@pytest.mark.parametrize("parameters", [
    [{"name": "a.z", "value": 1.0, "unit": "cm", "role": "height", "set_with": "ruler"}],
    [{"name": "a.z", "value": 1.0, "unit": "mm", "role": "height", "set_with": "tape"}],
    [{"name": "a.z", "value": "x", "unit": "mm", "role": "height", "set_with": "ruler"}],
    [{"value": 1.0, "unit": "mm", "role": "height", "set_with": "ruler"}],
])
def test_bad_stated_parameters_are_one_line(parameters):
    with pytest.raises(SimConfigError) as caught:
        SimulatedWorld().place([{"name": "a", "center_mm": [0, 0], "parameters": parameters}], attempt=0)
    assert "parameters" in str(caught.value) and "\n" not in str(caught.value)
