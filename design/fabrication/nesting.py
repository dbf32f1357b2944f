"""Kerf compensation and nesting of parts on a sheet.

Kerf: the laser removes a strip ``kerf`` wide centred on its path, so the path runs half a kerf *outside* a part's
outline and half a kerf *inside* its holes: a shapely buffer of ``+kerf/2`` does both at once on a polygon with
holes (round joins keep gear tips round).

Nesting: a deterministic bottom-left fill on a raster of the sheet. Parts are placed largest first. For each part,
upright and turned by 90° (labels never end upside down), the free positions are found at once by correlating the
sheet's occupancy with the part's footprint (an FFT). The position that keeps the envelope of all placed parts
smallest wins (then the lowest, then the leftmost). Rings' open centres stay free, so small gears nest inside ring
gears. Every placement is then checked exactly with shapely (gap kept to every other part).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import shapely
from scipy.signal import fftconvolve
from shapely.geometry import Polygon

from design.errors import ConstraintViolation, parameter_error
from design.fabrication.parts import Part
from design.fabrication.sizes import PartSize

__all__ = ["kerf_compensate", "Placement", "Sheet", "nest_parts", "nest_sheets", "check_sizes_fit",
           "largest_fitting_scale"]


def kerf_compensate(shape: Polygon, kerf: float) -> Polygon:
    """The laser path outline for ``shape``: outline offset outward and holes inward by ``kerf/2`` (mm)."""
    _check_kerf(kerf)
    if kerf == 0:
        return shape
    grown = shape.buffer(kerf / 2.0, quad_segs=16, join_style="round")
    if isinstance(grown, Polygon):
        return grown
    return max(grown.geoms, key=lambda g: g.area)


def _check_kerf(kerf: float) -> None:
    if not (math.isfinite(kerf) and 0.0 <= kerf <= 2.0):
        raise parameter_error("fabrication", "kerf", "a width in [0, 2] mm", kerf)


@dataclass(frozen=True)
class Placement:
    """Where one part goes: rotated by ``angle`` degrees about its origin, then moved by ``(dx, dy)`` mm."""

    index: int
    angle: float
    dx: float
    dy: float


@dataclass(frozen=True)
class Sheet:
    """A nested sheet.

    Attributes
    ----------
    width, height, gap, kerf : float
        Sheet size, least distance between cut paths, kerf (mm).
    placements : tuple of Placement
        One per part on this sheet, in the order the parts were given; ``index`` is the part's position there.
    parts : tuple of Part
        Parts as placed on the sheet (designed outlines, sheet coordinates, y up from the front-left corner).
    cut_shapes : tuple of Polygon
        Kerf-compensated outlines as placed: the laser follows their boundaries.
    """

    width: float
    height: float
    gap: float
    kerf: float
    placements: tuple[Placement, ...]
    parts: tuple[Part, ...]
    cut_shapes: tuple[Polygon, ...]

    @property
    def parts_area(self) -> float:
        """Material area of the parts (mm²)."""
        return float(sum(p.shape.area for p in self.parts))

    @property
    def used_width(self) -> float:
        """Width of the sheet's corner rectangle that holds every part (mm)."""
        return float(max(s.bounds[2] for s in self.cut_shapes)) + self.gap if self.cut_shapes else 0.0

    @property
    def used_height(self) -> float:
        """Height of the sheet's corner rectangle that holds every part (mm)."""
        return float(max(s.bounds[3] for s in self.cut_shapes)) + self.gap if self.cut_shapes else 0.0

    @property
    def usage(self) -> float:
        """Fraction of the whole sheet's area that ends up in parts."""
        return self.parts_area / (self.width * self.height)

    @property
    def envelope_usage(self) -> float:
        """Fraction of the used corner rectangle (``used_width × used_height``) that ends up in parts: how densely
        the parts are packed; the rest of the sheet stays usable."""
        used = self.used_width * self.used_height
        return self.parts_area / used if used > 0 else 0.0


def _raster(shape: Polygon, resolution: float, origin: tuple[float, float], size: tuple[int, int]) -> np.ndarray:
    """A 0/1 mask of ``shape`` on a grid of ``size = (rows, cols)`` cells of ``resolution`` mm from ``origin``."""
    mask = np.zeros(size, dtype=np.uint8)

    def pixels(ring) -> np.ndarray:
        xy = (np.asarray(ring.coords) - np.asarray(origin)) / resolution
        return np.round(xy * 16).astype(np.int32)  # 4 fractional bits for cv2's sub-pixel polygons

    geoms = getattr(shape, "geoms", [shape])
    for geom in geoms:
        cv2.fillPoly(mask, [pixels(geom.exterior)], 1, lineType=cv2.LINE_8, shift=4)
        for hole in geom.interiors:
            cv2.fillPoly(mask, [pixels(hole)], 0, lineType=cv2.LINE_8, shift=4)
    # Conservative: a cell partly covered counts as covered.
    return cv2.dilate(mask, np.ones((3, 3), np.uint8))


