"""build_guide: the guide plane, true outlines, tags, reference tags and the assembly order of the examples."""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path

import numpy as np
import pytest
import shapely
import tomllib
from shapely.geometry import box

from design.contraption import load_scenario, scenario_from_data
from projector.build import build_guide, steps_text
from projector.errors import ProjectorError
from projector.guide import REFERENCE_TAG_IDS, ParameterTolerance, PartKind

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
ALL = sorted(p.name for p in EXAMPLES.glob("*.toml"))


@functools.cache
def _scenario(name: str):
    return load_scenario(EXAMPLES / name)


@functools.cache
def _guide(name: str, view: str | None = None):
    """The guide of an example at its default layout (built once: several tests read it)."""
    return build_guide(_scenario(name), view=view)


def _data(name: str) -> dict:
    return tomllib.loads((EXAMPLES / name).read_text())


@pytest.fixture(scope="module")
def ballrun():
    scenario = _scenario("ballrun.toml")
    return scenario, build_guide(scenario, scenario.layout("success"))


@pytest.fixture(scope="module")
def switch():
    scenario = _scenario("causalityswitch_ball.toml")
    return scenario, build_guide(scenario, scenario.layout("success"))


def _ry(degrees: float) -> np.ndarray:
    """The file's roll: a right-handed turn about +y (written out here, not taken from the code under test)."""
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def test_ballrun_is_drawn_on_its_board_as_seen_from_in_front(ballrun):
    scenario, guide = ballrun
    assert guide.view == "side"
    # The board faces +y: from in front of it, world +x runs to the maker's left and z up.
    assert np.allclose(guide.plane.u_axis, [-1, 0, 0]) and np.allclose(guide.plane.v_axis, [0, 0, 1])
    assert np.allclose(guide.plane.normal, [0, 1, 0])
    layout = scenario.design_space.as_dict(scenario.layout("success"))
    bottom = guide.part("bottom_track")
    assert bottom.center_mm == pytest.approx((-50.0, 1000 * layout["bottom_track.z"]))
    # A positive roll tilts the +x end down: seen from in front, that end is on the left, so the part turns
    # counter-clockwise by the roll.
    assert bottom.heading_deg == pytest.approx(layout["bottom_track.roll"])
    # The ball rides on the top track (its parent): its centre is the track's transform applied to its own.
    track = np.array([layout["top_track.x"], 0.0135, layout["top_track.z"]])
    ball = track + _ry(layout["top_track.roll"]) @ np.array([-0.13, 0.0, 0.0081])
    assert guide.part("ball").center_mm == pytest.approx((-1000 * ball[0], 1000 * ball[2]), abs=1e-6)
    # Not mirrored: the ball starts at the high end of the top track, which rises to the maker's right.
    top = guide.part("top_track")
    assert top.heading_deg > 0 and guide.part("ball").center_mm[0] > top.center_mm[0]
    assert guide.part("ball").center_mm[1] > top.center_mm[1]


def test_causalityswitch_top_and_side(switch):
    scenario, top = switch
    assert top.view == "top"
    assert np.allclose(top.plane.u_axis, [1, 0, 0]) and np.allclose(top.plane.v_axis, [0, 1, 0])
    assert top.part("plank").center_mm == pytest.approx((1000 * scenario.layout("success")[3], -60.0))
    assert top.part("switch_centre").heading_deg == pytest.approx(45.0)
    side = build_guide(scenario, scenario.layout("success"), view="side")
    assert side.view == "side"
    # No board in this scenario: a virtual one behind the parts, facing +y like BALLRUN's.
    assert np.allclose(side.plane.u_axis, [-1, 0, 0]) and np.allclose(side.plane.normal, [0, 1, 0])
    assert side.part("plank").center_mm[1] == pytest.approx(152.1)
    # The track joint's roll is the track's turn on the board.
    assert side.part("ball_track").heading_deg == pytest.approx(scenario.layout("success")[1])
    assert [p.name for p in side.parts] == [p.name for p in top.parts]


@pytest.mark.parametrize("name", ALL)
def test_every_example_builds_in_both_views_with_every_part_numbered(name):
    scenario = _scenario(name)
    expected = {o.name for o in scenario.objects if o.type not in ("Plane", "Empty", "Pivot", "Fastener",
                                                                       "TensionRope", "RopePulley")}
    for view in ("top", "side"):
        guide = _guide(name, view)
        assert {p.name for p in guide.parts} == expected
        assert [p.step for p in guide.parts] == list(range(1, len(expected) + 1))
        for part in guide.parts:
            assert part.outline.is_valid and part.outline.area > 0
        lines = steps_text(guide)
        assert len(lines) == len(expected)
        for line, part in zip(lines, guide.parts):
            assert line.startswith(f"{part.step}. ") and f"`{part.name}`" in line


