"""The shapes of a mechanism preview (:meth:`~design.machines.base.DrawingMachine.mechanism`) and their JSON form.

Gears are circles (or an ellipse), arms and rods segments, joints and the pen points; coordinates are in gear-radius
units, in the frame :meth:`~design.machines.base.DrawingMachine.mechanism` was asked for.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Circle:
    """A gear (its primitive circle), a turntable, or a pivot's path: ``center`` (x, y) and ``radius``."""

    label: str
    center: tuple[float, float]
    radius: float
    kind: str = "circle"


@dataclass(frozen=True)
class Ellipse:
    """An elliptic gear: ``center``, semi-axes ``a`` (along ``angle``) and ``b``."""

    label: str
    center: tuple[float, float]
    a: float
    b: float
    angle: float
    kind: str = "ellipse"

    def polyline(self, n: int = 96) -> np.ndarray:
        """Closed (n, 2) outline of the ellipse."""
        u = np.linspace(0.0, 2.0 * np.pi, n)
        z = (self.a * np.cos(u) + 1j * self.b * np.sin(u)) * np.exp(1j * self.angle) + complex(*self.center)
        return np.column_stack([z.real, z.imag])


@dataclass(frozen=True)
class Segment:
    """An arm, rod or radius marker from ``start`` to ``end``."""

    label: str
    start: tuple[float, float]
    end: tuple[float, float]
    kind: str = "segment"


@dataclass(frozen=True)
class Point:
    """A joint, pivot or the pen: a ``position``."""

    label: str
    position: tuple[float, float]
    kind: str = "point"


Shape = Circle | Ellipse | Segment | Point


def xy(z: complex) -> tuple[float, float]:
    """A complex position as the ``(x, y)`` pair of plain floats the shapes hold."""
    return (float(np.real(z)), float(np.imag(z)))


def shapes_to_jsonable(shapes: Sequence[Shape]) -> list[dict[str, Any]]:
    """Plain-JSON form of :meth:`DrawingMachine.mechanism` shapes."""
    out = []
    for shape in shapes:
        item = {"kind": shape.kind, "label": shape.label}
        item.update({k: v for k, v in shape.__dict__.items() if k not in ("kind", "label")})
        out.append(item)
    return out
