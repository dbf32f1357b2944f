"""Materials in scenarios: [materials.NAME] tables, uncertain values, overrides, with_physics and the content hash."""

from __future__ import annotations

from pathlib import Path

import pytest

from design.contraption import ScenarioFormatError, load_scenario, scenario_from_data, with_physics
from design.contraption.validation import parse_text

ROOT = Path(__file__).resolve().parents[3]
EXAMPLES = ROOT / "examples" / "scenarios"
SLIDE = Path(__file__).resolve().parents[2] / "data" / "calibration" / "slide.toml"

BASE = """
[scenario]
name = "M"
[materials.wood]
friction = { value = 0.6, range = [0.3, 0.9] }
restitution = 0.2
[[objects]]
name = "floor"
type = "Plane"
[[objects]]
name = "block"
type = "Box"
shape = { size = [0.02, 0.02, 0.02] }
material = "wood"
physics = { mass = 0.01, restitution = 0.5 }
transform = { z = 0.0101 }
[[events]]
name = "rest"
type = "NotMoving"
body = "block"
"""


def load(text: str, file: str = "m.toml"):
    return scenario_from_data(parse_text(text.encode(), file, ".toml"), file=file)


def test_material_values_reach_objects_and_object_keys_override():
    scenario = load(BASE)
    block = scenario.object("block")
    assert block.material == "wood"
    assert (block.physics.friction, block.physics.restitution, block.physics.mass) == (0.6, 0.5, 0.01)
    assert scenario.object("floor").physics.friction == 0.5  # no material: the format's default
    assert scenario.uncertain_parameters() == {"wood.friction": (0.6, (0.3, 0.9))}
    assert scenario.physics_parameters() == {"wood.friction": 0.6, "wood.restitution": 0.2}


@pytest.mark.parametrize(("old", "new", "message"), [
    ('material = "wood"', 'material = "oak"',
     "m.toml: objects[1].material: unknown material 'oak'; expected one of: wood"),
    ("friction = { value = 0.6, range = [0.3, 0.9] }", "friction = { value = 0.95, range = [0.3, 0.9] }",
     "m.toml: materials.wood.friction.value: expected a value inside its range [0.3, 0.9], got 0.95"),
    ("friction = { value = 0.6, range = [0.3, 0.9] }", "friction = { value = 0.6, range = [0.9, 0.3] }",
     "m.toml: materials.wood.friction.range: expected [min, max] with 0 <= min < max, got [0.9, 0.3]"),
    ("friction = { value = 0.6, range = [0.3, 0.9] }", "friction = { value = 0.6 }",
     "m.toml: materials.wood.friction.range: missing; expected [min, max]"),
    ("friction = { value = 0.6, range = [0.3, 0.9] }", 'friction = "high"',
     "m.toml: materials.wood.friction: expected a number >= 0 or { value = V, range = [MIN, MAX] }, got text"),
    ("restitution = 0.2", "mass = 0.2",
     "m.toml: materials.wood.mass: unknown field; expected one of: friction, rolling_friction"),
    ("physics = { mass = 0.01, restitution = 0.5 }", "physics = { mass = 0.01, restitution = { value = 0.5 } }",
     "m.toml: objects[1].physics.restitution: expected a number >= 0 (uncertain values with a range go in a "
     "[materials.NAME] table)"),
])
def test_bad_materials_are_one_line_naming_file_and_field(old, new, message):
    assert old in BASE
    with pytest.raises(ScenarioFormatError) as error:
        load(BASE.replace(old, new))
    assert str(error.value).startswith(message)
    assert "\n" not in str(error.value)


def test_with_physics_sets_values_keeps_ranges_and_changes_the_hash():
    scenario = load(BASE)
    other = with_physics(scenario, {"wood.friction": 0.42})
    assert other.object("block").physics.friction == 0.42
    assert other.uncertain_parameters() == {"wood.friction": (0.42, (0.3, 0.9))}
    assert other.physics_overrides == {"wood.friction": 0.42}
    assert other.content_hash != scenario.content_hash
    assert with_physics(scenario, {"wood.friction": 0.6}).content_hash == scenario.content_hash
    assert with_physics(scenario, {}) is scenario
    for bad, words in [({"wood.friction": 0.95}, 'physics."wood.friction": expected a value inside the scenario'),
                       ({"oak.friction": 0.5}, "no material 'oak' in the scenario; it has: wood"),
                       ({"wood.mass": 0.5}, "expected MATERIAL.PARAM"),
                       ({"wood.damping": 0.5}, "expected MATERIAL.PARAM")]:
        with pytest.raises(ScenarioFormatError, match=words):
            with_physics(scenario, bad)


