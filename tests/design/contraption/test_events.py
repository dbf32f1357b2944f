"""Event conditions (App. C.2) and causal-graph supervision (4.3, with OR-joins and duration events of 5.2)."""

from __future__ import annotations

import pytest

from design.contraption import Simulator, scenario_from_data, simulate
from design.contraption.simulation import Supervisor

FLOOR = {"name": "floor", "type": "Plane", "physics": {"restitution": 0.6}}
BALL = {"name": "ball", "type": "Ball", "shape": {"radius": 0.01}, "physics": {"mass": 0.01, "restitution": 0.6},
        "transform": {"z": 0.2}}
SHELF = {"name": "shelf", "type": "Box", "shape": {"size": [0.05, 0.05, 0.01]}, "transform": {"x": 0.2, "z": 0.1}}
RESTING = {"name": "resting", "type": "Ball", "shape": {"radius": 0.01}, "physics": {"mass": 0.01},
           "transform": {"x": 0.2, "z": 0.1151}}


def scenario(events, objects=(FLOOR, BALL, SHELF, RESTING), **settings):
    data = {"objects": list(objects), "events": events, "settings": {"max_duration": 3.0, **settings}}
    return scenario_from_data(data)


def states(result):
    return result.states()


def test_falling_contact_rising_nocontact_stopping():
    s = scenario([
        {"name": "falls", "type": "Falling", "body": "ball"},
        {"name": "lands", "type": "Contact", "a": "ball", "b": "floor", "after": ["falls"]},
        {"name": "bounces", "type": "Rising", "body": "ball", "after": ["lands"]},
        {"name": "leaves", "type": "NoContact", "a": "ball", "b": "floor", "after": ["lands"]},
        {"name": "stops", "type": "Stopping", "body": "ball", "after": ["bounces", "leaves"]},
    ])
    result = simulate(s)
    assert result.success, states(result)
    t = {name: o.time for name, o in result.events.items()}
    # Free fall from 0.19 m: about 0.197 s to the floor.
    assert t["lands"] == pytest.approx(0.197, abs=0.01)
    assert t["falls"] < t["lands"] < t["bounces"] and t["lands"] < t["leaves"] < t["stops"]


def test_toppling_pivoting_and_not_moving():
    objects = (
        {"name": "floor", "type": "Plane"},
        {"name": "domino", "type": "Box", "shape": {"size": [0.005, 0.02, 0.04]},
         "physics": {"mass": 0.01}, "transform": {"z": 0.02}},
        {"name": "ball", "type": "Ball", "shape": {"radius": 0.01}, "physics": {"mass": 0.02},
         "transform": {"x": -0.1, "z": 0.06}},
        {"name": "bystander", "type": "Box", "shape": {"size": [0.02, 0.02, 0.02]},
         "physics": {"mass": 0.01}, "transform": {"x": 0.3, "z": 0.01}},
    )
    s = scenario([
        {"name": "hit", "type": "Contact", "a": "ball", "b": "domino"},
        {"name": "turns", "type": "Pivoting", "body": "domino", "axis": [0, 1, 0], "after": ["hit"]},
        {"name": "topples", "type": "Toppling", "body": "domino", "angle": 30, "after": ["turns"]},
        {"name": "still", "type": "NotMoving", "body": "bystander", "duration": 0.3, "after": ["topples"]},
    ], objects=objects)
    sim = Simulator(s)
    world = sim.build()
    sim.client.resetBaseVelocity(world.uid("ball"), [1.0, 0, 0])
    # Drive the supervisor by hand to start the ball with a push (the scenario's root only waits for contact).
    supervisor = Supervisor(s, world)
    for step in range(1, 1000):
        sim.client.stepSimulation()
        supervisor.update(step * s.settings.time_step)
        if supervisor.verdict() is not None:
            break
    assert supervisor.verdict() is True, supervisor.state
    assert supervisor.time["still"] - supervisor.woke["still"] == pytest.approx(0.3, abs=0.003)


