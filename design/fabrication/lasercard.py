"""A laser material test card as pure geometry: a power x feed grid of engraved squares and cut lines, a kerf comb,
four reference tags at the corners, and the card's manifest (``card.json``).

Card coordinates are millimetres from the card's lower-left corner, y up (as the card lies on the bed). Every
burned path is a plain ``(n, 2)`` array; each belongs to one named operation with its own power, feed and passes:

* ``mark``: the reference tags (filled by scan lines), the labels and the title, at the material's engrave settings;
* ``engrave r{row}c{column}``: the cell's square, filled by scan lines at the cell's power and feed, one pass;
* ``cut r{row}c{column}``: the cell's straight cut line at the cell's power and feed, ``passes`` times;
* ``comb``: the kerf comb's slots and the matching tab, at the material's cut settings;
* ``outline``: the card's outline, cut last (the card drops out only when everything else is done).

The kerf comb's slots are cut on their nominal outlines, without compensation: a slot opens ``nominal + kerf`` wide,
so the camera reads the kerf as the opening less the nominal width. The tab (nominal width = the material's
thickness) comes out ``thickness - kerf`` wide: the slot it fits snugly tells the maker which joint width to draw.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from design.errors import DesignError
from design.fabrication.labels import text_polylines

__all__ = [
    "CARD_FORMAT",
    "CARD_TAG_IDS",
    "Card",
    "CardCell",
    "CardError",
    "CardManifest",
    "CardSpec",
    "CombSlot",
    "card_geometry",
    "card_manifest",
    "geometric_steps",
    "linear_steps",
    "read_manifest",
]

#: ``card.json``'s ``format`` field; ``version`` counts incompatible changes.
CARD_FORMAT = "chaos-station laser test card"
CARD_VERSION = 1
#: The reference tags (tag36h11) at the corners: lower-left, lower-right, upper-right, upper-left.
CARD_TAG_IDS = (570, 571, 572, 573)
TAG_SIZE = 8.0          # the black square's edge, mm (its white border, one cell, is left unburned around it)
MARGIN = 3.0            # from the card's edge to the tags' white border
CELL_W, CELL_H = 14.0, 17.0
SQUARE = 8.0            # the engraved square's edge
LINE_LENGTH = 10.0      # the cut line's length
LABEL_HEIGHT = 1.6
TITLE_HEIGHT = 2.2
STRIP = 14.0            # height of the top strip (title, tab) and of the bottom strip (comb)
SLOT_LENGTH = 9.0
SLOT_WEB = 4.0          # wood between two slots
#: Scan-line interval of filled areas (squares, tags), mm.
LINE_INTERVAL = 0.1


class CardError(DesignError):
    """A test card's settings or manifest are bad; the message names the field and what was expected."""


@dataclass(frozen=True)
class CardSpec:
    """What to put on a card.

    ``powers`` (fractions of max power) run along the columns, ``feeds`` (mm/min) along the rows; ``passes`` is the
    cut lines' passes. ``mark`` and ``comb`` are ``(power, feed, passes)`` of the tags and labels and of the kerf comb
    (the material's engrave and cut settings). ``slot_widths`` are the comb's nominal slot widths (mm).
    """

    material: str
    thickness: float
    powers: tuple[float, ...]
    feeds: tuple[float, ...]
    passes: int
    mark: tuple[float, float, int]
    comb: tuple[float, float, int]
    slot_widths: tuple[float, ...] = ()

    def widths(self) -> tuple[float, ...]:
        """The comb's nominal slot widths: given, else five around the thickness, 0.1 mm apart."""
        if self.slot_widths:
            return tuple(self.slot_widths)
        base = self.thickness if self.thickness > 0.5 else 3.0
        return tuple(round(base + step * 0.1, 3) for step in (-2, -1, 0, 1, 2))


@dataclass(frozen=True)
class CardCell:
    """One cell of the grid: its settings and where its square, cut line, label and blank reference patch are."""

    row: int
    column: int
    power: float
    feed: float
    square: tuple[float, float, float, float]   # x0, y0, x1, y1
    cut_line: tuple[tuple[float, float], tuple[float, float]]
    blank: tuple[float, float, float, float]    # unburned wood next to the square: the cell's reference level
    label: str

    @property
    def name(self) -> str:
        return f"r{self.row}c{self.column}"


