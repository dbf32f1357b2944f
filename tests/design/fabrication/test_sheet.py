"""Kerf offsets, nesting without overlaps, SVG layers, PNG preview, parts of the machines."""

from __future__ import annotations

import io
import itertools
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import shapely
from PIL import Image
from shapely.geometry import Point, box

from design.errors import ConstraintViolation, ParameterError
from design.fabrication import Part, kerf_compensate, machine_parts, nest_parts, render_png, write_svg
from design.fabrication.labels import text_polylines


def synthetic_parts(count=7, seed=0):
    rng = np.random.default_rng(seed)
    parts = []
    for i in range(count):
        w, h = rng.uniform(15, 70, size=2)
        shape = box(-w / 2, -h / 2, w / 2, h / 2).difference(Point(0, 0).buffer(min(w, h) / 4))
        parts.append(Part(f"plate {i}", shape))
    # A ring with a large free centre: small parts may go inside it.
    parts.append(Part("ring", Point(0, 0).buffer(60).difference(Point(0, 0).buffer(45))))
    return parts


def test_kerf_offsets_outline_outward_and_holes_inward():
    shape = box(0, 0, 40, 20).difference(Point(20, 10).buffer(5, quad_segs=64))
    kerf = 0.2
    path = kerf_compensate(shape, kerf)
    minx, miny, maxx, maxy = path.bounds
    assert (maxx - minx, maxy - miny) == pytest.approx((40 + kerf, 20 + kerf), abs=1e-9)
    hole = path.interiors[0]
    hole_radius = np.hypot(*(np.asarray(hole.coords) - [20, 10]).T)
    assert hole_radius == pytest.approx(np.full(len(hole_radius), 5 - kerf / 2), abs=2e-3)
    assert kerf_compensate(shape, 0.0).equals(shape)
    with pytest.raises(ParameterError, match="kerf"):
        kerf_compensate(shape, -0.1)


def test_nested_sheet_has_no_overlaps_and_keeps_the_gap():
    parts = synthetic_parts()
    gap, kerf = 2.5, 0.2
    sheet = nest_parts(parts, 260, 200, gap=gap, kerf=kerf)
    assert len(sheet.parts) == len(parts)
    for a, b in itertools.combinations(sheet.cut_shapes, 2):
        assert a.intersection(b).area == 0.0
        assert a.distance(b) >= gap - 1e-6
    for shape in sheet.cut_shapes:
        minx, miny, maxx, maxy = shape.bounds
        assert minx >= gap - 1e-6 and miny >= gap - 1e-6 and maxx <= 260 - gap + 1e-6 and maxy <= 200 - gap + 1e-6
    # Placed parts are the originals moved rigidly (same area, same holes).
    for original, placed in zip(parts, sheet.parts):
        assert placed.shape.area == pytest.approx(original.shape.area)
    assert 0 < sheet.usage <= sheet.envelope_usage <= 1
    assert sheet.usage == pytest.approx(sum(p.shape.area for p in parts) / (260 * 200))
    # Deterministic.
    again = nest_parts(parts, 260, 200, gap=gap, kerf=kerf)
    assert again.placements == sheet.placements


def test_small_parts_go_inside_a_ring():
    ring = Part("ring", Point(0, 0).buffer(60).difference(Point(0, 0).buffer(45)))
    small = Part("disc", Point(0, 0).buffer(20))
    sheet = nest_parts([ring, small], 300, 300, gap=3)
    placed_ring, placed_disc = sheet.cut_shapes
    hole = placed_ring.interiors[0]
    from shapely.geometry import Polygon

    assert Polygon(hole).contains(placed_disc)


def test_a_part_larger_than_the_sheet_is_refused_by_name():
    with pytest.raises(ConstraintViolation, match="ring"):
        nest_parts(synthetic_parts(), 100, 100, gap=3)


