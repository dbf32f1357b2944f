"""Pattern retrieval from a sketch (thesis, section 3.4): the whole pipeline.

sketch -> symmetry copies -> stroke order (TSP) -> closed smoothing spline -> curve uniform in arc length ->
spectrum -> radii hypotheses (Eq. 3.6) -> pruned candidate rows per machine -> symmetric Procrustes distance over
direction and start point (Eq. 3.13) -> best design per distinct (machine, radii) -> optional bounded refinement of
the continuous parameters -> ranked candidates.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import minimize

from common.progress import Reporter
from design.errors import DesignError
from design.sketch.candidates import (
    CandidateDatabase,
    DatabaseSettings,
    curve_spectra,
    default_settings,
    load_database,
)
from design.sketch.distance import DEFAULT_POINTS, SpectrumBank, low_spectrum
from design.sketch.errors import RetrievalSettingError, SketchError
from design.sketch.fourier import RadiiHypothesis, Spectrum, estimate_symmetry, radii_hypotheses, spectrum
from design.sketch.ordering import StrokeOrder, order_strokes
from design.sketch.refine import refine_many
from design.sketch.spline import ClosedSpline, fit_closed_spline
from design.sketch.strokes import Sketch, check_symmetry

#: Most candidates a query may return.
MAX_TOP = 100
#: When the best pruned candidate over every machine is farther than this, the search widens (leading radius only,
#: then every candidate unless the symmetry order was given). Good matches of the benchmark sketches are below 0.02.
PRUNE_FALLBACK_DISTANCE = 0.05
#: Candidates whose continuous parameters are refined by default (:func:`design.sketch.refine.refine_many`): the
#: database samples a few designs per gear radii, the sketched design lies between them.
DEFAULT_REFINE = 3


@dataclass(frozen=True)
class PreparedSketch:
    """A sketch turned into a target curve.

    Attributes
    ----------
    sketch : Sketch
        The input.
    strokes : list of ndarray
        The strokes with their symmetry copies.
    order : StrokeOrder
        Their shortest closed tour.
    spline : ClosedSpline
        The fitted closed spline.
    curve : ndarray
        ``(N, 2)`` points of the spline uniform in arc length.
    spectrum : Spectrum
        Its DFT and dominant peaks.
    coefficients : ndarray
        Its normalized low-frequency spectrum, for the distance.
    """

    sketch: Sketch
    strokes: list[np.ndarray]
    order: StrokeOrder
    spline: ClosedSpline
    curve: np.ndarray
    spectrum: Spectrum
    coefficients: np.ndarray


def prepare_sketch(
    sketch: Sketch,
    smoothing: float = 0.01,
    points: int = DEFAULT_POINTS,
    harmonics: int | None = None,
    ordering: str = "auto",
) -> PreparedSketch:
    """Symmetrize, order, fit and resample a sketch (thesis 3.4.1), and take its spectrum (3.4.2).

    Raises
    ------
    SketchError
        When the sketch cannot give a closed curve (too few points, degenerate spline, ...).
    """
    from design.sketch.distance import DEFAULT_HARMONICS

    harmonics = DEFAULT_HARMONICS if harmonics is None else harmonics
    strokes = sketch.symmetrized()
    order = order_strokes(strokes, method=ordering)
    return _prepared(sketch, strokes, order, order.path(strokes), smoothing, points, harmonics)


def prepare_variants(
    sketch: Sketch, smoothing: float = 0.01, points: int = DEFAULT_POINTS, harmonics: int | None = None
) -> list[PreparedSketch]:
    """The ways a sketch may be read: :func:`prepare_sketch`, and for a sector sketch (symmetry ``k > 1``) also its
    copies chained in drawing order (:func:`design.sketch.sector.
    sector_path`). Retrieval keeps, for each candidate, the reading it matches best."""
    from design.sketch.distance import DEFAULT_HARMONICS
    from design.sketch.sector import sector_path

    harmonics = DEFAULT_HARMONICS if harmonics is None else harmonics
    variants = [prepare_sketch(sketch, smoothing, points, harmonics)]
    if sketch.symmetry > 1:
        # also when symmetrize() dropped copies as retracing others: on a ring the copies of a sector overlap
        chained = sector_path(sketch)
        if chained is not None:
            path, strokes, order = chained
            try:
                variants.append(_prepared(sketch, strokes, order, path, smoothing, points, harmonics))
            except SketchError:
                pass  # the tour's reading stands alone
    return variants


def _prepared(sketch: Sketch, strokes: list[np.ndarray], order: StrokeOrder, path: np.ndarray, smoothing: float,
              points: int, harmonics: int) -> PreparedSketch:
    """Fit, resample and analyse one closed path of a sketch."""
    spline = fit_closed_spline(path, smoothing)
    curve = spline.resample(points, "arclength")
    extent = np.ptp(curve, axis=0)
    if not np.all(np.isfinite(curve)) or extent.max() <= 0:
        raise SketchError(f"{sketch.source}: the fitted curve is degenerate; draw a larger pattern")
    return PreparedSketch(sketch, strokes, order, spline, curve, spectrum(curve), low_spectrum(curve, harmonics))


@dataclass(frozen=True)
class Candidate:
    """A retrieved design.

    Attributes
    ----------
    machine : str
        Machine name.
    params : dict
        The design's parameters (radii as ints).
    distance : float
        Symmetric Procrustes distance to the sketch, in ``[0, 1]`` (lower is better).
    radii : tuple of int
        Gear radii in the machine's Eq. 3.6 role order.
    refined : bool
        Whether the continuous parameters were refined by local optimization.
    """

    machine: str
    params: dict[str, float]
    distance: float
    radii: tuple[int, ...]
    refined: bool = False

    def to_json(self) -> dict[str, Any]:
        """``{"machine", "params", "distance"}`` plus ``radii`` and ``refined``."""
        return {
            "machine": self.machine,
            "params": dict(self.params),
            "distance": round(float(self.distance), 6),
            "radii": list(self.radii),
            "refined": self.refined,
        }


@dataclass
class MachineReport:
    """What happened for one machine during a query."""

    machine: str
    candidates_total: int
    candidates_compared: int
    hypotheses: list[RadiiHypothesis]
    pruned: bool
    seconds: float
    stage: str = "all"


@dataclass
class RetrievalResult:
    """Ranked candidates and how they were found."""

    candidates: list[Candidate]
    prepared: PreparedSketch
    reports: list[MachineReport]
    timings: dict[str, float] = field(default_factory=dict)


class SketchRetriever:
    """Retrieve drawing-machine designs from sketches, with one candidate database per machine.

    Parameters
    ----------
    machines : sequence of str, optional
        Machine names (all registered machines by default).
    cache_dir : path, optional
        Where databases are cached (the station passes ``station.paths.cache_dir()``); ``None``: not cached.
    settings : mapping of machine name -> DatabaseSettings, optional
        Database settings per machine (defaults from :func:`default_settings`).
    report : Reporter, optional
        Called with a :class:`common.progress.Progress` while databases are built (see
        :func:`~design.sketch.candidates.load_database`); a stop asked for ends a build with
        :class:`common.progress.Cancelled` (nothing is cached, the next query builds it again).
    """

    def __init__(
        self,
        machines: Sequence[str] | None = None,
        cache_dir: str | Path | None = None,
        settings: Mapping[str, DatabaseSettings] | None = None,
        report: Reporter | None = None,
    ) -> None:
        from design.machines import get_machine, machine_names

        names = list(machines) if machines else list(machine_names())
        known = set(machine_names())
        for name in names:
            if name not in known:
                raise RetrievalSettingError(
                    f"retrieve: unknown machine {name!r}; expected one of {', '.join(sorted(known))}"
                )
        self.machine_names = list(dict.fromkeys(names))
        self.machines = {n: get_machine(n) for n in self.machine_names}
        self.cache_dir = cache_dir
        self.settings = {n: (settings or {}).get(n, default_settings(n)) for n in self.machine_names}
        harmonics = {s.harmonics for s in self.settings.values()}
        if len(harmonics) != 1:
            raise RetrievalSettingError(
                f"retrieve: every database must keep the same number of harmonics, got {harmonics}"
            )
        self.harmonics = harmonics.pop()
        self.report = Reporter.of(report)
        self._databases: dict[str, CandidateDatabase] = {}

    def database(self, name: str) -> CandidateDatabase:
        """The candidate database of one machine (loaded or built on first use)."""
        if name not in self._databases:
            self._databases[name] = load_database(
                self.machines[name], self.cache_dir, self.settings[name], self.report
            )
        return self._databases[name]

    def load_all(self) -> None:
        """Load (or build) every machine's database now."""
        for name in self.machine_names:
            self.database(name)

    def query(
        self,
        sketch: Sketch,
        top: int = 5,
        symmetry: int | None = None,
        prune: bool = True,
        refine: int = DEFAULT_REFINE,
        smoothing: float = 0.01,
        mirror: bool = False,
        machines: Sequence[str] | None = None,
    ) -> RetrievalResult:
        """Ranked candidates for a sketch.

        Parameters
        ----------
        sketch : Sketch
            The sketch (its own symmetry order is used unless ``symmetry`` is given).
        top : int
            Number of candidates returned, each a distinct (machine, radii) combination.
        symmetry : int, optional
            Overrides the sketch's symmetry order.
        prune : bool
            Compare only candidates whose radii agree with the spectrum (Eq. 3.6); falls back to every candidate of
            a machine when none agree.
        refine : int
            Refine the continuous parameters of this many top candidates by a local search of the same distance
            (:func:`design.sketch.refine.refine_many`), 0 for none.
        smoothing : float
            Relative smoothing factor of the spline (see :func:`fit_closed_spline`).
        mirror : bool
            Also match mirror images of the candidates.
        machines : sequence of str, optional
            Search only these of the retriever's machines (all by default).
        """
        searched = list(dict.fromkeys(machines)) if machines else self.machine_names
        for name in searched:
            if name not in self.machines:
                raise RetrievalSettingError(
                    f"retrieve: machine {name!r} is not one this retriever searches ({', '.join(self.machine_names)})"
                )
        if isinstance(top, bool) or not isinstance(top, (int, np.integer)) or not 1 <= top <= MAX_TOP:
            raise RetrievalSettingError(f"retrieve: top must be an integer in [1, {MAX_TOP}], got {top!r}")
        if isinstance(refine, bool) or not isinstance(refine, (int, np.integer)) or not 0 <= refine <= MAX_TOP:
            raise RetrievalSettingError(f"retrieve: refine must be an integer in [0, {MAX_TOP}], got {refine!r}")
        timings: dict[str, float] = {}
        clock = time.perf_counter()
        if symmetry is not None:
            sketch = sketch.with_symmetry(check_symmetry(symmetry))
        variants = prepare_variants(sketch, smoothing=smoothing, harmonics=self.harmonics)
        prepared = variants[0]
        targets = np.stack([v.coefficients for v in variants])
        timings["prepare"] = time.perf_counter() - clock
        known_symmetry = sketch.symmetry if sketch.symmetry > 1 else None
        estimated = estimate_symmetry(prepared.spectrum)
        # Trust the spectrum's symmetry order when the two strongest peaks are clear (a near-circle is not).
        clear = len(prepared.spectrum.peaks) >= 2 and prepared.spectrum.magnitude(int(prepared.spectrum.peaks[1])) > 0.1
        lead = known_symmetry or (estimated if estimated > 1 and clear else None)
        plans: dict[str, tuple[list[RadiiHypothesis], list[np.ndarray | None], list[str]]] = {}
        for name in searched:
            database = self.database(name)
            hypotheses: list[RadiiHypothesis] = []
            stages: list[np.ndarray | None] = [None]
            names: list[str] = ["all"]
            if prune:
                n_gears = database.radii.shape[1]
                stages, names = [], []
                if n_gears in (2, 3):
                    hypotheses = [h for v in variants for h in radii_hypotheses(v.spectrum, n_gears, known_symmetry)]
                    if known_symmetry is None and estimated > 1:
                        hypotheses.append(RadiiHypothesis((estimated,) + (None,) * (n_gears - 1), 0.0))
                    stages.append(database.rows_matching(hypotheses))
                    names.append("spectrum radii")
                if lead is not None:
                    # A design whose pattern has another symmetry order cannot draw the sketch.
                    stages.append(database.rows_with_symmetry(lead))
                    names.append("symmetry")
                if known_symmetry is None:
                    names.append("all")
                    stages.append(None)  # an estimated symmetry may be wrong: everything, as a last resort
            plans[name] = (hypotheses, stages, names)
        # Widen the search, level by level for every machine, while no candidate matches well (a misread peak, a
        # wrong symmetry estimate); a machine is not searched wider just because it cannot draw the sketch.
        levels = max(len(stages) for _, stages, _ in plans.values())
        results: dict[str, tuple[list[Candidate], int, str, float]] = {}
        for level in range(levels):
            for name, (_hypotheses, stages, names) in plans.items():
                if level >= len(stages) or (name in results and level > 0 and _same(stages, level)):
                    continue
                rows = stages[level]
                begin = time.perf_counter()
                database = self.database(name)
                distances = database.bank.screen(targets, rows=rows, mirror=mirror)
                indices = np.arange(len(database)) if rows is None else rows
                spent = time.perf_counter() - begin + (results[name][3] if name in results else 0.0)
                results[name] = (
                    _best_per_radii(database, indices, distances, top + refine),
                    len(indices),
                    names[level],
                    spent,
                )
            best = min((c.distance for found, *_ in results.values() for c in found), default=np.inf)
            if best <= PRUNE_FALLBACK_DISTANCE:
                break
        pool: list[Candidate] = []
        reports: list[MachineReport] = []
        for name, (hypotheses, _, _) in plans.items():
            found, compared, stage, spent = results.get(name, ([], 0, "none", 0.0))
            pool.extend(found)
            database = self.database(name)
            reports.append(MachineReport(name, len(database), compared, hypotheses, stage != "all", spent, stage))
        timings["match"] = sum(r.seconds for r in reports)
        pool.sort(key=lambda c: c.distance)
        if refine:
            begin = time.perf_counter()
            refined = []
            for name in searched:
                mine = [c for c in pool[:refine] if c.machine == name]
                refined.extend(refine_many(self.machines[name], mine, targets, mirror=mirror))
            pool = sorted(refined + pool[refine:], key=lambda c: c.distance)
            timings["refine"] = time.perf_counter() - begin
        timings["total"] = time.perf_counter() - clock
        if len(variants) > 1 and pool:
            # show the reading the best candidate matches
            best = pool[0]
            database = self.database(best.machine)
            spectra = curve_spectra(self.machines[best.machine], np.array([[best.params[n] for n in
                                    database.parameter_names]]), 512, self.harmonics)
            bank = SpectrumBank(spectra)
            prepared = min(variants, key=lambda v: float(bank.match(v.coefficients, mirror=mirror).distance[0]))
        return RetrievalResult(pool[:top], prepared, reports, timings)