def test_timeout_fails_at_wake_plus_timeout_and_stops_early():
    s = scenario([
        {"name": "falls", "type": "Falling", "body": "ball"},
        {"name": "never", "type": "Falling", "body": "resting", "after": ["falls"], "timeout": 0.5},
    ])
    result = simulate(s)
    assert not result.success
    never = result.events["never"]
    assert never.state == "failure"
    assert never.time == pytest.approx(never.woke + 0.5, abs=0.0021)
    assert result.duration == pytest.approx(never.time)
    assert result.early_stopped
    full = simulate(s, early_stop=False)
    assert full.steps == 1500 and full.events == result.events and not full.success


def test_and_join_needs_every_parent_or_join_needs_one():
    events = [
        {"name": "falls", "type": "Falling", "body": "ball"},
        {"name": "lands", "type": "Contact", "a": "ball", "b": "floor", "after": ["falls"]},
        {"name": "other_falls", "type": "Falling", "body": "resting", "after": ["falls"], "timeout": 0.5},
        {"name": "joined", "type": "Rising", "body": "ball", "after": ["lands", "other_falls"]},
    ]
    with_and = simulate(scenario(events))
    assert not with_and.success
    assert with_and.events["joined"].state == "asleep"
    assert with_and.events["other_falls"].state == "failure"

    events[3] = {**events[3], "join": "any"}
    with_or = simulate(scenario(events))
    assert with_or.success, states(with_or)
    assert with_or.events["joined"].state == "success"
    assert with_or.events["joined"].woke == with_or.events["lands"].time
    # The parent that never happened does not sink the graph: its OR-child succeeded (5.2 extension).
    assert with_or.events["other_falls"].state in ("awake", "failure")


def test_or_join_fails_when_every_parent_fails():
    events = [
        {"name": "falls", "type": "Falling", "body": "ball"},
        {"name": "a", "type": "Falling", "body": "resting", "after": ["falls"], "timeout": 0.3},
        {"name": "b", "type": "Rising", "body": "resting", "after": ["falls"], "timeout": 0.4},
        {"name": "either", "type": "Stopping", "body": "ball", "after": ["a", "b"], "join": "any"},
    ]
    result = simulate(scenario(events))
    assert not result.success
    assert result.duration == pytest.approx(result.events["b"].time)  # decided when the last parent failed


def test_duration_event_waits_for_an_unbroken_hold():
    s = scenario([
        {"name": "falls", "type": "Falling", "body": "ball"},
        {"name": "rests", "type": "Contact", "a": "ball", "b": "floor", "after": ["falls"], "duration": 0.4},
    ])
    result = simulate(s)
    assert result.success
    # The ball bounces: the first contacts do not last 0.4 s, so the success comes well after the first landing.
    first_landing = 0.197
    assert result.events["rests"].time > first_landing + 0.4 + 0.05


def test_duration_event_fails_when_no_hold_starts_before_timeout():
    s = scenario([
        {"name": "falls", "type": "Falling", "body": "ball"},
        {"name": "held", "type": "Contact", "a": "ball", "b": "shelf", "after": ["falls"], "duration": 0.2,
         "timeout": 0.5},
    ])
    result = simulate(s)
    assert result.events["held"].state == "failure"
    assert result.events["held"].time == pytest.approx(result.events["held"].woke + 0.5, abs=0.0021)


def test_events_are_only_evaluated_once_awake():
    # "lands" would be true from the start for the resting ball, but it only wakes after the ball falls.
    s = scenario([
        {"name": "falls", "type": "Falling", "body": "ball"},
        {"name": "resting_contact", "type": "Contact", "a": "resting", "b": "shelf", "after": ["falls"]},
    ])
    result = simulate(s)
    assert result.success
    assert result.events["resting_contact"].time > result.events["falls"].time


def test_timeline_records_each_state_change_in_order():
    s = scenario([
        {"name": "falls", "type": "Falling", "body": "ball"},
        {"name": "lands", "type": "Contact", "a": "ball", "b": "floor", "after": ["falls"]},
    ])
    seen = []
    result = simulate(s, on_change=lambda t, st: seen.append((t, dict(st))))
    assert [(name, state) for _t, name, state in result.timeline] == [
        ("falls", "awake"), ("falls", "success"), ("lands", "awake"), ("lands", "success")]
    assert seen[0] == (0.0, {"falls": "awake", "lands": "asleep"})
    assert seen[-1][1] == {"falls": "success", "lands": "success"}
