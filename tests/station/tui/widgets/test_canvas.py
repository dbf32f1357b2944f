from __future__ import annotations

import numpy as np

from station.tui.widgets.canvas import Marker, PatternCanvas, densify, rasterize, world_to_cell


def test_horizontal_line_fills_the_middle_row_of_dots():
    codes, owner = rasterize([np.array([[0.0, 0.0], [1.0, 0.0]])], cells_w=10, cells_h=1, bounds=(0, -0.05, 1, 0.05))
    # A horizontal line at mid-height sets the same dot row in every cell it crosses.
    lit = codes[0][codes[0] > 0]
    assert len(lit) >= 8
    # Interior cells have both dots of row 2 lit (0x04 | 0x20); only the two end cells may be half lit.
    assert set(lit[1:-1].tolist()) == {0x24}
    assert set(owner[0][codes[0] > 0].tolist()) == {0}


def test_later_layers_own_shared_cells_and_empty_input_is_blank():
    a = np.array([[0.0, 0.0], [1.0, 1.0]])
    b = np.array([[0.0, 1.0], [1.0, 0.0]])
    _, owner = rasterize([a, b], 20, 10)
    assert (owner == 1).any() and (owner == 0).any()
    codes, owner = rasterize([], 5, 5)
    assert not codes.any() and (owner == -1).all()
    codes, _ = rasterize([np.array([[np.nan, 0.0]])], 5, 5)
    assert not codes.any()


def test_densify_bounds_spacing():
    dense = densify(np.array([[0.0, 0.0], [10.0, 0.0]]), 0.5)
    assert np.max(np.diff(dense[:, 0])) <= 0.5 + 1e-9
    assert dense[0, 0] == 0 and dense[-1, 0] == 10


def test_aspect_ratio_is_kept_for_a_circle():
    t = np.linspace(0, 2 * np.pi, 400)
    circle = np.column_stack((np.cos(t), np.sin(t)))
    codes, _ = rasterize([circle], 40, 20)
    rows, cols = np.nonzero(codes)
    width_dots = (cols.max() - cols.min() + 1) * 2
    height_dots = (rows.max() - rows.min() + 1) * 4
    assert abs(width_dots - height_dots) <= 4


def test_render_text_has_markers_and_size():
    canvas = PatternCanvas()
    canvas.set_polylines([np.array([[0.0, 0.0], [1.0, 1.0]])], ["red"], markers=[Marker((0.5, 0.5), "X")])
    text = canvas.render_text(12, 6)
    lines = text.plain.split("\n")
    assert len(lines) == 6 and all(len(line) == 12 for line in lines)
    assert "X" in text.plain
    cell = world_to_cell((0.5, 0.5), 12, 6, canvas.current_bounds())
    assert lines[cell[1]][cell[0]] == "X"
