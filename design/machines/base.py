"""The drawing-machine model API shared by every machine (thesis 3.3 and Appendix A).

A machine is a :class:`DrawingMachine` subclass that declares

* its design parameters (:class:`Parameter`: discrete gear radii, which are positive integers so that the pattern
  is finite (A.5), and continuous lengths and angles, each with a default and a closed box of bounds);
* its constraint system (:class:`Constraint`: one named, evaluable inequality per line of Appendix A, with the
  category of A.1.2 it belongs to and a message in words and numbers);
* its kinematics, as a vectorized function of the parameters and of time returning complex positions.

Everything else (validation, violations, exact period, sampling uniform in time or arc length, batch sampling,
slider bounds) is implemented here once, vectorized with numpy, so a new machine is mostly its equations.

Conventions: lengths are in gear-radius units (the physical scale is chosen at fabrication); angles are radians;
time ``t`` is the rotation angle of the machine's driving part, and one pattern spans ``[0, period(params)]``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np

from design.errors import ConstraintViolation, parameter_error

#: Arbitrary integer bound B_r of Appendix A on gear radii (radii are strictly smaller). With coprime radii below
#: 30, a pattern needs at most 29 turns of a gear: long enough for rich patterns, short enough to plot.
MAX_GEAR_RADIUS = 30

#: The categories of constraints of Appendix A.1.2, in the order the thesis gives them.
CATEGORIES = (
    "finite pattern",
    "compatible curvatures",
    "valid layout",
    "symmetry reduction",
    "drawing bounds",
    "singularity avoidance",
    "practical dimensions",
)

Params = dict[str, float]
Spacing = Literal["time", "arclength"]


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


@dataclass(frozen=True)
class Constraint:
    """One inequality of a machine's constraint system.

    Attributes
    ----------
    name : str
        Short identifier, unique within the machine (e.g. ``"pen_inside_gear"``).
    category : str
        One of :data:`CATEGORIES`.
    equation : str
        Thesis equation number (``"A.9"``), or ``""`` for a constraint the station adds (documented in its message).
    margin : callable
        ``margin(P) -> ndarray``: how much the inequality holds, vectorized over parameter arrays ``P`` (a mapping
        name -> array, all broadcastable). Satisfied when ``margin >= 0`` (``> 0`` if ``strict``).
    message : callable
        ``message(p) -> str`` for scalar parameters ``p``: what must hold, in words and numbers
        (e.g. ``"l1 must exceed r_g1 + r_p1 = 6.5, got 5"``).
    strict : bool
        Whether equality violates the constraint.
    depends : tuple of str
        Parameters the margin depends on (to skip constraints when computing one parameter's slider bounds).
    """

    name: str
    category: str
    equation: str
    margin: Callable[[Mapping[str, np.ndarray]], np.ndarray]
    message: Callable[[Mapping[str, float]], str]
    strict: bool = True
    depends: tuple[str, ...] = ()

    def satisfied(self, margin: np.ndarray) -> np.ndarray:
        margin = np.asarray(margin)
        return (margin > 0) if self.strict else (margin >= 0)


@dataclass(frozen=True)
class Violation:
    """A violated constraint: its name, a message in words and numbers, and its margin (<= 0; how far off)."""

    constraint: str
    message: str
    margin: float
    category: str = ""
    equation: str = ""


# --- shapes of a mechanism preview -------------------------------------------------------------------------------


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


def _xy(z: complex) -> tuple[float, float]:
    return (float(np.real(z)), float(np.imag(z)))


# --- the base class ----------------------------------------------------------------------------------------------


class DrawingMachine:
    """Base class of drawing-machine models; subclasses declare parameters, constraints and kinematics.

    Subclasses set ``name``, ``title``, ``description``, ``parameters`` and implement :meth:`constraints`,
    :meth:`_period`, :meth:`_positions` and :meth:`mechanism`. Instances hold no design state: every method takes
    the design's parameters (a mapping name -> value; missing names take their defaults).
    """

    name: ClassVar[str] = ""
    title: ClassVar[str] = ""
    description: ClassVar[str] = ""
    parameters: ClassVar[tuple[Parameter, ...]] = ()
    #: Name of the gear whose reduced radius is the order of rotational symmetry of the pattern (thesis 3.4.2).
    symmetry_gear: ClassVar[str] = ""

    def __init__(self) -> None:
        self._by_name = {p.name: p for p in self.parameters}
        self._constraints: tuple[Constraint, ...] = tuple(self._box_constraints()) + tuple(self.constraints())
        names = [c.name for c in self._constraints]
        if len(set(names)) != len(names):  # pragma: no cover - a programming error in a model
            raise TypeError(f"{type(self).__name__}: duplicate constraint names {names}")

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r}>"

    # -- to implement --------------------------------------------------------------------------------------------

    def constraints(self) -> Iterable[Constraint]:
        """The machine's constraints beyond parameter boxes and integrality (which the base adds)."""
        raise NotImplementedError

    def _period(self, P: Mapping[str, np.ndarray]) -> np.ndarray:
        """Vectorized period (time length of one closed pattern)."""
        raise NotImplementedError

    def _positions(self, P: Mapping[str, np.ndarray], t: np.ndarray) -> np.ndarray:
        """Vectorized pen positions as complex numbers, broadcasting ``P`` against ``t``."""
        raise NotImplementedError

    def mechanism(self, params: Mapping[str, float], t: float, frame: str = "drawing") -> list[Shape]:
        """Positions of the machine's parts at time ``t`` (gears as circles, arms as segments, joints and pen).

        Parameters
        ----------
        params : mapping
            Design parameters (validated).
        t : float
            Time (same scale as :meth:`curve`).
        frame : {"drawing", "fixed"}
            ``"drawing"`` (default) expresses the parts in the frame of the paper, so the pen point equals
            ``curve(params, [t])[0]`` and the preview overlays the pattern; ``"fixed"`` in the machine's base frame
            (differs only for turntable machines, whose paper rotates).
        """
        raise NotImplementedError

    def _check_frame(self, frame: str) -> None:
        if frame not in ("drawing", "fixed"):
            raise parameter_error(self.name, "frame", "'drawing' or 'fixed'", frame)

    # -- parameters ----------------------------------------------------------------------------------------------

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    @property
    def discrete_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters if p.is_discrete)

    @property
    def continuous_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters if not p.is_discrete)

    def parameter(self, name: str) -> Parameter:
        """The :class:`Parameter` called ``name`` (``ParameterError`` if there is none)."""
        try:
            return self._by_name[name]
        except KeyError:
            raise parameter_error(self.name, name, f"one of {', '.join(self.parameter_names)}", name) from None

    def defaults(self) -> Params:
        """The default design (feasible), discrete values as ints."""
        return {p.name: (int(p.default) if p.is_discrete else float(p.default)) for p in self.parameters}

    def all_constraints(self) -> tuple[Constraint, ...]:
        """Every constraint, box bounds and integrality first."""
        return self._constraints

    def complete(self, params: Mapping[str, Any] | None) -> Params:
        """Fill missing names with defaults and convert to numbers; no bounds or constraint check.

        Raises
        ------
        ParameterError
            For an unknown name, a value that is not a finite real number.
        """
        values = self.defaults()
        for name, value in (params or {}).items():
            parameter = self.parameter(name)
            expected = "an integer gear radius" if parameter.is_discrete else "a finite real number"
            if isinstance(value, (bool, np.bool_)):
                raise parameter_error(self.name, name, expected, value)
            try:
                number = float(value)
            except (TypeError, ValueError):
                raise parameter_error(self.name, name, expected, value) from None
            if not math.isfinite(number):
                raise parameter_error(self.name, name, expected, value)
            if parameter.is_discrete and number == round(number):
                values[name] = int(round(number))
            else:
                values[name] = number
        return values

    def validate(self, params: Mapping[str, Any] | None = None) -> Params:
        """Complete ``params`` with defaults, coerce gear radii to int, and check every constraint.

        Returns
        -------
        dict
            The complete, checked design.

        Raises
        ------
        ParameterError
            Unknown name, not a number, a gear radius that is not an integer, a value outside its box bounds.
        ConstraintViolation
            The first violated constraint of Appendix A, with a message in words and numbers; ``constraint`` and
            ``margin`` attributes say which and by how much.
        """
        values = self.complete(params)
        for parameter in self.parameters:
            value = values[parameter.name]
            if parameter.is_discrete:
                expected = f"an integer gear radius in [{parameter.lower:g}, {parameter.upper:g}]"
                if not isinstance(value, int) or not parameter.lower <= value <= parameter.upper:
                    raise parameter_error(self.name, parameter.name, expected, value)
            elif not parameter.lower <= value <= parameter.upper:
                expected = f"in [{parameter.lower:g}, {parameter.upper:g}] ({parameter.unit or 'ratio'})"
                raise parameter_error(self.name, parameter.name, expected, value)
        found = self.violations(values)
        if found:
            first = found[0]
            more = f" (and {len(found) - 1} more: {', '.join(v.constraint for v in found[1:])})" if found[1:] else ""
            where = f"{first.category}, {first.equation}" if first.equation else first.category
            raise ConstraintViolation(
                f"{self.name}: constraint {first.constraint!r} ({where}) violated: {first.message}{more}",
                constraint=first.constraint,
                margin=first.margin,
            )
        return values

    def violations(self, params: Mapping[str, Any] | None = None) -> list[Violation]:
        """Every violated constraint (box bounds and integrality included); empty when the design is feasible."""
        values = self.complete(params)
        P = {k: np.float64(v) for k, v in values.items()}
        found = []
        with np.errstate(all="ignore"):
            for constraint in self._constraints:
                margin = float(constraint.margin(P))
                if not bool(constraint.satisfied(margin)):
                    found.append(
                        Violation(
                            constraint.name,
                            constraint.message(values),
                            margin if math.isfinite(margin) else -math.inf,
                            constraint.category,
                            constraint.equation,
                        )
                    )
        return found

    def is_feasible(self, params: Mapping[str, Any] | None = None) -> bool:
        """Whether the design satisfies every constraint."""
        return not self.violations(params)

    def as_arrays(self, rows: Any) -> dict[str, np.ndarray]:
        """Parameter rows as a dict of 1-d float arrays (missing names take their defaults).

        ``rows`` is a sequence of mappings, a mapping of name -> array, or a (k, p) array whose columns follow
        :attr:`parameter_names`.
        """
        defaults = self.defaults()
        if isinstance(rows, Mapping):
            for name in rows:
                self.parameter(name)
            arrays = {name: np.atleast_1d(np.asarray(rows.get(name, defaults[name]), dtype=float)) for name in defaults}
            k = max(a.size for a in arrays.values())
            return {name: np.broadcast_to(a, (k,)).astype(float) for name, a in arrays.items()}
        if isinstance(rows, np.ndarray) and rows.ndim == 2 and rows.dtype != object:
            if rows.shape[1] != len(self.parameters):
                raise parameter_error(
                    self.name,
                    "rows",
                    f"an array with {len(self.parameters)} columns {self.parameter_names}",
                    rows.shape,
                )
            return {name: rows[:, i].astype(float) for i, name in enumerate(self.parameter_names)}
        completed = [self.complete(row) for row in rows]
        return {name: np.array([row[name] for row in completed], dtype=float) for name in self.parameter_names}

    def feasible_mask(self, rows: Any) -> np.ndarray:
        """Vectorized feasibility of many designs (see :meth:`as_arrays` for ``rows``): a bool array."""
        P = self.as_arrays(rows)
        k = len(next(iter(P.values())))
        ok = np.ones(k, dtype=bool)
        with np.errstate(all="ignore"):
            for constraint in self._constraints:
                ok &= np.broadcast_to(constraint.satisfied(constraint.margin(P)), (k,))
        return ok

    # -- period and curves ---------------------------------------------------------------------------------------

    def period(self, params: Mapping[str, Any] | None = None) -> float:
        """Time length of one closed pattern (lcm rule of A.1.1 on the integer gear radii)."""
        values = self.validate(params)
        return float(self._period({k: np.float64(v) for k, v in values.items()}))

    def turns(self, params: Mapping[str, Any] | None = None) -> int:
        """Whole turns of the driving part in one period (``period / 2 pi``)."""
        return int(round(self.period(params) / (2.0 * np.pi)))

    def symmetry_order(self, params: Mapping[str, Any] | None = None) -> int:
        """Order of rotational symmetry of the pattern (generic designs; thesis 3.4.2).

        Shifting time so that every other gear is back in place rotates the pattern about the center; with
        ``r`` the radius of :attr:`symmetry_gear` (the ring or turntable) and ``m`` the lcm of the other gear
        radii, the pattern repeats ``r / gcd(r, m)`` times per turn (e.g. Spirograph: ``r_f / gcd(r_f, r_r)``).
        """
        values = self.validate(params)
        lead = int(values[self.symmetry_gear])
        others = 1
        for name in self.discrete_names:
            if name != self.symmetry_gear:
                others = math.lcm(others, int(values[name]))
        return lead // math.gcd(lead, others)

    def curve(self, params: Mapping[str, Any] | None, t: Any) -> np.ndarray:
        """Pen positions at times ``t``: an array of shape ``(len(t), 2)`` (vectorized, validated design)."""
        values = self.validate(params)
        t = np.asarray(t, dtype=float)
        z = self._positions({k: np.float64(v) for k, v in values.items()}, t)
        return np.stack([z.real, z.imag], axis=-1)

    def period_many(self, rows: Any, check: bool = True) -> np.ndarray:
        """Periods of many designs at once, shape ``(k,)`` (see :meth:`as_arrays` for ``rows``)."""
        P = self._checked_arrays(rows, check)
        k = len(next(iter(P.values())))
        return np.broadcast_to(self._period(P), (k,)).astype(float)

    def curve_many(self, rows: Any, t: Any, check: bool = True) -> np.ndarray:
        """Positions of many designs at given times: an array of shape ``(k, n, 2)``.

        Parameters
        ----------
        rows : sequence of mappings, mapping of arrays, or (k, p) array
            The designs (see :meth:`as_arrays`).
        t : array of shape (n,) or (k, n)
            Times, shared by all designs or one row per design (e.g. ``fractions * period_many(rows)[:, None]``).
        check : bool
            Raise for an infeasible row (default); ``False`` for rows already filtered with :meth:`feasible_mask`.
        """
        P = self._checked_arrays(rows, check)
        k = len(next(iter(P.values())))
        t = np.asarray(t, dtype=float)
        if t.ndim == 1:
            t = np.broadcast_to(t, (k, t.size))
        if t.ndim != 2 or t.shape[0] != k:
            raise parameter_error(self.name, "t", f"an array of shape (n,) or ({k}, n)", t.shape)
        z = self._positions({name: a.reshape(k, 1) for name, a in P.items()}, t)
        return np.stack([z.real, z.imag], axis=-1)

    def _checked_arrays(self, rows: Any, check: bool) -> dict[str, np.ndarray]:
        P = self.as_arrays(rows)
        if check:
            ok = self.feasible_mask(P)
            if not ok.all():
                index = int(np.flatnonzero(~ok)[0])
                try:
                    self.validate({name: float(a[index]) for name, a in P.items()})
                except Exception as error:
                    raise _prefixed(error, f"row {index}: ") from None
        return P

    def sample(self, params: Mapping[str, Any] | None = None, n: int = 1024, spacing: Spacing = "time") -> np.ndarray:
        """One period of the pattern as ``n`` points, uniform in time or in arc length; closed (last == first).

        Parameters
        ----------
        params : mapping
            The design (validated).
        n : int
            Number of points, at least 3 (the last one repeats the first).
        spacing : {"time", "arclength"}
            ``"time"`` samples the driving angle uniformly; ``"arclength"`` makes consecutive points equidistant
            along the curve (what plotters and curve distances want).
        """
        values = self.validate(params)
        return self._sample_arrays({k: np.array([v], dtype=float) for k, v in values.items()}, n, spacing)[0]

    def sample_many(self, rows: Any, n: int = 256, spacing: Spacing = "time", check: bool = True) -> np.ndarray:
        """Batch sampling of many designs at once: an array of shape ``(k, n, 2)``.

        Parameters
        ----------
        rows : sequence of mappings, mapping of arrays, or (k, p) array
            The designs (see :meth:`as_arrays`; columns of an array follow :attr:`parameter_names`).
        n : int
            Points per pattern (closed: ``out[:, -1] == out[:, 0]``).
        spacing : {"time", "arclength"}
            As in :meth:`sample`.
        check : bool
            Raise ``ConstraintViolation`` naming the first infeasible row (default). Pass ``False`` only for rows
            already filtered with :meth:`feasible_mask` (it skips the check for speed).
        """
        return self._sample_arrays(self._checked_arrays(rows, check), n, spacing)

    def _sample_arrays(self, P: Mapping[str, np.ndarray], n: int, spacing: str) -> np.ndarray:
        if spacing not in ("time", "arclength"):
            raise parameter_error(self.name, "spacing", "'time' or 'arclength'", spacing)
        if not isinstance(n, (int, np.integer)) or n < 3:
            raise parameter_error(self.name, "n", "an integer number of points >= 3", n)
        k = len(next(iter(P.values())))
        column = {name: a.reshape(k, 1) for name, a in P.items()}
        period = np.broadcast_to(self._period(column), (k, 1))
        if spacing == "time":
            t = period * np.linspace(0.0, 1.0, n)[None, :]
        else:
            t = self._arclength_times(column, period, n)
        z = self._positions(column, t)
        z[:, -1] = z[:, 0]  # exact closure: the last point is the first, not a rounding error away
        return np.stack([z.real, z.imag], axis=-1)

    #: Dense evaluations per output point when inverting the arc length (at least ``ARCLENGTH_MIN_DENSE``).
    ARCLENGTH_OVERSAMPLING: ClassVar[int] = 8
    ARCLENGTH_MIN_DENSE: ClassVar[int] = 2048

    def _arclength_times(self, P: Mapping[str, np.ndarray], period: np.ndarray, n: int) -> np.ndarray:
        """Times at which the curves are equidistant in arc length (vectorized over designs).

        1. Evaluate each curve densely and accumulate its length, each chord corrected to its arc by the turning
           angle ``theta`` at its ends (``arc = chord (1 + theta^2 / 24)`` on a circle through three points).
        2. Invert the cumulative length by linear interpolation (one ``searchsorted`` for every design).
        3. One Newton step inside each dense interval, measuring the length reached with the chord to the
           interpolated point, which removes the error of assuming a constant speed within the interval.
        Relative spacing errors are ~1e-4 at 256 points (larger across cusps, where chords cannot follow arcs).
        """
        k = period.shape[0]
        dense = max(self.ARCLENGTH_OVERSAMPLING * n, self.ARCLENGTH_MIN_DENSE)
        h = period / (dense - 1)  # (k, 1) dense time step
        z = self._positions(P, h * np.arange(dense)[None, :])
        dz = np.diff(z, axis=1)
        chord = np.abs(dz)
        safe = np.where(dz == 0, 1.0, dz)
        turn = np.abs(np.angle(safe[:, 1:] / safe[:, :-1]))
        theta = np.empty_like(chord)
        theta[:, 1:-1] = 0.5 * (turn[:, 1:] + turn[:, :-1])
        theta[:, 0], theta[:, -1] = turn[:, 0], turn[:, -1]
        arc = chord * (1.0 + theta * theta / 24.0)
        length = np.concatenate([np.zeros((k, 1)), np.cumsum(arc, axis=1)], axis=1)
        total = np.where(length[:, -1:] > 0, length[:, -1:], 1.0)
        target = np.linspace(0.0, 1.0, n)[None, :] * total
        # One searchsorted for all rows: offset each row's (non-decreasing) normalized lengths by 2 x its index.
        offset = 2.0 * np.arange(k)[:, None]
        flat = (length / total + offset).ravel()
        goal = (target / total + offset).ravel()
        index = np.searchsorted(flat, goal, side="right").reshape(k, n) - 1 - dense * np.arange(k)[:, None]
        index = np.clip(index, 0, dense - 2)
        rows = np.arange(k)[:, None]
        start, step, step_chord = length[rows, index], arc[rows, index], chord[rows, index]
        moving = step > 0
        weight = np.clip(np.where(moving, (target - start) / np.where(moving, step, 1.0), 0.0), 0.0, 1.0)
        t = (index + weight) * h
        # Newton step: the length reached at t is the interval's arc times the chord fraction to z(t).
        reached = start + step * np.abs(self._positions(P, t) - z[rows, index]) / np.where(moving, step_chord, 1.0)
        speed = np.where(moving, step / h, 1.0)
        t = np.clip(t + np.where(moving, (target - reached) / speed, 0.0), index * h, (index + 1) * h)
        t[:, 0], t[:, -1] = 0.0, period[:, 0]
        return t

    # -- slider bounds -------------------------------------------------------------------------------------------

    def feasible_interval(
        self, params: Mapping[str, Any] | None, name: str, *, grid: int = 257, tolerance: float = 1e-11
    ) -> tuple[float, float]:
        """The interval of feasible values of one continuous parameter, the others fixed (slider bounds).

        The constraints are evaluated, vectorized, on a grid over the parameter's box; the feasible run that
        contains the current value (or, if it is infeasible, the nearest run) is returned, its ends refined by
        bracketing (48 points per round, both ends at once) down to ``tolerance`` times the box width. Where the
        constraints closing an end are affine in the parameter (box bounds, ``d <= r_r``, ``l1 > r_g1 + r_p1``,
        ...) the end is then solved exactly (moved a few ulps inside for a strict inequality); otherwise
        (curvatures, drawing bounds, distances between gears) the bracketed end is returned. Both ends are
        feasible values; a value just outside is not. A feasible set narrower than the grid step can be missed
        (then the nearest wider run is returned).

        Raises
        ------
        ParameterError
            Unknown or discrete ``name``, or a bad value elsewhere.
        ConstraintViolation
            When no value of ``name`` makes the design feasible (e.g. the gear radii are not coprime).
        """
        parameter = self.parameter(name)
        if parameter.is_discrete:
            raise parameter_error(self.name, name, f"a continuous parameter ({', '.join(self.continuous_names)})", name)
        values = self.complete(params)
        current = float(values[name])
        lower, upper = float(parameter.lower), float(parameter.upper)
        others = {k: np.float64(v) for k, v in values.items() if k != name}
        relevant = [c for c in self._constraints if not c.depends or name in c.depends]
        fixed = [c for c in self._constraints if c.depends and name not in c.depends]

        with np.errstate(all="ignore"):
            for constraint in fixed:
                if not bool(constraint.satisfied(constraint.margin(others | {name: np.float64(current)}))):
                    message = constraint.message(values)
                    raise ConstraintViolation(
                        f"{self.name}: no value of {name} is feasible: constraint {constraint.name!r} "
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
                return self._exact_end(relevant, margins, feasible, good, bad, inner)

            xs = np.linspace(lower, upper, grid)
            inside = lower <= current <= upper
            if inside:
                xs = np.sort(np.append(xs, current))
            ok = feasible(xs)
            if not ok.any():
                raise ConstraintViolation(
                    f"{self.name}: no value of {name} in [{lower:g}, {upper:g}] is feasible with the other "
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
            refined = self._refine(feasible, list(brackets.values()), tolerance * width)
            for side, (good, bad) in zip(brackets, refined):
                ends[side] = exact(good, bad, middle)
        return float(ends[0]), float(ends[1])

    @staticmethod
    def _exact_end(
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

    @staticmethod
    def _refine(
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

    # -- misc ----------------------------------------------------------------------------------------------------

    def describe(self) -> dict[str, Any]:
        """Plain-JSON description: name, title, parameters, constraints (used by ``station machines --json``)."""
        return {
            "name": self.name,
            "title": self.title,
            "description": self.description,
            "parameters": [p.as_dict() for p in self.parameters],
            "defaults": self.defaults(),
            "constraints": [
                {"name": c.name, "category": c.category, "equation": c.equation, "strict": c.strict}
                for c in self._constraints
            ],
        }

    def _box_constraints(self) -> Iterable[Constraint]:
        """Box bounds and integrality of every parameter, as constraints (so violations() lists them too)."""
        for parameter in self.parameters:
            yield from _box_constraints_of(parameter)


def _box_constraints_of(parameter: Parameter) -> Iterable[Constraint]:
    name, lower, upper, unit = parameter.name, parameter.lower, parameter.upper, parameter.unit
    if parameter.is_discrete:
        yield Constraint(
            f"{name}_integer",
            "finite pattern",
            "A.5",
            lambda P, n=name: -np.abs(P[n] - np.rint(P[n])),
            lambda p, n=name: (
                f"{n} must be a whole number (gear radii are integers so the pattern closes), got {p[n]:g}"
            ),
            strict=False,
            depends=(name,),
        )
    yield Constraint(
        f"{name}_min",
        parameter.category,
        parameter.equation,
        lambda P, n=name, lo=lower: P[n] - lo,
        lambda p, n=name, lo=lower, u=unit: f"{n} must be at least {lo:g}{' ' + u if u else ''}, got {p[n]:g}",
        strict=False,
        depends=(name,),
    )
    yield Constraint(
        f"{name}_max",
        parameter.category,
        parameter.equation,
        lambda P, n=name, hi=upper: hi - P[n],
        lambda p, n=name, hi=upper, u=unit: f"{n} must be at most {hi:g}{' ' + u if u else ''}, got {p[n]:g}",
        strict=False,
        depends=(name,),
    )


def gcd_margin(*arrays: np.ndarray) -> np.ndarray:
    """Margin of a coprimality constraint: 0 when the integers are coprime, 1 - gcd (< 0) otherwise."""
    ints = [np.rint(np.asarray(a)).astype(np.int64) for a in arrays]
    g = ints[0]
    for other in ints[1:]:
        g = np.gcd(g, other)
    return (1 - g).astype(float)


def coprime_constraint(equation: str, *names: str) -> Constraint:
    """The symmetry-reduction constraint of ``equation``: the gear radii ``names`` share no common divisor, else the
    same pattern exists with smaller gears."""

    def message(p: Mapping[str, float]) -> str:
        values = [int(round(p[n])) for n in names]
        shown = ", ".join(f"{p[n]:g}" for n in names)
        listed = " and ".join(names) if len(names) == 2 else ", ".join(names[:-1]) + f" and {names[-1]}"
        rule = "be coprime" if len(names) == 2 else "share no common divisor"
        return (f"{listed} must {rule}, got gcd({shown}) = {math.gcd(*values)} "
                "(the same pattern exists with smaller gears)")

    return Constraint(
        "coprime_radii",
        "symmetry reduction",
        equation,
        lambda P: gcd_margin(*(P[n] for n in names)),
        message,
        strict=False,
        depends=names,
    )


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


def format_number(x: float) -> str:
    """Numbers in messages: short but exact enough to see why a constraint fails."""
    return f"{x:.6g}"


def shapes_to_jsonable(shapes: Sequence[Shape]) -> list[dict[str, Any]]:
    """Plain-JSON form of :meth:`DrawingMachine.mechanism` shapes."""
    out = []
    for shape in shapes:
        item = {"kind": shape.kind, "label": shape.label}
        item.update({k: v for k, v in shape.__dict__.items() if k not in ("kind", "label")})
        out.append(item)
    return out


__all__ = [
    "CATEGORIES",
    "MAX_GEAR_RADIUS",
    "Circle",
    "Constraint",
    "DrawingMachine",
    "Ellipse",
    "Parameter",
    "Point",
    "Segment",
    "Shape",
    "Violation",
    "format_number",
    "gcd_margin",
    "gear_period",
    "rotate",
    "shapes_to_jsonable",
]


def _prefixed(error: Exception, prefix: str) -> Exception:
    """A copy of ``error`` whose message starts with ``prefix``, of the same type and with the same attributes.

    Rebuilding it as ``type(error)(message)`` would lose what the constructor sets besides the message
    (``ConstraintViolation.constraint`` and ``.margin``) and fails for errors whose constructor takes more than a
    message, so the copy is made without calling the constructor.
    """
    copied = type(error).__new__(type(error))
    copied.__dict__.update(error.__dict__)
    copied.args = (prefix + str(error),)
    return copied
