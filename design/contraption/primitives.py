"""Primitives (thesis App. C.1) as collision shapes: what bodies each object makes, in its own frame.

Every solid's frame is at the centre of its bounding box (a Track's, a Goblet's, an OpenBox's too), so that resting
one thing on another is a matter of half heights. Compound primitives are unions of boxes, cylinders and spheres
(pybullet compound shapes); their centre of mass is the frame's origin and their inertia is Bullet's bounding-box
estimate for compounds (a simplification: a real goblet's centre of mass is lower).

Constraint and complex primitives (Pivot, Fastener, Lever, Pulley, TensionRope, RopePulley) are wired in
:mod:`design.contraption.world`; this module only says which rigid bodies exist and their shapes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from design.contraption.geometry import Pose
from design.contraption.model import ObjectSpec, domino_count


@dataclass(frozen=True)
class ShapePart:
    """One convex part of a body, in the body's frame.

    ``kind`` is ``"box"`` (dims = half extents), ``"sphere"`` (radius,), ``"cylinder"`` (radius, height; axis z),
    ``"capsule"`` (radius, length of the cylindrical part; axis z) or ``"plane"`` (normal +z, infinite).
    """

    kind: str
    dims: tuple[float, ...]
    pose: Pose

    def smallest_dimension(self) -> float:
        if self.kind == "box":
            return 2 * min(self.dims)
        if self.kind == "sphere":
            return 2 * self.dims[0]
        if self.kind in ("cylinder", "capsule"):
            return min(2 * self.dims[0], self.dims[1] + (2 * self.dims[0] if self.kind == "capsule" else 0.0))
        return math.inf

    def surface_points(self, n: int = 16) -> np.ndarray:
        """Points on the part's hull in the body frame (for rendering and bounds)."""
        if self.kind == "box":
            hx, hy, hz = self.dims
            corners = np.array([[sx * hx, sy * hy, sz * hz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
            return self.pose.apply(corners)
        if self.kind == "sphere":
            r = self.dims[0]
            # A coarse sphere: three great circles are enough for projected outlines.
            t = np.linspace(0, 2 * np.pi, n, endpoint=False)
            c, s = np.cos(t) * r, np.sin(t) * r
            z = np.zeros_like(t)
            points = np.concatenate([np.c_[c, s, z], np.c_[c, z, s], np.c_[z, c, s]])
            return self.pose.apply(points)
        if self.kind in ("cylinder", "capsule"):
            r, h = self.dims
            t = np.linspace(0, 2 * np.pi, n, endpoint=False)
            ring = np.c_[np.cos(t) * r, np.sin(t) * r]
            top = np.c_[ring, np.full(n, h / 2)]
            bottom = np.c_[ring, np.full(n, -h / 2)]
            points = [top, bottom]
            if self.kind == "capsule":
                points.append(np.array([[0, 0, h / 2 + r], [0, 0, -h / 2 - r]]))
            return self.pose.apply(np.concatenate(points))
        size = 0.5  # a plane: a finite patch for drawing
        patch = np.array([[-size, -size, 0], [size, -size, 0], [size, size, 0], [-size, size, 0]])
        return self.pose.apply(patch)


@dataclass(frozen=True)
class BodySpec:
    """A rigid body an object makes: its label (``ball``, ``run[3]``), pose in the object's frame, parts."""

    label: str
    pose: Pose
    parts: tuple[ShapePart, ...]

    def smallest_dimension(self) -> float:
        return min(p.smallest_dimension() for p in self.parts)

    def characteristic_size(self) -> float:
        points = [p.surface_points(8) for p in self.parts if p.kind != "plane"]
        if not points:
            return math.inf
        allp = np.concatenate(points)
        return float(np.max(np.ptp(allp, axis=0)))


def _box(half, position=(0.0, 0.0, 0.0), rotation: Rotation | None = None) -> ShapePart:
    return ShapePart("box", tuple(float(h) for h in half), Pose(position, rotation))


def body_specs(obj: ObjectSpec) -> list[BodySpec]:
    """The rigid bodies of ``obj`` (none for Empty, Pivot, Fastener and ropes)."""
    s = obj.shape
    origin = Pose()
    kind = obj.type
    if kind == "Plane":
        return [BodySpec(obj.name, origin, (ShapePart("plane", (), Pose()),))]
    if kind == "Ball":
        return [BodySpec(obj.name, origin, (ShapePart("sphere", (s["radius"],), Pose()),))]
    if kind in ("Box", "Lever"):
        return [BodySpec(obj.name, origin, (_box(np.asarray(s["size"]) / 2),))]
    if kind == "Cylinder":
        return [BodySpec(obj.name, origin, (ShapePart("cylinder", (s["radius"], s["height"]), Pose()),))]
    if kind == "Capsule":
        return [BodySpec(obj.name, origin, (ShapePart("capsule", (s["radius"], s["length"]), Pose()),))]
    if kind == "Pulley":
        # The wheel turns about the object's local y axis (the layout plane's normal in x-z layouts).
        axis_y = Rotation.from_euler("x", 90, degrees=True)
        return [BodySpec(obj.name, origin, (ShapePart("cylinder", (s["radius"], s["height"]), Pose(rotation=axis_y)),))]
    if kind == "Track":
        length, width, height, wall = s["length"], s["width"], s["height"], s["wall_thickness"]
        parts = (
            _box((length / 2, width / 2, wall / 2), (0, 0, -height / 2 + wall / 2)),
            _box((length / 2, wall / 2, height / 2), (0, width / 2 - wall / 2, 0)),
            _box((length / 2, wall / 2, height / 2), (0, -width / 2 + wall / 2, 0)),
        )
        return [BodySpec(obj.name, origin, parts)]
    if kind == "OpenBox":
        sx, sy, sz = s["size"]
        t = s["thickness"]
        parts = (
            _box((sx / 2, sy / 2, t / 2), (0, 0, -sz / 2 + t / 2)),
            _box((t / 2, sy / 2, sz / 2), (sx / 2 - t / 2, 0, 0)),
            _box((t / 2, sy / 2, sz / 2), (-sx / 2 + t / 2, 0, 0)),
            _box((sx / 2 - t, t / 2, sz / 2), (0, sy / 2 - t / 2, 0)),
            _box((sx / 2 - t, t / 2, sz / 2), (0, -sy / 2 + t / 2, 0)),
        )
        return [BodySpec(obj.name, origin, parts)]
    if kind == "Goblet":
        return [BodySpec(obj.name, origin, tuple(goblet_parts(s)))]
    if kind == "DominoRun":
        size = np.asarray(s["size"], dtype=float)
        part = (_box(size / 2),)
        return [
            BodySpec(f"{obj.name}[{i}]", Pose((x, y, size[2] / 2), Rotation.from_euler("z", h, degrees=True)), part)
            for i, (x, y, h) in enumerate(domino_poses(s))
        ]
    return []


def goblet_parts(s) -> list[ShapePart]:
    """A goblet (or cup) as a disc and ``sides`` slanted wall panels; radii are mid-wall radii."""
    height, r_top, r_bottom, t, sides = s["height"], s["radius_top"], s["radius_bottom"], s["thickness"], s["sides"]
    slope = math.atan2(r_top - r_bottom, height)
    slant = math.hypot(height, r_top - r_bottom)
    # Panels overlap a little at their edges so that nothing slips between them.
    half_width = max(r_top, r_bottom) * math.tan(math.pi / sides) * 1.08 + t / 2
    parts = [ShapePart("cylinder", (r_bottom + t / 2, t), Pose((0, 0, -height / 2 + t / 2)))]
    r_mid = (r_top + r_bottom) / 2
    for i in range(sides):
        phi = 2 * math.pi * i / sides
        rotation = Rotation.from_euler("z", phi) * Rotation.from_euler("y", slope)
        centre = (r_mid * math.cos(phi), r_mid * math.sin(phi), 0.0)
        parts.append(_box((t / 2, half_width, slant / 2), centre, rotation))
    return parts


def domino_poses(s) -> list[tuple[float, float, float]]:
    """(x, y, heading in degrees) of each domino of a DominoRun, in the run's frame."""
    if "poses" in s:
        return [tuple(float(v) for v in pose) for pose in s["poses"]]
    points = np.asarray(s["path"], dtype=float)
    seg = np.diff(points, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    cumulative = np.concatenate([[0.0], np.cumsum(seg_len)])
    total = cumulative[-1]
    count = domino_count(s)
    if "count" in s:
        stations = np.linspace(0.0, total, count)
    else:
        stations = np.arange(count) * s["spacing"]
    poses = []
    for station in stations:
        i = int(np.clip(np.searchsorted(cumulative, station, side="right") - 1, 0, len(seg) - 1))
        if seg_len[i] == 0:
            continue
        frac = (station - cumulative[i]) / seg_len[i]
        x, y = points[i] + frac * seg[i]
        heading = math.degrees(math.atan2(seg[i][1], seg[i][0]))
        poses.append((float(x), float(y), heading))
    return poses
