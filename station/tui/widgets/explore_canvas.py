"""The pattern canvas of guided exploration: PoIs drawn as markers, a click picks the nearest PoI."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from textual import events
from textual.message import Message

from station.tui.widgets.canvas import Marker, PatternCanvas, fit_transform

#: Marker characters and colours per PoI state.
POI_STYLE = {
    "curvature": ("○", "grey62"),
    "intersection": ("×", "grey62"),
    "highlighted": ("◉", "yellow"),
    "selected": ("●", "red"),
    "invariant": ("◆", "green"),
}


def poi_markers(
    pois: Sequence, highlighted: int | None, selected: Sequence[int], invariant: Sequence[int]
) -> list[Marker]:
    """Markers for PoIs (objects with ``id``, ``kind``, ``xy``); state styles win over kind styles."""
    markers = []
    # Plain PoIs first, so that highlighted / selected / frozen ones are drawn last (on top).
    ordered = sorted(
        pois, key=lambda p: (p.id == highlighted, p.id in selected, p.id in invariant)
    )
    for p in ordered:
        if p.id == highlighted:
            char, color = POI_STYLE["highlighted"]
        elif p.id in selected:
            char, color = POI_STYLE["selected"]
        elif p.id in invariant:
            char, color = POI_STYLE["invariant"]
        else:
            char, color = POI_STYLE[p.kind]
        markers.append(Marker(tuple(p.xy), char, color))
    return markers


class ExploreCanvas(PatternCanvas):
    """A :class:`PatternCanvas` that reports clicks in world coordinates."""

    class Clicked(Message):
        """The user clicked at world point ``xy``."""

        def __init__(self, xy: tuple[float, float]) -> None:
            super().__init__()
            self.xy = xy

    def cell_to_world(self, col: int, row: int) -> tuple[float, float] | None:
        """World coordinates of the centre of a cell (inverse of the canvas's fit)."""
        bounds = self.current_bounds()
        if bounds is None:
            return None
        scale, x0, y0 = fit_transform(bounds, 2 * self.size.width, 4 * self.size.height)
        return (float((2 * col + 0.5) / scale + x0), float(y0 - (4 * row + 1.5) / scale))

    def on_click(self, event: events.Click) -> None:
        offset = event.get_content_offset(self)  # relative to the drawing area (inside the border)
        if offset is None:
            return
        xy = self.cell_to_world(offset.x, offset.y)
        if xy is not None:
            self.post_message(self.Clicked(xy))


def nearest_poi(pois: Sequence, xy: tuple[float, float]) -> int | None:
    """Id of the PoI nearest to ``xy`` (None when there is none)."""
    if not pois:
        return None
    positions = np.array([p.xy for p in pois], dtype=float)
    return int(pois[int(np.argmin(np.hypot(*(positions - np.asarray(xy)).T)))].id)
