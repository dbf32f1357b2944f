"""The simulator gives the outcomes it gave at commit 599036c: labels, every event's state, and its time and wake-up
time within one step, on recorded seeded layouts of every example scenario (tests/data/simulation, made and
checked by bench/simulation_fixtures.py).

The default suite takes a part of each file (about 25 s of CPU: all of SIMPLE's and BALLRUN's layouts, fewer of
the large scenarios'); ``-m slow`` takes every recorded layout. The helpers that replace scipy's Rotation objects
in the rope impulses must be bit for bit scipy's (the impulses feed back into the physics); the event conditions
only read the world and are checked against the same formulas with scipy.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.simulation_fixtures import compare, outcome
from design.contraption import events, load_scenario
from design.contraption import world as world_module
from design.contraption.simulation import simulate

ROOT = Path(__file__).resolve().parents[3]
FIXTURES = ROOT / "tests" / "data" / "simulation"
#: Layouts per scenario in the default suite (the named layouts come first in each file).
DEFAULT = {"simple": 52, "ballrun": 52, "branching": 16, "teapotadventure": 10, "longchain": 6,
           "causalityswitch_ball": 5, "causalityswitch_dominoes": 5}


def _cases(slow: bool):
    for file in sorted(FIXTURES.glob("*.json")):
        marks = [pytest.mark.slow] if slow else []
        yield pytest.param(file.stem, None if slow else DEFAULT.get(file.stem, 4), marks=marks,
                           id=f"{file.stem}-{'all' if slow else 'part'}")


def check_fixture(stem: str, limit: int | None) -> None:
    data = json.loads((FIXTURES / f"{stem}.json").read_text())
    scenario = load_scenario(ROOT / "examples" / "scenarios" / data["scenario"])
    assert scenario.content_hash == data["content_hash"], f"{stem}: the scenario file changed since the recording"
    rows = data["layouts"][:limit] if limit else data["layouts"]
    problems = []
    for row in rows:
        new = outcome(simulate(scenario, np.array(row["x"]), early_stop=True))
        problems += [f"{row['name']}: {p}" for p in compare(row, new, data["time_step"])]
    assert not problems, f"{stem}: outcomes differ from the recording:\n" + "\n".join(problems)


@pytest.mark.parametrize(("stem", "limit"), list(_cases(slow=False)) + list(_cases(slow=True)))
def test_outcomes_match_the_recorded_ones(stem, limit):
    check_fixture(stem, limit)


def test_every_example_scenario_is_recorded():
    recorded = {p.stem for p in FIXTURES.glob("*.json")}
    shipped = {p.stem for p in (ROOT / "examples" / "scenarios").glob("*.toml")}
    assert shipped <= recorded
    for stem in recorded:
        data = json.loads((FIXTURES / f"{stem}.json").read_text())
        assert len(data["layouts"]) >= 50 and data["early_stop"] is True


def test_compare_finds_a_changed_label_and_a_time_two_steps_off():
    row = {"success": True, "steps": 10, "events": {"a": ["success", 0.010, 0.0]}}
    same = {"success": True, "steps": 8, "events": {"a": ["success", 0.012, 0.0]}}
    assert compare(row, same, 0.002) == []
    late = {"success": True, "steps": 10, "events": {"a": ["success", 0.014, 0.0]}}
    assert compare(row, late, 0.002) == ["a: time 0.01 -> 0.014"]
    flipped = {"success": False, "steps": 10, "events": {"a": ["failure", 0.010, 0.0]}}
    assert compare(row, flipped, 0.002) == ["label True -> False", "a: success -> failure"]


def test_rope_rotations_are_scipys_bit_for_bit():
    rng = np.random.default_rng(39)
    for _ in range(2000):
        q, inertial, v, w = rng.normal(size=4), rng.normal(size=4), rng.normal(size=3), rng.normal(size=3)
        expected = (Rotation.from_quat(q) * Rotation.from_quat(inertial)).inv().apply(np.cross(v, w))
        rotation = world_module._compose(world_module._from_quat(q), world_module._from_quat(inertial))
        got = world_module._apply(world_module._inverse(rotation), world_module._cross(v, w))
        assert np.array_equal(got, expected)
        assert np.array_equal(world_module._apply(world_module._from_quat(q), v), Rotation.from_quat(q).apply(v))


def test_condition_rotations_agree_with_scipy():
    rng = np.random.default_rng(40)
    for _ in range(2000):
        initial, now, offset = rng.normal(size=4), rng.normal(size=4), rng.normal(size=3)
        x, y, z, w = events._unit(initial)
        composed = events._unit(events._compose((-x, -y, -z, w), events._unit(now)))
        angle = 2.0 * math.atan2(math.sqrt(sum(c * c for c in composed[:3])), abs(composed[3]))
        expected = (Rotation.from_quat(initial).inv() * Rotation.from_quat(now)).magnitude()
        assert angle == pytest.approx(expected, abs=1e-12)
        local = events._rotate_inverse(events._unit(now), tuple(offset))
        assert np.allclose(local, Rotation.from_quat(now).inv().apply(offset), atol=1e-12)


def test_a_rope_judged_still_slack_is_slack():
    from design.contraption.simulation import Simulator

    scenario = load_scenario(ROOT / "examples" / "scenarios" / "teapotadventure.toml")
    rng = np.random.default_rng(41)
    with Simulator(scenario) as simulator:
        world = simulator.build(scenario.layout("success"))
        rope = world.ropes[0]
        carriers = (*rope.ends, *(uid for uid, _ in rope.pulley_guides))
        start = [world.client.getBasePositionAndOrientation(uid) for uid in carriers]
        # Make the rope slack by a known amount, then move its carriers at random by up to a few millimetres.
        _, length = world.rope_path(rope)
        rope.length = length + 0.005
        rope.slack_since = (length, start)
        judged = 0
        for _ in range(300):
            scale = rng.choice([1e-4, 1e-3, 5e-3])
            for uid, (position, quaternion) in zip(carriers, start):
                turn = Rotation.from_rotvec(rng.normal(size=3) * scale * 10) * Rotation.from_quat(quaternion)
                world.client.resetBasePositionAndOrientation(
                    uid, list(np.asarray(position) + rng.normal(size=3) * scale), list(turn.as_quat()))
            poses = [world.client.getBasePositionAndOrientation(uid) for uid in carriers]
            if world_module._still_slack(rope, poses):
                judged += 1
                assert world.rope_path(rope)[1] - rope.length < -1e-4
        assert 0 < judged < 300