@dataclass(frozen=True)
class CombSlot:
    """One slot of the kerf comb: its nominal width and nominal outline ``(x0, y0, x1, y1)``."""

    nominal_width: float
    rect: tuple[float, float, float, float]


@dataclass(frozen=True)
class Card:
    """The card's geometry and its burned paths by operation (in burning order)."""

    spec: CardSpec
    width: float
    height: float
    cells: tuple[CardCell, ...]
    slots: tuple[CombSlot, ...]
    tab: tuple[float, float, float, float]
    tags: tuple[tuple[int, tuple[float, float], float], ...]   # (id, centre, size)
    operations: tuple[tuple[str, tuple[float, float, int], tuple[np.ndarray, ...], bool], ...] = field(repr=False)
    """``(name, (power, feed, passes), paths, closed)`` per operation, in burning order."""


def linear_steps(low: float, high: float, count: int) -> tuple[float, ...]:
    """``count`` values from ``low`` to ``high``, equally spaced (powers)."""
    return tuple(float(v) for v in np.round(np.linspace(low, high, count), 4))


def geometric_steps(low: float, high: float, count: int) -> tuple[float, ...]:
    """``count`` values from ``low`` to ``high`` in equal ratios (feeds: a cut at 300 and an engraving at 3000
    mm/min fit on one card), rounded to whole mm/min."""
    return tuple(float(v) for v in np.round(np.geomspace(low, high, count)))


def _rect(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1], [x0, y0]], dtype=float)


def _scan_fill(x0: float, y0: float, x1: float, y1: float) -> list[np.ndarray]:
    """Horizontal scan lines filling a rectangle, :data:`LINE_INTERVAL` apart, half an interval in from its edges."""
    count = max(1, int(round((y1 - y0) / LINE_INTERVAL)))
    ys = y0 + (np.arange(count) + 0.5) * (y1 - y0) / count
    return [np.array([[x0, y], [x1, y]]) for y in ys]


def _tag_fill(cells: np.ndarray, centre: tuple[float, float], size: float) -> list[np.ndarray]:
    """Scan lines over a tag's black cells (``cells`` 10 x 10, True = white, row 0 the top), the tag upright."""
    cell = size / 8.0
    left, top = centre[0] - 5 * cell, centre[1] + 5 * cell
    lines = []
    rows_per_cell = max(1, int(round(cell / LINE_INTERVAL)))
    for row in range(10):
        black = ~np.asarray(cells[row], dtype=bool)
        if not black.any():
            continue
        # runs of black cells along the row
        edges = np.flatnonzero(np.diff(np.concatenate([[0], black.astype(int), [0]])))
        for k in range(rows_per_cell):
            y = top - (row + (k + 0.5) / rows_per_cell) * cell
            for start, stop in zip(edges[::2], edges[1::2]):
                lines.append(np.array([[left + start * cell, y], [left + stop * cell, y]]))
    return lines


def _text(text: str, height: float, centre: tuple[float, float]) -> list[np.ndarray]:
    return [stroke + np.asarray(centre, dtype=float) for stroke in text_polylines(text, height)]


def _check_spec(spec: CardSpec) -> None:
    if not spec.powers or not spec.feeds:
        raise CardError("test card: expected at least one power and one feed")
    for power in spec.powers:
        if not (math.isfinite(power) and 0.0 < power <= 1.0):
            raise CardError(f"test card: power: expected fractions of max power in (0, 1], got {power!r}")
    for feed in spec.feeds:
        if not (math.isfinite(feed) and feed > 0):
            raise CardError(f"test card: feed: expected mm/min > 0, got {feed!r}")
    if len(spec.powers) > 12 or len(spec.feeds) > 12:
        raise CardError(f"test card: expected at most 12 powers and 12 feeds, got {len(spec.powers)} x "
                        f"{len(spec.feeds)}")
    if isinstance(spec.passes, bool) or not isinstance(spec.passes, int) or not 1 <= spec.passes <= 20:
        raise CardError(f"test card: passes: expected a whole number from 1 to 20, got {spec.passes!r}")
    for width in spec.widths():
        if not (math.isfinite(width) and 0.5 <= width <= 12.0):
            raise CardError(f"test card: slot width: expected 0.5 to 12 mm, got {width!r}")


