"""The as-built check on synthetic camera frames: a part moved by a known offset is named
with that offset and the right instruction, a covered tag is reported missing, the CLI prints CHECK.json.

The frames come from the camera twin's renderer (drivers.sim.camera_render: its own tag bitmaps and ray casting,
not the detector's conventions) at 1080p, f = 1400 px, 1 m above the plane, with blur, noise and JPEG. The moved
part's tag is placed where the guide draws it at the moved layout (the scene graph), not by the check's own offset
arithmetic.
"""

from __future__ import annotations

import functools
import json
import re

import numpy as np
import pytest
from PIL import Image

from calibration.intrinsics import CameraIntrinsics
from drivers.sim.camera_render import render
from drivers.sim.camera_scene import CameraModel, Occluder, PlaneScene, RenderOptions, TagItem
from projector.build import build_guide
from station.cli import main
from station.services import check as service

RENDER = RenderOptions(blur_px=0.8, noise=2.0, jpeg_quality=90, supersample=2, seed=3)
MOVE = {"goblet.x": 0.004, "goblet.z": -0.0025, "goblet.roll": 3.0}  # BALLRUN's u is -x: 4 mm to the left


@functools.cache
def _ballrun():
    return service.prepare_check("ballrun", "success")


def _camera(guide) -> CameraModel:
    u0, v0, u1, v1 = guide.extent_mm
    return CameraModel.looking_down(target_mm=((u0 + u1) / 2, (v0 + v1) / 2), height_mm=1000.0)


def _frame(job, changes=None, covered=(), extra=()):
    """The camera's frame of the parts at the layout moved by ``changes``; its intrinsics (a calibrated camera)."""
    scenario, guide = job.scenario, job.guide
    x = np.array(job.layout.x, dtype=float)
    names = list(scenario.design_space.names)
    for name, delta in (changes or {}).items():
        x[names.index(name)] += delta
    there = build_guide(scenario, x, view=guide.view)
    tags = [TagItem(t.id, t.center_mm, t.size_mm) for t in guide.reference_tags]
    occluders = []
    for part in (view for each in there.parts for view in each.tag_views()):  # own tags and those on bodies
        tags.append(TagItem(part.tag_id, part.tag_center_mm, part.tag_size_mm, part.tag_heading_deg,
                            part.tag_height_mm))
        if part.tag_id in covered:  # a hand flat over the tag, a little above it
            square = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * part.tag_size_mm + part.tag_center_mm
            occluders.append(Occluder(square, part.tag_height_mm + 10.0))
    camera = _camera(guide)
    image, _ = render(PlaneScene(tags=(*tags, *extra), occluders=tuple(occluders)), camera, RENDER)
    return image, CameraIntrinsics(camera.camera_matrix, camera.dist_coeffs, camera.image_size), x


def test_a_moved_part_is_named_with_its_offset_and_the_right_instruction():
    job = _ballrun()
    image, intrinsics, moved = _frame(job, MOVE)
    check = service.check_frame(job, image, intrinsics)
    report = check.report
    first = report.parts[0]
    assert first.name == "goblet" and first.found
    du, dv, distance, dheading = first.error
    assert du == pytest.approx(-4.0, abs=0.3) and dv == pytest.approx(-2.5, abs=0.3)
    assert dheading == pytest.approx(3.0, abs=0.5)
    assert re.fullmatch(r"move `goblet` (3\.[789]|4\.[0-3]) mm right and 2\.[2-8] mm up, "
                        r"turn it (2\.[5-9]|3\.[0-5]) deg clockwise", first.instruction), first.instruction
    others = [p for p in report.parts[1:] if p.found]
    assert others and all(p.error[2] < 0.3 for p in others)  # the parts left alone read as in place
    names = list(job.scenario.design_space.names)
    for name, tolerance in (("goblet.x", 0.0003), ("goblet.z", 0.0003), ("goblet.roll", 0.5)):
        assert report.as_built[name] == pytest.approx(moved[names.index(name)], abs=tolerance)
    assert "top_track.x" in report.not_measured and "goblet.x" not in report.not_measured
    # low_plank's 10 mm tag is 14 px across from 1 m: below what tag36h11 decodes reliably, so it may be missing
    small = {p.tag_id for p in job.guide.parts if p.tag_id is not None and p.tag_size_mm < 15}
    assert set(report.missing_tags) <= small and report.unknown_tags == () and report.plane.residual_mm < 0.5
    assert report.predicted_success_as_built is None and "no fitted success model" in report.prediction_note
    drawn = service.camera_overlay(check)
    assert drawn.shape == image.shape and np.any(drawn != image)


