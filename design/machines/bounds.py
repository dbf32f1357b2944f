"""Slider bounds: the interval of feasible values of one continuous parameter, the others fixed.

:func:`feasible_interval` implements :meth:`design.machines.base.DrawingMachine.feasible_interval`: a vectorized
grid over the parameter's box finds the feasible run around the current value,
:func:`refine` shrinks both of its ends at once by bracketing, and :func:`exact_end` replaces an end by the exact
root where the constraints closing it are affine in the parameter.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any, Protocol

import numpy as np

from design.errors import ConstraintViolation, parameter_error
from design.machines.constraints import Constraint
from design.machines.parameters import Parameter


class BoundedMachine(Protocol):
    """What the interval search reads of a machine (a :class:`~design.machines.base.DrawingMachine` has it all):
    its parameters and its constraints, nothing of how it draws."""

    name: str

    @property
    def continuous_names(self) -> tuple[str, ...]: ...

    def parameter(self, name: str) -> Parameter: ...

    def all_constraints(self) -> tuple[Constraint, ...]: ...

    def complete(self, params: Mapping[str, Any] | None) -> dict[str, float]: ...


def feasible_interval(
    machine: BoundedMachine, params: Mapping[str, Any] | None, name: str, *, grid: int = 257, tolerance: float = 1e-11
) -> tuple[float, float]:
    """:meth:`DrawingMachine.feasible_interval <design.machines.base.DrawingMachine.feasible_interval>` of
    ``machine``: the method's documentation describes the algorithm, its guarantees and its errors."""
    parameter = machine.parameter(name)
    if parameter.is_discrete:
        expected = f"a continuous parameter ({', '.join(machine.continuous_names)})"
        raise parameter_error(machine.name, name, expected, name)
    values = machine.complete(params)
    current = float(values[name])
    lower, upper = float(parameter.lower), float(parameter.upper)
    others = {k: np.float64(v) for k, v in values.items() if k != name}
    relevant = [c for c in machine.all_constraints() if not c.depends or name in c.depends]
    fixed = [c for c in machine.all_constraints() if c.depends and name not in c.depends]

    with np.errstate(all="ignore"):
        for constraint in fixed:
            if not bool(constraint.satisfied(constraint.margin(others | {name: np.float64(current)}))):
                message = constraint.message(values)
                raise ConstraintViolation(
                    f"{machine.name}: no value of {name} is feasible: constraint {constraint.name!r} "
                    f"({constraint.category}) does not depend on it and is violated: {message}",
                    constraint=constraint.name,
                )

        def feasible(x: np.ndarray) -> np.ndarray:
            P = dict(others)
            P[name] = x
            ok = np.ones(x.shape, dtype=bool)
            for constraint in relevant:
                ok &= np.broadcast_to(constraint.satisfied(constraint.margin(P)), x.shape)
            return ok

        def margins(constraint: Constraint, x: np.ndarray) -> np.ndarray:
            return np.broadcast_to(constraint.margin(dict(others) | {name: x}), x.shape).astype(float)

        def exact(good: float, bad: float, inner: float) -> float:
            return exact_end(relevant, margins, feasible, good, bad, inner)

        xs = np.linspace(lower, upper, grid)
        inside = lower <= current <= upper
        if inside:
            xs = np.sort(np.append(xs, current))
        ok = feasible(xs)
        if not ok.any():
            raise ConstraintViolation(
                f"{machine.name}: no value of {name} in [{lower:g}, {upper:g}] is feasible with the other "
                f"parameters fixed ({', '.join(f'{k}={v:g}' for k, v in values.items() if k != name)})",
                constraint="",
            )
        # Runs of consecutive feasible grid points.
        edges = np.diff(np.concatenate([[0], ok.astype(np.int8), [0]]))
        starts = np.flatnonzero(edges == 1)
        stops = np.flatnonzero(edges == -1) - 1
        position = int(np.searchsorted(xs, current))
        position = min(max(position, 0), len(xs) - 1)
        containing = np.flatnonzero((starts <= position) & (stops >= position))
        if containing.size and ok[position]:
            run = int(containing[0])
        else:
            distance = np.minimum(np.abs(xs[starts] - current), np.abs(xs[stops] - current))
            run = int(np.argmin(distance))
        i0, i1 = int(starts[run]), int(stops[run])
        width = max(upper - lower, 1e-300)
        middle = 0.5 * (xs[i0] + xs[i1])
        ends = [xs[i0], xs[i1]]
        brackets = {0: (xs[i0 - 1], xs[i0])} if i0 > 0 else {}
        if i1 < len(xs) - 1:
            brackets[1] = (xs[i1 + 1], xs[i1])
        refined = refine(feasible, list(brackets.values()), tolerance * width)
        for side, (good, bad) in zip(brackets, refined):
            ends[side] = exact(good, bad, middle)
    return float(ends[0]), float(ends[1])


