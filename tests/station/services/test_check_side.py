"""The side camera: heights and tilts read on the board's plane through each jig stand's face tag.

The moved layouts are moved in their design parameters and the side scene placed by the scene graph
(:func:`calibration.asbuilt.part_plane_pose` of the moved layout), so the check's own arithmetic is not what puts
the tags where they are. The frames are the camera twin's (its own tag bitmaps and ray casting) at 1080p, 700 mm
from the board, with blur, noise and JPEG.
"""

from __future__ import annotations

import functools
import json
import re

import cv2
import numpy as np
import pypdfium2 as pdfium
import pytest

from calibration.side import side_instruction
from projector.board import BOARD_TAG_IDS, side_board
from station.cli import main
from station.services import check as service
from station.services import check_side
from vision.detection import TagDetector

SIDE_URL = "sim://camera?view=side&height=700&blur=0.8&noise=2&jpeg=90&seed=4"


@functools.cache
def _simple():
    from station.services.guide import GuideRequest, make_guide

    # the check's guide, without its tolerances
    return make_guide(GuideRequest("simple", "success", tolerances=False, jigs=True))


def _check(changes: dict[str, float]):
    """The check of SIMPLE's parts with the layout moved by ``changes`` as the side camera sees them."""
    job = _simple()
    board = side_board(job.guide)
    targets = check_side.side_targets(job, board)
    x = np.array(job.layout.x, dtype=float)
    names = list(job.scenario.design_space.names)
    for name, delta in changes.items():
        x[names.index(name)] += delta
    picture, lens = check_side.side_frame(job, board, targets, SIDE_URL, layout=x)
    side = check_side.measure_side(job, board, targets, picture, lens, camera="side")
    frame, top_lens, _, _ = service.camera_frame(job.guide, service.FrameSource(camera="sim://camera?seed=2"))
    return service.check_frame(job, frame, top_lens, service.CheckRequest(camera="top"), side=side).report, x, names


def test_the_side_camera_reads_the_jig_stand_and_measures_height_and_tilt():
    report, x, names = _check({"track.z": -0.003})
    assert report.measured_by["track.z"] == "side" and report.measured_by["track.roll"] == "side"
    assert "track.z" not in report.not_measured and "track.roll" not in report.not_measured
    assert abs(report.as_measured["track.z"] - x[names.index("track.z")]) < 0.0005
    assert abs(report.as_measured["track.roll"] - x[names.index("track.roll")]) < 0.5
    (side,) = report.side_parts
    assert (side.name, side.via, side.view, side.found) == ("track", "J1", "side", True)
    raised = re.match(r"raise `track`'s lower end (\d+\.\d) mm", side.instruction)
    assert raised and abs(float(raised.group(1)) - 3.0) <= 0.2, side.instruction  # the measurement's own 0.1-0.2 mm
    assert "tilt" not in side.instruction


@pytest.mark.parametrize("steeper", [True, False])
def test_a_tilt_off_by_1_5_deg_is_told_steeper_or_flatter(steeper):
    job = _simple()
    (target,) = check_side.side_targets(job, side_board(job.guide))
    from calibration.asbuilt import part_plane_pose

    names = list(job.scenario.design_space.names)
    x = np.array(job.layout.x, dtype=float)
    x[names.index("track.roll")] += 1.5
    turn = part_plane_pose(job.scenario, x, side_board(job.guide).plane, ["track"])["track"].heading_deg \
        - target.heading_deg
    flatter = abs(target.tilt_deg + turn) < abs(target.tilt_deg)  # the scene graph's own answer
    delta = 1.5 if flatter == steeper else -1.5
    report, _, _ = _check({"track.roll": delta})
    words = report.side_parts[0].instruction
    tilt = re.search(r"tilt it (\d+\.\d) deg (steeper|flatter)", words)
    assert tilt and tilt.group(2) == ("steeper" if steeper else "flatter"), words
    assert abs(float(tilt.group(1)) - 1.5) <= 0.2, words


