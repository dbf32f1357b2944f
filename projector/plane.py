"""The guide plane of a scenario: which plane (``top`` or ``side``), its (u, v) frame, and headings in it.

The (u, v) frame is the plane as the maker sees it, facing it from the side where the parts stand (the side its
normal points to): ``v`` is away from the maker on the table (``top``, world +y) or up on a board (``side``, world
+z), and ``u = v x n`` runs to the maker's right, so ``u x v = n``. A floor facing +z gives (u, v) = (x, y); a
backboard facing +y (BALLRUN's ``board``, a Plane with pitch -90) gives (-x, z): from in front of that board, world
+x runs to the maker's left. (The contraption renders of :mod:`design.contraption.render` look at the board from
behind it, x to the right: the sheets must not copy them, or they would come out mirrored.)

Which plane, when the scenario has several or none:

- ``top`` is the scenario's first upward-facing Plane (a floor); without one, a virtual floor under the lowest part.
- ``side`` is the scenario's first vertical Plane (a backboard), its normal turned towards the parts; without one,
  a virtual board behind the rearmost part, facing +y (the examples' convention: BALLRUN's parts stand in front of
  a board facing +y, TEAPOTADVENTURE's second track lies "in front" at +y).

Both views exist for every scenario (a virtual plane is a plane the maker can pin a sheet to); the guide's origin,
(u, v) = (0, 0), is the world origin projected on the plane along its normal.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from design.contraption.geometry import Pose
from design.contraption.model import Scenario
from projector.errors import ProjectorError
from projector.guide import GuidePlane

__all__ = ["VIEWS", "guide_plane", "heading_in_plane", "plane_normals", "range_axes"]

VIEWS = ("top", "side")
_Z = np.array([0.0, 0.0, 1.0])
#: |normal . z| above this is a floor, below 1 - this a wall (the examples' planes are exact).
_HORIZONTAL = 0.9
_VERTICAL = 0.1


def plane_normals(scenario: Scenario, frames: dict[str, Pose]) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(name, world point, unit normal) of each Plane object, in file order (a Plane's normal is its local +z)."""
    planes = []
    for obj in scenario.objects:
        if obj.type == "Plane":
            pose = frames[obj.name]
            normal = pose.rotation.apply(_Z)
            planes.append((obj.name, pose.position.copy(), normal / np.linalg.norm(normal)))
    return planes


def range_axes(scenario: Scenario) -> dict[str, int]:
    """How many free layout parameters move parts in each view's plane: ``top`` (y, heading), ``side`` (z, roll).

    ``x`` lies in both planes and ``pitch`` in neither, so they count for none.
    """
    counts = {"top": 0, "side": 0}
    for name in scenario.design_space.names:
        key = name.rsplit(".", 1)[1]
        if key in ("y", "heading"):
            counts["top"] += 1
        elif key in ("z", "roll"):
            counts["side"] += 1
    return counts


def guide_plane(scenario: Scenario, frames: dict[str, Pose], view: str, points: np.ndarray) -> GuidePlane:
    """The guide plane of ``view`` (see the module notes for which plane and its frame).

    Parameters
    ----------
    scenario : Scenario
    frames : dict of str to Pose
        World pose of every object's frame at the layout.
    view : str
        ``"top"`` or ``"side"``.
    points : ndarray, shape (n, 3)
        World points of the parts (metres): where a virtual plane goes, and which side of a board they stand on.

    Raises
    ------
    ProjectorError
        For a view other than ``top`` or ``side``.
    """
    if view not in VIEWS:
        raise ProjectorError(f"view: expected one of {', '.join(VIEWS)}, got {view!r}")
    planes = plane_normals(scenario, frames)
    if view == "top":
        floors = [(p, n) for _, p, n in planes if n @ _Z > _HORIZONTAL]
        point = floors[0][0] if floors else np.array([0.0, 0.0, points[:, 2].min() if len(points) else 0.0])
        normal = _Z.copy()
        v_axis = np.array([0.0, 1.0, 0.0])
    else:
        walls = [(p, n) for _, p, n in planes if abs(n @ _Z) < _VERTICAL]
        if walls:
            point, normal = walls[0]
            normal = normal - (normal @ _Z) * _Z
            normal /= np.linalg.norm(normal)
            # The parts stand on the side the maker faces the board from: turn the normal towards them.
            if len(points) and float(np.mean((points - point) @ normal)) < 0.0:
                normal = -normal
        else:
            normal = np.array([0.0, 1.0, 0.0])
            point = np.array([0.0, points[:, 1].min() if len(points) else 0.0, 0.0])
        v_axis = _Z.copy()
    u_axis = np.cross(v_axis, normal)
    u_axis /= np.linalg.norm(u_axis)
    origin = float(point @ normal) * normal  # the world origin projected on the plane
    return GuidePlane(view=view, origin=origin, u_axis=u_axis, v_axis=v_axis, normal=normal)


def heading_in_plane(rotation: Rotation, plane: GuidePlane) -> float:
    """The rotation's turn about the plane's normal, counter-clockwise as the maker sees it, in (-180, 180] degrees.

    The twist of a swing-twist decomposition about the normal: for a rotation about the normal alone it is that
    rotation's angle (a track's ``roll`` on a board facing +y, a part's ``heading`` on a floor).
    """
    x, y, z, w = rotation.as_quat()
    along = float(np.array([x, y, z]) @ plane.normal)
    angle = math.degrees(2.0 * math.atan2(along, w))
    angle = (angle + 180.0) % 360.0 - 180.0
    return 180.0 if angle == -180.0 else angle