def _label(power: float, feed: float) -> str:
    return f"{100 * power:.0f}% {feed:.0f}"


def card_geometry(spec: CardSpec, tag_cells: Callable[[int], np.ndarray]) -> Card:
    """The card for ``spec``; ``tag_cells(id)`` gives a tag's 10 x 10 cells (True = white, row 0 the top as printed).

    Raises
    ------
    CardError
        A bad power, feed, passes or slot width.
    """
    _check_spec(spec)
    columns, rows = len(spec.powers), len(spec.feeds)
    widths = spec.widths()
    tag_box = TAG_SIZE * 10.0 / 8.0
    comb_width = sum(w + SLOT_WEB for w in widths) - SLOT_WEB
    inner = max(columns * CELL_W, comb_width + 2 * (tag_box + 2.0), 60.0)
    width = inner + 2 * MARGIN
    height = 2 * MARGIN + 2 * STRIP + rows * CELL_H + 4.0
    tag_offset = MARGIN + tag_box / 2.0
    tag_centres = ((tag_offset, tag_offset), (width - tag_offset, tag_offset),
                   (width - tag_offset, height - tag_offset), (tag_offset, height - tag_offset))
    tags = tuple((tag_id, (round(c[0], 4), round(c[1], 4)), TAG_SIZE) for tag_id, c in zip(CARD_TAG_IDS, tag_centres))

    # The grid, feeds from the bottom row up; the top row is the first feed so the card reads like a table.
    grid_x0 = MARGIN + (inner - columns * CELL_W) / 2.0
    grid_y0 = MARGIN + STRIP + 2.0
    cells = []
    for row, feed in enumerate(spec.feeds):
        y = grid_y0 + (rows - 1 - row) * CELL_H
        for column, power in enumerate(spec.powers):
            x = grid_x0 + column * CELL_W
            sx0 = x + (CELL_W - SQUARE) / 2.0
            square = (sx0, y + 4.5, sx0 + SQUARE, y + 4.5 + SQUARE)
            lx0 = x + (CELL_W - LINE_LENGTH) / 2.0
            cut_line = ((lx0, y + 2.0), (lx0 + LINE_LENGTH, y + 2.0))
            blank = (square[2] + 0.8, square[1] + 1.0, x + CELL_W - 0.4, square[3] - 1.0)
            cells.append(CardCell(row, column, float(power), float(feed), tuple(round(v, 4) for v in square),
                                  tuple(tuple(round(v, 4) for v in p) for p in cut_line),
                                  tuple(round(v, 4) for v in blank), _label(power, feed)))

    # The comb between the bottom tags, the tab between the top ones.
    slots = []
    x = (width - comb_width) / 2.0
    slot_y0 = MARGIN + (STRIP - SLOT_LENGTH) / 2.0
    for nominal in widths:
        slots.append(CombSlot(float(nominal), (round(x, 4), round(slot_y0, 4), round(x + nominal, 4),
                                               round(slot_y0 + SLOT_LENGTH, 4))))
        x += nominal + SLOT_WEB
    thickness = spec.thickness if spec.thickness > 0.5 else 3.0
    tab_length = 12.0
    tab_x1 = width - MARGIN - tag_box - 3.0
    tab_yc = height - MARGIN - STRIP / 2.0
    tab = (round(tab_x1 - tab_length, 4), round(tab_yc - thickness / 2, 4), round(tab_x1, 4),
           round(tab_yc + thickness / 2, 4))

    marks: list[np.ndarray] = []
    for cell in cells:
        x0, y0, x1, y1 = cell.square
        marks += _text(cell.label, LABEL_HEIGHT, ((x0 + x1) / 2.0, y1 + 2.2))
    title = f"{spec.material} x{spec.passes}"
    title_x = MARGIN + tag_box + 2.0 + 0.5 * (tab[0] - 2.0 - (MARGIN + tag_box + 2.0))
    marks += _text(title, TITLE_HEIGHT, (title_x, tab_yc))

    # One group per tag (each is ordered on its own: a few hundred scan lines), then the labels and the title.
    operations: list[tuple[str, tuple[float, float, int], tuple[np.ndarray, ...], bool]] = [
        ("mark", spec.mark, tuple(_tag_fill(tag_cells(tag_id), centre, size)), False)
        for tag_id, centre, size in tags]
    operations.append(("mark", spec.mark, tuple(marks), False))
    for cell in cells:
        operations.append((f"engrave {cell.name}", (cell.power, cell.feed, 1), tuple(_scan_fill(*cell.square)),
                           False))
    for cell in cells:
        operations.append((f"cut {cell.name}", (cell.power, cell.feed, spec.passes),
                           (np.array(cell.cut_line, dtype=float),), False))
    operations.append(("comb", spec.comb, tuple(_rect(*slot.rect) for slot in slots) + (_rect(*tab),), True))
    operations.append(("outline", spec.comb, (_rect(0.0, 0.0, width, height),), True))
    return Card(spec, round(width, 4), round(height, 4), tuple(cells), tuple(slots), tab, tags, tuple(operations))


