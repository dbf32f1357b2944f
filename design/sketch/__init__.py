"""Sketch retrieval (thesis, section 3.4): find drawing-machine designs from a rough sketch.

>>> from design.sketch import load_sketch, SketchRetriever
>>> sketch = load_sketch("examples/sketches/trefoil.json")            # doctest: +SKIP
>>> result = SketchRetriever(cache_dir=cache).query(sketch, top=5)    # doctest: +SKIP
>>> [(c.machine, c.params, c.distance) for c in result.candidates]    # doctest: +SKIP

Modules: :mod:`~design.sketch.strokes` (input, symmetry copies), :mod:`~design.sketch.files` (sketch files),
:mod:`~design.sketch.svg` (SVG sketches), :mod:`~design.sketch.ordering` (stroke order as a TSP, MILP + heuristic),
:mod:`~design.sketch.spline` (closed smoothing spline), :mod:`~design.sketch.fourier` (DFT, radii by Eq. 3.6),
:mod:`~design.sketch.candidates` (Farey / feasible-grid or uniformly sampled database, cached),
:mod:`~design.sketch.distance` (Procrustes distance, Eq. 3.13), :mod:`~design.sketch.sector` (a sector sketch's copies
chained in drawing order), :mod:`~design.sketch.refine` (batched refinement of the best candidates' continuous
parameters), :mod:`~design.sketch.retrieval` (the pipeline), :mod:`~design.sketch.synthetic` (seeded benchmark
sketches).
"""

from design.sketch.candidates import CandidateDatabase, DatabaseSettings, default_settings, load_database
from design.sketch.errors import CandidateDatabaseError, RetrievalSettingError, SketchError, SketchFileError
from design.sketch.files import load_sketch
from design.sketch.retrieval import Candidate, RetrievalResult, SketchRetriever, prepare_sketch, retrieve
from design.sketch.strokes import Sketch, make_sketch

__all__ = [
    "Candidate",
    "CandidateDatabase",
    "CandidateDatabaseError",
    "DatabaseSettings",
    "RetrievalResult",
    "RetrievalSettingError",
    "Sketch",
    "SketchError",
    "SketchFileError",
    "SketchRetriever",
    "default_settings",
    "load_database",
    "load_sketch",
    "make_sketch",
    "prepare_sketch",
    "retrieve",
]
