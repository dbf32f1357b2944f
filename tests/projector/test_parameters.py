"""Every design parameter on the guide, in the maker's words: the manifest reads the layout back, the heights and
tilts follow the geometry, every output says them, and nothing names a path of the machine that made it."""

from __future__ import annotations

import functools
import io
import json
import math
from pathlib import Path
from unittest import mock

import pypdfium2 as pdfium
import pytest

from design.contraption import load_scenario
from projector.build import build_guide, steps_text
from projector.drawing import place_labels
from projector.errors import ProjectorError
from projector.frames import detail_caption
from projector.guide import SET_WITH, ParameterTolerance
from projector.parameters import layout_from_manifest
from projector.pdf import write_pdf
from projector.pdf_elevation import ElevationDrawing
from station.services.guide import GuideRequest, make_guide

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
ALL = sorted(p.name for p in EXAMPLES.glob("*.toml"))
#: What the guide prints: 0.1 mm (0.0001 m) and 0.1 deg, so a value reads back within half of that.
PRINTED = {"mm": 0.05e-3, "deg": 0.05}


@functools.cache
def _scenario(name: str):
    return load_scenario(EXAMPLES / name)


def _unit(name: str) -> str:
    return "deg" if name.rsplit(".", 1)[-1] in ("heading", "pitch", "roll") else "mm"


def _reads_back(scenario, x, manifest) -> None:
    again = layout_from_manifest(json.loads(json.dumps(manifest)))  # what a program with only the file knows
    assert set(again) == set(scenario.design_space.names), "every design parameter, and only those"
    for name, value in zip(scenario.design_space.names, x):
        assert abs(again[name] - value) <= PRINTED[_unit(name)] + 1e-12, (name, again[name], value)


@pytest.mark.parametrize("name", ALL)
@pytest.mark.parametrize("layout", [None, "success"])
def test_the_manifest_reads_back_every_design_parameter_of_every_example(name, layout):
    scenario = _scenario(name)
    job = make_guide(GuideRequest(str(EXAMPLES / name), layout, tolerances=False))
    x = scenario.default_layout() if layout is None else scenario.layout(layout)
    _reads_back(scenario, x, job.manifest())
    for part in job.manifest()["parts"]:
        for entry in part["parameters"]:
            assert set(entry) >= {"name", "value", "unit", "meaning", "set_with"}
            assert entry["unit"] in ("mm", "deg") and entry["set_with"] in SET_WITH and entry["meaning"]


@pytest.mark.parametrize("name, values", [
    ("simple.toml", {"track.x": -0.0832, "track.z": 0.0747, "track.roll": 41.3}),
    ("causalityswitch_ball.toml", {"track_joint.z": 0.0123, "track_joint.roll": -4.4, "switch.x": -0.4321,
                                   "plank.x": 0.0187}),
])
def test_a_hand_written_layout_reads_back_from_its_manifest(name, values, tmp_path):
    scenario = _scenario(name)
    path = tmp_path / "mine.json"
    path.write_text(json.dumps({"parameters": values}))
    job = make_guide(GuideRequest(str(EXAMPLES / name), str(path), tolerances=False))
    _reads_back(scenario, [values[n] for n in scenario.design_space.names], job.manifest())