def test_hash_is_of_what_is_simulated():
    """Materials resolved into physics: the same effective values hash the same; ranges do not count."""
    explicit = BASE.replace("""[materials.wood]
friction = { value = 0.6, range = [0.3, 0.9] }
restitution = 0.2
""", "").replace('material = "wood"\nphysics = { mass = 0.01, restitution = 0.5 }',
                 "physics = { mass = 0.01, restitution = 0.5, friction = 0.6 }")
    assert load(explicit).content_hash == load(BASE).content_hash
    wider = BASE.replace("range = [0.3, 0.9]", "range = [0.1, 1.0]")
    assert load(wider).content_hash == load(BASE).content_hash
    assert load(BASE.replace("value = 0.6", "value = 0.7")).content_hash != load(BASE).content_hash


def test_examples_use_materials_with_the_thesis_values():
    simple = load_scenario(EXAMPLES / "simple.toml")
    assert simple.object("dominoes").material == "domino"
    assert simple.object("dominoes").physics.friction == 0.6
    assert simple.object("floor").physics.friction == 0.504
    # The hash the optimizer's saved layouts were written for (before materials): unchanged.
    assert simple.content_hash == "a36509f667380e99fdc4c107aeedaab63239ad689dfe4e01ba25262d10570545"
    switch = load_scenario(EXAMPLES / "causalityswitch_ball.toml")
    assert switch.uncertain_parameters()["domino.friction"] == (0.623, (0.3, 0.9))  # thesis 4.8
    assert switch.uncertain_parameters()["domino.restitution"][0] == 0.754
    assert switch.uncertain_parameters()["domino.angular_damping"][0] == 0.087
    for path in sorted(EXAMPLES.glob("*.toml")):
        assert load_scenario(path).uncertain_parameters(), path.name


def test_a_problem_keeps_its_physics_in_worker_processes():
    import pickle

    from design.robust.contraption import load_problem

    problem = load_problem(SLIDE, {"wood.friction": 0.7})
    again = pickle.loads(pickle.dumps(problem))
    assert again.scenario.object("plank").physics.friction == 0.7
    assert again.content_hash == problem.content_hash != load_problem(SLIDE).content_hash


@pytest.mark.parametrize(("name", "value", "expected"), [
    ("wood.friction", 0.5, (0.25, 0.75)), ("felt.rolling_friction", 0.01, (0.005, 0.015)),
    ("wood.restitution", 0.2, (0.0, 0.5)), ("steel.restitution", 0.8, (0.5, 0.99)),
    ("domino.angular_damping", 0.1, (0.025, 0.4)), ("wood.friction", 0.0, (0.0, 0.05))])
def test_a_plain_material_value_has_a_default_range(name, value, expected):
    from design.contraption.materials import default_range

    assert default_range(name, value) == pytest.approx(expected)


def test_every_material_adds_the_plain_values_in_their_default_ranges():
    from station.services.sim_calibration import choose_parameters, material_ranges

    scenario = load(BASE)
    assert material_ranges(scenario) == {"wood.friction": (0.6, (0.3, 0.9))}
    every = choose_parameters([scenario], None, every_material=True)
    assert every == {"wood.friction": (0.6, (0.3, 0.9)), "wood.restitution": (0.2, (0.0, pytest.approx(0.5)))}
    assert choose_parameters([scenario], ["wood.restitution"], every_material=True) == {
        "wood.restitution": every["wood.restitution"]}
    with pytest.raises(Exception, match="--all-materials"):
        choose_parameters([scenario], ["wood.restitution"])


def test_ranges_that_do_not_overlap_refuse_only_the_value_that_is_fitted():
    # SIMPLE's steel.restitution ranges over [0.05, 0.5], BALLRUN's over [0.5, 0.95]: fitting both scenarios' wood
    # alone (`station calibrate sim simple ballrun --params wood.friction`) never looks at the steel.
    from station.errors import ServiceError
    from station.services.contraption import open_scenario
    from station.services.sim_calibration import choose_parameters

    both = [open_scenario("simple"), open_scenario("ballrun")]
    assert choose_parameters(both, ["wood.friction"]) == {"wood.friction": (0.5, (0.3, 0.8))}
    with pytest.raises(ServiceError, match="steel.restitution has ranges that do not overlap"):
        choose_parameters(both, None)
    with pytest.raises(ServiceError, match="steel.restitution has ranges that do not overlap"):
        choose_parameters(both, ["wood.friction", "steel.restitution"])