def test_the_views_chosen_for_the_examples():
    chosen = {name: _guide(name).view for name in ALL}
    assert chosen == {"ballrun.toml": "side", "branching.toml": "top", "causalityswitch_ball.toml": "top",
                      "causalityswitch_dominoes.toml": "top", "longchain.toml": "side", "simple.toml": "top",
                      "teapotadventure.toml": "side"}


def test_static_parts_first_and_the_ball_last(ballrun, switch):
    _, guide = ballrun
    names = [p.name for p in guide.parts]
    statics = [p.name for p in guide.parts if p.kind is PartKind.STATIC]
    assert set(statics) == {"top_track", "bottom_track", "stop", "goblet"}
    assert names[:len(statics)] == statics
    assert names[-1] == "ball"  # the first event's actor: the trigger
    assert names.index("base_lever") < names.index("high_plank")  # parent first
    _, guide = switch
    names = [p.name for p in guide.parts]
    assert names[0] == "support" and names[-1] == "starter" and names[-2] == "ball"


def test_what_rests_on_the_trigger_comes_after_it():
    guide = _guide("longchain.toml")
    names = [p.name for p in guide.parts]
    # The box lever starts the chain under the weight of its box: the lever, its box, then the weight in it.
    assert names[-3:] == ["box_lever", "weight_box", "box_weight"]
    # A cage that covers a ball goes on after the ball (TEAPOTADVENTURE), and the trigger ball at the very end.
    names = [p.name for p in _guide("teapotadventure.toml").parts]
    assert names.index("ball2") < names.index("cage") and names[-1] == "ball1"


def test_a_track_shows_its_u_only_seen_along_it(ballrun):
    _, guide = ballrun
    # From in front of the board (and from above) a track's floor and walls cast one rectangle.
    track = guide.part("top_track").outline
    assert track.area == pytest.approx(track.convex_hull.area, rel=1e-6)
    data = _data("ballrun.toml")
    top = next(o for o in data["objects"] if o["name"] == "top_track")
    top["transform"].update(heading=90.0, roll=0.0)  # turned across the board, level: its end faces the maker
    top["ranges"] = {}
    data.pop("layouts")
    guide = build_guide(scenario_from_data(data), view="side")
    outline = guide.part("top_track").outline
    assert outline.area < 0.95 * outline.convex_hull.area
    # The U's opening: the channel between the walls is outside the outline, the walls and floor inside.
    centre = guide.part("top_track").center_mm
    assert not outline.contains(shapely.Point(centre[0], centre[1] + 2.0))
    assert outline.contains(shapely.Point(centre[0] + 11.0, centre[1]))


def test_domino_runs_are_drawn_domino_by_domino(switch):
    _, guide = switch
    wave = guide.part("wave").outline
    assert wave.geom_type == "MultiPolygon" and len(wave.geoms) == 22
    for domino in wave.geoms:
        assert domino.area == pytest.approx(7 * 20, rel=1e-6)  # each domino's 7 x 20 mm footprint


@pytest.mark.parametrize("name", ALL)
def test_reference_tags_sit_outside_every_outline(name):
    for view in ("top", "side"):
        guide = _guide(name, view)
        assert [t.id for t in guide.reference_tags] == list(REFERENCE_TAG_IDS)
        parts = shapely.union_all([p.outline for p in guide.parts])
        u0, v0, u1, v1 = guide.extent_mm
        for tag in guide.reference_tags:
            half = tag.size_mm / 2 + tag.size_mm / 8  # the black square and its white border
            square = box(tag.center_mm[0] - half, tag.center_mm[1] - half, tag.center_mm[0] + half,
                         tag.center_mm[1] + half)
            assert square.distance(parts) >= 10.0 - 1e-9
            assert u0 <= square.bounds[0] and square.bounds[2] <= u1 and v0 <= square.bounds[1]
            assert square.bounds[3] <= v1
        corners = [t.center_mm for t in guide.reference_tags]
        # Counter-clockwise from the lower left, as the maker sees the plane.
        assert corners[0][0] < corners[1][0] and corners[1][1] < corners[2][1] and corners[3][0] < corners[2][0]