def test_simple_track_height_and_tilt_in_the_makers_words():
    scenario = _scenario("simple.toml")
    guide = build_guide(scenario)  # track at z 60 mm, roll 30 deg; the dominoes to its right (+x)
    track = guide.part("track")
    assert {s.name: (s.role, s.set_with, s.unit) for s in track.settings} == {
        "track.x": ("u", "check", "mm"), "track.z": ("height", "ruler", "mm"), "track.roll": ("tilt", "ruler", "deg")}
    assert {s.name: s.value for s in track.settings} == pytest.approx({"track.x": -60.0, "track.z": 60.0,
                                                                       "track.roll": 30.0})
    side = track.elevation
    (s_low, h_low), (s_high, h_high) = side.ends
    assert side.tilt_deg == pytest.approx(30.0)
    # the underside runs the track's 100 mm length: its two ends differ by 100 sin 30 = 50 mm, the middle halfway
    assert h_high - h_low == pytest.approx(100.0 * math.sin(math.radians(30.0)), abs=1e-6)
    assert side.middle[1] == pytest.approx((h_low + h_high) / 2, abs=1e-6)
    assert s_low > s_high, "the lower end is on the dominoes' side (+u)"
    assert side.toward == "towards `dominoes` (to your right)"
    tilt = next(s for s in track.settings if s.name == "track.roll")
    assert tilt.meaning.startswith("tilt: 30.0 deg (tolerance unknown), lower end towards `dominoes` (to your right)")
    assert f"{h_low:.1f} mm above the table at the lower end, {h_high:.1f} mm at the upper end" in tilt.meaning

    # 5 mm higher: every named height 5 mm higher; 15 deg steeper: the ends 100 sin 45 apart
    higher = build_guide(scenario, [-0.06, 0.065, 30.0]).part("track").elevation
    assert [h for _, h in higher.ends] == pytest.approx([h_low + 5.0, h_high + 5.0], abs=1e-6)
    assert higher.middle[1] == pytest.approx(side.middle[1] + 5.0, abs=1e-6)
    steeper = build_guide(scenario, [-0.06, 0.06, 45.0]).part("track").elevation
    assert steeper.tilt_deg == pytest.approx(45.0)
    assert steeper.ends[1][1] - steeper.ends[0][1] == pytest.approx(100.0 * math.sin(math.radians(45.0)), abs=1e-6)


def test_causalityswitch_track_falls_towards_the_ball_run_and_lies_level_at_zero():
    scenario = _scenario("causalityswitch_ball.toml")
    guide = build_guide(scenario)  # the joint at the support's edge, the track tilted 10 deg down to -x
    track = guide.part("ball_track")
    assert [(s.name, s.role) for s in track.settings] == [("track_joint.z", "height"), ("track_joint.roll", "tilt")]
    assert track.elevation.tilt_deg == pytest.approx(10.0)
    assert track.elevation.toward == "towards `ball_run` (to your left)"
    assert track.elevation.ends[1][1] - track.elevation.ends[0][1] == pytest.approx(
        150.0 * math.sin(math.radians(10.0)), abs=1e-6)
    x = scenario.default_layout()
    x[list(scenario.design_space.names).index("track_joint.roll")] = 0.0
    level = build_guide(scenario, x).part("ball_track")
    assert level.elevation.level and level.elevation.toward == ""
    tilt = next(s for s in level.settings if s.role == "tilt")
    assert tilt.meaning.startswith("tilt: level (0.0 deg, tolerance unknown), its underside ")
    # the parts the sheet places: a part without a tag is set on the sheet
    assert [(s.name, s.set_with) for s in guide.part("plank").settings] == [("plank.x", "sheet")]


def test_tolerances_stand_next_to_each_value():
    scenario = _scenario("simple.toml")
    tolerances = {"track.x": ParameterTolerance("track.x", 4.0, "mm", 0.9),
                  "track.z": ParameterTolerance("track.z", 5.3, "mm", 0.9),
                  "track.roll": ParameterTolerance("track.roll", 10.6, "deg", 0.9)}
    guide = build_guide(scenario, tolerances=tolerances)
    line = steps_text(guide)[0]
    assert line.startswith("1. Fix `track` (tag 0): centre (-60.0, 0.0) mm, turned 0.0 deg (counter-clockwise, "
                           "seen from above), tolerance +-4.0 mm; height above the table: its underside at the middle ")
    assert "mm (+-5.3 mm), with a ruler; tilt: 30.0 deg (+-10.6 deg), lower end towards `dominoes`" in line
    parameters = guide.manifest()["parts"][0]["parameters"]
    assert [(p["name"], p["tolerance"]) for p in parameters] == [("track.x", 4.0), ("track.z", 5.3),
                                                                ("track.roll", 10.6)]
    track = guide.part("track")
    caption = detail_caption(track, guide.view)
    assert "tolerance x +-4.0 mm" in caption and "tilt 30.0 deg +-10.6" in caption and "roll" not in caption
    label = place_labels(guide)["track"]
    assert label.off_plane.startswith(f"height {track.elevation.middle[1]:.1f} mm ±5.3 mm, tilt 30.0° ±10.6°")
    assert label.off_plane.endswith("lower end towards dominoes (to your right)")