def test_the_instructions_words():
    assert side_instruction("track", (0.2, -3.0), 1.5, -30.0) == \
        "raise `track`'s lower end 3.0 mm, tilt it 1.5 deg steeper"
    assert side_instruction("track", (0.0, 2.0), -1.5, -30.0) == "lower `track`'s lower end 2.0 mm, tilt it 1.5 deg " \
        "flatter"
    assert side_instruction("plank", (0.0, 0.1), 0.8, 0.0) == \
        "tilt `plank` 0.8 deg back to level: lower its right end as the side camera sees it"
    assert side_instruction("track", (0.0, 0.2), 0.1, 20.0) == "`track` is at its height and tilt"
    assert side_instruction("track", (0.0, -1.0), 0.0, 20.0, via="J1").endswith(
        "(through jig J1: is its plate down in the base's slot and its base flat on the table?)")


def test_station_check_with_two_cameras_writes_the_views_in_check_json(tmp_path, capsys):
    out = tmp_path / "check.json"
    code = main(["check", "simple", "success", "--jigs", "--camera", "sim://camera", "--camera", SIDE_URL,
                 "--sim-side-offset", "track=0,-3", "--predict", "0", "--out", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    # the dominoes stand between the side camera and the board's lower right tag: the plane from the other three
    assert "side view (heights and tilts): plane from board tags 579, 581, 582" in text
    assert "side view: board tag 580 hidden: `dominoes` stands between the side camera and it" in text
    assert re.search(r"raise `track`'s lower end (2\.[89]|3\.[01]) mm", text), text
    data = json.loads(out.read_text())
    for key in ("format", "version", "parts", "plane", "as_built", "as_measured", "not_measured", "view"):
        assert key in data  # the contract's fields stay
    assert [v["view"] for v in data["views"]] == ["top", "side"]
    assert data["views"][1]["plane"]["reference_ids"] == [579, 581, 582]
    assert data["views"][1]["missing_reference_tags"] == [580]
    assert data["views"][1]["hidden_tags"] == {"580": ["dominoes"]}
    assert data["views"][1]["plane"]["residual_mm"] < 0.2
    assert data["measured_by"]["track.z"] == "side" and data["measured_by"]["track.x"] == "top"
    (side,) = data["side_parts"]
    assert side["view"] == "side" and side["via_jig"] == "J1" and side["tag_id"] >= 500
    assert abs(side["error"]["dv_mm"] + 3.0) < 0.3
    assert data["parts"][0]["view"] == "top"


def test_a_side_offset_without_a_side_camera_is_one_line(capsys):
    assert main(["check", "simple", "success", "--jigs", "--camera", "sim://camera", "--sim-side-offset",
                 "nothing=0,-3", "--predict", "0"]) == 2
    errors = [line for line in capsys.readouterr().err.splitlines() if "error" in line]
    assert len(errors) == 1 and "--sim-side-offset: no side camera" in errors[0]


def test_the_guide_writes_the_board_sheet_and_says_where_it_stands(tmp_path, capsys):
    plain = tmp_path / "plain.pdf"
    assert main(["guide", "simple", "success", "--pdf", str(plain), "--no-tolerances"]) == 0
    assert not (tmp_path / "plain-board.pdf").exists()  # no jig stand: nothing for the side camera to read
    capsys.readouterr()
    pdf = tmp_path / "simple.pdf"
    assert main(["guide", "simple", "success", "--jigs", "--pdf", str(pdf), "--no-tolerances"]) == 0
    assert "simple-board.pdf: the side camera's board sheet" in capsys.readouterr().out
    board = tmp_path / "simple-board.pdf"
    page = pdfium.PdfDocument(str(board))[0]
    width, height = page.get_size()
    assert abs(width / 72 * 25.4 - 297.0) < 0.5 and abs(height / 72 * 25.4 - 210.0) < 0.5  # A4 landscape, 1:1
    grey = np.asarray(page.render(scale=150 / 72).to_pil().convert("L"))
    assert sorted(t.tag_id for t in TagDetector(1.0, 1).detect(grey)) == list(BOARD_TAG_IDS)
    assert main(["guide", "simple", "success", "--json", "--no-tolerances"]) == 0
    manifest = json.loads(capsys.readouterr().out)
    assert [t["id"] for t in manifest["side_board"]["reference_tags"]] == list(BOARD_TAG_IDS)
    assert "lower edge on the table" in manifest["side_board"]["words"]


def _hidden_board_tags(job, board, tilt: float = 0.0) -> set[int]:
    """The board tags the camera twin hides behind the parts, from the side camera 700 mm away at ``tilt`` (its
    field of view at a quarter of the pixels: what stands before what does not change)."""
    truth = []
    check_side.side_frame(job, board, check_side.side_targets(job, board),
                          f"sim://camera?view=side&height=700&tilt={tilt:g}&size=960x540&f=700", truth=truth)
    return {t.tag_id for t in truth if t.tag_id in BOARD_TAG_IDS and not t.visible}


def test_the_board_stands_where_no_part_hides_its_tags(tmp_path):
    # SIMPLE with its track 50 mm left of the middle: behind the middle the dominoes hide the lower right tag from a
    # camera at the board's mid-height; a little to the right the parts stand between the two columns of tags
    from station.services.guide import GuideRequest, make_guide

    layout = tmp_path / "left.json"
    layout.write_text(json.dumps({"parameters": {"track.x": -0.05, "track.z": 0.06, "track.roll": 30.0}}))
    job = make_guide(GuideRequest("simple", str(layout), tolerances=False, jigs=True))
    board = side_board(job.guide)
    assert _hidden_board_tags(job, board) == set()
    assert board.hidden == () and "raise the side camera" not in board.words()
    assert job.manifest()["side_board"]["hidden_tags"] == {}


def test_where_no_place_is_clear_the_board_hides_the_fewest_tags_and_the_guide_says_which():
    # CAUSALITYSWITCH's dominoes run along the whole table: from the board's mid-height some tag is behind the parts
    # wherever the board stands. It stands where the station's side camera (raised 255 mm) sees all four, near the
    # jig stand whose face tag it reads, and the guide says which tags a camera level with the board loses
    from dataclasses import replace

    from station.services.guide import GuideRequest, make_guide

    job = make_guide(GuideRequest("causalityswitch_ball", None, tolerances=False, jigs=True))
    board = side_board(job.guide)
    assert _hidden_board_tags(job, board, -20.0) == set()
    level = _hidden_board_tags(job, board)
    assert level == {tag_id for tag_id, _ in board.hidden} and board.hidden_raised == ()  # as the twin draws it
    (stand,) = job.guide.jigs
    low, _, high, _ = stand.footprint.bounds
    assert board.center_u_mm - 297.0 < low and high < board.center_u_mm + 297.0  # within a sheet's width of it
    hiders = list(dict.fromkeys(name for _, names in board.hidden for name in names))
    assert (f"seen level with the board's middle, {', '.join(f'`{n}`' for n in hiders[:-1])} and `{hiders[-1]}` hide "
            f"board tags {' and '.join(str(t) for t, _ in board.hidden)}, so raise the side camera") in board.words()
    assert job.manifest()["side_board"]["hidden_tags"] == {str(t): list(names) for t, names in board.hidden}
    # elsewhere within a sheet's width of the stand, the twin's raised camera loses as many or more, or the level one
    for centre in np.linspace(high - 297.0, low + 297.0, 4):
        moved = replace(board, center_u_mm=float(centre), reference_tags=tuple(
            replace(t, center_mm=(t.center_mm[0] + centre - board.center_u_mm, t.center_mm[1]))
            for t in board.reference_tags))
        assert (len(_hidden_board_tags(job, moved, -20.0)), len(_hidden_board_tags(job, moved))) >= (0, len(level))


def test_the_simulated_world_serves_the_side_camera_where_its_maker_set_the_part():
    from calibration.asbuilt import part_plane_pose
    from station.services.world import as_placed_layout, grab_placed_side, open_world, place_parts

    job = _simple()
    world = open_world("sim://world?seed=3&jig_mm=2&jig_deg=2")
    place_parts(world, job.guide, attempt=0, highlighted=False, scenario=job.scenario)
    picture, lens = grab_placed_side(SIDE_URL, job, world, seed=1)
    board = side_board(job.guide)
    side = check_side.measure_side(job, board, check_side.side_targets(job, board), picture, lens)
    truth = part_plane_pose(job.scenario, as_placed_layout(job.scenario, job.guide, world), board.plane,
                            ["track"])["track"]
    (check,) = side.checks
    assert abs(check.measured_center_mm[1] - truth.center_mm[1]) < 0.5
    assert abs(check.measured_heading_deg - truth.heading_deg) < 0.5


def test_frames_of_an_independent_renderer_read_back_the_height_and_tilt():
    # bench/side_render.py shares no convention with the twin or with the board-plane arithmetic: its own look-at
    # pinhole, the jig's face tag carried in 3-D with its part, Pillow's rasteriser
    from bench.side_render import independent_side_frame
    from calibration.asbuilt import PlanePose, as_built_layout

    job = _simple()
    board = side_board(job.guide)
    names = list(job.scenario.design_space.names)
    moved = np.array(job.layout.x, dtype=float)
    moved[names.index("track.z")] -= 0.004
    moved[names.index("track.roll")] += 2.0
    picture, lens = independent_side_frame(job, board, moved, seed=5)
    side = check_side.measure_side(job, board, check_side.side_targets(job, board), picture, lens)
    (check,) = side.checks
    fitted = as_built_layout(job.scenario, job.layout.x, board.plane,
                             {"track": PlanePose(check.measured_center_mm, check.measured_heading_deg)},
                             {"track": ("track.z", "track.roll")})
    assert abs(fitted.unclipped[names.index("track.z")] - moved[names.index("track.z")]) < 0.0005
    assert abs(fitted.unclipped[names.index("track.roll")] - moved[names.index("track.roll")]) < 0.5


def test_the_cameras_named_in_station_toml_are_both_used(tmp_path, monkeypatch, capsys):
    config = tmp_path / "station.toml"
    config.write_text('[[devices]]\nname = "overhead"\nkind = "camera"\nurl = "sim://camera"\n\n'
                      f'[[devices]]\nname = "front"\nkind = "camera"\nurl = "{SIDE_URL}"\n', encoding="utf-8")
    monkeypatch.setenv("CHAOS_STATION_CONFIG", str(config))
    assert main(["check", "simple", "success", "--jigs", "--predict", "0", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [(v["view"], v["camera"]) for v in data["views"]] == [("top", "overhead"), ("side", "front")]
    assert data["side_parts"][0]["found"] is True


def test_the_top_camera_reads_a_jig_stands_base_tag_for_a_part_without_its_own():
    from dataclasses import replace

    job = _simple()
    untagged = tuple(replace(p, tag_id=None, tag_center_mm=None) if p.name == "track" else p for p in job.guide.parts)
    job = replace(job, guide=replace(job.guide, parts=untagged))
    (stand,) = job.guide.jigs
    frame, lens = service.grab_frame("sim://camera?seed=3", job.guide, offsets={"track": (2.0, -1.0, 0.0)})
    report = service.check_frame(job, frame, lens).report
    (track,) = [p for p in report.parts if p.name == "track"]
    assert (track.tag_id, track.via, track.found) == (stand.tag_id, "J1", True)
    assert abs(track.error[0] - 2.0) < 0.3 and abs(track.error[1] + 1.0) < 0.3
    assert track.instruction.startswith("move jig J1 (with `track` on it) 2.0 mm left")
    assert "track" not in report.by_eye and stand.tag_id not in report.unknown_tags
    assert report.measured_by.get("track.x") == "top"


def test_frames_from_files_for_both_views(tmp_path, capsys):
    from PIL import Image

    job = _simple()
    board = side_board(job.guide)
    targets = check_side.side_targets(job, board)
    side, side_lens = check_side.side_frame(job, board, targets, SIDE_URL, offsets={"track": (0.0, 2.5, 0.0)})
    top, top_lens = service.grab_frame("sim://camera?seed=2", job.guide)
    files = {}
    for name, picture, lens in (("top", top, top_lens), ("side", side, side_lens)):
        files[name] = (tmp_path / f"{name}.png", tmp_path / f"{name}.json")
        Image.fromarray(picture).save(files[name][0])
        files[name][1].write_text(json.dumps(lens.to_json()))
    assert main(["check", "simple", "success", "--jigs", "--image", str(files["top"][0]), "--intrinsics",
                 str(files["top"][1]), "--side-image", str(files["side"][0]), "--side-intrinsics",
                 str(files["side"][1]), "--predict", "0", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    (part,) = data["side_parts"]
    assert abs(part["error"]["dv_mm"] - 2.5) < 0.3 and part["instruction"].startswith("lower `track`'s lower end")
    assert main(["check", "simple", "success", "--jigs", "--image", str(files["top"][0]), "--side-intrinsics",
                 str(files["side"][1])]) == 2
    assert "--side-intrinsics goes with --side-image" in capsys.readouterr().err


def test_the_worlds_maker_is_told_the_side_cameras_heights_and_tilts():
    from station.services.world import check_moves

    report, _, _ = _check({"track.z": -0.003, "track.roll": -2.0})
    (move,) = [m for m in check_moves(report.to_json(), _simple().guide) if m["name"] == "track"]
    assert abs(move["parameters"]["track.z"] - 3.0) < 0.3 and abs(move["parameters"]["track.roll"] - 2.0) < 0.3
    small, _, _ = _check({"track.z": -0.0003})
    assert not [m for m in check_moves(small.to_json(), _simple().guide) if "parameters" in m]


@pytest.mark.parametrize("scenario", ["simple", "causalityswitch_ball"])
def test_a_stands_face_tag_is_on_its_plate_clear_of_the_slot_and_the_part(scenario):
    from shapely.geometry import box

    from station.services.guide import GuideRequest, make_guide

    job = make_guide(GuideRequest(scenario, "success", tolerances=False, jigs=True))
    (stand,) = [j for j in job.jigs.plan.jigs if j.kind == "stand"]
    ids = {j.tag_id for j in job.jigs.plan.jigs} | {p.tag_id for p in job.guide.parts}
    assert stand.face_tag_id is not None and stand.face_tag_id not in ids and 500 <= stand.face_tag_id < 579
    x, y = stand.face_tag_center_mm
    half = stand.face_tag_size_mm * 10 / 8 / 2  # with its white border
    square = box(x - half, y - half, x + half, y + half)
    assert stand.outline.contains(square)
    assert y - half > stand.thickness_mm  # above the base's slot
    assert not square.intersects(stand.silhouette)  # the part resting on the plate does not hide it
    assert [t["id"] for t in job.manifest()["jigs"]] and job.manifest()["jigs"][0]["face_tag_id"] == stand.face_tag_id


def test_real_cameras_are_told_apart_by_the_board_they_see(tmp_path, capsys):
    # two "real" cameras (video files through OpenCV's driver), given in the wrong order: the frames say which is which
    import cv2

    from station.services import calibrate

    job = _simple()
    board = side_board(job.guide)
    targets = check_side.side_targets(job, board)
    side, side_lens = check_side.side_frame(job, board, targets, SIDE_URL, offsets={"track": (0.0, -2.0, 0.0)})
    top, top_lens = service.grab_frame("sim://camera?seed=2", job.guide)
    assert check_side.view_of_frame(side, board) == "side" and check_side.view_of_frame(top, board) == "top"
    clips = {}
    for name, picture in (("front", side), ("overhead", top)):
        clips[name] = tmp_path / f"{name}.avi"
        writer = cv2.VideoWriter(str(clips[name]), cv2.VideoWriter_fourcc(*"MJPG"), 5, picture.shape[1::-1])
        for _ in range(3):
            writer.write(cv2.cvtColor(picture, cv2.COLOR_RGB2BGR))
        writer.release()
    # their calibrations as `station calibrate camera` keeps them: the first --camera is "camera", the second
    # "camera-2"
    for name, lens in (("camera", side_lens), ("camera-2", top_lens)):
        calibrate.camera_file(name).parent.mkdir(parents=True, exist_ok=True)
        calibrate.camera_file(name).write_text(json.dumps(lens.to_json()))
    assert main(["check", "simple", "success", "--jigs", "--camera", str(clips["front"]), "--camera",
                 str(clips["overhead"]), "--predict", "0", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [(v["view"], v["camera"]) for v in data["views"]] == [("top", "camera-2"), ("side", "camera")]
    assert abs(data["side_parts"][0]["error"]["dv_mm"] + 2.0) < 0.3  # through MJPEG's compression
    assert "guessed" not in (data["prediction_note"] or "")


# -- what stands between the side camera and a tag ----------------------------------------------------------------


def _side_view(job, url, *, layout=None, occluded=()):
    board = side_board(job.guide)
    targets = check_side.side_targets(job, board)
    picture, lens = check_side.side_frame(job, board, targets, url, layout=layout, occluded=occluded)
    return picture, check_side.measure_side(job, board, targets, picture, lens, camera="side")


def test_a_part_in_front_of_a_board_tag_hides_it_and_the_plane_comes_from_the_other_three():
    # SIMPLE's dominoes stand 90-110 mm in front of the board, 40 mm tall, before its lower right tag (580) as the
    # camera at the board's mid-height sees them: the twin draws them, so the frame shows three board tags
    from calibration.asbuilt import part_plane_pose

    job = _simple()
    picture, side = _side_view(job, SIDE_URL)
    found = {t.tag_id for t in TagDetector(1.0, 1).detect(np.asarray(picture).mean(axis=2).astype(np.uint8))}
    assert found & set(BOARD_TAG_IDS) == {579, 581, 582}
    assert side.measurement.plane.reference_ids == (579, 581, 582)
    assert side.hidden == {580: ("dominoes",)}
    (check,) = side.checks
    truth = part_plane_pose(job.scenario, job.layout.x, side.board.plane, ["track"])["track"]
    assert check.found and abs(check.measured_center_mm[1] - truth.center_mm[1]) < 0.3
    assert abs(check.measured_heading_deg - truth.heading_deg) < 0.3
    # the overlay marks where the hidden tag should show (red), through the plane of the other three
    overlay = check_side.side_overlay(side)
    red = np.all(np.abs(overlay.astype(int) - (230, 30, 30)) < 30, axis=2)
    tag = side.board.reference_tags[1]
    assert tag.id == 580
    u, v = np.argwhere(red)[:, 1], np.argwhere(red)[:, 0]
    matrix, plane = side.intrinsics.camera_matrix, side.measurement.plane
    corner = cv2.projectPoints(np.array([[tag.center_mm[0] - 25.0, tag.center_mm[1] + 25.0, 0.0]]),  # with border
                               plane.rvec, plane.tvec, matrix, side.intrinsics.dist_coeffs)[0].reshape(2)
    assert red.sum() > 200 and np.min(np.hypot(u - corner[0], v - corner[1])) < 3.0


def test_what_hides_a_tag_is_named_from_where_the_top_camera_found_the_parts():
    # the track set 40 mm to the left of its place: it and its stand now stand before the board's lower left tag (579)
    # as the side camera at the board's mid-height sees them. The top camera measured the track there, so the check
    # names the track, not the empty place the design leaves before that tag
    job = _simple()
    board = side_board(job.guide)
    targets = check_side.side_targets(job, board)
    names = list(job.scenario.design_space.names)
    moved = np.array(job.layout.x, dtype=float)
    moved[names.index("track.x")] -= 0.040
    picture, lens = check_side.side_frame(job, board, targets, SIDE_URL, layout=moved)
    side = check_side.measure_side(job, board, targets, picture, lens, camera="side")
    assert not side.hidden.get(579)  # the design has nothing before it
    frame, top_lens = service.grab_frame("sim://camera?seed=2", job.guide, offsets={"track": (-40.0, 0.0, 0.0)})
    report = service.check_frame(job, frame, top_lens, service.CheckRequest(camera="top"), side=side).report
    assert report.measured_by["track.x"] == "top"
    assert abs(report.as_measured["track.x"] - moved[names.index("track.x")]) < 0.001
    view = report.to_json()["views"][1]
    assert view["hidden_tags"] == {"579": ["track", "jig J1"], "580": ["dominoes"]}
    assert view["hidden_tags_as_built"] == ["track"]
    lines = check_side.side_lines(report)
    assert "side view: board tag 579 hidden: `track` and jig J1 stand between the side camera and it" in lines


def test_the_parts_drawn_where_they_hide_nothing_change_no_measurement(monkeypatch):
    # the side camera raised 255 mm (tilt -20 deg) looks over every part: the same frame with and without the
    # parts' solids reads the same numbers, and the parts are in it
    job = _simple()
    url = "sim://camera?view=side&height=700&tilt=-20&blur=0.8&noise=2&jpeg=90&seed=4"
    with_parts, side = _side_view(job, url)
    monkeypatch.setattr(check_side, "_scene_solids", lambda *args: [])
    without, bare = _side_view(job, url)
    assert side.measurement.plane.reference_ids == bare.measurement.plane.reference_ids == tuple(BOARD_TAG_IDS)
    assert side.hidden == {} and side.checks[0].found and bare.checks[0].found
    # the track's body beside its face tag changes the JPEG blocks and the blur at the tag's edge, no more: the
    # readings agree far inside the side view's accuracy (0.5 mm, 0.5 deg)
    assert np.allclose(side.checks[0].measured_center_mm, bare.checks[0].measured_center_mm, atol=0.05)
    assert abs(side.checks[0].measured_heading_deg - bare.checks[0].measured_heading_deg) < 0.1
    assert np.count_nonzero(np.abs(with_parts.astype(int) - without.astype(int)).max(axis=2) > 40) > 5000


def test_two_board_tags_are_no_plane_and_the_check_says_which_are_missing():
    # a hand over 579 and the dominoes before 580: two upper tags hold the board's tilt about their line too loosely
    # for heights (off by up to 0.75 mm on the twin); nothing is measured rather than a wrong number
    job = _simple()
    _, side = _side_view(job, SIDE_URL, occluded=(579,))
    assert side.measurement.plane is None and side.measurement.missing_reference_ids == (579, 580)
    (check,) = side.checks
    assert not check.found and check.measured_center_mm is None
    assert "not measured: the side camera found too few board tags (missing 579, 580)" in check.instruction


def test_a_board_hidden_behind_dominoes_measures_nothing_and_says_what_hides_it_and_what_to_do():
    from station.services.guide import GuideRequest, make_guide

    job = make_guide(GuideRequest("causalityswitch_ball", "success", tolerances=False, jigs=True))
    _, side = _side_view(job, SIDE_URL)
    frame, top_lens, _, _ = service.camera_frame(job.guide, service.FrameSource(camera="sim://camera?seed=2"))
    report = service.check_frame(job, frame, top_lens, service.CheckRequest(camera="top"), side=side).report
    assert side.measurement.plane is None
    assert side.hidden[579] and side.hidden[580] and side.hidden[501] == ("wave",)
    assert "track_joint.z" in report.not_measured and "track_joint.roll" in report.not_measured
    assert not any(view == "side" for view in report.measured_by.values())
    lines = check_side.side_lines(report)
    names = [f"`{n}`" for n in side.hidden[579]]
    names = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
    assert f"side view: board tag 579 hidden: {names} stand{'s' if len(side.hidden[579]) == 1 else ''} between " \
           "the side camera and it" in lines
    (no_plane,) = [line for line in lines if "no plane" in line]
    assert "3 of the board's 4 tags are needed (missing 579, 580); no height measured: raise the side camera to " \
           "look over" in no_plane
    assert "`ball_track`: tag 501 (jig J1) not measured" in lines[-1] and "`wave` stands in front" in lines[-1]


@pytest.mark.parametrize("scenario, tilt", [("simple", 0.0), ("simple", -20.0), ("causalityswitch_ball", 0.0)])
def test_the_twin_and_the_independent_renderer_hide_the_same_tags(scenario, tilt):
    # bench/side_render.py ray casts the scene graph's own shapes (boxes, spheres, cylinders, the jigs' prisms) in the
    # world; the twin clips the shapes' hulls into slabs on the board's frame: each says which tags it hid
    import math

    from bench.side_render import independent_side_frame
    from station.services.guide import GuideRequest, make_guide

    job = _simple() if scenario == "simple" else make_guide(GuideRequest(scenario, "success", tolerances=False,
                                                                         jigs=True))
    board = side_board(job.guide)
    targets = check_side.side_targets(job, board)
    u0, v0, u1, v1 = board.extent_mm
    aim = ((u0 + u1) / 2 + 15.0, (v0 + v1) / 2 - 10.0)
    truth = []
    check_side.side_frame(job, board, targets, f"sim://camera?view=side&height=700&tilt={tilt:g}&target={aim[0]},"
                          f"{aim[1]}", truth=truth)
    twin = {t.tag_id: t.visible for t in truth}
    independent = {}
    independent_side_frame(job, board, job.layout.x, aim_mm=aim, rise_mm=700.0 * math.tan(math.radians(-tilt)),
                           visibility=independent)
    assert twin == independent
    assert (not all(twin.values())) == (tilt == 0.0)  # at the board's mid-height the parts hide some
