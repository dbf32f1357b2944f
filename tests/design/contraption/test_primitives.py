"""Every primitive builds and behaves as a physical thing should (App. C.1)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from design.contraption import Simulator, check_validity, scenario_from_data, simulate
from design.contraption.primitives import body_specs, domino_poses

FLOOR = {"name": "floor", "type": "Plane"}


def scene(objects, events=None, **settings):
    events = events or [{"name": "e", "type": "NotMoving", "body": next(o["name"] for o in objects if
                                                                           o["type"] in ("Ball", "Box"))}]
    data = {"objects": [FLOOR, *objects], "events": events}
    if settings:
        data["settings"] = settings
    return scenario_from_data(data)


def run_for(scenario, seconds, x=None):
    """Step a built world for ``seconds`` and return it (with its simulator, to keep the client alive)."""
    sim = Simulator(scenario)
    world = sim.build(x)
    for _ in range(int(round(seconds / scenario.settings.time_step))):
        sim.client.stepSimulation()
        world.enforce_ropes(scenario.settings.time_step)
    return sim, world


def test_ball_falls_and_rests_on_plane():
    s = scene([{"name": "ball", "type": "Ball", "shape": {"radius": 0.01}, "physics": {"mass": 0.01},
                "transform": {"z": 0.1}}])
    sim, world = run_for(s, 1.0)
    assert world.pose("ball").position[2] == pytest.approx(0.01, abs=5e-4)


def test_box_cylinder_capsule_rest_at_their_half_heights():
    s = scene([
        {"name": "box", "type": "Box", "shape": {"size": [0.02, 0.03, 0.04]}, "physics": {"mass": 0.01},
         "transform": {"z": 0.021}},
        {"name": "cyl", "type": "Cylinder", "shape": {"radius": 0.01, "height": 0.05}, "physics": {"mass": 0.01},
         "transform": {"x": 0.1, "z": 0.026}},
        {"name": "cap", "type": "Capsule", "shape": {"radius": 0.01, "length": 0.03}, "physics": {"mass": 0.01},
         "transform": {"x": 0.2, "z": 0.026}},
    ])
    assert check_validity(s) == []
    sim, world = run_for(s, 0.5)
    assert world.pose("box").position[2] == pytest.approx(0.02, abs=5e-4)
    assert world.pose("cyl").position[2] == pytest.approx(0.025, abs=5e-4)
    assert world.pose("cap").position[2] == pytest.approx(0.025, abs=5e-4)


def test_static_object_does_not_move():
    s = scene([{"name": "shelf", "type": "Box", "shape": {"size": [0.1, 0.1, 0.01]}, "transform": {"z": 0.3}},
               {"name": "ball", "type": "Ball", "shape": {"radius": 0.01}, "physics": {"mass": 0.01},
                "transform": {"z": 0.5}}])
    sim, world = run_for(s, 0.5)
    assert world.pose("shelf").position.tolist() == [0.0, 0.0, 0.3]
    assert world.pose("ball").position[2] == pytest.approx(0.315, abs=1e-3)


def test_track_guides_a_rolling_ball_along_its_length():
    s = scene([
        {"name": "track", "type": "Track", "shape": {"length": 0.3, "width": 0.02, "height": 0.006,
                                                     "wall_thickness": 0.002},
         "transform": {"z": 0.1, "roll": 10, "heading": 30}},
        {"name": "ball", "type": "Ball", "parent": "track", "shape": {"radius": 0.008}, "physics": {"mass": 0.005},
         "transform": {"x": -0.12, "z": 0.0071}},
    ])
    assert check_validity(s) == []
    sim, world = run_for(s, 0.3)
    p = world.pose("ball").position
    direction = np.array([math.cos(math.radians(30)), math.sin(math.radians(30))])
    start = world.bodies["ball"].initial.position
    moved = p[:2] - start[:2]
    assert moved @ direction > 0.05  # rolled down the slope
    assert abs(direction[0] * moved[1] - direction[1] * moved[0]) < 0.002  # and stayed between the walls


@pytest.mark.parametrize("container", [
    {"name": "cup", "type": "Goblet", "shape": {"height": 0.06, "radius_top": 0.03, "radius_bottom": 0.02},
     "transform": {"z": 0.0303}},
    {"name": "cup", "type": "OpenBox", "shape": {"size": [0.06, 0.06, 0.04], "thickness": 0.003},
     "transform": {"z": 0.0201}},
])
def test_ball_dropped_into_goblet_or_open_box_stays_inside(container):
    s = scene([container, {"name": "ball", "type": "Ball", "shape": {"radius": 0.008},
                           "physics": {"mass": 0.005, "restitution": 0.5}, "transform": {"x": 0.004, "z": 0.15}}],
              events=[{"name": "in", "type": "Inclusion", "body": "ball", "container": "cup", "duration": 0.5}])
    assert check_validity(s) == []
    result = simulate(s)
    assert result.success
    sim, world = run_for(s, 1.5)
    assert np.hypot(*world.pose("ball").position[:2]) < 0.03


def test_empty_parent_composes_transforms():
    s = scene([
        {"name": "frame", "type": "Empty", "transform": {"x": 0.1, "heading": 90}},
        {"name": "box", "type": "Box", "parent": "frame", "shape": {"size": [0.02, 0.02, 0.02]},
         "transform": {"x": 0.05, "z": 0.0101}},
    ])
    sim, world = run_for(s, 0.0)
    np.testing.assert_allclose(world.pose("box").position, [0.1, 0.05, 0.0101], atol=1e-9)


def test_lever_pivots_about_its_hinge_when_loaded_on_one_end():
    s = scene([
        {"name": "lever", "type": "Lever", "shape": {"size": [0.2, 0.02, 0.005], "pivot": [0.0, 0.0, 0.0]},
         "physics": {"mass": 0.02}, "transform": {"z": 0.1}},
        {"name": "ball", "type": "Ball", "shape": {"radius": 0.01}, "physics": {"mass": 0.05},
         "transform": {"x": 0.08, "z": 0.1126}},
    ])
    sim, world = run_for(s, 0.15)
    pose = world.pose("lever")
    np.testing.assert_allclose(pose.position, [0.0, 0.0, 0.1], atol=1e-3)  # the hinge holds the centre
    tilt = pose.rotation.as_rotvec()
    assert tilt[1] > 0.1  # turned about +y: the +x end (with the ball) went down
    assert abs(tilt[0]) < 0.01 and abs(tilt[2]) < 0.01


def test_pivot_with_offset_axis_is_a_pendulum():
    s = scene([
        {"name": "bar", "type": "Box", "shape": {"size": [0.01, 0.01, 0.1]}, "physics": {"mass": 0.01},
         "transform": {"z": 0.2, "roll": 30}},
        # The hinge at the bar's top end (0.05 m from its centre, rolled 30 degrees).
        {"name": "hinge", "type": "Pivot", "shape": {"body": "bar", "axis": "y"},
         "transform": {"x": 0.025, "z": 0.2433013}},
    ])
    sim, world = run_for(s, 0.0)
    hinge = np.array([0.025, 0.0, 0.2433013])
    angles, distances = [], []
    for _ in range(600):
        sim.client.stepSimulation()
        pose = world.pose("bar")
        angles.append(pose.rotation.as_rotvec()[1])
        distances.append(np.linalg.norm(pose.position - hinge))
    assert max(angles) > 0.4 and min(angles) < -0.4  # swings through the vertical both ways
    np.testing.assert_allclose(distances, 0.05, atol=1e-3)  # about the hinge


def test_pivot_between_two_bodies_and_fastener_glue():
    s = scene([
        {"name": "base", "type": "Box", "shape": {"size": [0.05, 0.05, 0.05]}, "physics": {"mass": 0.1},
         "transform": {"z": 0.0251}},
        {"name": "flag", "type": "Box", "shape": {"size": [0.01, 0.01, 0.05]}, "physics": {"mass": 0.01},
         "transform": {"x": 0.03, "z": 0.08}},
        {"name": "glue", "type": "Fastener", "shape": {"bodies": ["base", "flag"]}},
        {"name": "held", "type": "Ball", "shape": {"radius": 0.01}, "physics": {"mass": 0.01},
         "transform": {"x": 0.2, "z": 0.2}},
        {"name": "nail", "type": "Fastener", "shape": {"bodies": ["held"]}},
    ])
    assert check_validity(s) == []
    sim, world = run_for(s, 0.5)
    np.testing.assert_allclose(world.pose("flag").position, [0.03, 0.0, 0.08], atol=2e-3)
    np.testing.assert_allclose(world.pose("held").position, [0.2, 0.0, 0.2], atol=1e-3)


def test_pulley_turns_about_its_axis_only():
    s = scene([
        {"name": "wheel", "type": "Pulley", "shape": {"radius": 0.03, "height": 0.01}, "physics": {"mass": 0.02},
         "transform": {"z": 0.2}},
        {"name": "ball", "type": "Ball", "shape": {"radius": 0.01}, "physics": {"mass": 0.05},
         "transform": {"x": 0.02, "z": 0.3}},
    ])
    sim, world = run_for(s, 0.4)
    pose = world.pose("wheel")
    np.testing.assert_allclose(pose.position, [0, 0, 0.2], atol=1e-3)
    rotvec = pose.rotation.as_rotvec()
    assert abs(rotvec[1]) > 0.05 and abs(rotvec[0]) < 0.01 and abs(rotvec[2]) < 0.01


def test_domino_run_from_poses_path_spacing_and_count():
    from design.contraption.scenario import domino_count

    assert domino_poses({"poses": [[0, 0, 0], [0.02, 0, 10]]}) == [(0.0, 0.0, 0.0), (0.02, 0.0, 10.0)]
    shape = {"path": [[0, 0], [0.1, 0], [0.1, 0.1]], "spacing": 0.025}
    poses = domino_poses(shape)
    assert len(poses) == domino_count(shape) == 9
    assert poses[4][:2] == pytest.approx((0.1, 0.0)) and poses[5][2] == pytest.approx(90.0)
    counted = domino_poses({"path": [[0, 0], [0.1, 0]], "count": 5})
    assert [p[0] for p in counted] == pytest.approx([0, 0.025, 0.05, 0.075, 0.1])
    obj = scene([{"name": "run", "type": "DominoRun", "transform": {"x": 1.0},
                  "shape": {"size": [0.005, 0.02, 0.04], "path": [[0, 0], [0.03, 0]], "count": 3}},
                 {"name": "b", "type": "Ball", "shape": {"radius": 0.01}}]).object("run")
    labels = [spec.label for spec in body_specs(obj)]
    assert labels == ["run[0]", "run[1]", "run[2]"]


def test_domino_run_topples_in_sequence():
    s = scene(
        [{"name": "run", "type": "DominoRun", "shape": {"size": [0.005, 0.02, 0.04], "path": [[0, 0], [0.09, 0]],
                                                        "count": 7},
          "physics": {"mass": 0.01, "friction": 0.6}},
         {"name": "ball", "type": "Ball", "shape": {"radius": 0.01}, "physics": {"mass": 0.02},
          "transform": {"x": -0.05, "z": 0.035}}],
        events=[{"name": "first", "type": "Toppling", "body": "run[0]"},
                {"name": "last", "type": "Toppling", "body": "run[-1]", "after": ["first"]}],
    )
    sim = Simulator(s)
    world = sim.build()
    sim.client.resetBaseVelocity(world.uid("ball"), [0.5, 0, 0])
    times = {}
    for step in range(1, 800):
        sim.client.stepSimulation()
        for i in range(7):
            if i not in times and world.pose(f"run[{i}]").rotation.magnitude() > math.radians(15):
                times[i] = step
    assert sorted(times) == list(range(7))
    assert [times[i] for i in range(7)] == sorted(times[i] for i in range(7))


def test_tension_rope_is_a_pendulum_string():
    s = scene([
        {"name": "hook", "type": "Box", "shape": {"size": [0.01, 0.01, 0.01]}, "transform": {"z": 0.3}},
        {"name": "bob", "type": "Ball", "shape": {"radius": 0.01}, "physics": {"mass": 0.02},
         "transform": {"x": 0.1, "z": 0.3}},
        {"name": "rope", "type": "TensionRope", "shape": {"ends": ["hook", "bob"]}},
    ])
    assert check_validity(s) == []
    sim, world = run_for(s, 0.0)
    distances = []
    for _ in range(300):
        sim.client.stepSimulation()
        world.enforce_ropes(s.settings.time_step)
        distances.append(np.linalg.norm(world.pose("bob").position - [0, 0, 0.3]))
    assert max(distances) < 0.1 * 1.01  # inextensible (1 % at most)
    assert world.pose("bob").position[2] < 0.25  # it swung down
    assert min(distances[-50:]) > 0.095  # and the string stayed taut


def test_tension_rope_through_guide_and_slack():
    s = scene([
        {"name": "anchor", "type": "Box", "shape": {"size": [0.01, 0.01, 0.01]}, "transform": {"z": 0.5}},
        {"name": "weight", "type": "Box", "shape": {"size": [0.02, 0.02, 0.02]}, "physics": {"mass": 0.05},
         "transform": {"x": 0.2, "z": 0.3}},
        {"name": "rope", "type": "TensionRope",
         "shape": {"ends": ["anchor", "weight"], "guides": [[0.2, 0.0, 0.5]], "length": 0.45}},
    ])
    sim, world = run_for(s, 0.6)
    _, length = world.rope_path(world.ropes[0])
    assert length == pytest.approx(0.45, abs=0.005)  # fell 0.15 m then caught by the rope
    assert world.pose("weight").position[2] == pytest.approx(0.25, abs=0.01)


def test_rope_pulley_heavier_side_lifts_the_lighter():
    s = scene([
        {"name": "wheel", "type": "Pulley", "shape": {"radius": 0.01, "height": 0.005}, "physics": {"mass": 0.005},
         "transform": {"z": 0.4}},
        {"name": "heavy", "type": "Box", "shape": {"size": [0.02, 0.02, 0.02]}, "physics": {"mass": 0.05},
         "transform": {"x": 0.05, "z": 0.25}},
        {"name": "light", "type": "Box", "shape": {"size": [0.02, 0.02, 0.02]}, "physics": {"mass": 0.02},
         "transform": {"x": -0.05, "z": 0.011}},
        {"name": "rope", "type": "RopePulley", "shape": {"ends": ["heavy", "light"], "pulleys": ["wheel"]}},
    ])
    assert check_validity(s) == []
    sim, world = run_for(s, 0.15)
    drop = 0.25 - world.pose("heavy").position[2]
    rise = world.pose("light").position[2] - 0.011
    expected = 0.5 * (0.03 / 0.07) * 9.81 * 0.15**2  # Atwood machine
    assert drop == pytest.approx(expected, rel=0.15)
    assert rise > 0.75 * drop  # less than the drop: the light box also swings in under the wheel
    _, length = world.rope_path(world.ropes[0])
    assert length == pytest.approx(world.ropes[0].length, abs=2e-3)


def test_rope_too_short_for_layout_is_invalid():
    s = scene([
        {"name": "hook", "type": "Box", "shape": {"size": [0.01, 0.01, 0.01]}, "transform": {"z": 0.3}},
        {"name": "bob", "type": "Ball", "shape": {"radius": 0.01}, "physics": {"mass": 0.02},
         "transform": {"x": 0.1, "z": 0.3}, "ranges": {"x": [0.05, 0.2]}},
        {"name": "rope", "type": "TensionRope", "shape": {"ends": ["hook", "bob"], "length": 0.12}},
    ])
    assert check_validity(s, [0.1]) == []
    problems = check_validity(s, [0.15])
    assert [p.kind for p in problems] == ["rope"]
    assert problems[0].amount == pytest.approx(0.03, abs=1e-6)
    assert "rope rope" in problems[0].message and "30.0 mm" in problems[0].message


def test_interpenetration_names_the_pair_and_depth():
    s = scene([
        {"name": "a", "type": "Box", "shape": {"size": [0.02, 0.02, 0.02]}, "physics": {"mass": 0.01},
         "transform": {"z": 0.0101}, "ranges": {"x": [-0.05, 0.05]}},
        {"name": "b", "type": "Box", "shape": {"size": [0.02, 0.02, 0.02]}, "physics": {"mass": 0.01},
         "transform": {"x": 0.05, "z": 0.0101}},
    ])
    assert check_validity(s, [0.0]) == []
    assert check_validity(s, [0.0295]) == []  # 0.5 mm: within 5 % of 20 mm
    problems = check_validity(s, [0.04])
    assert len(problems) == 1
    assert problems[0].objects == ("a", "b")
    assert problems[0].amount == pytest.approx(0.01, abs=3e-4)
    assert "a and b interpenetrate by 10.0" in problems[0].message


def test_clearances_are_signed_margins_matching_validity():
    from design.contraption import clearances

    s = scene([
        {"name": "a", "type": "Box", "shape": {"size": [0.02, 0.02, 0.02]}, "physics": {"mass": 0.01},
         "transform": {"z": 0.0101}, "ranges": {"x": [-0.05, 0.05]}},
        {"name": "b", "type": "Box", "shape": {"size": [0.02, 0.02, 0.02]}, "physics": {"mass": 0.01},
         "transform": {"x": 0.05, "z": 0.0101}},
    ])

    def margin(x):
        found = [c for c in clearances(s, [x], radius=0.01) if c.objects == ("a", "b")]
        return found[0].margin if found else None

    assert margin(-0.05) is None  # 8 cm apart: beyond the radius
    assert margin(0.025) == pytest.approx(0.005 + 0.001, abs=2e-4)  # 5 mm gap + 1 mm tolerance
    assert margin(0.0295) > 0 and check_validity(s, [0.0295]) == []
    assert margin(0.04) == pytest.approx(-0.01 + 0.001, abs=3e-4) and check_validity(s, [0.04])
