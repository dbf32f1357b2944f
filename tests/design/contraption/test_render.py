"""The PNG views of a scenario: nothing drawn across a panel's border, thrown parts kept in view, labels apart."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from PIL import Image, ImageDraw

from design.contraption import Simulator, load_scenario
from design.contraption.catalog import EXAMPLES_DIR, example_names
from design.contraption.geometry import Pose
from design.contraption.render import (
    _font,
    _text_size,
    clip_polygon,
    clip_polyline,
    layout_panels,
    place_labels,
    render_result,
    render_views,
)

BORDER = (200, 200, 200)


@pytest.fixture(scope="module")
def ballrun_run():
    # BALLRUN's success layout throws the high plank far to the right: the case the issue saw drawn across the border.
    scenario = load_scenario(EXAMPLES_DIR / "ballrun.toml")
    with Simulator(scenario) as sim:
        return scenario, sim.run(scenario.layout("success"), record=True)


def start_snapshots():
    for name in example_names():
        scenario = load_scenario(EXAMPLES_DIR / f"{name}.toml")
        with Simulator(scenario) as sim:
            yield name, scenario, sim.build(scenario.layout("success")).snapshot()


def overlapping_pairs(boxes):
    return [(a, b) for a, b in itertools.combinations(boxes, 2)
            if min(a[2], b[2]) > max(a[0], b[0]) and min(a[3], b[3]) > max(a[1], b[1])]


def inside(points, frame):
    points = np.asarray(points)
    return bool(np.all(points[:, 0] > frame[0]) and np.all(points[:, 0] < frame[2])
                and np.all(points[:, 1] > frame[1]) and np.all(points[:, 1] < frame[3]))


def test_no_part_is_drawn_across_a_panel_border(ballrun_run):
    scenario, result = ballrun_run
    image = render_result(scenario, result).convert("RGB")
    width, height = 560, 420
    for row, col in itertools.product(range(2), range(2)):
        x0, y0 = col * width, 28 + row * height
        x1, y1 = x0 + width - 1, y0 + height - 1
        border = [(x, y0) for x in range(x0, x1 + 1)] + [(x, y1) for x in range(x0, x1 + 1)]
        border += [(x0, y) for y in range(y0, y1 + 1)] + [(x1, y) for y in range(y0, y1 + 1)]
        broken = [p for p in border if image.getpixel(p) != BORDER]
        assert not broken, f"panel {row, col}: {len(broken)} border pixels drawn over, e.g. {broken[:3]}"


def test_every_shape_and_line_lies_inside_its_panel_and_thrown_parts_stay_in_view(ballrun_run):
    scenario, result = ballrun_run
    panels = layout_panels(scenario, [("start", result.start), ("end", result.end)],
                           ropes=[result.ropes_start, result.ropes_end])
    assert len(panels) == 4
    for panel in panels:
        for _name, polygon in panel.polygons:
            assert inside(polygon, panel.frame)
        for points, _colour, _width in panel.lines:
            assert inside(points, panel.frame)
        # The view frames the end too: the thrown high plank is drawn, not cut away.
        assert panel.out_of_view == []
    end_top = panels[2]
    assert "high_plank" in {name for name, _polygon in end_top.polygons}


def test_a_part_thrown_very_far_is_named_out_of_view(ballrun_run):
    scenario, result = ballrun_run
    far = [(label, name, Pose(pose.position + [30.0, 0.0, 0.0], pose.rotation) if name == "high_plank" else pose,
            spec) for label, name, pose, spec in result.end]
    panels = layout_panels(scenario, [("start", result.start), ("end", far)])
    assert panels[2].out_of_view == ["high_plank"] and panels[3].out_of_view == ["high_plank"]
    # The scene is not shrunk to a dot to show it: the start views keep a useful scale.
    assert panels[0].scale > 300
    image = render_views(scenario, [("start", result.start), ("end", far)])
    assert image.size == (1120, 28 + 2 * 420)


def test_no_two_labels_overlap_in_any_example(ballrun_run):
    scratch = ImageDraw.Draw(Image.new("RGB", (1, 1)))
    font = _font(11)
    naive_overlaps = 0
    cases = [(n, s, [("start", snap)]) for n, s, snap in start_snapshots()]
    scenario, result = ballrun_run
    cases.append(("ballrun end", scenario, [("start", result.start), ("end", result.end)]))
    for case, scenario, snapshots in cases:
        for panel in layout_panels(scenario, snapshots):
            boxes = [box for _name, _anchor, box in panel.labels]
            assert overlapping_pairs(boxes) == [], f"{case}: {panel.caption}"
            for box in boxes:
                assert panel.frame[0] < box[0] and box[2] < panel.frame[2]
                assert panel.frame[1] + 18 < box[1] and box[3] < panel.frame[3] - 20  # off caption and scale bar
            # Where the labels were put before (4 px right of the anchor, 14 px up), they overlapped.
            naive = []
            for label, (ax, ay), _box in panel.labels:
                w, h = _text_size(scratch, label, font)
                naive.append((ax + 4, ay - 14, ax + 4 + w, ay - 14 + h))
            naive_overlaps += len(overlapping_pairs(naive))
    assert naive_overlaps > 20  # the examples are a real test of the placement


def test_place_labels_keeps_free_labels_at_their_anchor_and_moves_crowded_ones():
    area = (0, 0, 400, 300)
    boxes = place_labels([(100, 100), (300, 200)], [(40, 12), (40, 12)], area)
    assert boxes[0] == (104, 86, 144, 98) and boxes[1] == (304, 186, 344, 198)  # right-above, 4 px / 2 px away
    crowded = place_labels([(200, 150)] * 12, [(50, 12)] * 12, area)
    assert overlapping_pairs(crowded) == []
    assert all(0 <= b[0] and b[2] <= 400 and 0 <= b[1] and b[3] <= 300 for b in crowded)
    # Near the area's edge, a label goes to the side that has room.
    (edge,) = place_labels([(395, 5)], [(40, 12)], area)
    assert edge[2] <= 400 and edge[1] >= 0


def test_clipping_to_a_box():
    box = (0, 0, 10, 10)
    square = np.array([[5, 5], [15, 5], [15, 15], [5, 15]])
    clipped = clip_polygon(square, box)
    assert inside(clipped + [-1e-9, -1e-9], (0, 0, 10 + 1e-6, 10 + 1e-6))
    assert {tuple(p) for p in clipped} == {(5, 5), (10, 5), (10, 10), (5, 10)}
    assert len(clip_polygon(square + 20, box)) == 0
    pieces = clip_polyline(np.array([[-5, 5], [5, 5], [5, 20], [8, 20]]), box)
    assert [p.tolist() for p in pieces] == [[[0, 5], [5, 5], [5, 10]]]