def test_a_covered_tag_is_reported_missing_and_its_part_not_measured():
    job = _ballrun()
    goblet = job.guide.part("goblet").tag_id
    stop = job.guide.part("stop")
    u0, v0, _, _ = job.guide.extent_mm
    stray = (TagItem(77, (u0 + 80.0, v0 + 60.0), 30.0),  # a tag of something else, and a second copy of a part's
             TagItem(stop.tag_id, (u0 + 160.0, v0 + 60.0), 30.0))
    image, intrinsics, _ = _frame(job, MOVE, covered=(goblet,), extra=stray)
    report = service.check_frame(job, image, intrinsics).report
    assert report.unknown_tags == (77,) and report.duplicate_tags == (stop.tag_id,)
    assert "more than once" in next(p for p in report.parts if p.name == "stop").instruction
    assert goblet in report.missing_tags and stop.tag_id not in report.missing_tags
    entry = next(p for p in report.to_json()["parts"] if p["name"] == "goblet")
    assert entry["found"] is False and entry["measured"] is None and entry["error"] is None
    assert "not seen" in entry["instruction"]
    assert {"goblet.x", "goblet.z", "goblet.roll"} <= set(report.not_measured)
    assert report.as_built["goblet.x"] == pytest.approx(report.layout["goblet.x"])  # never guessed


def test_a_layout_with_a_model_is_scored_as_placed(tmp_path):
    from pathlib import Path

    layout = Path(__file__).resolve().parents[2] / "data" / "robust" / "simple-layout-with-model.json"
    job = service.prepare_check("simple", str(layout))
    image, intrinsics, _ = _frame(job, {"track.x": 0.02})
    report = service.check_frame(job, image, intrinsics).report
    assert report.parts[0].name == "track" and report.parts[0].error[0] == pytest.approx(20.0, abs=0.5)
    assert 0.0 <= report.predicted_success_as_built <= 1.0
    assert report.predicted_success_as_designed == pytest.approx(job.tolerances.model.predict(
        job.tolerances.problem.to_normalized(job.layout.x)[None, :])[0])
    assert report.parts[0].cost is not None and report.prediction_note is None


