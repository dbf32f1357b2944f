"""The as-built check's logic on measurements made by hand from guides drawn at moved layouts (no camera)."""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace

import numpy as np
import pytest

from calibration.asbuilt import PlanePose, as_built_layout, measurable_parameters
from calibration.check import check_parts, instruction, measured_pose
from calibration.sim_runs import widened
from design.contraption import load_scenario
from design.contraption.catalog import resolve_scenario_path
from projector.build import build_guide
from projector.guide import ParameterTolerance


@dataclass(frozen=True)
class Tag:  # calibration.measure.TagPose's fields the check reads
    tag_id: int
    center_mm: tuple[float, float]
    heading_deg: float
    height_mm: float = 0.0
    fit_residual_mm: float = 0.05


@dataclass(frozen=True)
class Seen:  # calibration.measure.Measurement's fields the check reads
    tags: tuple
    duplicate_ids: tuple = ()
    unknown_ids: tuple = ()
    missing_reference_ids: tuple = ()
    plane: object = "a plane"


@functools.cache
def _ballrun():
    scenario = load_scenario(resolve_scenario_path("ballrun"))
    return scenario, scenario.layout("success")


def _moved(scenario, x, changes: dict[str, float]) -> np.ndarray:
    names = list(scenario.design_space.names)
    moved = np.array(x, dtype=float)
    for name, delta in changes.items():
        moved[names.index(name)] += delta
    return moved


def _tags_of(guide, names) -> tuple:
    """What a perfect camera measures: each named part's tag where the guide (at its layout) draws it."""
    return tuple(Tag(guide.part(n).tag_id, guide.part(n).tag_center_mm, guide.part(n).tag_heading_deg)
                 for n in names)


def test_a_moved_and_turned_part_is_measured_and_its_parameters_recovered():
    scenario, x = _ballrun()
    guide = build_guide(scenario, x)
    assert guide.view == "side" and guide.part("goblet").tag_id is not None
    moved = _moved(scenario, x, {"goblet.x": 0.004, "goblet.z": -0.003, "goblet.roll": 2.0})
    there = build_guide(scenario, moved, view="side")
    checks, by_eye = check_parts(guide, Seen(_tags_of(there, ["goblet", "low_plank"])))
    goblet = next(c for c in checks if c.name == "goblet")
    # BALLRUN's board faces +y: u = -x, v = z, so +4 mm in x is 4 mm to the maker's left
    expected = np.subtract(there.part("goblet").center_mm, guide.part("goblet").center_mm)
    assert goblet.error[:2] == pytest.approx(tuple(expected), abs=1e-6)
    assert goblet.error[0] == pytest.approx(-4.0, abs=1e-6) and goblet.error[1] == pytest.approx(-3.0, abs=1e-6)
    assert goblet.error[3] == pytest.approx(2.0, abs=1e-6)
    assert goblet.instruction == "move `goblet` 4.0 mm right and 3.0 mm up, turn it 2.0 deg clockwise"
    assert "top_track" in by_eye and "ball" in by_eye  # seen edge-on / round: no tag
    low = next(c for c in checks if c.name == "low_plank")
    assert low.error[2] == pytest.approx(0.0, abs=1e-9) and low.instruction == "`low_plank` is in place"

    poses = {c.name: PlanePose(c.measured_center_mm, c.measured_heading_deg) for c in checks if c.found}
    built = as_built_layout(scenario, x, guide.plane, poses, {p.name: p.parameters for p in guide.parts})
    names = list(scenario.design_space.names)
    for name in ("goblet.x", "goblet.z", "goblet.roll"):
        assert built.x[names.index(name)] == pytest.approx(moved[names.index(name)], abs=1e-6)
        assert name in built.measured
    assert "top_track.x" in built.not_measured  # no tag on it: the layout's value, and said
    assert built.x[names.index("top_track.x")] == x[names.index("top_track.x")]


def test_a_tag_off_the_part_origin_turns_with_the_part():
    scenario, x = _ballrun()
    goblet = replace(build_guide(scenario, x).part("goblet"), tag_center_mm=(249.9, -105.8))  # 30 mm along u
    turn = np.radians(10.0)
    tag = np.add(goblet.center_mm, 30.0 * np.array([np.cos(turn), np.sin(turn)]))  # the part turned about its origin
    centre, heading = measured_pose(goblet, tag, goblet.tag_heading_deg + 10.0)
    assert centre == pytest.approx(goblet.center_mm, abs=1e-9)
    assert heading == pytest.approx(goblet.heading_deg + 10.0, abs=1e-9)
    centre, _ = measured_pose(goblet, np.add(tag, [1.0, -2.0]), goblet.tag_heading_deg + 10.0)
    assert centre == pytest.approx(np.add(goblet.center_mm, [1.0, -2.0]), abs=1e-9)


def test_the_camera_measures_only_what_lies_in_its_plane():
    scenario = load_scenario(resolve_scenario_path("simple"))
    x = scenario.layout("success")
    guide = build_guide(scenario, x, view="top")
    assert measurable_parameters(scenario, x, guide.plane, "track", ["track.x", "track.z", "track.roll"]) \
        == ["track.x"]  # seen from above: a height and a tilt in the x-z plane are not seen
    side = build_guide(scenario, x, view="side")
    assert measurable_parameters(scenario, x, side.plane, "track", ["track.x", "track.z", "track.roll"]) \
        == ["track.x", "track.z", "track.roll"]


