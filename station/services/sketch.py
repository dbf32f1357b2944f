"""Sketch retrieval as a service: a sketch → ranked drawing-machine designs (thesis 3.4).

Used by ``station retrieve`` and the Sketch retrieval screen. The candidate databases are built once per machine
and cached in the station's cache directory; building reports :class:`common.progress.Progress` (stages
``"build"``, ``"grid"`` or ``"sampling"``, ``"curves"``) and honours a cancel check.

>>> options = RetrieveOptions(machines=("spirograph",), top=3)
>>> options.check()
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

from common.progress import Reporter
from design.machines import get_machine, machine_names
from station.errors import ServiceError, station_errors
from station.paths import cache_dir

if TYPE_CHECKING:  # scipy and the spline/FFT machinery load only when a sketch is retrieved
    import numpy as np

    from design.sketch import Candidate, RetrievalResult, Sketch, SketchRetriever

#: Inclusive ranges of the retrieval options a person may set.
TOP_RANGE = (1, 100)
REFINE_RANGE = (0, 20)
SMOOTHING_RANGE = (0.0, 0.5)
GRID_RANGE = (1, 8)


@station_errors
@dataclass(frozen=True)
class RetrieveOptions:
    """What to search and how.

    Parameters
    ----------
    machines : tuple of str
        Machines to search (empty: every registered machine); repeats are dropped.
    top : int
        Candidates returned, each a distinct (machine, gear radii).
    refine : int
        Refine the continuous parameters of this many best candidates.
    smoothing : float
        Spline smoothing, a fraction of the sketch's size.
    prune : bool
        Compare only candidates whose radii agree with the sketch's spectrum (widening when none match well).
    mirror : bool
        Also accept mirror images of the patterns.
    grid : int, optional
        Values per continuous parameter of the grid databases (the Spirographs'; default: each machine's own). The
        databases that sample their feasible sets uniformly (Cycloid Drawing Machine, Hoot-Nanny) keep theirs.
    """

    machines: tuple[str, ...] = ()
    top: int = 5
    refine: int = 3
    smoothing: float = 0.01
    prune: bool = True
    mirror: bool = False
    grid: int | None = None

    def check(self) -> None:
        """Raise :class:`ServiceError` (its ``field`` the option's name) for the first option out of its domain."""
        known = machine_names()
        for name in self.machines:
            if name not in known:
                raise ServiceError(f"machine {name!r}: unknown machine; expected one of {', '.join(known)}",
                                   field="machine", value=name)
        _check_integer("top", self.top, TOP_RANGE)
        _check_integer("refine", self.refine, REFINE_RANGE)
        low, high = SMOOTHING_RANGE
        if not math.isfinite(self.smoothing) or not low <= self.smoothing <= high:
            raise ServiceError(f"smoothing must be a number in [{low:g}, {high:g}], got {self.smoothing}",
                               field="smoothing", value=self.smoothing)
        if self.grid is not None:
            _check_integer("grid", self.grid, GRID_RANGE)

    def machine_list(self) -> list[str] | None:
        """The machines to search, without repeats, or None for all."""
        return list(dict.fromkeys(self.machines)) or None


def _check_integer(field: str, value: int, bounds: tuple[int, int]) -> None:
    low, high = bounds
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise ServiceError(f"{field} must be an integer in [{low}, {high}], got {value}", field=field, value=value)


@station_errors
def make_retriever(options: RetrieveOptions | None = None, *, report: Reporter | None = None,
                   cache: str | Path | None = None) -> SketchRetriever:
    """A retriever over the options' machines, its databases cached in ``cache`` (default: the station's cache).

    A retriever keeps the databases it loaded: keep it to answer further sketches without reading them again.
    """
    from design.sketch import SketchRetriever  # heavy: scipy
    from design.sketch.candidates import default_settings  # heavy: scipy

    options = options or RetrieveOptions()
    options.check()
    machines = options.machine_list()
    settings = None
    if options.grid is not None:
        # only grid databases: a Hoot-Nanny grid over every radii up to 10 would hold 4^5 designs per radii
        settings = {n: (replace(default_settings(n), values_per_dimension=options.grid)
                        if default_settings(n).sampling == "grid" else default_settings(n))
                    for n in machines or machine_names()}
    return SketchRetriever(machines, cache_dir=cache_dir() if cache is None else cache, settings=settings,
                           report=report)


@station_errors
def load_sketch(path: str | Path, symmetry: int | None = None, center: object = None) -> Sketch:
    """A sketch from a ``.json`` or ``.svg`` file of strokes (one symmetric sector with ``symmetry`` K, about
    ``center``): :func:`design.sketch.load_sketch`."""
    from design.sketch import load_sketch as load  # scipy and the spline/FFT machinery: loaded when a sketch is read

    return load(path, symmetry=symmetry, center=center)


@station_errors
def sketch_from_strokes(strokes: list, symmetry: int = 1, center: object = None, source: str = "") -> Sketch:
    """A sketch from strokes drawn by hand (lists of (x, y) points; one symmetric sector with ``symmetry`` K, about
    ``center``): :func:`design.sketch.make_sketch`."""
    from design.sketch import make_sketch  # scipy and the spline/FFT machinery: loaded when a sketch is made

    return make_sketch(strokes, symmetry=symmetry, center=center, source=source)


@station_errors
def retrieve(sketch: Sketch, options: RetrieveOptions | None = None, *, retriever: SketchRetriever | None = None,
             report: Reporter | None = None) -> RetrievalResult:
    """Ranked candidates for ``sketch``.

    Parameters
    ----------
    sketch : Sketch
        From :func:`design.sketch.load_sketch` or :func:`design.sketch.make_sketch`.
    options : RetrieveOptions, optional
        Checked first (a :class:`ServiceError` names the option).
    retriever : SketchRetriever, optional
        One kept from :func:`make_retriever` (its databases already loaded); made from ``options`` otherwise,
        reporting to ``report`` (and stopping when it says so).

    Raises
    ------
    ServiceError
        An option out of its domain.
    design.sketch.SketchError
        The sketch gives no usable curve.
    common.progress.Cancelled
        A stop was asked for while a database was built.
    """
    options = options or RetrieveOptions()
    options.check()
    if retriever is None:
        retriever = make_retriever(options, report=report)
    return retriever.query(sketch, top=options.top, prune=options.prune, refine=options.refine,
                           smoothing=options.smoothing, mirror=options.mirror, machines=options.machine_list())


@station_errors
def candidate_curve(candidate: Candidate, points: int = 2048) -> np.ndarray:
    """The pattern of a candidate, ``(points, 2)`` uniform in arc length, for a preview."""
    return get_machine(candidate.machine).sample(candidate.params, n=points, spacing="arclength")


@station_errors
def write_contact_sheet(result: RetrievalResult, path: str | Path, points: int = 2048) -> Path:
    """A PNG of the sketch (strokes and fitted curve) beside each ranked candidate, labelled with its distance."""
    from design.sketch.contact_sheet import render_contact_sheet  # heavy: PIL, scipy

    path = Path(path)
    labelled = [
        (f"#{i} {c.machine} {'/'.join(map(str, c.radii))}\ndistance {c.distance:.4f}", candidate_curve(c, points))
        for i, c in enumerate(result.candidates, start=1)
    ]
    render_contact_sheet(path, result.prepared.strokes, result.prepared.curve, labelled)
    return path
