"""True outlines of parts on a guide plane, and where a tag fits on one.

A part's outline is the union of the orthogonal projections (along the plane's normal) of every collision part of
every body it makes, at the layout's poses: the silhouette the part casts on the plane, concave where the part is
(each domino of a run is its own polygon; a goblet seen from above is a ring). Each collision part is convex, so its
projection is convex and computed exactly: a box's is the hull of its eight projected corners, a sphere's a circle,
a cylinder's the hull of its two projected end circles (sampled), a capsule's its projected axis thickened by its
radius. (A U track's U shows only where the plane looks along the track: seen from above or from the front its
floor and walls cast one rectangle.)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from shapely import affinity
from shapely.geometry import LineString, MultiPoint, Point, Polygon, box
from shapely.geometry.base import BaseGeometry
from shapely.ops import polylabel

from design.contraption.geometry import Pose
from design.contraption.primitives import BodySpec, ShapePart
from projector.guide import GuidePlane

__all__ = ["PlacedBody", "Surface", "fit_tag", "part_outline", "project_shape"]

#: Points on each circle of a sampled cylinder (the outline is within 0.2 % of the radius).
_CIRCLE_POINTS = 48


@dataclass(frozen=True)
class PlacedBody:
    """A rigid body of a part at the layout: its label, world pose and collision parts."""

    label: str
    pose: Pose
    spec: BodySpec

    @property
    def solid_parts(self) -> tuple[ShapePart, ...]:
        return tuple(p for p in self.spec.parts if p.kind != "plane")

    def world_points(self) -> np.ndarray:
        points = [self.pose.apply(p.surface_points(16)) for p in self.solid_parts]
        return np.concatenate(points) if points else np.empty((0, 3))


def project_shape(pose: Pose, part: ShapePart, plane: GuidePlane) -> Polygon:
    """The projection on the plane (mm) of one convex collision part of a body at world pose ``pose``."""
    frame = pose * part.pose
    if part.kind == "sphere":
        centre = plane.to_plane(frame.position)[0]
        return Point(centre).buffer(1000.0 * part.dims[0], quad_segs=16)
    if part.kind == "capsule":
        radius, length = part.dims
        ends = plane.to_plane(frame.apply([[0.0, 0.0, -length / 2], [0.0, 0.0, length / 2]]))
        if np.allclose(ends[0], ends[1], atol=1e-9):
            return Point(ends[0]).buffer(1000.0 * radius, quad_segs=16)
        return LineString(ends).buffer(1000.0 * radius, quad_segs=16)
    if part.kind not in ("box", "cylinder"):
        raise ValueError(f"cannot project a {part.kind!r} part")  # planes are not parts
    # a box's corners, a cylinder's two end rings: their hull is the part's projection
    hull = MultiPoint(plane.to_plane(pose.apply(part.surface_points(_CIRCLE_POINTS)))).convex_hull
    # A part seen exactly edge-on (a zero-thickness slice) still has to be drawn: a hair-thin polygon.
    return hull if isinstance(hull, Polygon) else hull.buffer(0.05)


def part_outline(bodies: Sequence[PlacedBody], plane: GuidePlane) -> BaseGeometry:
    """The union of the projections of every collision part of ``bodies``: a Polygon or a MultiPolygon (mm)."""
    pieces = [project_shape(body.pose, part, plane) for body in bodies for part in body.solid_parts]
    outline = shapely.union_all(pieces)
    return outline if outline.is_valid else shapely.make_valid(outline)


class Surface:
    """A part's surface facing the maker, for rays coming down along the plane's normal (poses computed once).

    :meth:`height` answers how far above the plane (mm, along its normal) the ray at ``uv_mm`` first meets the part:
    exactly for a box or a sphere, and for a cylinder or capsule whose projection the ray crosses, that part's
    highest point (a bound). None when the ray misses the part.
    """

    def __init__(self, bodies: Sequence[PlacedBody], plane: GuidePlane) -> None:
        self.plane = plane
        self._parts = []
        for body in bodies:
            for part in body.solid_parts:
                frame = body.pose * part.pose
                matrix = frame.rotation.as_matrix()
                entry = (part.kind, part.dims, matrix.T, frame.position, None, 0.0)
                if part.kind not in ("box", "sphere"):
                    top = body.pose.apply(part.surface_points(_CIRCLE_POINTS))
                    entry = entry[:4] + (project_shape(body.pose, part, plane),
                                         float(np.max((top - plane.origin) @ plane.normal)))
                self._parts.append(entry)

    def height(self, uv_mm: Sequence[float]) -> float | None:
        origin = self.plane.to_world(np.asarray(uv_mm, dtype=float))[0]
        best = None
        for kind, dims, inverse, position, shadow, top in self._parts:
            o = inverse @ (origin - position)
            d = inverse @ self.plane.normal
            hit = _ray_top(kind, dims, o, d) if shadow is None else (top if shadow.contains(Point(uv_mm)) else None)
            if hit is not None and (best is None or hit > best):
                best = hit
        return None if best is None else 1000.0 * float(best)


def _ray_top(kind: str, dims, o: np.ndarray, d: np.ndarray) -> float | None:
    """The largest s with ``o + s * d`` (in the part's frame) in a box or sphere, None when the ray misses it."""
    if kind == "box":
        low, high = -math.inf, math.inf
        for axis in range(3):
            half = dims[axis]
            if abs(d[axis]) < 1e-12:
                if abs(o[axis]) > half:
                    return None
                continue
            a, b = (-half - o[axis]) / d[axis], (half - o[axis]) / d[axis]
            low, high = max(low, min(a, b)), min(high, max(a, b))
        return high if low <= high else None
    radius = dims[0]
    b = float(o @ d)
    c = float(o @ o) - radius * radius
    disc = b * b - c
    return None if disc < 0 else -b + math.sqrt(disc)


def fit_tag(outline: BaseGeometry, candidates: Sequence[Sequence[float]], sizes: Sequence[float],
            heading_deg: float, margin_mm: float,
            accept: Callable[[BaseGeometry], bool] | None = None) -> tuple[tuple[float, float], float] | None:
    """The largest tag (edge in ``sizes``) that fits inside ``outline`` with ``margin_mm`` all round, and its centre.

    Centres are tried in the order given (the part's own centre first), then each polygon's pole of inaccessibility
    (the inside point farthest from the edge), then points of a grid over the outline, nearest the first centre
    first (where another part hides the middle of a long track, its end may still take a tag). A tag fits when its
    square plus the margin lies inside the outline both upright and turned with the part (``heading_deg``), so a
    drawing may show it either way, and ``accept`` (given the tag's upright square) takes it: the caller's test
    that the camera can see it there.

    Returns
    -------
    ((u, v), size) or None
        None when not even the smallest size fits (a ball, a thin plank seen edge-on, a domino).
    """
    polygons = list(getattr(outline, "geoms", [outline]))
    points = [tuple(map(float, c)) for c in candidates]
    for polygon in sorted(polygons, key=lambda p: -p.area):
        if polygon.area > 0:
            label = polylabel(polygon, tolerance=0.1)
            points.append((label.x, label.y))
    points.extend(_grid(outline, points[0] if points else None))
    for size in sorted(sizes, reverse=True):
        half = size / 2.0 + margin_mm
        for u, v in points:
            square = box(u - half, v - half, u + half, v + half)
            turned = affinity.rotate(square, heading_deg, origin=(u, v))
            if outline.contains(square) and outline.contains(turned) and (accept is None or accept(square)):
                return (u, v), float(size)
    return None


def _grid(outline: BaseGeometry, near, count: int = 200) -> list[tuple[float, float]]:
    """About ``count`` points of a square grid over the outline's box that lie inside it, nearest ``near`` first."""
    u0, v0, u1, v1 = outline.bounds
    step = max(math.sqrt((u1 - u0) * (v1 - v0) / count), 1.0)
    us, vs = np.arange(u0 + step / 2, u1, step), np.arange(v0 + step / 2, v1, step)
    grid = [(float(u), float(v)) for u in us for v in vs]
    inside = [p for p, ok in zip(grid, shapely.contains_xy(outline, *np.array(grid).T)) if ok] if grid else []
    if near is not None:
        inside.sort(key=lambda p: (p[0] - near[0]) ** 2 + (p[1] - near[1]) ** 2)
    return inside