def _check_sheet(width: float, height: float, gap: float) -> None:
    for name, value in (("sheet width", width), ("sheet height", height)):
        if not (math.isfinite(value) and value > 0):
            raise parameter_error("fabrication", name, "a positive length (mm)", value)
    if not (math.isfinite(gap) and gap >= 0):
        raise parameter_error("fabrication", "gap", "a non-negative length (mm)", gap)


def _no_room(part: Part, cut_shape: Polygon, width: float, height: float, gap: float) -> ConstraintViolation:
    bx = cut_shape.bounds
    return ConstraintViolation(
        f"sheet {width:g}x{height:g} mm: no room for part {part.name!r} ({bx[2] - bx[0]:.1f}x{bx[3] - bx[1]:.1f} mm) "
        f"with a {gap:g} mm gap; use a larger sheet (--sheet WxH) or a smaller scale", constraint="sheet size")


def nest_parts(parts: Sequence[Part], width: float, height: float, gap: float = 3.0, kerf: float = 0.0,
               resolution: float | None = None) -> Sheet:
    """Place every part on one ``width`` × ``height`` mm sheet, at least ``gap`` mm apart and from the edges.

    Raises
    ------
    ConstraintViolation
        When a part cannot be placed (the message names it and its size).
    """
    sheets = nest_sheets(parts, width, height, gap, kerf, resolution, max_sheets=1)
    return sheets[0]


def nest_sheets(parts: Sequence[Part], width: float, height: float, gap: float = 3.0, kerf: float = 0.0,
                resolution: float | None = None, max_sheets: int = 8) -> list[Sheet]:
    """Place every part on as few ``width`` × ``height`` mm sheets as this greedy packing finds.

    Parts are offered largest first to the first sheet; those that find no room there go to the next sheet, and so
    on. Deterministic.

    Raises
    ------
    ConstraintViolation
        When a part does not fit even an empty sheet, or more than ``max_sheets`` would be needed.
    """
    _check_sheet(width, height, gap)
    resolution = _resolution(width, height, resolution)
    cut_shapes = [kerf_compensate(p.shape, kerf) for p in parts]
    remaining = sorted(range(len(parts)), key=lambda i: (-cut_shapes[i].area, parts[i].name))
    sheets: list[Sheet] = []
    while remaining:
        if len(sheets) == max_sheets:
            first = remaining[0]
            if max_sheets == 1:
                raise _no_room(parts[first], cut_shapes[first], width, height, gap)
            raise ConstraintViolation(
                f"the parts need more than {max_sheets} sheets of {width:g}x{height:g} mm; use a larger sheet "
                "(--sheet WxH) or a smaller scale", constraint="sheet count")
        placements, left = _fill_sheet(remaining, cut_shapes, resolution, gap, width, height)
        if not placements:
            first = remaining[0]
            raise _no_room(parts[first], cut_shapes[first], width, height, gap)
        indices = sorted(placements)  # keep the parts' given order on each sheet
        ordered = tuple(placements[i] for i in indices)
        sheets.append(Sheet(float(width), float(height), float(gap), float(kerf), ordered,
                            tuple(parts[i].transformed(pl.angle, pl.dx, pl.dy) for i, pl in zip(indices, ordered)),
                            tuple(_moved(cut_shapes[i], pl) for i, pl in zip(indices, ordered))))
        remaining = left
    return sheets


def _resolution(width: float, height: float, resolution: float | None) -> float:
    """The raster cell (mm): fine enough for gear teeth, at most 800 cells on the sheet's long side."""
    return max(0.5, max(width, height) / 800.0) if resolution is None else resolution


def _fill_sheet(order: list[int], cut_shapes: list[Polygon], resolution: float, gap: float, width: float,
                height: float) -> tuple[dict[int, Placement], list[int]]:
    """Place what fits of ``order`` on one empty sheet; returns the placements and the parts left over."""
    cols, rows = int(math.ceil(width / resolution)), int(math.ceil(height / resolution))
    occupied = np.zeros((rows, cols), dtype=np.float32)
    placements: dict[int, Placement] = {}
    placed_shapes: list[Polygon] = []
    left: list[int] = []
    for index in order:
        # The footprint (part + gap) must stay on the sheet, so parts keep the gap from the edges too.
        placement = _place_one(index, cut_shapes[index], occupied, placed_shapes, resolution, gap, width, height)
        if placement is None:
            left.append(index)
            continue
        placements[index] = placement
        placed = _moved(cut_shapes[index], placement)
        placed_shapes.append(placed)
        # Occupy the placed part (holes stay free for smaller parts).
        occupied = np.maximum(occupied, _raster(placed, resolution, (0.0, 0.0), (rows, cols)).astype(np.float32))
    return placements, left