def test_set_with_overrides_say_how_and_bad_ones_are_refused():
    scenario = _scenario("simple.toml")
    guide = build_guide(scenario, set_with={"track.z": "jig", "track.roll": "jig"})
    assert [s.set_with for s in guide.part("track").settings] == ["check", "jig", "jig"]
    assert steps_text(guide)[0].count(", with its jig") == 2
    with pytest.raises(ProjectorError, match=r"set_with: unknown layout parameter 'track\.y'; expected one of "
                                             r"track\.x, track\.z, track\.roll"):
        build_guide(scenario, set_with={"track.y": "jig"})
    with pytest.raises(ProjectorError, match=r"set_with\['track\.z'\]: expected one of sheet, ruler, jig, check, "
                                             r"got 'tape'"):
        build_guide(scenario, set_with={"track.z": "tape"})
    job = make_guide(GuideRequest(str(EXAMPLES / "simple.toml"), None, set_with={"track.roll": "jig"}))
    assert [p["set_with"] for p in job.manifest()["parts"][0]["parameters"]] == ["check", "ruler", "jig"]


def test_the_printed_guide_lists_every_parameter_and_draws_the_side_view():
    scenario = _scenario("causalityswitch_ball.toml")
    guide = build_guide(scenario)
    stream = io.BytesIO()
    guide = write_pdf(guide, stream, steps=steps_text(guide))
    document = pdfium.PdfDocument(stream.getvalue())
    lists = "\n".join(document[i].get_textpage().get_text_range() for i in range(len(guide.pages), len(document)))
    lists = " ".join(lists.split())
    assert "Parameters" in lists and "Heights and tilts" in lists and "seen from the front" in lists
    for name in scenario.design_space.names:
        assert name in lists
    track = guide.part("ball_track")
    (_, low), (_, high) = track.elevation.ends
    for height in (low, high, track.elevation.middle[1]):
        assert f"{height:.1f}" in lists
    sheets = " ".join(" ".join(document[p.index].get_textpage().get_text_range() for p in guide.pages).split())
    assert "tilt 10.0°, lower end towards ball_run (to your left)" in sheets


def test_the_side_view_is_drawn_at_one_to_one_with_its_heights_dimensioned():
    from reportlab.lib.units import mm

    guide = build_guide(_scenario("simple.toml"))
    side = guide.part("track").elevation
    drawing = ElevationDrawing(side)
    width, height = drawing.wrap(190 * mm, 250 * mm)
    assert drawing.scale == 1.0 and drawing.scale_text == "1:1"
    canvas = mock.MagicMock()
    drawing.canv = canvas
    drawing.draw()
    # every height is a vertical dimension line from the table, as long on paper as the height (mm, at 1:1)
    verticals = [abs(c.args[3] - c.args[1]) for c in canvas.line.call_args_list
                 if len(c.args) == 4 and abs(c.args[0] - c.args[2]) < 1e-9]
    for _, h in (*side.ends, side.middle):
        assert any(abs(length - h) < 1e-6 for length in verticals), (h, verticals)
    # too tall for the page at 1:1: drawn smaller, and says so
    tall = ElevationDrawing(build_guide(_scenario("simple.toml"), [-0.06, 0.15, 75.0]).part("track").elevation)
    tall.wrap(190 * mm, 250 * mm)
    assert tall.scale < 1.0 and tall.scale_text == f"1:{1 / tall.scale:g}"


