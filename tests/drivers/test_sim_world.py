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