def _same(stages: list[np.ndarray | None], level: int) -> bool:
    """Whether stage ``level`` holds the same rows as the one before (nothing new to compare)."""
    a, b = stages[level - 1], stages[level]
    if a is None or b is None:
        return a is None and b is None
    return len(a) == len(b) and bool(np.array_equal(a, b))


def _best_per_radii(database: CandidateDatabase, rows: np.ndarray, distance: np.ndarray, keep: int) -> list[Candidate]:
    """The best row of each distinct radii combination, the ``keep`` best combinations."""
    if len(rows) == 0:
        return []
    radii = database.radii[rows]
    order = np.argsort(distance, kind="stable")
    _, first = np.unique(radii[order], axis=0, return_index=True)
    winners = order[np.sort(first)]
    winners = winners[np.argsort(distance[winners], kind="stable")][:keep]
    return [
        Candidate(
            database.machine,
            database.design(int(rows[i])),
            float(distance[i]),
            tuple(int(r) for r in database.radii[rows[i]]),
        )
        for i in winners
    ]


def curve_distance(machine, params: Mapping[str, float], coefficients: np.ndarray, mirror: bool = False) -> float:
    """Distance from one design's curve to a sketch's coefficients (same measure as the database)."""
    harmonics = len(coefficients) // 2
    points = max(512, 4 * harmonics)
    curve = machine.sample(params, n=points + 1, spacing="arclength")[:-1]
    bank = SpectrumBank(low_spectrum(curve, harmonics)[None])
    return float(bank.match(coefficients, mirror=mirror).distance[0])