def _strings(value):
    if isinstance(value, dict):
        for item in value.values():
            yield from _strings(item)
    elif isinstance(value, list):
        for item in value:
            yield from _strings(item)
    elif isinstance(value, str):
        yield value


def test_no_manifest_names_a_path_of_the_machine_that_made_it(tmp_path, monkeypatch):
    layout = tmp_path / "mine.json"
    layout.write_text(json.dumps({"parameters": {"track.x": -0.05, "track.z": 0.07, "track.roll": 35.0}}))
    monkeypatch.chdir(tmp_path)
    inside = make_guide(GuideRequest(str(EXAMPLES / "simple.toml"), str(layout), tolerances=False)).manifest()
    assert inside["layout"]["source"] == "mine.json"
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    outside = make_guide(GuideRequest(str(EXAMPLES / "simple.toml"), str(layout), tolerances=False)).manifest()
    named = make_guide(GuideRequest(str(EXAMPLES / "simple.toml"), "success", tolerances=False)).manifest()
    assert outside["layout"]["source"] == "mine.json" and named["layout"]["source"] == "simple.toml"
    for manifest in (inside, outside, named):
        absolute = [s for s in _strings(manifest) if s.startswith("/") or str(tmp_path) in s or str(EXAMPLES) in s]
        assert absolute == []


def test_a_malformed_parameters_list_is_one_clear_error():
    with pytest.raises(ProjectorError, match=r"field 'parts\[0\]\.parameters\[0\]': expected"):
        layout_from_manifest({"parts": [{"parameters": [{"name": "a.x", "value": "1", "unit": "mm"}]}]})
    with pytest.raises(ProjectorError, match=r"a\.x is 2\.0 mm here and differs on another part"):
        layout_from_manifest({"parts": [{"parameters": [{"name": "a.x", "value": 1.0, "unit": "mm"}]},
                                        {"parameters": [{"name": "a.x", "value": 2.0, "unit": "mm"}]}]})


def test_a_label_says_a_height_and_tilt_once_with_their_values():
    scenario = _scenario("causalityswitch_ball.toml")
    tolerances = {"track_joint.z": ParameterTolerance("track_joint.z", 3.0, "mm", 0.9),
                  "track_joint.roll": ParameterTolerance("track_joint.roll", 1.2, "deg", 0.9)}
    guide = build_guide(scenario, tolerances=tolerances)
    label = place_labels(guide)["ball_track"]
    middle = guide.part("ball_track").elevation.middle[1]
    assert label.detail == "tight"  # the care; the deltas stand by their values on the line below
    assert label.off_plane == (f"height {middle:.1f} mm ±3.0 mm, tilt 10.0° ±1.2°, lower end towards ball_run "
                               "(to your left)")


def test_a_standing_part_leans_from_upright_towards_its_top():
    # BALLRUN's goblet drawn from above: it stands, turned 20 deg about y (its roll), so its top leans 20 deg to +x
    guide = build_guide(_scenario("ballrun.toml"), view="top")
    goblet = guide.part("goblet")
    side = goblet.elevation
    assert side.standing and side.lean_deg == pytest.approx(20.0) and side.toward.endswith("(to your right)")
    (_, foot), (_, top) = side.ends
    assert top > foot
    words = {s.role: s.meaning for s in goblet.settings}
    assert words["height"] == f"height above the table: its foot {foot:.1f} mm (tolerance unknown)"
    assert words["tilt"].startswith("tilt: leans 20.0 deg from upright (tolerance unknown), its top towards ")
    (a0, b0), (a1, b1) = side.axis
    assert math.degrees(math.atan2(a1 - a0, b1 - b0)) == pytest.approx(20.0)  # the length, 20 deg off plumb to +s
