"""Poses: positions (m) and quaternions (x, y, z, w, pybullet's order); the scene graph's composition."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.spatial.transform import Rotation

from design.contraption.model import ObjectSpec, Transform

IDENTITY = (0.0, 0.0, 0.0, 1.0)


def hpr_rotation(heading: float, pitch: float, roll: float) -> Rotation:
    """The rotation ``Rz(heading) Rx(pitch) Ry(roll)`` (degrees), Panda3D's HPR convention."""
    return Rotation.from_euler("ZXY", [heading, pitch, roll], degrees=True)


class Pose:
    """A rigid transform: ``p_world = rotation.apply(p_local) + position``."""

    __slots__ = ("position", "rotation")

    def __init__(self, position=(0.0, 0.0, 0.0), rotation: Rotation | None = None) -> None:
        self.position = np.asarray(position, dtype=float).reshape(3)
        self.rotation = rotation if rotation is not None else Rotation.identity()

    @classmethod
    def from_transform(cls, t: Transform) -> Pose:
        return cls((t.x, t.y, t.z), hpr_rotation(t.heading, t.pitch, t.roll))

    @classmethod
    def from_bullet(cls, position, quaternion) -> Pose:
        return cls(position, Rotation.from_quat(quaternion))

    def __mul__(self, other: Pose) -> Pose:
        return Pose(self.rotation.apply(other.position) + self.position, self.rotation * other.rotation)

    def apply(self, points) -> np.ndarray:
        return self.rotation.apply(np.asarray(points, dtype=float)) + self.position

    def inverse(self) -> Pose:
        inv = self.rotation.inv()
        return Pose(-inv.apply(self.position), inv)

    @property
    def quaternion(self) -> tuple[float, float, float, float]:
        return tuple(float(v) for v in self.rotation.as_quat())

    @property
    def matrix(self) -> np.ndarray:
        return self.rotation.as_matrix()

    def __repr__(self) -> str:
        return f"Pose({self.position.tolist()}, quat={list(self.quaternion)})"


def world_poses(objects, transforms: Mapping[str, Transform]) -> dict[str, Pose]:
    """World pose of each object's frame, composing the parents' transforms (the scene graph)."""
    by_name: dict[str, ObjectSpec] = {o.name: o for o in objects}
    result: dict[str, Pose] = {}

    def resolve(name: str) -> Pose:
        if name in result:
            return result[name]
        obj = by_name[name]
        local = Pose.from_transform(transforms[name])
        pose = local if obj.parent is None else resolve(obj.parent) * local
        result[name] = pose
        return pose

    for obj in objects:
        resolve(obj.name)
    return result