def refine_candidate(
    machine, candidate: Candidate, coefficients: np.ndarray, mirror: bool = False, evaluations: int = 120
) -> Candidate:
    """Bounded local optimization of a candidate's continuous parameters (radii fixed) under the constraints.

    Powell's method within each parameter's feasible interval around the start; an infeasible trial design scores
    worse than any feasible one, so the result is always feasible and never worse than the start.
    """
    names = list(machine.continuous_names)
    if not names:
        return candidate
    start = dict(candidate.params)
    bounds = []
    for name in names:
        try:
            bounds.append(machine.feasible_interval(start, name))
        except DesignError:
            bounds.append((start[name], start[name]))
    x0 = np.array([start[n] for n in names])
    scale = np.array([max(hi - lo, 1e-9) for lo, hi in bounds])
    lows = np.array([lo for lo, _ in bounds])

    def objective(u: np.ndarray) -> float:
        design = start | {n: float(v) for n, v in zip(names, lows + u * scale)}
        if not machine.is_feasible(design):
            return 2.0
        try:
            return curve_distance(machine, design, coefficients, mirror)
        except DesignError:
            return 2.0

    u0 = np.clip((x0 - lows) / scale, 0.0, 1.0)
    result = minimize(
        objective, u0, method="Powell", bounds=[(0.0, 1.0)] * len(names), options={"maxfev": evaluations, "xtol": 1e-3}
    )
    best = float(result.fun)
    if not np.isfinite(best) or best >= candidate.distance:
        return candidate
    design = start | {n: float(v) for n, v in zip(names, lows + np.clip(result.x, 0, 1) * scale)}
    return Candidate(candidate.machine, design, best, candidate.radii, refined=True)


def retrieve(
    sketch: Sketch,
    machines: Iterable[str] | None = None,
    cache_dir: str | Path | None = None,
    top: int = 5,
    **options: Any,
) -> RetrievalResult:
    """One-shot retrieval (builds or loads the databases); see :meth:`SketchRetriever.query` for ``options``."""
    retriever = SketchRetriever(list(machines) if machines else None, cache_dir)
    return retriever.query(sketch, top=top, **options)
