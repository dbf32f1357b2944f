"""A machine's design parameters, as a table: :class:`Parameter` and the builders of its usual rows.

A machine declares its parameters as a tuple of :class:`Parameter` (:func:`gear_radius`, :func:`length` and
:func:`angle` build the usual rows), and its kinematics on top of them (:func:`gear_period`, the lcm rule on the
integer gear radii; :func:`scalar_arrays`, one design's values as the numpy scalars the vectorized code takes).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

#: Arbitrary integer bound B_r of Appendix A on gear radii (radii are strictly smaller). With coprime radii below
#: 30, a pattern needs at most 29 turns of a gear: long enough for rich patterns, short enough to plot.
MAX_GEAR_RADIUS = 30

Params = dict[str, float]


@dataclass(frozen=True)
class Parameter:
    """One design parameter of a machine.

    Attributes
    ----------
    name : str
        Public name (part of the contract, e.g. ``"r_f"``).
    kind : {"discrete", "continuous"}
        Discrete parameters are gear radii: positive integers.
    default : float
        Value in the machine's default (feasible) design.
    lower, upper : float
        Closed box of allowed values (the constraints may cut it further, see
        :meth:`DrawingMachine.feasible_interval`).
    description : str
        What the parameter is, in words.
    unit : str
        ``"gear radius"`` for lengths (and radii), ``"rad"`` for angles, ``""`` for ratios.
    category : str
        The constraint category of A.1.2 its box bounds come from.
    equation : str
        The thesis equation of the box bounds (e.g. ``"A.7"``), if any.
    """

    name: str
    kind: Literal["discrete", "continuous"]
    default: float
    lower: float
    upper: float
    description: str
    unit: str = "gear radius"
    category: str = "practical dimensions"
    equation: str = ""

    @property
    def is_discrete(self) -> bool:
        return self.kind == "discrete"

    def as_dict(self) -> dict[str, Any]:
        """Plain-JSON description (used by ``station machines --json``)."""
        return {
            "name": self.name,
            "kind": self.kind,
            "default": self.default,
            "lower": self.lower,
            "upper": self.upper,
            "unit": self.unit,
            "description": self.description,
        }


def gear_radius(
    name: str,
    default: int,
    description: str,
    equation: str,
    *,
    lower: int = 1,
    upper: int = MAX_GEAR_RADIUS - 1,
    category: str = "finite pattern",
) -> Parameter:
    """A discrete gear radius: an integer in ``[lower, upper]`` (by default any radius below the bound B_r)."""
    return Parameter(name, "discrete", default, lower, upper, description, category=category, equation=equation)


def length(
    name: str, default: float, upper: float, description: str, equation: str, *, category: str = "valid layout"
) -> Parameter:
    """A continuous length in ``[0, upper]`` gear radii."""
    return Parameter(name, "continuous", default, 0.0, upper, description, category=category, equation=equation)


def angle(
    name: str, default: float, description: str, equation: str, *, category: str = "symmetry reduction"
) -> Parameter:
    """A continuous angle in ``[0, pi]`` radians (the other half-turn mirrors the pattern)."""
    return Parameter(
        name, "continuous", default, 0.0, float(np.pi), description, unit="rad", category=category, equation=equation
    )


def random_in_boxes(
    parameters: Sequence[Parameter], count: int, rng: np.random.Generator, *, max_radius: int = 12,
    max_length: float = 25.0,
) -> dict[str, np.ndarray]:
    """``count`` designs drawn uniformly in the parameter boxes, as float columns (for ``feasible_mask`` and the
    batch methods); most are infeasible, so callers keep the rows the machine accepts (rejection sampling).

    Gear radii are whole numbers from ``max(1, lower)`` to ``max_radius``; continuous values lie between their
    lower bound and ``min(upper, max_length)``. The parameters draw from ``rng`` in their order.
    """
    rows = {}
    for p in parameters:
        if p.is_discrete:
            rows[p.name] = rng.integers(max(1, int(p.lower)), max_radius + 1, count).astype(float)
        else:
            rows[p.name] = rng.uniform(p.lower, min(p.upper, max_length), count)
    return rows


def scalar_arrays(values: Mapping[str, float]) -> dict[str, np.ndarray]:
    """One design's values as the numpy scalars a vectorized margin or kinematics function takes."""
    return {k: np.float64(v) for k, v in values.items()}


def gear_period(driving_radius: np.ndarray, *radii: np.ndarray) -> np.ndarray:
    """Exact period of a gear train by the lcm rule of A.1.1, vectorized over integer radii.

    A gear of radius r meshing (directly or through the train) with the driving part of radius ``driving_radius``
    turns once every ``2 pi r / driving_radius`` units of time; the pattern closes when every gear has made a
    whole number of turns: ``T = 2 pi lcm(driving_radius, *radii) / driving_radius``.
    """
    base = np.rint(np.asarray(driving_radius)).astype(np.int64)
    multiple = base
    for r in radii:
        multiple = np.lcm(multiple, np.rint(np.asarray(r)).astype(np.int64))
    return 2.0 * np.pi * multiple / base


def rotate(z: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotate complex positions by ``angle`` (radians, counter-clockwise)."""
    return z * np.exp(1j * angle)
