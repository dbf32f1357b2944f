"""A machine's constraint system, as data: :class:`Constraint` and the constraints that recur across machines.

Each constraint is one named, evaluable inequality per line of Appendix A, with the category of A.1.2 it belongs to
and a message in words and numbers. The shapes that recur across machines (one part smaller than another, a positive
offset, coprime gear radii, the box bounds every parameter has) are built here.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from common.words import listed
from design.machines.parameters import Parameter

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
        Parameters the margin depends on (to skip constraints when computing one parameter's slider bounds);
        empty when it depends on every parameter.
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


# --- constraints that recur across machines ----------------------------------------------------------------------


def ordered(
    name: str, subject: str, relation: str, bound: str, equation: str, why: str = "", category: str = "valid layout"
) -> Constraint:
    """``subject < bound`` (``relation="<"``: a gear, slider or pivot that must fit inside a larger part) or
    ``subject > bound`` (``">"``) for two parameters, with the reason in words (``why``) if it is not plain."""
    if relation == "<":
        words, margin = "be smaller than", lambda P: P[bound] - P[subject]
    elif relation == ">":
        words, margin = "exceed", lambda P: P[subject] - P[bound]
    else:  # pragma: no cover - a programming error in a model
        raise ValueError(f"relation must be '<' or '>', got {relation!r}")
    reason = f" ({why})" if why else ""

    return Constraint(
        name,
        category,
        equation,
        margin,
        lambda p: f"{subject} must {words} {bound} = {p[bound]:g}{reason}, got {p[subject]:g}",
        depends=(subject, bound),
    )


def positive(name: str, parameter: str, equation: str, category: str, note: str = "") -> Constraint:
    """``parameter > 0``; ``note`` says what a non-positive value would mean (e.g. a mirrored copy)."""
    return Constraint(
        name,
        category,
        equation,
        lambda P: P[parameter],
        lambda p: f"{parameter} must be greater than 0{note}, got {p[parameter]:g}",
        depends=(parameter,),
    )


def box_constraints(parameter: Parameter) -> Iterable[Constraint]:
    """Box bounds and integrality of one parameter, as constraints (so violations() lists them too)."""
    name, lower, upper, unit = parameter.name, parameter.lower, parameter.upper, parameter.unit
    shown_unit = " " + unit if unit else ""
    if parameter.is_discrete:
        yield Constraint(
            f"{name}_integer",
            "finite pattern",
            "A.5",
            lambda P: -np.abs(P[name] - np.rint(P[name])),
            lambda p: f"{name} must be a whole number (gear radii are integers so the pattern closes), got {p[name]:g}",
            strict=False,
            depends=(name,),
        )
    for suffix, words, bound, sign in (("min", "at least", lower, 1.0), ("max", "at most", upper, -1.0)):
        yield Constraint(
            f"{name}_{suffix}",
            parameter.category,
            parameter.equation,
            lambda P, bound=bound, sign=sign: sign * (P[name] - bound),
            lambda p, words=words, bound=bound: f"{name} must be {words} {bound:g}{shown_unit}, got {p[name]:g}",
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
        rule = "be coprime" if len(names) == 2 else "share no common divisor"
        return (f"{listed(names)} must {rule}, got gcd({shown}) = {math.gcd(*values)} "
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


def format_number(x: float) -> str:
    """Numbers in messages: short but exact enough to see why a constraint fails."""
    return f"{x:.6g}"