def test_svg_has_one_layer_per_operation_in_mm():
    parts = machine_parts("spirograph", {"r_f": 5, "r_r": 3, "d": 1.5}, 6.0)
    sheet = nest_parts(parts, 200, 150, gap=3, kerf=0.15)
    out = io.StringIO()
    write_svg(sheet, out)
    root = ET.fromstring(out.getvalue())
    ns = {"svg": "http://www.w3.org/2000/svg"}
    assert root.get("width") == "200mm" and root.get("height") == "150mm"
    assert root.get("viewBox") == "0 0 200 150"
    layers = root.findall("svg:g", ns)
    inkscape = "{http://www.inkscape.org/namespaces/inkscape}"
    assert [g.get(f"{inkscape}label") for g in layers] == ["engrave", "cut"]
    assert all(g.get(f"{inkscape}groupmode") == "layer" for g in layers)
    cut_paths = layers[1].findall(".//svg:path", ns)
    # Every contour of every part: outlines + holes.
    assert len(cut_paths) == sum(1 + len(s.interiors) for s in sheet.cut_shapes)
    assert len(layers[0].findall(".//svg:path", ns)) == sum(len(p.engrave) for p in sheet.parts) > 0
    # Coordinates in mm inside the sheet.
    numbers = np.array([float(v) for p in cut_paths for pair in p.get("d").replace("M", "").replace("Z", "").split()
                        for v in pair.split(",")])
    assert numbers.min() >= 0 and numbers.max() <= 200


def test_png_preview_shows_material_and_cuts():
    parts = machine_parts("spirograph", {"r_f": 5, "r_r": 3, "d": 1.5}, 6.0)
    sheet = nest_parts(parts, 200, 150, gap=3, kerf=0.15)
    image = Image.open(io.BytesIO(render_png(sheet, max_pixels=400))).convert("RGB")
    assert image.size == (401, 301)
    pixels = np.asarray(image).reshape(-1, 3)
    red = (pixels[:, 0] > 200) & (pixels[:, 1] < 50) & (pixels[:, 2] < 50)
    wood = (np.abs(pixels.astype(int) - [222, 184, 135]).sum(axis=1) < 10)
    assert red.sum() > 100 and wood.sum() > 1000


def test_label_font_strokes_have_the_requested_height():
    strokes = text_polylines("RING Z55", 5.0)
    points = np.concatenate(strokes)
    assert points[:, 1].max() - points[:, 1].min() == pytest.approx(5.0, rel=0.05)


@pytest.mark.parametrize("machine", ["spirograph", "elliptic_spirograph"])
def test_machine_parts_are_valid_polygons_with_their_holes(machine):
    parts = machine_parts(machine, {}, 8.0)
    assert len({p.name for p in parts}) == len(parts)
    for part in parts:
        assert part.shape.is_valid and part.shape.area > 0
        assert part.engrave, f"{part.name} has no label"
        for stroke in part.engrave:
            assert part.shape.contains(Point(stroke.mean(axis=0)).buffer(0.1)) or part.shape.buffer(1e-6).covers(
                Point(stroke[0]))
    rolling = parts[1]
    pen = rolling.info["holes"][0]
    assert pen["name"] == "pen hole"
    x, y = pen["at_mm"]
    assert math.hypot(x, y) == pytest.approx(rolling.info["pen_distance_mm"])
    assert not rolling.shape.contains(Point(x, y))


def test_a_pen_hole_that_cuts_the_teeth_is_refused():
    with pytest.raises(ConstraintViolation, match="pen hole"):
        machine_parts("spirograph", {"r_f": 5, "r_r": 3, "d": 2.95}, 6.0)


def test_bad_scale_and_machine_are_refused():
    with pytest.raises(ParameterError, match="scale"):
        machine_parts("spirograph", {}, -1.0)
    with pytest.raises(ParameterError, match="machine"):
        machine_parts("harmonograph", {}, 5.0)


def test_cycloid_machine_parts_sit_at_the_model_positions():
    params = {"r_t": 7, "r_e": 4, "d_tf": 9.0, "theta_te": 2.4, "r_s": 2.0, "d_fh": 10.5}
    scale = 8.0
    parts = {p.name: p for p in machine_parts("cycloid_drawing_machine", params, scale)}
    plate = parts["base plate"]
    axles = plate.info["axles_mm"]
    g_e = np.array(axles["external gear axle"])
    assert axles["turntable axle"] == [0.0, 0.0]
    assert axles["fulcrum pivot"] == pytest.approx([9.0 * scale, 0.0])
    # The gears mesh where the plate holds them: centre distance = (r_T + r_E) × scale = sum of pitch radii.
    pitch_sum = parts["turntable gear"].info["pitch_radius_mm"] + parts["external gear"].info["pitch_radius_mm"]
    assert np.linalg.norm(g_e) == pytest.approx(pitch_sum, abs=1e-3)
    assert math.atan2(g_e[1], g_e[0]) == pytest.approx(2.4, abs=1e-4)
    for name in axles:
        assert not plate.shape.contains(Point(axles[name]))
    # The slider pin's whole range fits the arm's slot; the pen hole is at d_FH from the pivot.
    arm = parts["pen arm"]
    d_fe = np.linalg.norm(g_e - np.array(axles["fulcrum pivot"])) / scale
    lo, hi = arm.info["slot_mm"]
    assert (lo, hi) == pytest.approx(((d_fe - 2.0) * scale, (d_fe + 2.0) * scale), abs=1e-3)
    for x in np.linspace(lo, hi, 9):
        assert not arm.shape.intersects(Point(x, 0.0).buffer(1.5))  # a 3 mm pin slides freely
    assert not arm.shape.contains(Point(10.5 * scale, 0.0))
    assert arm.shape.contains(Point((10.5 * scale + lo) / 2, 0.0))
    # r_S = 2 is well inside the external gear: its slider pin hole is in the gear itself, no crank.
    assert "external gear crank" not in parts
    assert not parts["external gear"].shape.contains(Point(2.0 * scale, 0.0))