@pytest.mark.parametrize("name", ALL)
def test_part_tags_fit_inside_their_parts_and_never_clash(name):
    scenario = _scenario(name)
    guide = _guide(name)
    ids = [p.tag_id for p in guide.parts if p.tag_id is not None]
    assert len(ids) == len(set(ids)) and not set(ids) & set(REFERENCE_TAG_IDS)
    assert ids == sorted(ids)  # numbered in step order
    for part in guide.parts:
        if scenario.object(part.name).type == "Ball":
            assert part.tag_id is None
        if part.tag_id is None:
            continue
        u, v = part.tag_center_mm
        half = part.tag_size_mm / 2
        assert part.tag_size_mm in (10, 15, 20, 25)
        assert part.outline.contains(box(u - half, v - half, u + half, v + half).buffer(2.0))
        assert isinstance(part.tag_height_mm, float) and part.tag_height_mm > 0


def test_tag_height_is_the_face_towards_the_maker():
    guide = _guide("branching.toml")
    track = guide.part("track")  # a static track at z = 30 mm, 6 mm high, 2 mm floor: the tag sits on its floor
    assert track.tag_id is not None
    assert track.tag_height_mm == pytest.approx(30 - 3 + 2, abs=0.05)
    guide = _guide("teapotadventure.toml")
    pulley = guide.part("pulley")  # a wheel 8 mm thick at y = 0, its axis the board's normal: its face at y = 4 mm
    assert pulley.tag_height_mm == pytest.approx(4.0 - 1000 * guide.plane.origin[1], abs=0.05)


def test_a_part_hidden_behind_another_gets_no_tag():
    guide = _guide("longchain.toml")
    # The weight stands inside the weight box, behind its front wall: the camera could not see a tag on it.
    weight, box_ = guide.part("box_weight"), guide.part("weight_box")
    assert box_.outline.contains(weight.outline) and box_.tag_id is not None and weight.tag_id is None


def test_a_scenario_tag_is_kept_and_auto_ids_skip_it():
    data = _data("simple.toml")
    track = next(o for o in data["objects"] if o["name"] == "track")
    track["tag"] = {"id": 0, "x": 0.01, "z": 0.0015, "size": 0.012}
    dominoes = next(o for o in data["objects"] if o["name"] == "dominoes")
    dominoes["shape"]["size"] = [0.03, 0.04, 0.04]  # big enough for a tag each: the run gets the next free id
    guide = build_guide(scenario_from_data(data))
    assert guide.part("track").tag_id == 0 and guide.part("track").tag_size_mm == pytest.approx(12.0)
    assert guide.part("track").tag_center_mm[0] == pytest.approx(-60.0 + 10.0 * math.cos(math.radians(30)), abs=1)
    assert guide.part("dominoes").tag_id == 1
    track["tag"]["id"] = 584
    with pytest.raises(ProjectorError, match="reference tag"):
        build_guide(scenario_from_data(data))


def test_a_domino_runs_tags_on_its_first_and_last_dominoes_are_drawn_and_listed(tmp_path):
    import io

    from projector.svg import write_svg

    data = _data("simple.toml")
    run = next(o for o in data["objects"] if o["name"] == "dominoes")
    run["shape"] = {"size": [0.03, 0.04, 0.04], "path": [[0.0, 0.0], [0.12, 0.0]], "count": 3}
    run["tag"] = [{"id": 5, "body": 0, "z": 0.02, "size": 0.02, "angle": 90}, {"id": 6, "body": -1, "z": 0.02}]
    guide = build_guide(scenario_from_data(data), view="top")
    dominoes = guide.part("dominoes")
    assert dominoes.tag_id is None and [(b.body, b.tag_id) for b in dominoes.body_tags] == [(0, 5), (2, 6)]
    first, last = dominoes.body_tags
    assert first.tag_center_mm == pytest.approx((20.0, 0.0)) and last.center_mm == pytest.approx((140.0, 0.0))
    assert first.tag_heading_deg == pytest.approx(90.0) and first.tag_height_mm == pytest.approx(40.0)
    assert [t.tag_id for t in dominoes.tag_views()] == [5, 6]
    entry = next(p for p in guide.manifest()["parts"] if p["name"] == "dominoes")
    assert [b["tag_id"] for b in entry["body_tags"]] == [5, 6] and entry["tag_id"] is None
    svg = io.StringIO()
    write_svg(guide, svg)
    assert 'id="tag-5"' in svg.getvalue() and 'id="tag-6"' in svg.getvalue()
    assert guide.part("track").tag_id not in (5, 6)  # the guide's own ids skip them