def exact_end(
    relevant: Sequence[Constraint],
    margins: Callable[[Constraint, np.ndarray], np.ndarray],
    feasible: Callable[[np.ndarray], np.ndarray],
    good: float,
    bad: float,
    inner: float,
) -> float:
    """Replace a bracketed end by the exact root when the constraints that close it are affine in the parameter.

    The constraints violated at ``bad`` are the ones that end the feasible run. If each is affine in the
    parameter (checked on three points between the end and ``inner``, a point well inside the run), its
    root is solved for; the most restrictive root, moved inward by a few ulps until it is feasible (strict
    inequalities), is the end. Otherwise (curvature, drawing bounds) the bracketed end is kept.
    """
    closing = [c for c in relevant if not bool(c.satisfied(margins(c, np.array([bad])))[0])]
    if not closing or inner == good:
        return good
    probes = np.array([good, 0.5 * (good + inner), inner])
    roots = []
    for constraint in closing:
        m = margins(constraint, probes)
        slope = (m[2] - m[0]) / (probes[2] - probes[0])
        predicted = m[0] + slope * (probes[1] - probes[0])
        scale = np.abs(m).max() + 1e-300
        if slope == 0 or not np.isfinite(m).all() or abs(predicted - m[1]) > 1e-9 * scale:
            return good
        roots.append(good - m[0] / slope)
    root = max(roots) if bad < good else min(roots)
    if not abs(root - good) <= 2.0 * abs(good - bad) + 1e-300:
        return good
    direction = np.inf if bad < good else -np.inf
    for _ in range(8):
        if bool(feasible(np.array([root]))[0]):
            return float(root)
        root = float(np.nextafter(root, direction))
    return good


def refine(
    feasible: Callable[[np.ndarray], np.ndarray],
    brackets: Sequence[tuple[float, float]],
    tolerance: float,
    probes: int = 48,
) -> list[tuple[float, float]]:
    """Shrink brackets (bad, good) (infeasible, feasible) around boundaries, all in one evaluation per round.

    Returns ``(good, bad)`` per bracket, ``|good - bad| <= tolerance``. The new feasible end is the first
    feasible probe seen from the bad side (so the run containing ``good`` stays connected).
    """
    bad = np.array([b for b, _ in brackets], dtype=float)
    good = np.array([g for _, g in brackets], dtype=float)
    fractions = np.linspace(0.0, 1.0, probes + 2)[1:-1]
    for _ in range(64):  # each round divides the bracket by probes + 1; 64 rounds is never reached
        active = np.abs(good - bad) > tolerance
        if not active.any():
            break
        points = bad[active, None] + (good - bad)[active, None] * fractions[None, :]
        ok = feasible(points.ravel()).reshape(points.shape)
        first = np.argmax(ok, axis=1)
        found = ok.any(axis=1)
        rows = np.arange(points.shape[0])
        new_good = np.where(found, points[rows, first], good[active])
        previous = np.where(first > 0, points[rows, np.maximum(first - 1, 0)], bad[active])
        new_bad = np.where(found, previous, points[:, -1])
        stalled = (new_good == good[active]) & (new_bad == bad[active])
        if stalled.all():  # pragma: no cover - floating point stall
            break
        good[active], bad[active] = new_good, new_bad
    return [(float(g), float(b)) for g, b in zip(good, bad)]