def _moved(shape: Polygon, placement: Placement) -> Polygon:
    rotated = shapely.affinity.rotate(shape, placement.angle, origin=(0, 0))
    return shapely.affinity.translate(rotated, placement.dx, placement.dy)


def _place_one(index: int, shape: Polygon, occupied: np.ndarray, placed: list[Polygon], resolution: float,
               gap: float, width: float, height: float) -> Placement | None:
    if placed:
        bounds = np.array([p.bounds for p in placed])
        envelope = (float(bounds[:, 2].max()), float(bounds[:, 3].max()))
    else:
        envelope = (0.0, 0.0)
    best: tuple[tuple[float, float], Placement] | None = None
    # Quarter turns that keep labels readable (never upside down).
    for angle in (0.0, 90.0):
        rotated = shapely.affinity.rotate(shape, angle, origin=(0, 0))
        # The footprint is the part grown by the gap: where it is free, the part keeps the gap to everything.
        footprint = rotated.buffer(gap, quad_segs=8) if gap > 0 else rotated
        minx, miny, maxx, maxy = footprint.bounds
        rows = int(math.ceil((maxy - miny) / resolution)) + 3
        cols = int(math.ceil((maxx - minx) / resolution)) + 3
        if rows > occupied.shape[0] or cols > occupied.shape[1]:
            continue
        mask = _raster(footprint, resolution, (minx - resolution, miny - resolution), (rows, cols))
        # overlap[y, x] = number of occupied cells under the mask placed with its corner at cell (y, x).
        overlap = fftconvolve(occupied, mask[::-1, ::-1].astype(np.float32), mode="valid")
        free = np.argwhere(overlap < 0.5)
        if free.size == 0:
            continue
        # Score every free position at once: the smallest envelope (from the sheet's corner) of everything placed so
        # far plus this part, then the lowest top edge, then the leftmost. The envelope term sends small parts into
        # the free centres of ring gears instead of next to them.
        smin_x, smin_y, smax_x, smax_y = rotated.bounds
        dx = free[:, 1] * resolution - (minx - resolution)
        dy = free[:, 0] * resolution - (miny - resolution)
        right = np.maximum(envelope[0], smax_x + dx)
        top = np.maximum(envelope[1], smax_y + dy)
        score = np.lexsort((np.round(dx, 6), np.round(smax_y + dy, 6), np.round(right * top, 3)))
        for pick in score[:16]:
            candidate = Placement(index, angle, float(dx[pick]), float(dy[pick]))
            moved = _moved(shape, candidate)
            if not _fits(moved, placed, gap, width, height):
                continue
            key = (round(float(right[pick] * top[pick]), 3), round(moved.bounds[3], 6), float(dx[pick]))
            if best is None or key < best[0]:
                best = (key, candidate)
            break
    return None if best is None else best[1]


def _fits(shape: Polygon, placed: list[Polygon], gap: float, width: float, height: float) -> bool:
    minx, miny, maxx, maxy = shape.bounds
    tolerance = 1e-6
    if minx < gap - tolerance or miny < gap - tolerance or maxx > width - gap + tolerance \
            or maxy > height - gap + tolerance:
        return False
    if placed:
        # Prepared geometries make the distance test use GEOS's indexed facet distance.
        others = np.array(placed, dtype=object)
        shapely.prepare(others)
        if gap > 1e-6:
            if np.any(shapely.dwithin(others, shape, gap - 1e-6)):
                return False
        elif np.any(shapely.overlaps(others, shape) | shapely.contains(others, shape) | shapely.within(others, shape)):
            return False
    return True



# ---------------------------------------------------------------------------------------------------------------
# Sizes against the sheet before the parts are built (gear generation is the slow part of a fabrication).


def _orientations(size: PartSize) -> tuple[tuple[float, float], tuple[float, float]]:
    """The part's box upright and turned by 90°, the two ways :func:`nest_sheets` tries."""
    return (size.width, size.height), (size.height, size.width)


def _footprint_fits(w: float, h: float, width: float, height: float, gap: float, kerf: float,
                    resolution: float) -> bool:
    """Whether a ``w`` × ``h`` mm part's footprint (kerf and gap around it) fits the sheet's raster as
    :func:`_place_one` counts it: its cells plus three of padding, against the sheet's cells."""
    cols, rows = int(math.ceil(width / resolution)), int(math.ceil(height / resolution))
    return (int(math.ceil((w + kerf + 2.0 * gap) / resolution - 1e-9)) + 3 <= cols
            and int(math.ceil((h + kerf + 2.0 * gap) / resolution - 1e-9)) + 3 <= rows)


