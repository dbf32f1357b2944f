"""The reach stop: a run ends once no awake event can still happen before its timeout, with the outcomes of the run
that waits for the timeout (the recorded ones, tests/data/simulation; the whole set is checked by
test_simulation_equivalence.py)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bench.simulation_fixtures import compare, outcome
from design.contraption import Simulator, load_scenario
from design.contraption import reach as reach_module
from design.contraption.reach import Reach
from design.contraption.simulation import simulate

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def simple():
    return load_scenario(ROOT / "examples" / "scenarios" / "simple.toml")


def _recorded(stem: str, name: str) -> tuple[dict, float]:
    data = json.loads((ROOT / "tests" / "data" / "simulation" / f"{stem}.json").read_text())
    return next(row for row in data["layouts"] if row["name"] == name), data["time_step"]


def test_a_ball_flying_over_the_dominoes_is_known_to_fail_long_before_the_timeout(simple):
    row, dt = _recorded("simple", "failure")
    result = simulate(simple, np.array(row["x"]))
    assert compare(row, outcome(result), dt) == []
    # The verdict comes at the contact's timeout (2 s after the ball started rolling), as recorded; the physics
    # stopped once the ball was rolling away from the first domino with nothing to turn it back.
    assert result.duration == pytest.approx(row["steps"] * dt)
    assert result.steps < row["steps"] / 2
    assert result.early_stopped


def test_a_recorded_run_keeps_the_world_up_to_the_verdict(simple):
    row, dt = _recorded("simple", "failure")
    result = simulate(simple, np.array(row["x"]), record=True)
    assert compare(row, outcome(result), dt) == []
    assert result.steps == row["steps"]


def _rolling_ball_bounds(simple, speed: float):
    with Simulator(simple) as simulator:
        world = simulator.build(simple.layout("success"))
        client = world.client
        ball = world.uid("ball")
        radius = 0.010
        # On the floor, 15 cm past the last domino, rolling along x without slipping.
        client.resetBasePositionAndOrientation(ball, [0.2, 0.0, radius], [0, 0, 0, 1])
        client.resetBaseVelocity(ball, [speed, 0.0, 0.0], [0.0, speed / radius, 0.0])
        reach = Reach(world)
        reach.bounds(0.0, 1.5, 0.04)
        for _ in range(20):
            client.stepSimulation()
        bounds = reach.bounds(0.04, 1.5, 0.04)
        return bounds, ball, world.uid("dominoes[0]"), world.uid("dominoes[2]")


def test_a_ball_rolling_away_cannot_come_back_to_the_dominoes(simple):
    bounds, ball, first, last = _rolling_ball_bounds(simple, 0.3)
    assert bounds.fixed(first) and bounds.fixed(last)
    assert bounds.apart(ball, first) and bounds.apart(ball, last)


def test_a_ball_rolling_towards_the_dominoes_may_reach_them(simple):
    bounds, ball, first, last = _rolling_ball_bounds(simple, -0.3)
    assert not bounds.apart(ball, last)
    assert not bounds.fixed(last)


def test_groups_are_the_chains_of_joined_bodies():
    joined = np.zeros((6, 6), dtype=bool)
    for a, b in ((0, 3), (3, 5), (1, 2)):
        joined[a, b] = joined[b, a] = True
    assert reach_module._components(joined).tolist() == [0, 1, 1, 0, 4, 0]


def test_a_box_stands_its_least_half_extent_above_the_floor_and_a_sphere_its_radius():
    points = np.array([[sx * 0.01, sy * 0.02, sz * 0.03] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    assert reach_module._hull_depth(points) == pytest.approx(0.01)
    # An origin outside the hull may go below the floor: by no more than its distance to the farthest point.
    shifted = points + [0.05, 0.0, 0.0]
    assert reach_module._hull_depth(shifted) == pytest.approx(-np.max(np.linalg.norm(shifted, axis=1)))
