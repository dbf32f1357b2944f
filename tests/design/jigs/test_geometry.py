"""The jigs' geometry: a stand carries its part exactly where the layout puts it, and follows the layout."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from shapely.geometry import Point

from design.jigs import JigSettings, PartInput, plan_jigs
from projector.build import build_guide
from station.services.contraption import open_scenario
from station.services.jig_plan import JIG_TAG_IDS, JigOptions
from station.services.jigs import make_jigs
from vision.tags import tag_cells

SETTINGS = JigSettings(thickness=3.0, sheet=(400.0, 400.0))


def write_layout(tmp_path, name: str, values: dict[str, float]) -> str:
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps({"parameters": values}))
    return str(path)


def stand_of(scenario: str, layout: str, part: str, **options):
    result = make_jigs(scenario, layout, JigOptions(**options), tolerances=False)
    jigs = [j for j in result.plan.jigs if j.part == part]
    assert len(jigs) == 1, [j.part for j in result.plan.jigs]
    return jigs[0]


def angle(support) -> float:
    (x0, y0), (x1, y1) = support
    return math.degrees(math.atan2(y1 - y0, x1 - x0))


SIMPLE = {"track.x": -0.06, "track.z": 0.06, "track.roll": 30.0}
SWITCH = {"track_joint.z": 0.0364, "track_joint.roll": -11.4552, "switch.x": -0.4421, "plank.x": 0.0248}


@pytest.mark.parametrize("scenario, values, part, height", [
    ("simple", SIMPLE, "track", "track.z"),
    ("causalityswitch_ball", SWITCH, "ball_track", "track_joint.z"),
])
def test_five_millimetres_higher_moves_the_support_up_five_millimetres(tmp_path, scenario, values, part, height):
    before = stand_of(scenario, write_layout(tmp_path, "before", values), part)
    after = stand_of(scenario, write_layout(tmp_path, "after", {**values, height: values[height] + 0.005}), part)
    moved = np.asarray(after.support) - np.asarray(before.support)
    assert moved[:, 1] == pytest.approx([5.0, 5.0], abs=0.1)  # up by 5 mm at both ends
    assert moved[:, 0] == pytest.approx([0.0, 0.0], abs=0.1)  # along the table, nothing
    assert angle(after.support) == pytest.approx(angle(before.support), abs=0.1)


@pytest.mark.parametrize("scenario, values, part, tilt", [
    ("simple", SIMPLE, "track", "track.roll"),
    ("causalityswitch_ball", SWITCH, "ball_track", "track_joint.roll"),
])
def test_five_degrees_more_tilt_turns_the_support_five_degrees(tmp_path, scenario, values, part, tilt):
    before = stand_of(scenario, write_layout(tmp_path, "before", values), part)
    after = stand_of(scenario, write_layout(tmp_path, "after", {**values, tilt: values[tilt] + 5.0}), part)
    assert abs(angle(after.support) - angle(before.support)) == pytest.approx(5.0, abs=0.1)


def test_the_support_is_the_tracks_underside_at_the_layout(tmp_path):
    # SIMPLE's track: 100 mm long, its channel 3 mm high, centre 60 mm above the table, rolled 30 deg (its +x end,
    # towards the dominoes, down). Its underside is 1.5 mm below its centre line: 58.70 mm at the middle, +-25 mm at
    # the ends, 86.60 mm apart along the table.
    jig = stand_of("simple", write_layout(tmp_path, "l", SIMPLE), "track")
    (x0, y0), (x1, y1) = jig.support
    middle = 60.0 - 1.5 * math.cos(math.radians(30))
    assert (y0, y1) == pytest.approx((middle + 25.0, middle - 25.0), abs=0.01)
    assert x1 - x0 == pytest.approx(100.0 * math.cos(math.radians(30)), abs=0.01)
    assert jig.stop == "lower end" and jig.faces == "front"
    assert jig.parameters == ("track.x", "track.z", "track.roll")
    # the plate stands on the table (y = 0) and rises to the support, no higher but for the stop past the lower end
    assert jig.outline.bounds[1] == pytest.approx(0.0, abs=1e-9)
    assert jig.outline.bounds[3] == pytest.approx(y0, abs=0.01)
    # the base lies on the guide sheet under the track's middle line, across the track's x
    assert jig.footprint.contains(Point(-60.0, 0.0))
    assert jig.kind == "stand" and jig.thickness_mm == 3.0


def test_the_stop_rises_as_high_as_the_part_end_and_no_higher(tmp_path):
    jig = stand_of("simple", write_layout(tmp_path, "l", SIMPLE), "track")
    (x0, y0), (x1, y1) = jig.support
    along = np.array([x1 - x0, y1 - y0]) / math.hypot(x1 - x0, y1 - y0)
    up = np.array([-along[1], along[0]])
    rise = max((np.asarray(p) - [x1, y1]) @ up for p in jig.outline.exterior.coords)
    assert rise == pytest.approx(1.0, abs=1e-3)  # the track's floor: 1 mm (its walls are 3 mm, beside the plate)


def test_a_stand_cut_back_from_a_part_under_its_end_holds_the_other_end(tmp_path):
    # BRANCHING's goblet stands under the track's lower end (the ball drops into it): the plate stops short of it
    # and the stop holds the upper end.
    jig = stand_of("branching", "success", "track")
    assert jig.stop == "upper end"
    assert any("goblet" in note for note in jig.notes)
    guide = make_jigs("branching", "success", tolerances=False).job.guide
    goblet = guide.part("goblet").outline
    assert not jig.footprint.buffer(-0.5).intersects(goblet.buffer(-1.0))


def test_every_jig_gets_its_own_tag_from_a_range_the_guide_does_not_use():
    result = make_jigs("ballrun", None, tolerances=False)
    guide = result.job.guide
    used = {p.tag_id for p in guide.parts} | {t.id for t in guide.reference_tags}
    tags = [j.tag_id for j in result.plan.jigs]
    assert len(tags) >= 2 and None not in tags
    assert len(set(tags)) == len(tags) and all(t in JIG_TAG_IDS and t not in used for t in tags)


def test_a_height_beyond_the_sheet_is_set_by_hand(tmp_path):
    result = make_jigs("simple", write_layout(tmp_path, "l", SIMPLE), JigOptions(sheet=(60.0, 60.0)),
                       tolerances=False)
    assert not result.plan.jigs
    (entry,) = result.plan.by_hand
    assert entry.part == "track" and entry.set_with == "ruler"
    assert set(entry.parameters) == {"track.z", "track.roll"}
    assert "larger than the 60 x 60 mm sheet" in entry.reason
    assert "ruler" in entry.how and "protractor" in entry.how
    # and the guide says so in the track's step, with the ruler
    step = result.job.steps[0]
    assert "no jig: its stand would be" in step


def test_a_part_the_layout_puts_through_the_table_gets_no_stand_and_a_reason(tmp_path):
    # its lower end 21 mm under the table top: a plate there would cross itself (shapely refused to union it)
    layout = write_layout(tmp_path, "l", {"track.x": -0.0817, "track.z": 0.0169, "track.roll": 47.5})
    result = make_jigs("simple", layout, JigOptions(), tolerances=False)
    assert not result.plan.jigs
    (entry,) = result.plan.by_hand
    assert entry.part == "track" and "21.0 mm below the table top" in entry.reason


def test_a_shape_shapely_cannot_compute_leaves_its_part_by_hand_and_the_plan_goes_on(tmp_path, monkeypatch):
    # no layout of the examples makes shapely fail any more (a part through the table top was the one: above, and
    # random layouts of every example find no other), so the failure is injected where the plate meets the other
    # parts: `station jigs`, the guide and the loop get the part set by hand with shapely's words, not a traceback
    from shapely.errors import GEOSException

    from design.jigs import plan

    def fails(self, name, plate, frame):
        raise GEOSException("TopologyException: side location conflict at 19.3 0. This can occur if the input "
                            "geometry is invalid.")

    monkeypatch.setattr(plan._Context, "_blocked", fails)
    result = make_jigs("simple", write_layout(tmp_path, "l", SIMPLE), JigOptions(), tolerances=False)
    assert not result.plan.jigs
    (entry,) = result.plan.by_hand
    assert entry.part == "track" and set(entry.parameters) == {"track.z", "track.roll"}
    assert entry.reason == ("its jig's shape cannot be computed at this layout (shapely: TopologyException: side "
                            "location conflict at 19.3 0)")
    assert "(no jig: its jig's shape cannot be computed" in result.job.steps[0]


def test_a_part_hanging_from_a_rope_is_set_by_hand(tmp_path):
    scenario = tmp_path / "hanging.toml"
    scenario.write_text('''
[scenario]
name = "HANGING"
description = "A weight hangs from a hook by a rope."
[settings]
time_step = 0.002
event_timeout = 2.0
max_duration = 2.0
[[objects]]
name = "floor"
type = "Plane"
[[objects]]
name = "hook"
type = "Box"
shape = { size = [0.02, 0.02, 0.02] }
transform = { z = 0.3 }
[[objects]]
name = "weight"
type = "Box"
shape = { size = [0.06, 0.02, 0.02] }
physics = { mass = 0.05 }
transform = { z = 0.1, roll = 10 }
ranges = { z = [0.08, 0.12], roll = [0, 20] }
[[objects]]
name = "rope"
type = "TensionRope"
shape = { ends = ["hook", "weight"] }
[[events]]
name = "still"
type = "NotMoving"
body = "weight"
duration = 0.2
label = "the weight hangs still"
''')
    loaded = open_scenario(str(scenario))
    guide = build_guide(loaded, None, view="top")
    parts = [PartInput(p.name, p.step, p.parameters, p.outline) for p in guide.parts]
    plan = plan_jigs(loaded, None, guide.plane, parts, SETTINGS)
    assert not plan.jigs
    (entry,) = plan.by_hand
    assert entry.part == "weight" and "rope" in entry.reason and entry.set_with == "ruler"


def test_a_tight_place_on_the_table_gets_a_template_with_a_pocket_round_the_part():
    scenario = open_scenario("branching")
    x = scenario.layout("success")
    guide = build_guide(scenario, x)
    parts = [PartInput(p.name, p.step, p.parameters, p.outline) for p in guide.parts]
    plan = plan_jigs(scenario, x, guide.plane, parts, SETTINGS, tight={"goblet.x"}, tag_ids=iter(JIG_TAG_IDS),
                     tag_cells=tag_cells)
    templates = [j for j in plan.jigs if j.kind == "template"]
    assert [t.part for t in templates] == ["goblet"]
    template = templates[0]
    assert template.parameters == ("goblet.x",) and template.support is None
    # the pocket (the footprint's hole) holds the goblet's foot, a 14.75 mm disc at (177.5, 30), with 0.2 mm all round
    (pocket,) = [np.asarray(ring.coords) for ring in template.footprint.interiors]
    distance = np.hypot(pocket[:, 0] - 177.5, pocket[:, 1] - 30.0)
    assert distance.min() >= 14.75 + 0.2 - 0.05
    assert distance.min() <= 14.75 + 0.2 + 0.5
    assert template.tag_id in JIG_TAG_IDS
    # without a tight place, no template
    plain = plan_jigs(scenario, x, guide.plane, parts, SETTINGS)
    assert not [j for j in plain.jigs if j.kind == "template"]