def _settings(power: float, feed: float, passes: int) -> dict:
    return {"power": power, "feed_mm_min": feed, "passes": passes}


def card_manifest(card: Card, *, profile: str, offset: Sequence[float], files: Mapping[str, str]) -> dict:
    """``card.json``: what is where on the card and how it was burned (a public format; see the guide)."""
    spec = card.spec
    return {
        "format": CARD_FORMAT,
        "version": CARD_VERSION,
        "profile": profile,
        "material": spec.material,
        "thickness_mm": spec.thickness,
        "card_mm": [card.width, card.height],
        "offset_mm": [float(offset[0]), float(offset[1])],
        "coordinates": "card mm from the card's lower-left corner, y up; on the machine at offset_mm",
        "powers": list(spec.powers),
        "feeds_mm_min": list(spec.feeds),
        "cut_passes": spec.passes,
        "scan_interval_mm": LINE_INTERVAL,
        "mark": _settings(*spec.mark),
        "cells": [{"name": c.name, "row": c.row, "column": c.column, "power": c.power, "feed_mm_min": c.feed,
                   "engrave_passes": 1, "cut_passes": spec.passes, "square_mm": list(c.square),
                   "cut_line_mm": [list(p) for p in c.cut_line], "blank_mm": list(c.blank), "label": c.label}
                  for c in card.cells],
        "comb": {**_settings(*spec.comb),
                 "slots": [{"nominal_width_mm": s.nominal_width, "rect_mm": list(s.rect)} for s in card.slots],
                 "tab": {"nominal_width_mm": round(card.tab[3] - card.tab[1], 4), "rect_mm": list(card.tab)}},
        "tag_family": "tag36h11",
        "tags": [{"id": tag_id, "center_mm": list(centre), "size_mm": size} for tag_id, centre, size in card.tags],
        "files": dict(files),
    }


# ---------------------------------------------------------------------------------------------------------------
# Reading a manifest back (the measurement's input).


@dataclass(frozen=True)
class CardManifest:
    """The parts of ``card.json`` a measurement needs, checked."""

    source: str
    profile: str
    material: str
    card_mm: tuple[float, float]
    cells: tuple[CardCell, ...]
    cut_passes: int
    slots: tuple[CombSlot, ...]
    comb: tuple[float, float, int]
    tags: tuple[tuple[int, tuple[float, float], float], ...]
    data: Mapping = field(repr=False, default_factory=dict)


