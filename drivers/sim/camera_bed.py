"""What a simulated camera over a laser's bed sees: the bed (dark honeycomb), a sheet of stock lying on it, and on
the stock what the simulated laser burned (``sim://camera?laser=NAME&bed=U,V,ANGLE&stock=U,V,W,H,ANGLE``).

Coordinates: the camera's plane (u, v) mm (:mod:`drivers.sim.camera_scene`). ``bed`` says where the laser's
machine coordinates lie on it: machine ``(x, y)`` is at ``(u, v) + R(angle) @ (x, y)``. ``stock`` is a sheet's
lower-left corner on the plane, its width and height (mm) and its turn (degrees, counter-clockwise about that
corner). The burns are the laser's executed feed moves with the laser on (the shared twin
``sim://grbl?name=NAME``'s record), drawn ``kerf`` mm wide on the stock's texture: a burn off the stock marks
nothing the camera can see (the honeycomb).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from drivers.sim.camera_scene import ImageItem

__all__ = ["BED_COLOR", "BURN_COLOR", "STOCK_COLOR", "BedView"]

BED_COLOR = (70, 72, 74)
STOCK_COLOR = (208, 176, 128)
BURN_COLOR = (52, 38, 30)
#: Texture pixels per mm of the stock (burns of a tenth of a millimetre stay visible).
TEXELS_PER_MM = 10.0


@dataclass(frozen=True)
class BedView:
    """A laser's bed as a simulated camera sees it (module docstring)."""

    laser: str = ""
    bed: tuple[float, float, float] = (0.0, 0.0, 0.0)
    stock: tuple[float, float, float, float, float] | None = None
    kerf: float = 0.15
    #: Blocks the laser ran before this sheet was laid on the bed (their burns are on another sheet).
    since: int = 0

    def plane_from_machine(self, points) -> np.ndarray:
        """Machine ``(n, 2)`` mm -> plane (u, v) mm."""
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        c, s = math.cos(math.radians(self.bed[2])), math.sin(math.radians(self.bed[2]))
        rotation = np.array([[c, -s], [s, c]])
        return points @ rotation.T + np.array(self.bed[:2])

    def machine_from_plane(self, points) -> np.ndarray:
        """Plane (u, v) ``(n, 2)`` mm -> machine mm."""
        points = np.asarray(points, dtype=float).reshape(-1, 2) - np.array(self.bed[:2])
        c, s = math.cos(math.radians(self.bed[2])), math.sin(math.radians(self.bed[2]))
        return points @ np.array([[c, -s], [s, c]])

    def stock_corners(self) -> np.ndarray | None:
        """The stock's plane corners ``(4, 2)``: lower-left, lower-right, upper-right, upper-left."""
        if self.stock is None:
            return None
        u, v, width, height, angle = self.stock
        c, s = math.cos(math.radians(angle)), math.sin(math.radians(angle))
        local = np.array([[0, 0], [width, 0], [width, height], [0, height]], dtype=float)
        return local @ np.array([[c, -s], [s, c]]).T + np.array([u, v])

    def items(self, burns: list[tuple[np.ndarray, np.ndarray]]) -> tuple[ImageItem, ...]:
        """The stock with the burns ``[(start, end)]`` (machine XY mm) on it, as the scene's picture."""
        corners = self.stock_corners()
        if corners is None:
            return ()
        _, _, width, height, _ = self.stock
        w, h = max(2, int(round(width * TEXELS_PER_MM))), max(2, int(round(height * TEXELS_PER_MM)))
        texture = np.empty((h, w, 3), dtype=np.uint8)
        texture[:] = STOCK_COLOR
        if burns:
            # machine -> plane -> the stock's own mm (from its lower-left corner) -> texture pixels (row 0 on top)
            origin, c, s = corners[0], *self._stock_axes()
            thickness = max(1, int(round(self.kerf * TEXELS_PER_MM)))
            shift = 4
            for start, end in burns:
                ends = self.plane_from_machine(np.array([start, end])) - origin
                local = np.column_stack([ends @ np.array([c, s]), ends @ np.array([-s, c])])
                pixels = np.column_stack([local[:, 0] * TEXELS_PER_MM, (height - local[:, 1]) * TEXELS_PER_MM])
                a, b = np.round(pixels * (1 << shift)).astype(np.int64)
                if np.abs(np.concatenate([a, b])).max() > 2**30:
                    continue
                cv2.line(texture, (int(a[0]), int(a[1])), (int(b[0]), int(b[1])), BURN_COLOR, thickness,
                         cv2.LINE_AA, shift)
        # ImageItem's corners: top-left, top-right, bottom-right, bottom-left of the picture
        return (ImageItem(texture, np.array([corners[3], corners[2], corners[1], corners[0]])),)

    def _stock_axes(self) -> tuple[float, float]:
        angle = math.radians(self.stock[4])
        return math.cos(angle), math.sin(angle)


def burns_of(machine, since: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
    """The feed moves a simulated GRBL ran with the laser on (from its ``since``-th block): ``[(start, end)]``
    machine XY mm."""
    if machine is None:
        return []
    record = machine.snapshot()
    return [(np.array(b.start[:2]), np.array(b.end[:2])) for b in record.executed[since:]
            if b.power > 0 and not b.rapid and not b.jog]
