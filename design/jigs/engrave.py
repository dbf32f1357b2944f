"""An AprilTag engraved by the laser: its black cells filled with hatch strokes.

Wood and card darken where the beam passes at engraving power, and stay light elsewhere: the black cells are filled
by straight strokes :data:`HATCH_PITCH_MM` apart (about the width a diode laser's spot darkens), each stroke one run
of black cells along a row, so that the laser is dark between runs (a run is a separate stroke of the job). The
white border cells stay unburnt. The cells come from the caller (``vision.tags.tag_cells``: 10 x 10, True white,
row 0 the top as printed), so this module holds no tag family of its own.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["HATCH_PITCH_MM", "tag_strokes"]

#: Distance between hatch strokes (mm): a diode laser's spot darkens about 0.15-0.25 mm of wood.
HATCH_PITCH_MM = 0.2


def tag_strokes(cells: np.ndarray, size_mm: float, centre: tuple[float, float], heading_deg: float = 0.0,
                pitch: float = HATCH_PITCH_MM) -> list[np.ndarray]:
    """Hatch strokes filling the black cells of a tag whose black square is ``size_mm`` across, centred at
    ``centre`` (mm), its printed "up" turned ``heading_deg`` counter-clockwise from +y.

    ``cells``: the tag's cells with their white border (True white), row 0 at the top.
    """
    cells = np.asarray(cells, dtype=bool)
    rows, cols = cells.shape
    black_cells = rows - 2  # the black square spans every cell but the white border ring
    cell = size_mm / black_cells
    half_w, half_h = cols * cell / 2.0, rows * cell / 2.0
    strokes = []
    for row in range(rows):
        top = half_h - row * cell
        runs = _runs(~cells[row])
        if not runs:
            continue
        count = max(1, int(math.floor(cell / pitch + 1e-9)))
        step = cell / count
        for k in range(count):
            y = top - step * (k + 0.5)
            # alternate the direction of successive strokes, so the job's ordering finds them end to end
            for first, last in (runs if k % 2 == 0 else runs[::-1]):
                xa, xb = -half_w + first * cell, -half_w + (last + 1) * cell
                strokes.append(np.array([[xa, y], [xb, y]] if k % 2 == 0 else [[xb, y], [xa, y]]))
    angle = math.radians(heading_deg)
    rotation = np.array([[math.cos(angle), math.sin(angle)], [-math.sin(angle), math.cos(angle)]])
    offset = np.asarray(centre, dtype=float)
    return [stroke @ rotation + offset for stroke in strokes]


def _runs(black: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) column of each run of consecutive True cells."""
    runs, start = [], None
    for index, value in enumerate(black):
        if value and start is None:
            start = index
        elif not value and start is not None:
            runs.append((start, index - 1))
            start = None
    if start is not None:
        runs.append((start, len(black) - 1))
    return runs