def test_the_cli_prints_and_writes_check_json(tmp_path, capsys):
    job = _ballrun()
    image, intrinsics, _ = _frame(job, MOVE)
    frame, lens = tmp_path / "frame.png", tmp_path / "camera.json"
    Image.fromarray(image).save(frame)
    lens.write_text(json.dumps(intrinsics.to_json()))
    out, overlay = tmp_path / "check.json", tmp_path / "overlay.png"
    code = main(["check", "ballrun", "success", "--image", str(frame), "--intrinsics", str(lens), "--out", str(out),
                 "--overlay", str(overlay), "--predict", "4", "--json"])
    assert code == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed == json.loads(out.read_text())
    assert printed["format"] == "chaos-station check" and printed["scenario"] == "BALLRUN"
    part = printed["parts"][0]
    assert set(part) >= {"name", "tag_id", "found", "measured", "error", "within_tolerance", "instruction"}
    assert part["name"] == "goblet" and set(part["error"]) == {"du_mm", "dv_mm", "distance_mm", "heading_deg"}
    assert set(printed) >= {"missing_tags", "unknown_tags", "as_built", "predicted_success_as_built",
                            "predicted_success_as_designed", "by_eye", "not_measured", "prediction_note"}
    # every measured parameter as measured (here inside its range: the same as as_built), none of the others
    assert printed["as_measured"] == {k: v for k, v in printed["as_built"].items() if k not in printed["not_measured"]}
    assert Image.open(overlay).size == (1920, 1080)
    physical = printed["physical_success"]  # the as-built layout's physical success and the attempts to expect
    assert physical["samples"] == 4 and physical["interval"][0] <= physical["probability"] <= physical["interval"][1]

    from station.services.guide import GuideRequest, make_guide

    manifest = tmp_path / "ballrun-guide.json"  # what `station guide ballrun success --json` prints
    manifest.write_text(json.dumps(make_guide(GuideRequest("ballrun", "success", tolerances=False)).manifest()))
    code = main(["check", "ballrun", "success", "--image", str(frame), "--intrinsics", str(lens), "--predict", "0",
                 "--guide",
                 str(manifest), "--json"])
    again = json.loads(capsys.readouterr().out)
    assert code == 0 and [p["name"] for p in again["parts"]] == [p["name"] for p in printed["parts"]]
    assert again["parts"][0]["error"] == pytest.approx(printed["parts"][0]["error"], abs=0.01)  # manifest: 3 decimals
    assert again["as_built"] == pytest.approx(printed["as_built"], abs=0.01)
    other = tmp_path / "guide.json"
    other.write_text(json.dumps(make_guide(GuideRequest("simple", None, tolerances=False)).manifest()))
    code = main(["check", "ballrun", "success", "--image", str(frame), "--guide", str(other), "--predict", "0"])
    error = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(error) == 1 and error[0].startswith("station: error: --guide ") and "SIMPLE" in error[0]


@pytest.mark.slow
def test_the_as_built_layout_is_simulated_with_the_measurement_error(tmp_path):
    from pathlib import Path

    layout = Path(__file__).resolve().parents[2] / "data" / "robust" / "simple-layout-with-model.json"
    job = service.prepare_check("simple", str(layout))
    image, intrinsics, _ = _frame(job, {"track.x": 0.01})
    report = service.check_frame(job, image, intrinsics, service.CheckRequest(simulate=4, seed=1)).report
    assert report.simulated_success_as_built in (0.0, 0.25, 0.5, 0.75, 1.0)
    assert report.residual_error["position_mm"] > 0 and report.to_json()["simulated_success_as_built"] is not None


def test_a_domino_run_is_checked_by_its_first_and_last_dominoes(tmp_path):
    from pathlib import Path

    import tomllib

    data = tomllib.loads((Path(__file__).parents[3] / "examples" / "scenarios" / "simple.toml").read_text())
    run = next(o for o in data["objects"] if o["name"] == "dominoes")
    run["shape"] = {"size": [0.03, 0.04, 0.04], "path": [[0.0, 0.0], [0.12, 0.0]], "count": 3}  # room for a tag
    run["ranges"] = {"x": [0.0, 0.05], "heading": [-20.0, 20.0]}
    run["tag"] = [{"id": 5, "body": 0, "z": 0.02, "size": 0.025}, {"id": 6, "body": -1, "z": 0.02, "size": 0.025}]
    data.pop("layouts", None)
    scenario = tmp_path / "big-dominoes.json"
    scenario.write_text(json.dumps(data))
    layout = tmp_path / "layout.json"
    layout.write_text(json.dumps({"parameters": {}}))
    job = service.prepare_check(str(scenario), str(layout))
    dominoes = job.guide.part("dominoes")
    assert [b.body for b in dominoes.body_tags] == [0, 2] and dominoes.tag_id is None
    image, intrinsics, moved = _frame(job, {"dominoes.x": 0.006, "dominoes.heading": 4.0})
    report = service.check_frame(job, image, intrinsics).report
    checked = {p.name: p for p in report.parts}
    first, last = checked["dominoes[0]"], checked["dominoes[2]"]
    assert first.found and last.found and "dominoes" not in report.by_eye
    # the run turns 4 deg about its origin (the first domino's place): the last domino swings 120 mm x 4 deg sideways
    assert first.error[0] == pytest.approx(6.0, abs=0.3) and first.error[1] == pytest.approx(0.0, abs=0.3)
    assert last.error[1] == pytest.approx(120.0 * np.sin(np.radians(4.0)), abs=0.4)
    assert first.error[3] == pytest.approx(4.0, abs=0.5) and last.error[3] == pytest.approx(4.0, abs=0.5)
    names = list(job.scenario.design_space.names)
    assert report.as_built["dominoes.x"] == pytest.approx(moved[names.index("dominoes.x")], abs=0.0003)
    assert report.as_built["dominoes.heading"] == pytest.approx(moved[names.index("dominoes.heading")], abs=0.3)
    drawn = service.camera_overlay(service.check_frame(job, image, intrinsics))
    assert drawn.shape == image.shape