def test_hoot_nanny_arms_and_near_rim_pins():
    params = {"r_t": 10, "r_g1": 3, "r_g2": 2, "theta_12": 1.2, "r_p1": 2.8, "r_p2": 1.0, "l1": 13.5, "l2": 7.2}
    scale = 6.0
    parts = {p.name: p for p in machine_parts("hoot_nanny", params, scale)}
    assert parts["arm 1"].info["pivot_to_pen_mm"] == pytest.approx(13.5 * scale)
    assert parts["arm 2"].info["pivot_to_pen_mm"] == pytest.approx(7.2 * scale)
    teeth = {name: parts[name].info["teeth"] for name in ("turntable gear", "gear 1", "gear 2")}
    assert teeth["turntable gear"] * 3 == teeth["gear 1"] * 10 and teeth["gear 1"] * 2 == teeth["gear 2"] * 3
    # r_P1 = 2.8 of 3 would cut gear 1's teeth: the pin is on a crank disc at the same radius.
    crank = parts["gear 1 crank"]
    assert crank.info["pin_at_mm"] == pytest.approx(2.8 * scale)
    assert not crank.shape.contains(Point(2.8 * scale, 0.0))
    assert crank.notes and "crank" in crank.notes[0]
    # r_P2 = 1.0 fits in gear 2 itself.
    assert "gear 2 crank" not in parts
    assert not parts["gear 2"].shape.contains(Point(1.0 * scale, 0.0))
    g2 = parts["base plate"].info["axles_mm"]["gear 2 axle"]
    assert np.hypot(*g2) == pytest.approx((10 + 2) * scale, abs=1e-3)


@pytest.mark.parametrize("machine", ["cycloid_drawing_machine", "hoot_nanny"])
def test_every_part_gets_a_label_even_small_ones(machine):
    parts = machine_parts(machine, {}, 5.0)
    for part in parts:
        assert part.engrave, f"{part.name} has no label"
        strokes = np.concatenate(part.engrave)
        # Every stroke point inside the material, clear of the holes.
        assert shapely.contains_xy(part.shape, strokes[:, 0], strokes[:, 1]).all()


def test_nesting_without_a_gap_still_never_overlaps():
    sheet = nest_parts(synthetic_parts(seed=4), 260, 220, gap=0.0)
    for a, b in itertools.combinations(sheet.cut_shapes, 2):
        assert a.intersection(b).area < 1e-9


def test_parts_too_many_for_one_sheet_go_on_more_sheets():
    from design.fabrication import nest_sheets

    parts = [Part(f"disc {i}", Point(0, 0).buffer(30)) for i in range(7)]
    with pytest.raises(ConstraintViolation, match="no room"):
        nest_parts(parts, 140, 140, gap=3)
    sheets = nest_sheets(parts, 140, 140, gap=3)
    assert len(sheets) >= 2
    placed = sorted(pl.index for sheet in sheets for pl in sheet.placements)
    assert placed == list(range(7))  # every part exactly once
    for sheet in sheets:
        for a, b in itertools.combinations(sheet.cut_shapes, 2):
            assert a.distance(b) >= 3 - 1e-6
    with pytest.raises(ConstraintViolation, match="more than 1 sheets|no room"):
        nest_sheets(parts, 140, 140, gap=3, max_sheets=1)
    with pytest.raises(ConstraintViolation, match="disc"):
        nest_sheets([Part("disc", Point(0, 0).buffer(100))], 140, 140)
