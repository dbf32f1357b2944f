"""The guide with its jigs: the steps say how to use them, the parameters they set are set with them, and the
sheets, the SVG and the projected steps draw where each lies."""

from __future__ import annotations

import json

import numpy as np
import pytest
from shapely.geometry import Polygon, box

from projector.frames import JIG_EDGE, render_step
from station.cli import main
from station.services.guide import GuideRequest, make_guide


def test_the_guide_with_jigs_says_how_to_use_them_and_marks_what_they_set():
    job = make_guide(GuideRequest("simple", "success", tolerances=False, jigs=True))
    data = job.manifest()
    (jig,) = data["jigs"]
    assert jig["id"] == "J1" and jig["part"] == "track" and jig["kind"] == "stand"
    assert jig["parameters"] == ["track.x", "track.z", "track.roll"] and jig["tag_id"] == 500
    track = next(p for p in data["parts"] if p["name"] == "track")
    assert {p["name"]: p["set_with"] for p in track["parameters"]} == {"track.x": "jig", "track.z": "jig",
                                                                       "track.roll": "jig"}
    step = data["steps"][0]
    assert step.startswith("1. Stand jig J1 on its outline (drawn on the sheet), its plate in the base's slot with "
                           "the engraved face to the front; rest `track` on it, lower end against the stop")
    assert "Fix `track` (tag 0)" in step
    # the reference tags keep clear of the jig's footprint (its base reaches past the track)
    footprint = Polygon(jig["footprint_mm"])
    for tag in data["reference_tags"]:
        (u, v), half = tag["center_mm"], tag["size_mm"] * 0.625
        assert not footprint.intersects(box(u - half, v - half, u + half, v + half))
    u0, v0, u1, v1 = job.guide.extent_mm
    assert box(u0, v0, u1, v1).contains(footprint)


def test_without_jigs_the_guide_is_as_before():
    job = make_guide(GuideRequest("simple", "success", tolerances=False))
    data = job.manifest()
    assert data["jigs"] == [] and job.jigs is None
    track = next(p for p in data["parts"] if p["name"] == "track")
    assert "jig" not in {p["set_with"] for p in track["parameters"]}
    assert "jig" not in data["steps"][0]


def test_a_stand_whose_lower_end_is_taken_holds_the_upper_end_in_the_steps():
    job = make_guide(GuideRequest("branching", "success", tolerances=False, jigs=True))
    step = next(line for line in job.steps if "`track`" in line and line.startswith("2."))
    assert "rest `track` on it, upper end against the stop" in step


def test_the_projected_step_draws_its_jig():
    with_jigs = make_guide(GuideRequest("simple", "success", tolerances=False, jigs=True)).guide
    without = make_guide(GuideRequest("simple", "success", tolerances=False)).guide
    for guide, expected in ((with_jigs, True), (without, False)):
        frame = render_step(guide, 1, (1280, 800))[150:]  # below the caption (its warning line is orange too)
        near = np.all(np.abs(frame.astype(int) - np.array(JIG_EDGE)) < 30, axis=-1)
        assert (near.sum() > 200) == expected  # the footprint's edges, anti-aliased


def test_station_guide_jigs_writes_the_jigs_and_draws_them(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["guide", "causalityswitch_ball", "success", "--svg", "g.svg", "--jigs", "cut",
                 "--no-tolerances"]) == 0
    out = capsys.readouterr().out
    assert "2. Stand jig J1 on its outline" in out and "wrote 1 jig to cut: jigs.gcode" in out
    for name in ("jigs.gcode", "jigs.svg", "jigs.json", "sheet.png", "jig-J1.png"):
        assert (tmp_path / "cut" / name).is_file()
    assert 'id="jig-J1"' in (tmp_path / "g.svg").read_text()
    assert json.loads((tmp_path / "cut" / "jigs.json").read_text())["jigs"][0]["part"] == "ball_track"


@pytest.mark.parametrize("argv", [["--jigs"], ["--jigs", "--json"]])
def test_jigs_without_a_folder_only_plans_them(argv, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["guide", "simple", "success", "--svg", "g.svg", "--no-tolerances", *argv]) == 0
    out = capsys.readouterr().out
    assert "Stand jig J1" in out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.svg"]
