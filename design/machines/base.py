"""The drawing-machine model API shared by every machine (thesis 3.3 and Appendix A).

A machine is a :class:`DrawingMachine` subclass that declares

* its design parameters (:class:`~design.machines.parameters.Parameter`: discrete gear radii, which are positive
  integers so that the pattern is finite (A.5), and continuous lengths and angles, each with a default and a closed
  box of bounds);
* its constraint system (:class:`~design.machines.parameters.Constraint`: one named, evaluable inequality per line of
  Appendix A, with the category of A.1.2 it belongs to and a message in words and numbers);
* its kinematics, as a vectorized function of the parameters and of time returning complex positions.

Everything else (validation, violations, exact period, sampling uniform in time or arc length, batch sampling,
slider bounds) is implemented once, vectorized with numpy, so a new machine is mostly its equations. The code is
split by topic: parameters and constraints (:mod:`design.machines.parameters`), preview shapes
(:mod:`design.machines.shapes`), arc-length sampling (:mod:`design.machines.sampling`) and slider bounds
(:mod:`design.machines.bounds`); this module holds the class that ties them together and re-exports their names
(``from design.machines.base import X`` for any of them).

Conventions: lengths are in gear-radius units (the physical scale is chosen at fabrication); angles are radians;
time ``t`` is the rotation angle of the machine's driving part, and one pattern spans ``[0, period(params)]``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from typing import Any, ClassVar, Literal

import numpy as np

from design.errors import ConstraintViolation, parameter_error
from design.machines import bounds
from design.machines.constraints import (
    CATEGORIES,
    Constraint,
    Violation,
    box_constraints,
    coprime_constraint,
    format_number,
    gcd_margin,
    ordered,
    positive,
)
from design.machines.parameters import (
    MAX_GEAR_RADIUS,
    Parameter,
    Params,
    angle,
    gear_period,
    gear_radius,
    length,
    rotate,
    scalar_arrays,
)
from design.machines.sampling import arclength_times
from design.machines.shapes import Circle, Ellipse, Point, Segment, Shape, shapes_to_jsonable, xy

Spacing = Literal["time", "arclength"]


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

    def _preview_design(self, params: Mapping[str, float], frame: str) -> Params:
        """The checked design a :meth:`mechanism` preview draws (after checking its ``frame``)."""
        self._check_frame(frame)
        return self.validate(params)

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
        P = scalar_arrays(values)
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
        return float(self._period(scalar_arrays(values)))

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
        z = self._positions(scalar_arrays(values), t)
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
        """Times at which the curves are equidistant in arc length (:func:`design.machines.sampling.arclength_times`,
        with ``ARCLENGTH_OVERSAMPLING`` dense points per output point, at least ``ARCLENGTH_MIN_DENSE``)."""
        dense = max(self.ARCLENGTH_OVERSAMPLING * n, self.ARCLENGTH_MIN_DENSE)
        return arclength_times(self._positions, P, period, n, dense)

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
        return bounds.feasible_interval(self, params, name, grid=grid, tolerance=tolerance)

    def sampling_box(self, radii: Mapping[str, np.ndarray]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """A box of the continuous parameters that holds every feasible design with the given gear radii.

        ``radii`` maps each radius name to an array (one value per design); returns name -> ``(lower, upper)``
        arrays of the same length. The parameters' own boxes by default; a machine whose constraints bound a
        parameter by its radii tightens it, so that rejection sampling (uniform over the feasible set, see
        :mod:`design.machines.feasible_sampling`) finds its designs.
        """
        k = len(next(iter(radii.values()))) if radii else 1
        return {n: (np.full(k, self.parameter(n).lower), np.full(k, self.parameter(n).upper))
                for n in self.continuous_names}

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
            yield from box_constraints(parameter)


class TurntableMachine(DrawingMachine):
    """A machine whose paper lies on its driving gear, the turntable ``r_t`` (thesis A.2.3-A.2.4).

    The drawing is the pen's path in the turntable's rotating frame, ``gamma(t) = R_{-t} H(t)`` (A.52-A.53), where
    ``H(t)`` is the pen in the machine's fixed frame. Subclasses implement :meth:`_fixed_frame` (their moving parts
    in the fixed frame, the pen last) instead of :meth:`_positions`, and build their preview on
    :meth:`_turntable_preview`.
    """

    symmetry_gear: ClassVar[str] = "r_t"

    def _fixed_frame(self, P: Mapping[str, np.ndarray], t: np.ndarray) -> tuple[np.ndarray, ...]:
        """Complex positions of the machine's parts in its fixed frame at times t (vectorized), the pen last."""
        raise NotImplementedError

    def _positions(self, P: Mapping[str, np.ndarray], t: np.ndarray) -> np.ndarray:
        return self._fixed_frame(P, t)[-1] * np.exp(-1j * t)  # into the turntable's frame (A.52)

    @staticmethod
    def _pen_on_turntable(
        equation: str, farthest: Callable[[Mapping[str, np.ndarray]], np.ndarray], requirement: str, after: str = ""
    ) -> Constraint:
        """Drawing bounds: the pen's farthest distance from the turntable's center, ``farthest(P)``, is below r_t.

        ``requirement`` and ``after`` word the bound around ``r_t = <value>`` in the message. The margin depends on
        every parameter of a turntable machine (so ``depends`` is left empty).
        """
        return Constraint(
            "pen_on_turntable",
            "drawing bounds",
            equation,
            lambda P: P["r_t"] - farthest(P),
            lambda p: (
                f"the pen must stay on the turntable: {requirement} r_t = {p['r_t']:g}{after}, "
                f"got {float(farthest(scalar_arrays(p))):.6g}"
            ),
        )

    def _turntable_preview(
        self, params: Mapping[str, float], t: float, frame: str
    ) -> tuple[Params, tuple[complex, ...], list[Shape]]:
        """The checked design, its :meth:`_fixed_frame` parts at ``t`` expressed in ``frame``, and the turntable.

        The turntable is its circle and a mark on its rim that shows its rotation (the mark is fixed on the paper
        in the drawing frame, and turns in the fixed frame).
        """
        p = self._preview_design(params, frame)
        turn = np.exp(-1j * t) if frame == "drawing" else 1.0
        parts = tuple(complex(z * turn) for z in self._fixed_frame(scalar_arrays(p), np.float64(t)))
        mark = p["r_t"] * (1.0 if frame == "drawing" else np.exp(1j * t))
        turntable = [Circle("turntable", (0.0, 0.0), float(p["r_t"])), Segment("turntable mark", (0.0, 0.0), xy(mark))]
        return p, parts, turntable


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
    "TurntableMachine",
    "Violation",
    "angle",
    "coprime_constraint",
    "format_number",
    "gcd_margin",
    "gear_period",
    "gear_radius",
    "length",
    "ordered",
    "positive",
    "rotate",
    "scalar_arrays",
    "shapes_to_jsonable",
    "xy",
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