def test_the_projected_check_uses_the_projectors_saved_map():
    from calibration.projector_map import ProjectorMap, save_projector_map
    from station.devices import default_devices
    from station.services import projectors
    from station.services.projector_calibration import projector_map_file

    default = next(device.url for device in default_devices() if device.kind == "projector")
    assert projectors.projector_mapping(default, (1280, 800)).homography is None  # no map: fitted
    plane_from_pixel = np.array([[0.5, 0.0, -300.0], [0.0, -0.5, 200.0], [0.0, 0.0, 1.0]])
    path = projector_map_file("projector")
    path.parent.mkdir(parents=True, exist_ok=True)
    save_projector_map(ProjectorMap(plane_from_pixel, (1280, 800), {"p50": 0.2, "p95": 0.4, "max": 0.6}, {}), path)
    homography = projectors.projector_mapping(default, (1280, 800)).homography  # the default's key
    assert np.allclose(homography @ plane_from_pixel, np.eye(3))  # guide mm -> projector pixels
    assert projectors.projector_mapping(default, (1920, 1080)).homography is None  # another size
    # the guide's steps go through the same map: the configured projector (simulated, named "projector") at its
    # own size shows them at true scale
    from drivers.sim.projector import SimulatedProjector
    from station.services.guide import GuideRequest, make_guide, show_step
    from station.services.projectors import configured_projector

    assert configured_projector().name == "projector"
    job = make_guide(GuideRequest("simple", "success", tolerances=False))
    with SimulatedProjector("sim://projector?name=projector&size=1280x800") as shown:
        assert show_step(job, shown, 1) is True
    with SimulatedProjector("sim://projector?name=projector&size=1024x768") as shown:
        assert show_step(job, shown, 1) is False  # its map is of another size: fitted to the screen


def test_the_headline_is_the_physical_success_and_a_misplaced_part_no_parameter_places_is_said(capsys):
    # BALLRUN's low_plank has a tag but no design parameter: the simulations put it where the guide does, so the
    # physical success leaves its error out, and says so (text and CHECK.json's not_simulated).
    argv = ["check", "ballrun", "success", "--camera", "sim://camera", "--sim-offset", "low_plank=-12,0,20",
            "--predict", "4"]
    assert main([*argv, "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["not_simulated"] == ["low_plank"]
    assert main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[2].startswith("physical success on the table ") and "(as placed, 4 simulations)" in lines[2]
    assert any("leave out where `low_plank` stands" in line for line in lines)
    assert not any(line.startswith("predicted success") for line in lines)
    row = next(line for line in lines if line.startswith("low_plank "))
    assert row.split()[-2:] == ["NO*", "-"]  # no zone on the sheet and off by 12 mm: to move; no model cost
    assert any(line.strip().startswith("NO*/yes*: no zone on the sheet") for line in lines)
