"""The geometry every guide output shares (projector/drawing.py): tolerance axes, zones, hatching, labels."""

from __future__ import annotations

import dataclasses
import io
import itertools

import numpy as np
import pytest
import shapely
from shapely import affinity
from shapely.geometry import Polygon, box

from projector.drawing import (
    hatch_segments,
    place_labels,
    placement_deltas,
    tag_black_rects,
    tolerance_axes,
    tolerance_text,
    tolerance_zone,
)
from projector.guide import ParameterTolerance, PartDrawing, PartKind
from projector.pdf import write_pdf
from projector.samples import sample_guide, side_plane, tiny_guide, top_plane
from projector.svg import write_svg
from vision.tags import tag_cells

U_SHAPE = box(0, 0, 40, 30).difference(box(5, 5, 35, 31))


@pytest.mark.parametrize(("plane", "parameter", "unit", "axes"), [
    (top_plane(), "a.x", "mm", ("u",)), (top_plane(), "a.y", "mm", ("v",)), (top_plane(), "a.z", "mm", ()),
    (top_plane(), "a.heading", "deg", ("arc",)), (top_plane(), "a.roll", "deg", ()),
    (side_plane(), "a.x", "mm", ("u",)), (side_plane(), "a.z", "mm", ("v",)), (side_plane(), "a.y", "mm", ()),
    (side_plane(), "a.roll", "deg", ("arc",)), (side_plane(), "a.heading", "deg", ()),
    (top_plane(), "a.x", "deg", ()), (top_plane(), "colour", "mm", ()),
])
def test_which_mark_shows_a_tolerance(plane, parameter, unit, axes):
    assert tolerance_axes(ParameterTolerance(parameter, 1.0, unit), plane) == axes


def test_the_tighter_of_two_tolerances_on_an_axis_is_drawn():
    tolerances = (ParameterTolerance("a.x", 3.0, "mm"), ParameterTolerance("b.x", -1.5, "mm"),
                  ParameterTolerance("a.heading", 4.0, "deg"), ParameterTolerance("a.y", None, "mm"))
    part = PartDrawing("a", PartKind.PLACED, 1, U_SHAPE, (0, 0), 0.0, tolerances=tolerances, care="tight")
    assert placement_deltas(part, top_plane()) == (1.5, None, 4.0)
    assert tolerance_text(part, top_plane()) == "tight ±1.5 mm ±4.0°"
    assert tolerance_text(part, side_plane()) == "tight ±1.5 mm"  # y and heading are out of a backboard's plane


def test_a_label_with_no_zone_on_the_sheet_names_the_height_and_tilt_it_gives():
    # SIMPLE's track in the top view: x is bound only by its range's end (no zone to keep to), its height and tilt
    # are off the sheet. The label names them (the check has no zone to measure against either).
    tolerances = (ParameterTolerance("track.x", 30.6, "mm", bound_limited=True),
                  ParameterTolerance("track.z", 5.3, "mm"), ParameterTolerance("track.roll", -10.6, "deg"))
    part = PartDrawing("track", PartKind.STATIC, 1, U_SHAPE, (0, 0), 0.0, tolerances=tolerances, care="normal")
    assert placement_deltas(part, top_plane()) == (None, None, None)
    assert tolerance_text(part, top_plane()) == "normal height ±5.3 mm, tilt ±10.6°"
    assert tolerance_text(part, side_plane()) == "normal ±5.3 mm ±10.6°"  # on a backboard both are on its plane


def test_the_tolerance_zone_is_the_outline_swept_over_the_box():
    zone = tolerance_zone(U_SHAPE, 2.0, 1.0)
    # Brute force: the union of the outline moved over a fine grid of the box.
    swept = shapely.union_all([affinity.translate(U_SHAPE, du, dv)
                               for du, dv in itertools.product(np.linspace(-2, 2, 9), np.linspace(-1, 1, 5))])
    assert zone.symmetric_difference(swept).area < 0.02 * swept.area
    assert zone.area < 0.8 * zone.convex_hull.area  # still a U: the gap between the arms is not filled
    assert zone.bounds == pytest.approx((-2, -1, 42, 31), abs=0.06)
    assert tolerance_zone(U_SHAPE, None, None) is None


def test_hatching_stays_inside_the_part():
    segments = hatch_segments(U_SHAPE, spacing=3.0)
    assert len(segments) > 10
    grown = U_SHAPE.buffer(1e-6)
    assert all(grown.contains(shapely.LineString(s)) for s in segments)


def test_labels_do_not_overlap_each_other_and_stay_near_their_parts():
    guide = sample_guide()
    labels = place_labels(guide)
    boxes = [labels[p.name].box for p in guide.parts]
    for a, b in itertools.combinations(boxes, 2):
        assert a.intersection(b).area < 1e-6
    for part in guide.parts:
        label = labels[part.name]
        assert label.box.distance(part.outline) < 10.0
        assert label.number == part.step
        if label.leader is not None:
            assert part.outline.distance(shapely.Point(label.leader[1])) < 1e-6


def test_tag_black_rects_cover_exactly_the_black_cells():
    rects = tag_black_rects(42, (0.0, 0.0), 8.0)  # 1 mm cells, 10 x 10 with the border, from -5 to 5
    covered = np.ones((10, 10), dtype=bool)
    for u0, v0, u1, v1 in rects:
        assert v1 - v0 == pytest.approx(1.0)
        covered[int(round(5 - v1)), int(round(u0 + 5)):int(round(u1 + 5))] = False
    assert (covered == tag_cells(42)).all()


@pytest.mark.parametrize("outline", [Polygon(), box(0, 0, 0.5, 0.5)])
def test_odd_parts_and_an_empty_guide_still_print(outline):
    guide = tiny_guide(reference_tags=True)
    part = dataclasses.replace(guide.parts[0], outline=outline)
    for odd in (dataclasses.replace(guide, parts=(part,)), dataclasses.replace(guide, parts=())):
        assert len(write_pdf(odd, io.BytesIO()).pages) == 1
        write_svg(odd, io.StringIO())