def _need(data: Mapping, key: str, where: str, kind, what: str):
    value = data.get(key) if isinstance(data, Mapping) else None
    ok = isinstance(value, kind) and not isinstance(value, bool)
    if ok and isinstance(value, (int, float)):
        ok = math.isfinite(value)
    if not ok:
        raise CardError(f"{where}.{key}: expected {what}, got {value!r:.60}")
    return value


def _numbers(data: Mapping, key: str, where: str, count: int) -> tuple[float, ...]:
    value = data.get(key) if isinstance(data, Mapping) else None
    if not (isinstance(value, list) and len(value) == count
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)):
        raise CardError(f"{where}.{key}: expected a list of {count} numbers (mm), got {value!r:.60}")
    return tuple(float(v) for v in value)


def read_manifest(data: object, source: str = "card.json") -> CardManifest:
    """Check a parsed ``card.json``; a :class:`CardError` names the file, the field and what was expected."""
    if not isinstance(data, Mapping):
        raise CardError(f"{source}: expected a JSON object (a test card's manifest), got {type(data).__name__}")
    if data.get("format") != CARD_FORMAT:
        raise CardError(f"{source}.format: expected {CARD_FORMAT!r} (written by station lasertest card), got "
                        f"{data.get('format')!r:.60}")
    if data.get("version") != CARD_VERSION:
        raise CardError(f"{source}.version: expected {CARD_VERSION}, got {data.get('version')!r:.20}")
    profile = _need(data, "profile", source, str, "a profile name")
    material = _need(data, "material", source, str, "a material name")
    card_mm = _numbers(data, "card_mm", source, 2)
    passes = _need(data, "cut_passes", source, int, "a whole number of passes")
    cells = []
    raw_cells = _need(data, "cells", source, list, "a list of cells")
    if not raw_cells:
        raise CardError(f"{source}.cells: expected at least one cell, got none")
    for index, raw in enumerate(raw_cells):
        where = f"{source}.cells[{index}]"
        if not isinstance(raw, Mapping):
            raise CardError(f"{where}: expected an object, got {raw!r:.40}")
        line = raw.get("cut_line_mm")
        if not (isinstance(line, list) and len(line) == 2):
            raise CardError(f"{where}.cut_line_mm: expected two [x, y] points, got {line!r:.60}")
        points = tuple(_numbers({"p": p}, "p", f"{where}.cut_line_mm", 2) for p in line)
        cells.append(CardCell(
            _need(raw, "row", where, int, "a whole number"), _need(raw, "column", where, int, "a whole number"),
            float(_need(raw, "power", where, (int, float), "a fraction of max power")),
            float(_need(raw, "feed_mm_min", where, (int, float), "a feed in mm/min")),
            _numbers(raw, "square_mm", where, 4), points, _numbers(raw, "blank_mm", where, 4),
            str(raw.get("label", ""))))
    comb = _need(data, "comb", source, Mapping, "an object (the kerf comb)")
    slots = []
    for index, raw in enumerate(_need(comb, "slots", f"{source}.comb", list, "a list of slots")):
        where = f"{source}.comb.slots[{index}]"
        slots.append(CombSlot(float(_need(raw, "nominal_width_mm", where, (int, float), "a width in mm")),
                              _numbers(raw, "rect_mm", where, 4)))
    comb_settings = (float(_need(comb, "power", f"{source}.comb", (int, float), "a fraction of max power")),
                     float(_need(comb, "feed_mm_min", f"{source}.comb", (int, float), "a feed in mm/min")),
                     int(_need(comb, "passes", f"{source}.comb", int, "a whole number")))
    tags = []
    for index, raw in enumerate(_need(data, "tags", source, list, "a list of tags")):
        where = f"{source}.tags[{index}]"
        centre = _numbers(raw, "center_mm", where, 2)
        tags.append((_need(raw, "id", where, int, "a tag36h11 id"), centre,
                     float(_need(raw, "size_mm", where, (int, float), "a size in mm"))))
    if len(tags) < 2:
        raise CardError(f"{source}.tags: expected the card's reference tags (four), got {len(tags)}")
    return CardManifest(source, profile, material, card_mm, tuple(cells), passes, tuple(slots), comb_settings,
                        tuple(tags), dict(data))
