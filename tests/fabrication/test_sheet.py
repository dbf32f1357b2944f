"""Kerf offsets, nesting without overlaps, SVG layers, PNG preview, parts of the machines."""

from __future__ import annotations

import io
import itertools
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
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
