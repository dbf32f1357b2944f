"""A drawing machine's design worked on live (the Drawing machines screen): the machines to choose from, the
parameters' feasible bounds, the pattern and the mechanism at a time.

A face holds the machine's model (:func:`station.services.designs.get_machine`) and asks it through these
functions, so that a design the model refuses comes out as a station error with the model's own message.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from design.machines import get_machine, machine_names
from station.errors import station_errors

__all__ = ["feasible_interval", "machine_choices", "mechanism_at", "pattern", "validate_design"]


@station_errors
def machine_choices() -> list[tuple[str, str]]:
    """(title, name) of every available machine, the built-ins first (thesis order)."""
    return [(get_machine(name).title, name) for name in machine_names()]


@station_errors
def validate_design(model: Any, params: Mapping[str, float]) -> dict[str, float]:
    """``params`` checked against the machine's constraints, the missing ones at their defaults."""
    return dict(model.validate(dict(params)))


@station_errors
def feasible_interval(model: Any, params: Mapping[str, float], name: str) -> tuple[float, float]:
    """The values parameter ``name`` may take with the others fixed at ``params``."""
    lower, upper = model.feasible_interval(dict(params), name)
    return float(lower), float(upper)


@station_errors
def pattern(model: Any, params: Mapping[str, float],
            points: Callable[[float], int]) -> tuple[float, np.ndarray]:
    """The pattern's period (radians of the driving gear) and ``points(period)`` samples of one closed period."""
    period = float(model.period(dict(params)))
    return period, model.sample(dict(params), n=points(period))


@station_errors
def mechanism_at(model: Any, params: Mapping[str, float], t: float) -> list:
    """The machine's parts at time ``t`` (shapes: circles, segments, polylines, points)."""
    return list(model.mechanism(dict(params), t) or ())
