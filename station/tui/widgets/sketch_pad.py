"""A sketch pad: strokes drawn with the mouse at terminal-cell resolution, shown with the braille canvas.

World coordinates: a cell (column c, row r) is the point ``(c + 0.5, -2 (r + 0.5))`` (y up, and rows twice as
tall as columns are wide, as terminal cells are), so a drawn circle stays round. The spline fitted by the
retrieval smooths the staircase of cells away.
"""

from __future__ import annotations

import math

import numpy as np
from textual import events
from textual.message import Message

from station.tui.widgets.canvas import PatternCanvas

#: Vertical size of a cell relative to its width.
CELL_ASPECT = 2.0


class SketchPad(PatternCanvas):
    """Draw strokes with the mouse (press, drag, release); symmetry copies and construction lines are shown."""

    DEFAULT_CSS = """
    SketchPad { width: 1fr; height: 1fr; min-height: 12; border: round $primary-darken-1; }
    """

    can_focus = True

    class Changed(Message):
        """The strokes changed (a stroke was finished, removed or the pad cleared)."""

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.strokes: list[list[tuple[float, float]]] = []
        self.symmetry = 1
        self._current: list[tuple[float, float]] | None = None

    # -- geometry ----------------------------------------------------------------------------------------------
    def world_bounds(self) -> tuple[float, float, float, float]:
        """The pad's rectangle in world coordinates (fixed: the drawing does not rescale while drawing)."""
        width, height = max(self.size.width, 1), max(self.size.height, 1)
        return (0.0, -CELL_ASPECT * height, float(width), 0.0)

    def cell_to_world(self, column: int, row: int) -> tuple[float, float]:
        return (column + 0.5, -CELL_ASPECT * (row + 0.5))

    def center(self) -> tuple[float, float]:
        """Centre of the symmetry copies: the middle of the pad."""
        x0, y0, x1, y1 = self.world_bounds()
        return ((x0 + x1) / 2, (y0 + y1) / 2)

    # -- editing -----------------------------------------------------------------------------------------------
    def begin_stroke(self, point: tuple[float, float]) -> None:
        self._current = [point]
        self.redraw()

    def extend_stroke(self, point: tuple[float, float]) -> None:
        if self._current is not None and (not self._current or self._current[-1] != point):
            self._current.append(point)
            self.redraw()

    def end_stroke(self) -> None:
        if self._current:
            self.strokes.append(self._current)
            self.post_message(self.Changed())
        self._current = None
        self.redraw()

    def add_stroke(self, points: list[tuple[float, float]]) -> None:
        """Add a whole stroke (world coordinates), e.g. from a script or a test."""
        self.begin_stroke(points[0])
        for point in points[1:]:
            self.extend_stroke(point)
        self.end_stroke()

    def undo(self) -> None:
        if self.strokes:
            self.strokes.pop()
            self.post_message(self.Changed())
        self.redraw()

    def clear(self) -> None:
        self.strokes = []
        self._current = None
        self.post_message(self.Changed())
        self.redraw()

    def set_symmetry(self, k: int) -> None:
        self.symmetry = max(1, int(k))
        self.redraw()

    # -- mouse -------------------------------------------------------------------------------------------------
    def on_mouse_down(self, event: events.MouseDown) -> None:
        self.focus()
        self.capture_mouse()
        self.begin_stroke(self.cell_to_world(event.x, event.y))

    def on_mouse_move(self, event: events.MouseMove) -> None:
        if self._current is not None:
            self.extend_stroke(self.cell_to_world(event.x, event.y))

    def on_mouse_up(self, event: events.MouseUp) -> None:
        self.release_mouse()
        if self._current is not None:
            self.extend_stroke(self.cell_to_world(event.x, event.y))
            self.end_stroke()

    # -- drawing -----------------------------------------------------------------------------------------------
    def redraw(self) -> None:
        polylines: list[np.ndarray] = []
        colors: list[str] = []
        cx, cy = self.center()
        x0, y0, x1, y1 = self.world_bounds()
        reach = math.hypot(x1 - x0, y1 - y0)
        if self.symmetry > 1:
            for j in range(self.symmetry):  # construction lines through the centre
                angle = math.pi / 2 + 2 * math.pi * j / self.symmetry
                polylines.append(np.array([[cx, cy], [cx + reach * math.cos(angle), cy + reach * math.sin(angle)]]))
                colors.append("grey30")
        strokes = [np.asarray(s, dtype=float) for s in self.strokes]
        if self._current:
            strokes.append(np.asarray(self._current, dtype=float))
        for j in range(1, self.symmetry):
            angle = 2 * math.pi * j / self.symmetry
            rot = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
            for stroke in strokes:
                polylines.append((stroke - (cx, cy)) @ rot.T + (cx, cy))
                colors.append("grey50")
        for stroke in strokes:
            polylines.append(stroke if len(stroke) > 1 else np.vstack([stroke, stroke]))
            colors.append("bright_white")
        self.set_polylines(polylines, colors, bounds=self.world_bounds())

    def on_resize(self, event: events.Resize) -> None:
        self.redraw()
