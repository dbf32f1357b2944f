"""Reading a burned laser test card from one camera frame.

The card's four reference tags give the homography from card millimetres to the frame's pixels; the frame is
resampled onto the card at :data:`RECTIFIED_PX_PER_MM` (card y up, row 0 the card's top edge plus a margin), and
everything is measured there, in millimetres:

* **levels**: what lies under the card (the margin around it; a through-cut shows the same), and per cell the bare
  wood of its blank patch next to the square;
* **engraving darkness** of each square: ``1 - median / wood`` over the square less 1 mm all round; a square whose
  median is nearer to the light under the card than to the wood has burned through (it fell out);
* **cut lines**: a column across the line went through when its brightest pixel is nearer to the light under the
  card than to the wood; the line went through when at least :data:`THROUGH_SHARE` of its columns did. The mark's
  width is its darkness-equivalent width (the integral of ``1 - grey / wood`` across it);
* **kerf** from the comb: each slot's opening is the distance between its two edges, each found where the profile
  across the slot (averaged along the slot's middle) crosses halfway from the light in the slot to the darkest char
  beside it; a slot cut on its nominal outline opens ``nominal + kerf``. The kerf is the mean over the slots; its
  uncertainty the standard error over the slots combined with the tag fit's residual taken as a scale error (the
  residual over the tags' span, on the slots' opening) and with :data:`EDGE_PX` of a frame pixel for where an
  edge is placed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from calibration.errors import CalibrationError
from calibration.measure import detected_corners
from design.fabrication.lasercard import CardManifest
from vision.detection import detect_tags

__all__ = ["CardReading", "CellReading", "SlotReading", "read_card", "MIN_FRAME_PX_PER_MM", "RECTIFIED_PX_PER_MM",
           "SOFT_EDGE_MM"]

RECTIFIED_PX_PER_MM = 20.0
MARGIN_MM = 4.0
THROUGH_SHARE = 0.95
#: Below this many frame pixels per card millimetre the comb's edges are too coarse: on the twins the kerf reads
#: 0.01-0.02 mm wide at 8 px/mm, within 0.005 mm from 12 px/mm (docs/results/2026-12-05-laser-test-cards.md).
MIN_FRAME_PX_PER_MM = 12.0
#: How far off a slot's opening may be, in frame pixels, whatever the slots agree on: the charred band beside a
#: cut, when it is narrower than the blur, pulls the edges (the twins' campaign, docs/results: at 12 px/mm and more,
#: up to 0.1 pixel on plywood and MDF, 0.3 on card, whose cuts char less).
EDGE_PX = 0.25
#: Comb edges wider than this (mm, from a quarter to three quarters of the way down) come from a soft photo: the
#: kerf then reads wide, by 0.02-0.05 mm at 0.12-0.17 mm on the twins (docs/results).
SOFT_EDGE_MM = 0.09


@dataclass(frozen=True)
class CellReading:
    """One cell as measured: ``darkness`` (0..1, None when the square burned through), ``darkness_spread`` (the
    grain's standard deviation over the square), ``through_share`` of the cut line's columns that went through,
    ``through``, ``mark_width_mm``."""

    name: str
    row: int
    column: int
    power: float
    feed: float
    darkness: float | None
    darkness_spread: float
    square_through: bool
    through_share: float
    through: bool
    mark_width_mm: float


@dataclass(frozen=True)
class SlotReading:
    """One comb slot: its nominal width, the measured opening and the kerf it gives (None when it did not open)."""

    nominal_mm: float
    opening_mm: float | None
    kerf_mm: float | None
    edge_mm: float | None = None    # how wide its edges look: from a quarter to three quarters of the way down


@dataclass(frozen=True)
class CardReading:
    """The whole card: the tag fit, the levels, each cell and slot, the kerf and the rectified picture."""

    tags_found: tuple[int, ...]
    residual_mm: float
    homography: np.ndarray          # card mm (x, y, 1) -> frame pixel (OpenCV centres)
    light_level: float
    wood_level: float
    cells: tuple[CellReading, ...]
    slots: tuple[SlotReading, ...]
    kerf_mm: float | None
    kerf_uncertainty_mm: float | None
    rectified: np.ndarray           # RGB uint8, card + margin at RECTIFIED_PX_PER_MM
    frame_px_per_mm: float = float("nan")  # the frame's pixels per card millimetre at the card's centre
    edge_px: float = float("nan")   # how wide the comb's edges look in frame pixels (a soft photo's are wide)
    margin_mm: float = MARGIN_MM
    px_per_mm: float = RECTIFIED_PX_PER_MM


def _tag_corners_mm(centre, size: float) -> np.ndarray:
    half = size / 2.0
    cx, cy = centre
    return np.array([[cx - half, cy - half], [cx + half, cy - half], [cx + half, cy + half], [cx - half, cy + half]])


class _Card:
    """The rectified frame with card-mm lookups."""

    def __init__(self, grey: np.ndarray, rgb: np.ndarray, width: float, height: float, px: float, margin: float):
        self.grey, self.rgb, self.px, self.margin = grey, rgb, px, margin
        self.top = height + margin

    def col(self, x: float) -> float:
        return (x + self.margin) * self.px - 0.5

    def row(self, y: float) -> float:
        return (self.top - y) * self.px - 0.5

    def box(self, x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
        """The grey pixels whose centres lie in the card rectangle (NaN outside the frame)."""
        c0, c1 = int(math.ceil(self.col(x0))), int(math.floor(self.col(x1))) + 1
        r0, r1 = int(math.ceil(self.row(y1))), int(math.floor(self.row(y0))) + 1
        return self.grey[max(r0, 0):max(r1, 0), max(c0, 0):max(c1, 0)]


def _median(values: np.ndarray) -> float:
    values = values[np.isfinite(values)]
    return float(np.median(values)) if values.size else float("nan")


def _crossing(profile: np.ndarray, start: int, step: int, level: float) -> float | None:
    """Walking from ``start`` by ``step``, the fractional index where ``profile`` first falls below ``level``."""
    index = start
    while 0 <= index + step < len(profile):
        a, b = profile[index], profile[index + step]
        if a >= level > b:
            return index + step * (a - level) / (a - b)
        index += step
    return None


def _slot(card: _Card, rect, nominal: float, light: float, wood: float, char: float) -> SlotReading:
    x0, y0, x1, y1 = rect
    strip = card.box(x0 - 1.0, y0 + 2.0, x1 + 1.0, y1 - 2.0)
    if strip.size == 0 or not np.isfinite(strip).all():
        return SlotReading(nominal, None, None)
    profile = strip.mean(axis=0)
    first = card.col(x0 - 1.0)
    first = math.ceil(first)
    middle = int(round(card.col((x0 + x1) / 2.0))) - first
    inner = profile[max(0, middle - int(0.25 * nominal * card.px)):middle + int(0.25 * nominal * card.px) + 1]
    plateau = float(np.median(inner)) if inner.size else float("nan")
    if not plateau > wood + 0.5 * (light - wood):
        return SlotReading(nominal, None, None)  # the slug is still in: no opening to measure
    edge_reach = int(round(0.6 * card.px))
    left_edge = int(round(card.col(x0))) - first
    right_edge = int(round(card.col(x1))) - first
    dark_left = float(profile[max(0, left_edge - edge_reach):left_edge + edge_reach + 1].min())
    dark_right = float(profile[max(0, right_edge - edge_reach):right_edge + edge_reach + 1].min())
    # Halfway from the light to the char: the char seen beside the edge is brightened by the blur when the charred
    # band is narrow, so the char's own level (the darkest engraved square) is taken when it is darker.
    left = _crossing(profile, middle, -1, 0.5 * (plateau + min(dark_left, char)))
    right = _crossing(profile, middle, +1, 0.5 * (plateau + min(dark_right, char)))
    if left is None or right is None:
        return SlotReading(nominal, None, None)
    widths = []
    for step, dark in ((-1, dark_left), (+1, dark_right)):
        upper = _crossing(profile, middle, step, plateau - 0.25 * (plateau - dark))
        lower = _crossing(profile, middle, step, plateau - 0.75 * (plateau - dark))
        if upper is not None and lower is not None:
            widths.append(abs(lower - upper) / card.px)
    opening = (right - left) / card.px
    return SlotReading(nominal, round(opening, 4), round(opening - nominal, 4),
                       round(float(np.mean(widths)), 4) if widths else None)


def _line_through(band: np.ndarray, centre: int, contrast: float) -> np.ndarray:
    """Per column of ``band`` (rows across a cut line, ``centre`` its row): whether a bright core stands between
    the darkest pixels on either side of the line (a line cut through: light between two charred edges) by more
    than ``contrast``; a mark that did not go through is darkest in its middle."""
    above = np.argmin(band[:centre + 1], axis=0)
    below = centre + np.argmin(band[centre:], axis=0)
    rows = np.arange(band.shape[0])[:, None]
    between = (rows >= above[None, :]) & (rows <= below[None, :])
    core = np.where(between, band, -np.inf).max(axis=0)
    columns = np.arange(band.shape[1])
    flanks = np.maximum(band[above, columns], band[below, columns])
    return core - flanks > contrast


def _cell(card: _Card, cell, light: float, char: float) -> CellReading:
    wood = _median(card.box(*cell.blank))
    sx0, sy0, sx1, sy1 = cell.square
    inside = card.box(sx0 + 1.0, sy0 + 1.0, sx1 - 1.0, sy1 - 1.0)
    inside = inside[np.isfinite(inside)]
    median = float(np.median(inside)) if inside.size else float("nan")
    halfway = wood + 0.5 * (light - wood)
    square_through = bool(median > halfway)
    darkness = None if square_through or not wood > 0 else float(np.clip(1.0 - median / wood, 0.0, 1.0))
    spread = float(np.std(inside) / wood) if inside.size and wood > 0 else float("nan")
    (lx0, ly), (lx1, _) = cell.cut_line
    trim = 0.1 * (lx1 - lx0)
    band = card.box(lx0 + trim, ly - 0.7, lx1 - trim, ly + 0.7)
    if band.size == 0 or not np.isfinite(band).all() or not wood > 0:
        share, width = 0.0, float("nan")
    else:
        centre = int(round(card.row(ly))) - int(math.ceil(card.row(ly + 0.7)))
        share = float(np.mean(_line_through(band, centre, 0.12 * (light - char))))
        width = float(np.clip(1.0 - band / wood, 0.0, 1.0).sum(axis=0).mean() / card.px)
    return CellReading(cell.name, cell.row, cell.column, cell.power, cell.feed,
                       None if darkness is None else round(darkness, 4), round(spread, 4), square_through,
                       round(share, 3), share >= THROUGH_SHARE, round(width, 4))


def read_card(image: np.ndarray, manifest: CardManifest, *, px_per_mm: float = RECTIFIED_PX_PER_MM) -> CardReading:
    """Measure the card in ``image`` (RGB or grey uint8).

    Raises
    ------
    CalibrationError
        Fewer than three of the card's reference tags found, or the card not in the frame.
    """
    rgb = image if image.ndim == 3 else np.repeat(image[..., None], 3, axis=2)
    grey = cv2.cvtColor(np.ascontiguousarray(rgb[..., :3]), cv2.COLOR_RGB2GRAY)
    wanted = {tag_id for tag_id, _, _ in manifest.tags}
    found = [tag for tag in detect_tags(grey, 2.0) if tag.tag_id in wanted]
    if len({t.tag_id for t in found}) < len(wanted):
        found = [tag for tag in detect_tags(grey, 1.0) if tag.tag_id in wanted]
    ids = sorted({t.tag_id for t in found})
    if len(ids) < 3:
        raise CalibrationError(
            f"{manifest.source}: found {len(ids)} of the card's reference tags ({', '.join(map(str, sorted(wanted)))})"
            f"{' (' + ', '.join(map(str, ids)) + ')' if ids else ''} in the frame; expected at least 3: the whole "
            "card in view, lit evenly, sharp")
    by_id = {tag_id: (centre, size) for tag_id, centre, size in manifest.tags}
    card_points = np.concatenate([_tag_corners_mm(*by_id[t.tag_id]) for t in found])
    pixels = np.concatenate([detected_corners(t) for t in found])
    homography, _ = cv2.findHomography(card_points, pixels, 0)
    if homography is None:
        raise CalibrationError(f"{manifest.source}: the reference tags found do not fix the card's plane")
    back = cv2.perspectiveTransform(pixels.reshape(-1, 1, 2), np.linalg.inv(homography)).reshape(-1, 2)
    residual = float(np.sqrt(np.mean(np.sum((back - card_points) ** 2, axis=1))))

    width, height = manifest.card_mm
    size = (int(math.ceil((width + 2 * MARGIN_MM) * px_per_mm)), int(math.ceil((height + 2 * MARGIN_MM) * px_per_mm)))
    # rectified pixel (j, i) -> card mm: x = (j + 0.5) / px - margin, y = height + margin - (i + 0.5) / px
    to_card = np.array([[1.0 / px_per_mm, 0.0, 0.5 / px_per_mm - MARGIN_MM],
                        [0.0, -1.0 / px_per_mm, height + MARGIN_MM - 0.5 / px_per_mm], [0.0, 0.0, 1.0]])
    matrix = homography @ to_card
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    rect_grey = cv2.warpPerspective(grey.astype(np.float32), matrix, size, flags=flags,
                                    borderMode=cv2.BORDER_CONSTANT, borderValue=float("nan"))
    rect_rgb = cv2.warpPerspective(np.ascontiguousarray(rgb[..., :3]), matrix, size, flags=flags,
                                   borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0))
    card = _Card(rect_grey, rect_rgb, width, height, px_per_mm, MARGIN_MM)
    ring = np.concatenate([card.box(-MARGIN_MM + 0.5, 0, -1.0, height).ravel(),
                           card.box(width + 1.0, 0, width + MARGIN_MM - 0.5, height).ravel()])
    light = _median(ring)
    wood = _median(np.concatenate([card.box(*cell.blank).ravel() for cell in manifest.cells]))
    squares = [_median(card.box(c.square[0] + 1.0, c.square[1] + 1.0, c.square[2] - 1.0, c.square[3] - 1.0))
               for c in manifest.cells]
    squares = [v for v in squares if math.isfinite(v) and v < wood + 0.5 * (light - wood)]
    char = min(squares) if squares else 0.0  # the darkest engraved square: char
    cells = tuple(_cell(card, cell, light, char) for cell in manifest.cells)
    if not math.isfinite(light) or not light > wood + 20:
        raise CalibrationError(f"{manifest.source}: what lies around the card (grey {light:.0f}) is not brighter "
                               f"than the card's wood (grey {wood:.0f}); lay the card on a light surface so that "
                               "what is cut through shows")
    slots = tuple(_slot(card, slot.rect, slot.nominal_width, light, wood, char) for slot in manifest.slots)
    centre = np.array([[[width / 2, height / 2]], [[width / 2 + 1, height / 2]], [[width / 2, height / 2 + 1]]])
    seen = cv2.perspectiveTransform(centre, homography).reshape(3, 2)
    (ax, ay), (bx, by) = seen[1] - seen[0], seen[2] - seen[0]
    scale = math.sqrt(abs(float(ax * by - ay * bx)))  # pixels per mm: the root of the area of a mm square
    kerfs = np.array([s.kerf_mm for s in slots if s.kerf_mm is not None])
    if kerfs.size:
        spread = float(np.std(kerfs, ddof=1) / math.sqrt(kerfs.size)) if kerfs.size > 1 else float("nan")
        # The tag fit's residual as a scale error over the tags' span, on an opening of the slots' width.
        span = float(np.ptp(card_points, axis=0).max())
        openings = np.mean([s.opening_mm for s in slots if s.opening_mm is not None])
        fit = residual * openings / span
        edges = EDGE_PX / scale  # how well an edge is placed, whatever the slots agree on
        uncertainty = math.sqrt((spread if math.isfinite(spread) else residual) ** 2 + fit ** 2 + edges ** 2)
        kerf, kerf_u = round(float(kerfs.mean()), 4), round(uncertainty, 4)
    else:
        kerf, kerf_u = None, None
    edges = [s.edge_mm for s in slots if s.edge_mm is not None]
    edge_px = float(np.median(edges)) * scale if edges else float("nan")
    return CardReading(tuple(ids), round(residual, 4), homography, round(light, 1), round(wood, 1), cells, slots,
                       kerf, kerf_u, rect_rgb, round(scale, 2), round(edge_px, 2))