def test_missing_and_duplicate_tags_are_never_guessed():
    scenario, x = _ballrun()
    guide = build_guide(scenario, x)
    tags = _tags_of(guide, ["goblet", "low_plank"])
    checks, _ = check_parts(guide, Seen(tags[1:], duplicate_ids=(tags[1].tag_id,)))
    by_name = {c.name: c for c in checks}
    assert not by_name["goblet"].found and "not seen" in by_name["goblet"].instruction
    assert not by_name["low_plank"].found and "more than once" in by_name["low_plank"].instruction
    assert by_name["goblet"].error is None and by_name["goblet"].measured_center_mm is None
    blind, _ = check_parts(guide, Seen((), plane=None))  # no plane: nothing measured, nothing said missing
    assert all(not c.found and "too few reference tags" in c.instruction for c in blind)


def test_tolerances_decide_within_per_axis():
    scenario, x = _ballrun()
    tolerances = {"goblet.x": ParameterTolerance("goblet.x", 2.0, "mm"),
                  "goblet.roll": ParameterTolerance("goblet.roll", 3.0, "deg")}
    guide = build_guide(scenario, x, tolerances=tolerances)
    near = build_guide(scenario, _moved(scenario, x, {"goblet.x": 0.0015, "goblet.roll": 2.0}), view="side")
    far = build_guide(scenario, _moved(scenario, x, {"goblet.x": 0.0025}), view="side")
    inside = next(c for c in check_parts(guide, Seen(_tags_of(near, ["goblet"])))[0] if c.name == "goblet")
    outside = next(c for c in check_parts(guide, Seen(_tags_of(far, ["goblet"])))[0] if c.name == "goblet")
    assert inside.tolerance == (2.0, None, 3.0)
    assert inside.within_tolerance is True and inside.instruction.startswith("`goblet` is within its tolerance")
    assert outside.within_tolerance is False and outside.instruction == "move `goblet` 2.5 mm right"


@pytest.mark.parametrize(("view", "error", "words"), [
    ("top", (3.2, -1.0, 3.35, 1.5), "move `bottom_track` 3.2 mm left and 1.0 mm away from you, turn it 1.5 deg "
                                    "clockwise"),
    ("top", (-0.5, 2.0, 2.06, 0.0), "move `bottom_track` 0.5 mm right and 2.0 mm towards you"),
    ("side", (0.0, 1.0, 1.0, -2.0), "move `bottom_track` 1.0 mm down, turn it 2.0 deg counter-clockwise"),
    ("side", (0.04, 0.0, 0.04, -1.2), "turn `bottom_track` 1.2 deg counter-clockwise"),
    ("side", (0.3, -0.4, 0.5, 0.2), "`bottom_track` is in place"),  # under what the camera resolves
    # no tolerance on the sheet and off by less than 1 mm / 1 deg: in place, as the count of parts to move says
    ("top", (-0.7, 0.0, 0.7, 0.0), "`bottom_track` is in place: off by less than 1 mm / 1 deg, what a part with no "
                                   "tolerance on the sheet may be (to centre it: move `bottom_track` 0.7 mm right)"),
])
def test_instructions_speak_the_sheets_words(view, error, words):
    assert instruction("bottom_track", error, view) == words


def test_a_part_placed_beyond_its_range_is_scored_at_the_end_and_kept_as_measured():
    scenario, x = _ballrun()
    names = list(scenario.design_space.names)
    i = names.index("goblet.x")
    x = np.array(x, dtype=float)
    x[i] = scenario.design_space.upper[i]  # an optimizer's layout on its range's end, as they often are
    guide = build_guide(scenario, x)
    # where the part really is: 2 mm past the range's end (drawn on the ranges the calibration simulates)
    there = build_guide(widened(scenario), _moved(scenario, x, {"goblet.x": 0.002}), view="side")
    checks, _ = check_parts(guide, Seen(_tags_of(there, ["goblet"])))
    poses = {c.name: PlanePose(c.measured_center_mm, c.measured_heading_deg) for c in checks if c.found}
    built = as_built_layout(scenario, x, guide.plane, poses, {p.name: p.parameters for p in guide.parts})
    assert built.clipped == ("goblet.x",) and built.x[i] == scenario.design_space.upper[i]
    assert built.unclipped[i] == pytest.approx(x[i] + 0.002, abs=1e-6)
    measured = built.measured_values(names)
    assert measured["goblet.x"] == pytest.approx(x[i] + 0.002, abs=1e-6) and "top_track.x" not in measured


@pytest.mark.parametrize("check, expected", [
    ({"as_built": {"a.x": 0.1, "b.roll": 3.0}}, {"a.x": 0.1, "b.roll": 3.0}),  # a check written before as_measured
    ({"as_built": {"a.x": 0.1, "b.roll": 3.0}, "as_measured": {"a.x": 0.1021}}, {"a.x": 0.1021, "b.roll": 3.0}),
    ({"as_built": {"a.x": 0.1}, "as_measured": {"a.x": "far"}}, "as_measured.a.x: expected a number, got 'far'"),
    ({"as_built": {"a.x": True}}, "as_built.a.x: expected a number, got True"),
    ({"as_built": [0.1]}, "as_built: expected {parameter: value}, got [0.1]"),
    ({}, "as_built: expected {parameter: value}, got None"),
])
def test_the_as_built_of_a_check_takes_each_measured_value_as_measured(check, expected):
    from calibration.check import as_built_values

    if isinstance(expected, dict):
        assert as_built_values(check, ValueError) == expected
    else:
        with pytest.raises(ValueError) as error:
            as_built_values(check, ValueError)
        assert str(error.value) == expected