def _too_large(size: PartSize, width: float, height: float, gap: float, kerf: float, resolution: float) -> bool:
    """Whether :func:`nest_sheets` will surely refuse the part, whatever its exact outline: even its box less its
    tolerance (and the gap's buffer less its polygon's shortfall) finds no room upright or turned."""
    slack = size.tolerance + 0.01 * gap
    return not any(_footprint_fits(w - slack, h - slack, width, height, gap, kerf, resolution)
                   for w, h in _orientations(size))


def _fits_alone(size: PartSize, width: float, height: float, gap: float, kerf: float, resolution: float) -> bool:
    """Whether the part, at its full box, finds room on an empty sheet."""
    return any(_footprint_fits(w, h, width, height, gap, kerf, resolution) for w, h in _orientations(size))


def largest_fitting_scale(sizes_at, below: float, width: float, height: float, gap: float = 3.0,
                          kerf: float = 0.0, resolution: float | None = None) -> float | None:
    """The largest round scale under ``below`` at which every part fits an empty sheet on its own.

    Parameters
    ----------
    sizes_at : callable
        ``sizes_at(scale) -> list[PartSize]`` (e.g. :func:`~design.fabrication.parts.part_sizes` with the design
        bound); a :class:`~design.errors.DesignError` counts as "does not fit".
    below : float
        A scale at which some part does not fit.

    Returns
    -------
    float or None
        Rounded down to two significant digits; ``None`` when no scale fits (the hardware alone, e.g. the arms'
        width and the rims, is too large for the sheet). Sizes grow with the scale, but not strictly (the module
        is rounded so that tooth counts are whole), so the value is checked, not only bisected.
    """
    from design.errors import DesignError

    resolution = _resolution(width, height, resolution)

    def fits(scale: float) -> bool:
        try:
            return all(_fits_alone(size, width, height, gap, kerf, resolution) for size in sizes_at(scale))
        except DesignError:
            return False

    low = below
    for _ in range(40):
        low /= 2.0
        if fits(low):
            break
    else:
        return None
    high = below
    for _ in range(40):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if fits(middle) else (low, middle)
    unit = 10.0 ** (math.floor(math.log10(low)) - 1)
    rounded = math.floor(low / unit) * unit
    for _ in range(20):
        if rounded > 0 and fits(rounded):
            return float(f"{rounded:.12g}")
        rounded -= unit
    return low


def check_sizes_fit(sizes: Sequence[PartSize], width: float, height: float, gap: float = 3.0, kerf: float = 0.0,
                    scale: float | None = None, sizes_at=None, resolution: float | None = None) -> None:
    """Refuse, before anything is built, a part that cannot fit the sheet in either orientation.

    Parameters
    ----------
    sizes : sequence of PartSize
        From :func:`~design.fabrication.parts.part_sizes`.
    scale : float, optional
        The scale ``sizes`` are at, for the message.
    sizes_at : callable, optional
        ``sizes_at(scale) -> list[PartSize]``: with ``scale``, the message gives the largest scale that fits
        (:func:`largest_fitting_scale`), searched only when a part is refused.

    Raises
    ------
    ConstraintViolation
        Naming the largest such part, its size, the room on the sheet, and what to do.
    """
    _check_sheet(width, height, gap)
    _check_kerf(kerf)
    resolution = _resolution(width, height, resolution)
    too_large = [size for size in sizes if _too_large(size, width, height, gap, kerf, resolution)]
    if not too_large:
        return
    part = max(too_large, key=lambda size: size.width * size.height)
    at = f" at {scale:g} mm per unit" if scale is not None else ""
    largest_scale = None
    if scale is not None and sizes_at is not None:
        largest_scale = largest_fitting_scale(sizes_at, scale, width, height, gap, kerf, resolution)
    if largest_scale is not None:
        advice = f"the largest scale at which every part fits is {largest_scale:g} (--scale {largest_scale:g}), or use"
    else:
        advice = "no scale fits this sheet; use"
    # The sheet it needs: its box with the kerf and the gap all round, in whole raster cells plus the padding.
    need_w, need_h = (math.ceil((math.ceil((d + kerf + 2.0 * gap) / resolution) + 4) * resolution)
                      for d in (part.width, part.height))
    raise ConstraintViolation(
        f"sheet {width:g}x{height:g} mm: no room for part {part.name!r} ({part.width:.1f}x{part.height:.1f} mm{at} "
        f"needs a sheet of at least {need_w}x{need_h} mm with the {gap:g} mm gap); {advice} a larger sheet "
        "(--sheet WxH)", constraint="sheet size", margin=float(min(width - need_w, height - need_h)))
