"""Cross-sections of a part's collision shapes by a plane, in millimetres on that plane.

Every collision part of a body (:mod:`design.contraption.primitives`) is convex, so its section by a plane is the
convex hull of the points where the segments between its hull points on either side of the plane cross it: exact
for a box (eight corners), within the sampling for a cylinder (48 points a circle). A part's section is the union of
its collision parts' sections (a track cut along its middle is its floor; cut near a wall, floor and wall).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import MultiPoint, Polygon
from shapely.geometry.base import BaseGeometry

from design.contraption.geometry import Pose
from design.contraption.primitives import BodySpec, ShapePart

__all__ = ["PlaneFrame", "SolidPart", "part_solids", "section", "solid_heights"]

#: Points on each circle of a sampled cylinder or sphere.
_CIRCLE_POINTS = 48


@dataclass(frozen=True)
class SolidPart:
    """One convex collision part at the layout: its hull points in world metres."""

    kind: str
    points: np.ndarray


@dataclass(frozen=True)
class PlaneFrame:
    """A plane (world metres) with a millimetre frame on it: ``p = origin + (s e1 + t e2) / 1000``.

    ``normal`` is ``e1 x e2``; :meth:`coordinates` gives (s, t) mm of world points and their signed distance (m)."""

    origin: np.ndarray
    e1: np.ndarray
    e2: np.ndarray

    @property
    def normal(self) -> np.ndarray:
        return np.cross(self.e1, self.e2)

    def coordinates(self, points_m: np.ndarray) -> np.ndarray:
        rel = np.atleast_2d(points_m) - self.origin
        return 1000.0 * np.column_stack([rel @ self.e1, rel @ self.e2])

    def shifted(self, offset_m: float) -> PlaneFrame:
        """The parallel plane ``offset_m`` metres along the normal (same frame)."""
        return PlaneFrame(self.origin + offset_m * self.normal, self.e1, self.e2)


def part_solids(bodies: Iterable[tuple[Pose, BodySpec]]) -> list[SolidPart]:
    """The convex collision parts of bodies at their world poses (planes left out: they are not parts)."""
    solids = []
    for pose, spec in bodies:
        for part in spec.parts:
            if part.kind == "plane":
                continue
            solids.append(SolidPart(part.kind, pose.apply(_hull_points(part))))
    return solids


def _hull_points(part: ShapePart) -> np.ndarray:
    if part.kind == "sphere":
        # a fuller sphere than the three great circles drawings use: latitude rings
        radius = part.dims[0]
        lat = np.linspace(-np.pi / 2, np.pi / 2, 13)
        lon = np.linspace(0, 2 * np.pi, 24, endpoint=False)
        la, lo = np.meshgrid(lat, lon)
        local = radius * np.column_stack([(np.cos(la) * np.cos(lo)).ravel(), (np.cos(la) * np.sin(lo)).ravel(),
                                          np.sin(la).ravel()])
        return part.pose.apply(local)
    return part.surface_points(_CIRCLE_POINTS)


def section(solids: Sequence[SolidPart], frame: PlaneFrame) -> BaseGeometry:
    """The union of the solids' sections by ``frame``'s plane, in its (s, t) mm; empty when none crosses it."""
    pieces = []
    normal = frame.normal
    for solid in solids:
        distance = (solid.points - frame.origin) @ normal
        above, below = distance > 1e-12, distance < -1e-12
        on = solid.points[~above & ~below]
        crossing = [on]
        if above.any() and below.any():
            high, low = solid.points[above], solid.points[below]
            dh, dl = distance[above][:, None], distance[below][None, :]
            fraction = dh / (dh - dl)
            crossing.append((high[:, None, :] + fraction[..., None] * (low[None, :, :] - high[:, None, :]))
                            .reshape(-1, 3))
        points = np.concatenate(crossing)
        if len(points) < 3:
            continue
        hull = MultiPoint(frame.coordinates(points)).convex_hull
        if isinstance(hull, Polygon) and hull.area > 1e-6:
            pieces.append(hull)
    if not pieces:
        return Polygon()
    union = shapely.union_all(pieces)
    return union if union.is_valid else shapely.make_valid(union)


def solid_heights(solids: Sequence[SolidPart], origin: np.ndarray, normal: np.ndarray) -> tuple[float, float]:
    """The lowest and highest points of the solids above a plane (mm along its normal)."""
    points = np.concatenate([s.points for s in solids])
    heights = 1000.0 * (points - origin) @ normal
    return float(heights.min()), float(heights.max())
