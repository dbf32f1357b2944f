"""The tolerance map of a layout: how far each free parameter may be off on its own.

For each parameter of the design space, the largest error ±delta the layout tolerates with every other parameter
fixed while the predicted success stays at least :data:`RATIO` (90 %) of the layout's own, from the layout's fitted
success model (:class:`~design.robust.model_io.PortablePSP`). Each side is searched on its own: the first point
where the ratio falls below the threshold (a grid of :data:`GRID` steps out to the design space's bound, then
bisection between the last good and the first bad step, every parameter and side in one batch per step); a side
that never falls below it reaches the bound. The tolerance is the smaller side, so ±delta stays within the design
space; ``bound_limited`` says that a bound, not the model, set it (the model knows nothing beyond the range). A side
on which the layout sits at its bound is not counted (the range has nothing there).

:func:`verify_tolerances` checks each delta by simulation; without a model, :func:`simulated_tolerances` searches
delta by the simulated success rate (a coarse bisection within a budget). Values are reported in the parameter's
unit as the maker measures it: positions in millimetres (the design space is in metres), angles in degrees.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from design.contraption.schema import ANGLE_KEYS

__all__ = ["CARE_RULE", "GRID", "RATIO", "ToleranceEntry", "ToleranceMap", "care_level", "model_tolerances",
           "no_tolerances", "parameter_unit", "simulated_tolerances", "verify_tolerances", "verify_layouts"]

#: The share of the layout's predicted success the tolerance keeps.
RATIO = 0.9
#: Grid steps per side before bisection, and bisection steps after (the delta is found to (1/GRID) / 2**BISECTION
#: of the side's length).
GRID = 32
BISECTION = 20
#: A verification layout's parameter is drawn uniformly between (1 - BAND) x delta and delta on its side: the
#: simulation is deterministic, so N copies of one layout would measure one outcome N times, not a success rate;
#: the band stays inside ±delta, the errors the tolerance claims to survive (beyond it parts may collide).
BAND = 0.1
#: The care levels' rule: (tight below, loose above) per unit (see :func:`care_level`).
CARE_RULE = {"mm": (2.0, 6.0), "deg": (2.0, 6.0)}

#: Simulates normalized layouts (n, d) and returns per-event success (n, n_events), e.g. a BudgetedOracle.
Oracle = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class ToleranceEntry:
    """The tolerance of one free layout parameter.

    Attributes
    ----------
    parameter : str
        ``"top_track.x"``.
    part : str
        The scenario object it moves (``"top_track"``).
    kind : str
        ``"position"`` or ``"angle"``.
    delta : float or None
        The largest error ±delta tolerated, in ``unit``; None when unknown.
    unit : str
        ``"mm"`` or ``"deg"``.
    predicted_ratio : float or None
        The model's success at ±delta (the worse side) as a fraction of the layout's.
    predicted : float or None
        The model's mean success over the verification layouts at ±delta (or at ±delta itself, unverified): what
        ``measured`` is compared with.
    measured : float or None
        The simulated success rate of the verification layouts at ±delta (None unless verified).
    measured_minus, measured_plus : float or None
        The same at -delta and at +delta alone (which side fails).
    bound_limited : bool
        The design space's bound, not the success, set delta (delta is then a lower bound of the tolerance: the
        model knows nothing beyond the range).
    limited_by : str
        What set delta: ``"success"`` (the ratio fell below the threshold), ``"collision"`` (beyond it the parts
        overlap: a physically invalid layout), ``"bound"`` (the range ends) or ``""`` (unknown).
    in_model : bool or None
        Whether the model's success depends on the parameter at all (some classifier reads it); a parameter it
        ignores gets a delta from the range and collisions only. None without a model.
    minus, plus : float or None
        Each side's own limit (``unit``), before taking the smaller; None for a side at the bound.
    simulations : int
        Verification layouts simulated for this parameter.
    """

    parameter: str
    part: str
    kind: str
    delta: float | None
    unit: str
    predicted_ratio: float | None = None
    predicted: float | None = None
    measured: float | None = None
    measured_minus: float | None = None
    measured_plus: float | None = None
    bound_limited: bool = False
    limited_by: str = ""
    in_model: bool | None = None
    minus: float | None = None
    plus: float | None = None
    simulations: int = 0

    def to_dict(self) -> dict:
        """JSON-friendly."""
        return {name: getattr(self, name) for name in self.__dataclass_fields__}


@dataclass(frozen=True)
class ToleranceMap:
    """Every free parameter's tolerance and where they came from.

    Attributes
    ----------
    entries : tuple of ToleranceEntry
        In design-space order.
    source : str
        ``"model"`` (the layout's fitted success model), ``"simulation"`` (searched by simulation, no model) or
        ``"none"`` (no model and no simulations asked for: every delta is None).
    layout_psp : float or None
        The model's predicted success of the layout itself (None without a model).
    ratio : float
        The share of it the tolerances keep.
    layout_success : bool or None
        The layout's own simulated success, when it was simulated.
    note : str or None
        Why the tolerances came from where they did, when that is not the obvious (a success model too weak at
        the layout to be trusted).
    """

    entries: tuple[ToleranceEntry, ...]
    source: str
    layout_psp: float | None = None
    ratio: float = RATIO
    layout_success: bool | None = None
    note: str | None = None

    def by_part(self) -> dict[str, list[ToleranceEntry]]:
        """The entries grouped by part, in design-space order."""
        parts: dict[str, list[ToleranceEntry]] = {}
        for entry in self.entries:
            parts.setdefault(entry.part, []).append(entry)
        return parts

    def care(self) -> dict[str, str | None]:
        """Each part's care level (:func:`care_level`)."""
        return {part: care_level(entries) for part, entries in self.by_part().items()}

    def to_dict(self) -> dict:
        """JSON-friendly: source, layout_psp, ratio, layout_success, entries, care per part, and the note."""
        return {"source": self.source, "layout_psp": self.layout_psp, "ratio": self.ratio,
                "layout_success": self.layout_success, "entries": [e.to_dict() for e in self.entries],
                "care": self.care(), "note": self.note}


def care_level(entries: Sequence[ToleranceEntry]) -> str | None:
    """How carefully a part must be placed, from its parameters' tolerances: ``"tight"``, ``"normal"``, ``"loose"``.

    Tight when any position delta is under 2 mm or any angle delta under 2 degrees; loose when every known delta is
    over 6 mm / 6 degrees; else normal (:data:`CARE_RULE`). A bound-limited delta is only a lower bound of the
    tolerance, so it never makes a part tight. None when no delta is known. The one rule of the station: the
    tolerance table and the guide's colours both come from here.
    """
    known = [e for e in entries if e.delta is not None]
    if not known:
        return None
    if any(e.delta < CARE_RULE[e.unit][0] and not e.bound_limited for e in known):
        return "tight"
    if all(e.delta > CARE_RULE[e.unit][1] for e in known):
        return "loose"
    return "normal"


def parameter_unit(name: str) -> tuple[str, str, str, float]:
    """``(part, kind, unit, factor)`` of a design parameter ``"part.key"``: the factor turns the design space's unit
    (m, deg) into the maker's (mm, deg)."""
    part, _, key = name.rpartition(".")
    if key in ANGLE_KEYS:
        return part or name, "angle", "deg", 1.0
    return part or name, "position", "mm", 1000.0


def _entry(name: str, **values) -> ToleranceEntry:
    part, kind, unit, _ = parameter_unit(name)
    return ToleranceEntry(name, part, kind, unit=unit, **values)


# --------------------------------------------------------------------------------------------------------------
# From the model
# --------------------------------------------------------------------------------------------------------------
def _along(u: np.ndarray, index: np.ndarray, step: np.ndarray) -> np.ndarray:
    """Layouts ``u`` with parameter ``index[k]`` moved by ``step[k]`` (normalized), one row per k."""
    U = np.repeat(u[None, :], len(index), axis=0)
    U[np.arange(len(index)), index] += step
    return np.clip(U, 0.0, 1.0)


def _side_limits(score: Callable[[np.ndarray], np.ndarray], u: np.ndarray, reference: float,
                 ratio: float) -> tuple[np.ndarray, np.ndarray]:
    """Per parameter and side (rows: ``d`` minus sides then ``d`` plus sides): the limit in normalized units and
    whether the success ratio fell below ``ratio`` before the bound."""
    d = len(u)
    index = np.tile(np.arange(d), 2)
    sign = np.repeat([-1.0, 1.0], d)
    room = np.where(sign < 0, u[index], 1.0 - u[index])  # distance to the bound on each side
    fractions = np.arange(1, GRID + 1) / GRID
    steps = room[:, None] * fractions[None, :]  # (2d, GRID)
    grid = _along(u, np.repeat(index, GRID), (sign[:, None] * steps).ravel())
    good = (score(grid) >= ratio * reference).reshape(2 * d, GRID)
    crossed = ~good.all(axis=1)
    first_bad = np.where(crossed, np.argmin(good, axis=1), GRID)
    low = np.where(first_bad > 0, steps[np.arange(2 * d), np.maximum(first_bad - 1, 0)], 0.0)
    low = np.where(crossed, low, room)
    high = np.where(crossed, steps[np.arange(2 * d), np.minimum(first_bad, GRID - 1)], room)
    rows = np.flatnonzero(crossed)
    for _ in range(BISECTION if len(rows) else 0):  # every crossing side at once: one batch per step
        middle = 0.5 * (low[rows] + high[rows])
        ok = score(_along(u, index[rows], sign[rows] * middle)) >= ratio * reference
        low[rows] = np.where(ok, middle, low[rows])
        high[rows] = np.where(ok, high[rows], middle)
    return low, crossed


def model_tolerances(model, problem, u: np.ndarray, *, ratio: float = RATIO,
                     is_valid: Callable[[np.ndarray], np.ndarray] | None = None) -> ToleranceMap:
    """The tolerance map of layout ``u`` (normalized) from a fitted model (no simulation).

    Parameters
    ----------
    model : PortablePSP
        ``predict(U) -> (n,)`` on normalized layouts (a FactorizedPSP's ``predict_proba`` works too, wrapped).
    problem : LayoutProblem
        Names and bounds.
    u : ndarray, shape (d,)
    ratio : float
        The share of the layout's predicted success to keep (0.9).
    is_valid : callable, optional
        Physical validity of normalized layouts; an invalid one (parts in each other) counts as a failure.
    """
    u = np.clip(np.asarray(u, dtype=float).ravel(), 0.0, 1.0)

    def score(U: np.ndarray) -> np.ndarray:
        values = np.asarray(model.predict(U), dtype=float)
        return values if is_valid is None else np.where(is_valid(U), values, 0.0)

    reference = float(score(u[None, :])[0])
    names = problem.parameter_names
    used = getattr(model, "parameters_used", tuple(range(len(names))))
    if reference <= 0:
        return ToleranceMap(tuple(_entry(n, delta=None) for n in names), "model", reference, ratio)
    d = len(u)
    limits, crossed = _side_limits(score, u, reference, ratio)
    span = np.asarray(problem.upper, dtype=float) - np.asarray(problem.lower, dtype=float)
    at_bound = np.concatenate([u <= 1e-9, u >= 1 - 1e-9])
    entries = []
    for i, name in enumerate(names):
        factor = parameter_unit(name)[3] * span[i]
        sides = [k for k in (i, i + d) if not at_bound[k]]
        if not sides:
            entries.append(_entry(name, delta=None))
            continue
        k = min(sides, key=lambda row: limits[row])
        delta = float(limits[k])
        worse = score(_along(u, np.array([i, i]), np.array([-delta, delta])))
        limited_by = "bound"
        if crossed[k]:
            # Just past the limit: a model's low success, or parts in each other (the validity check)?
            beyond = _along(u, np.array([i]), np.array([(1 if k >= d else -1) * (delta + 1e-6)]))
            limited_by = "collision" if is_valid is not None and not is_valid(beyond)[0] else "success"
        entries.append(_entry(
            name, delta=delta * factor, predicted_ratio=float(worse.min() / reference),
            predicted=float(worse.mean()), bound_limited=not crossed[k], limited_by=limited_by, in_model=i in used,
            minus=None if at_bound[i] else float(limits[i] * factor),
            plus=None if at_bound[i + d] else float(limits[i + d] * factor)))
    return ToleranceMap(tuple(entries), "model", reference, ratio)


# --------------------------------------------------------------------------------------------------------------
# By simulation
# --------------------------------------------------------------------------------------------------------------
def verify_layouts(u: np.ndarray, index: int, delta: float, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` layouts at ``u`` ± ``delta`` (normalized) along parameter ``index``, half on each side, each drawn
    uniformly between (1 - :data:`BAND`) delta and delta on its side (kept in the design space); the other
    parameters fixed."""
    u = np.asarray(u, dtype=float)
    sides = np.where(np.arange(n) < n // 2, -1.0, 1.0)
    offsets = sides * delta * (1.0 - BAND * rng.uniform(0.0, 1.0, n))
    return _along(u, np.full(n, index), offsets)


def _normalized(entry: ToleranceEntry, span: float) -> float:
    return entry.delta / (parameter_unit(entry.parameter)[3] * span)


def verify_tolerances(tolerances: ToleranceMap, problem, u: np.ndarray, oracle: Oracle, n: int, *, seed: int = 0,
                      model=None, on_parameter: Callable[[int, str], None] | None = None) -> ToleranceMap:
    """Simulate ``n`` layouts at ±delta for each parameter with a delta (:func:`verify_layouts`) and record the
    success rate measured (and, with a ``model``, its mean prediction over the same layouts); the layout itself is
    simulated too (``layout_success``, the reference the measured rates are to keep 90 % of)."""
    u = np.clip(np.asarray(u, dtype=float).ravel(), 0.0, 1.0)
    rng = np.random.default_rng(seed)
    layout_success = bool(np.asarray(oracle(u[None, :])).all()) if n >= 1 else tolerances.layout_success
    span = np.asarray(problem.upper, dtype=float) - np.asarray(problem.lower, dtype=float)
    entries = []
    for i, entry in enumerate(tolerances.entries):
        if on_parameter is not None:
            on_parameter(i, entry.parameter)
        if entry.delta is None or n < 1:
            entries.append(entry)
            continue
        layouts = verify_layouts(u, i, _normalized(entry, span[i]), n, rng)
        success = np.asarray(oracle(layouts)).all(axis=1)
        half = n // 2  # verify_layouts puts the first half at -delta
        predicted = entry.predicted if model is None else float(np.mean(model.predict(layouts)))
        entries.append(replace(entry, measured=float(success.mean()), predicted=predicted, simulations=len(layouts),
                               measured_minus=float(success[:half].mean()) if half else None,
                               measured_plus=float(success[half:].mean())))
    return replace(tolerances, entries=tuple(entries), layout_success=layout_success)


def simulated_tolerances(problem, u: np.ndarray, oracle: Oracle, n: int, *, steps: int = 4, ratio: float = RATIO,
                         seed: int = 0, on_parameter: Callable[[int, str], None] | None = None) -> ToleranceMap:
    """The tolerance map without a model: per parameter, a coarse bisection of delta on the simulated success rate.

    The layout itself is simulated first; if it fails, no delta is known. Each parameter then gets ``steps``
    bisection steps between 0 and its room to the nearer bound that is not at the layout (the smaller side, as with
    the model), each measuring the success rate of ``n`` layouts at ±delta (:func:`verify_layouts`) against
    ``ratio``; a parameter whose whole room passes is bound-limited. At most ``1 + d (steps + 1) n`` simulations.
    """
    u = np.clip(np.asarray(u, dtype=float).ravel(), 0.0, 1.0)
    rng = np.random.default_rng(seed)
    success = bool(np.asarray(oracle(u[None, :])).all())
    names = problem.parameter_names
    if not success:
        return ToleranceMap(tuple(_entry(name, delta=None) for name in names), "simulation", None, ratio, False)
    span = np.asarray(problem.upper, dtype=float) - np.asarray(problem.lower, dtype=float)
    entries = []
    for i, name in enumerate(names):
        if on_parameter is not None:
            on_parameter(i, name)
        rooms = [r for r in (u[i], 1.0 - u[i]) if r > 1e-9]
        factor = parameter_unit(name)[3] * span[i]
        if not rooms or n < 1:
            entries.append(_entry(name, delta=None))
            continue

        def rate(delta: float, index: int = i) -> float:
            return float(np.asarray(oracle(verify_layouts(u, index, delta, n, rng))).all(axis=1).mean())

        room = min(rooms)
        measured_room = rate(room)
        used = n
        if measured_room >= ratio:
            entries.append(_entry(name, delta=room * factor, measured=measured_room, bound_limited=True,
                                  limited_by="bound", simulations=used))
            continue
        low, high, low_rate = 0.0, room, None
        for _ in range(steps):
            middle = 0.5 * (low + high)
            measured = rate(middle)
            used += n
            if measured >= ratio:
                low, low_rate = middle, measured
            else:
                high = middle
        entries.append(_entry(name, delta=low * factor, measured=low_rate, limited_by="success", simulations=used))
    return ToleranceMap(tuple(entries), "simulation", None, ratio, True)


def no_tolerances(problem) -> ToleranceMap:
    """The map of a layout without a model when no simulation was asked for: every delta unknown."""
    return ToleranceMap(tuple(_entry(name, delta=None) for name in problem.parameter_names), "none")