def test_one_tag_size_for_all():
    data = _data("longchain.toml")
    for obj in data["objects"]:
        obj.pop("tag", None)  # the example's own tags keep their sizes: the option sizes the guide's own
    guide = build_guide(scenario_from_data(data), tag_size_mm=10)
    assert {p.tag_size_mm for p in guide.parts if p.tag_id is not None} == {10.0}
    guide = build_guide(_scenario("longchain.toml"), reference_tag_size_mm=60)
    assert {t.size_mm for t in guide.reference_tags} == {60.0}


def test_tolerances_go_to_the_parts_they_move_and_set_the_care(ballrun):
    scenario, _ = ballrun
    tolerances = {
        "bottom_track.z": ParameterTolerance("bottom_track.z", 2.1, "mm", 0.9),
        "bottom_track.roll": ParameterTolerance("bottom_track.roll", 1.5, "deg", 0.9),
        "goblet.x": ParameterTolerance("goblet.x", 8.0, "mm", 0.9),
        "goblet.z": ParameterTolerance("goblet.z", 12.0, "mm", 0.9),
        "goblet.roll": ParameterTolerance("goblet.roll", 7.0, "deg", 0.9),
        "top_track.x": ParameterTolerance("top_track.x", 4.0, "mm", 0.9),
        "top_track.z": ParameterTolerance("top_track.z", None, "mm", None, source="none"),
    }
    guide = build_guide(scenario, scenario.layout("success"), tolerances=tolerances)
    assert guide.tolerance_source == "model"
    bottom = guide.part("bottom_track")
    assert [t.parameter for t in bottom.tolerances] == ["bottom_track.z", "bottom_track.roll"]
    assert bottom.care == "tight" and guide.part("goblet").care == "loose" and guide.part("top_track").care == "normal"
    assert guide.part("ball").care is None and guide.part("ball").tolerances == ()
    line = steps_text(guide)[[p.name for p in guide.parts].index("bottom_track")]
    assert line == ("2. Fix `bottom_track`: centre (-50.0, 44.5) mm, turned -10.7 deg, "
                    "tolerance +-2.1 mm / +-1.5 deg")
    assert "tolerance" not in steps_text(guide)[-1]
    assert build_guide(scenario).tolerance_source == "none"


def test_a_delta_bound_only_by_the_range_end_is_no_tolerance_to_keep(ballrun):
    # the layout sits at its range's end: 0.02 mm is where the design space stops, not where success falls
    scenario, _ = ballrun
    tolerances = {
        "top_track.z": ParameterTolerance("top_track.z", 0.02, "mm", 1.0, bound_limited=True),
        "top_track.roll": ParameterTolerance("top_track.roll", 9.2, "deg", 1.0),
    }
    guide = build_guide(scenario, scenario.layout("success"), tolerances=tolerances)
    top = guide.part("top_track")
    assert top.care == "normal"  # not tight (a lower bound is not loose either): design.robust.tolerance.care_level
    assert steps_text(guide)[0].endswith("tolerance +-9.2 deg")
    assert [t["bound_limited"] for t in guide.manifest()["parts"][0]["tolerances"]] == [True, False]


def test_an_empty_frame_s_parameters_belong_to_the_parts_it_carries(switch):
    scenario, _ = switch
    tolerance = {"switch.x": ParameterTolerance("switch.x", 3.0, "mm", 0.9)}
    guide = build_guide(scenario, tolerances=tolerance)
    assert guide.part("wave").parameters == ("switch.x",) and guide.part("wave").care == "normal"
    assert guide.part("ball_track").parameters == ("track_joint.z", "track_joint.roll")


def test_manifest_round_trips_through_json(ballrun):
    _, guide = ballrun
    manifest = guide.manifest()
    again = json.loads(json.dumps(manifest))
    assert again == manifest
    assert again["view"] == "side" and again["units"] == "mm"
    assert [p["name"] for p in again["parts"]] == [p.name for p in guide.parts]
    for part in again["parts"]:
        for ring in part["outline_mm"]:
            assert ring[0] == ring[-1] and len(ring) >= 4


def test_bad_input_is_one_clear_error():
    scenario = _scenario("ballrun.toml")
    with pytest.raises(ProjectorError, match="view: expected one of top, side, got 'front'"):
        build_guide(scenario, view="front")
    x = scenario.default_layout()
    x[0] = 5.0
    with pytest.raises(ProjectorError, match=r"top_track\.x = 5 is outside its range"):
        build_guide(scenario, x)
    with pytest.raises(ProjectorError, match="unknown layout parameter 'track.x'"):
        build_guide(scenario, tolerances={"track.x": ParameterTolerance("track.x", 1.0, "mm")})
    with pytest.raises(ProjectorError, match="tag_size_mm: expected a size in mm > 0"):
        build_guide(scenario, tag_size_mm=0)
