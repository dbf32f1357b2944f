"""Candidate database per machine: coprime radii from the Farey sequence, continuous parameters on a feasible grid.

For each machine (thesis, section 3.4): gear radii are coprime, taken from the Farey sequence ``F_n`` (fractions
``a/b``, ``1 <= a <= b <= n``, ``gcd(a, b) = 1``, both orientations); the continuous parameters are sampled on a
*feasible grid*: a tree of :meth:`feasible_interval` calls, one parameter at a time, so every grid point satisfies
the machine's constraints (``values_per_dimension`` per continuous parameter, 4 by default as in the thesis). Each
design's curve is sampled uniformly in arc length and stored as the low-frequency spectrum of its Procrustes-
normalized points (:func:`design.sketch.distance.low_spectrum`).

The database is built once and cached on disk (a path passed in) under a version key that hashes the settings, the
database format and the machine model's source code and a few of its curves, so that a model change invalidates it.
"""

from __future__ import annotations

import hashlib
import inspect
import itertools
import json
import math
import os
import tempfile
import time
import zipfile
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from common.progress import Reporter
from design.errors import DesignError
from design.sketch.distance import DEFAULT_HARMONICS, SpectrumBank, low_spectrum
from design.sketch.errors import CandidateDatabaseError, RetrievalSettingError
from design.sketch.fourier import RadiiHypothesis

#: Bump when the database layout or the way it is built changes (part of the cache key: a database of another
#: format is rebuilt, never read).
DATABASE_FORMAT = 5


@dataclass(frozen=True)
class DatabaseSettings:
    """How a machine's candidates are sampled.

    Parameters
    ----------
    max_radius : int
        Order ``n`` of the Farey sequence: every gear radius is at most this.
    max_other_radius : int, optional
        A lower bound for the radii other than the leading one (e.g. the Hoot-Nanny's small external gears).
    values_per_dimension : int
        Grid values per continuous parameter.
    points : int
        Points per curve (uniform in arc length) before the spectrum is taken. 512 is plenty for
        ``harmonics`` <= 255 and samples several times faster than 1024 (the query curve keeps 1024).
    harmonics : int
        Harmonics kept per curve.
    seed : int
        Seed of the random search for a feasible anchor design per radii combination (``"grid"``) or of the
        uniform sampler (``"uniform"``).
    sampling : {"grid", "uniform"}
        How the continuous parameters are sampled per radii combination: the feasible grid around an anchor design
        (``values_per_dimension`` per parameter), or ``samples`` designs uniform over the whole feasible set
        (:func:`design.machines.feasible_sampling.uniform_feasible`), which covers machines whose feasible set a
        grid around one anchor misses most of, at a fraction of the designs.
    samples : int
        Designs per radii combination with ``sampling="uniform"``.
    """

    max_radius: int = 8
    max_other_radius: int | None = None
    values_per_dimension: int = 4
    points: int = 512
    harmonics: int = DEFAULT_HARMONICS
    seed: int = 0
    sampling: str = "grid"
    samples: int = 64

    def __post_init__(self) -> None:
        checks = [
            ("max_radius", self.max_radius, 1, 40),
            ("values_per_dimension", self.values_per_dimension, 1, 12),
            ("points", self.points, 64, 8192),
            ("harmonics", self.harmonics, 4, 1024),
            ("samples", self.samples, 1, 4096),
        ]
        for name, value, lo, hi in checks:
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
                raise RetrievalSettingError(
                    f"candidate database: {name} must be an integer in [{lo}, {hi}], got {value!r}"
                )
        if self.max_other_radius is not None and not 1 <= self.max_other_radius <= self.max_radius:
            raise RetrievalSettingError(
                f"candidate database: max_other_radius must be in [1, max_radius = {self.max_radius}], "
                f"got {self.max_other_radius!r}"
            )
        if self.sampling not in ("grid", "uniform"):
            raise RetrievalSettingError(
                f"candidate database: sampling must be 'grid' or 'uniform', got {self.sampling!r}"
            )
        if 2 * self.harmonics + 1 > self.points:
            raise RetrievalSettingError(
                f"candidate database: harmonics must be below points / 2 = {self.points // 2}, got {self.harmonics}"
            )


#: Default settings per machine. The thesis' 4 values per continuous parameter for the Cycloid Drawing Machine and
#: the Hoot-Nanny (4^4 and 4^5 designs per radii combination); the Spirograph's one continuous parameter and the
#: elliptic Spirograph's two get 12 and 6 values, which costs little (hundreds of designs) and finds their close
#: matches without refinement. Smaller radii for the Hoot-Nanny, whose database is the largest.
DEFAULT_SETTINGS: dict[str, DatabaseSettings] = {
    "spirograph": DatabaseSettings(max_radius=12, values_per_dimension=12),
    "elliptic_spirograph": DatabaseSettings(max_radius=10, values_per_dimension=6),
    "cycloid_drawing_machine": DatabaseSettings(max_radius=12, sampling="uniform", samples=96),
    "hoot_nanny": DatabaseSettings(max_radius=10, sampling="uniform", samples=48),
}


def default_settings(machine_name: str) -> DatabaseSettings:
    """The default :class:`DatabaseSettings` of a machine (generic ones for a machine not listed)."""
    return DEFAULT_SETTINGS.get(machine_name, DatabaseSettings())


def farey(n: int) -> list[tuple[int, int]]:
    """The Farey sequence ``F_n`` without its first term ``0/1``: ``(a, b)`` with ``a/b`` ascending in ``(0, 1]``.

    Computed with the classic next-term recurrence, linear in the number of terms.
    """
    if n < 1:
        return []
    a, b, c, d = 0, 1, 1, n
    terms = []
    while c <= n:
        k = (n + b) // d
        a, b, c, d = c, d, k * c - a, k * d - b
        terms.append((a, b))
    return terms


def radius_roles(machine) -> tuple[str, ...]:
    """The machine's gear radii in the order of Eq. 3.6: the symmetry (leading) gear first, then the others."""
    discrete = list(machine.discrete_names)
    lead = getattr(machine, "symmetry_gear", "") or (discrete[0] if discrete else "")
    if lead not in discrete:
        raise CandidateDatabaseError(f"{machine.name}: symmetry gear {lead!r} is not one of its radii {discrete}")
    return (lead,) + tuple(n for n in discrete if n != lead)


def radius_combinations(machine, max_radius: int, max_other_radius: int | None = None) -> list[tuple[int, ...]]:
    """Coprime radii combinations in role order (see :func:`radius_roles`) within the parameters' bounds.

    Two gears: every Farey fraction ``a/b`` of ``F_n`` in both orientations. More gears: every combination whose
    radii share no common divisor as a whole (A.62), pairs of them may.
    """
    roles = radius_roles(machine)
    parameters = [machine.parameter(n) for n in roles]
    bounds = [(max(1, int(p.lower)), min(int(p.upper), max_radius)) for p in parameters]
    other = max_radius if max_other_radius is None else max_other_radius
    if len(roles) == 1:
        return [(r,) for r in range(bounds[0][0], bounds[0][1] + 1)]
    if len(roles) == 2:
        combos = sorted({(a, b) for a, b in farey(max_radius)} | {(b, a) for a, b in farey(max_radius)})
    else:
        # A.62: the radii share no common divisor as a whole; pairs of them may (e.g. a Hoot-Nanny 10 / 8 / 1)
        ranges = [range(1, max_radius + 1)] + [range(1, other + 1)] * (len(roles) - 1)
        combos = [c for c in itertools.product(*ranges) if math.gcd(*c) == 1]
    return [
        c for c in combos if all(lo <= r <= hi for r, (lo, hi) in zip(c, bounds)) and all(r <= other for r in c[1:])
    ]


def model_fingerprint(machine) -> str:
    """A hash of the machine model: its class source, its base class source, its parameters and a few curves."""
    digest = hashlib.sha256()
    for cls in type(machine).__mro__:
        if cls is object:
            continue
        try:
            digest.update(inspect.getsource(cls).encode())
        except (OSError, TypeError):
            digest.update(cls.__qualname__.encode())
    digest.update(repr(machine.parameters).encode())
    try:
        digest.update(np.round(machine.sample(machine.defaults(), n=64, spacing="time"), 9).tobytes())
    except DesignError:
        pass
    return digest.hexdigest()


def version_key(machine, settings: DatabaseSettings) -> str:
    """The cache key: database format, settings, model fingerprint (and the uniform sampler's source)."""
    sampler = ""
    if settings.sampling == "uniform":  # the sampler's code decides the designs as much as the settings do
        from design.machines import feasible_sampling

        sampler = hashlib.sha256(inspect.getsource(feasible_sampling).encode()).hexdigest()
    payload = json.dumps(
        {"format": DATABASE_FORMAT, "settings": asdict(settings), "model": model_fingerprint(machine),
         "sampler": sampler},
        sort_keys=True,
    )
    return hashlib.sha256(payload.encode()).hexdigest()[:20]


@dataclass
class CandidateDatabase:
    """Sampled designs of one machine and the spectra of their curves.

    Attributes
    ----------
    machine : str
        Machine name.
    parameter_names : tuple of str
        Columns of :attr:`params`.
    roles : tuple of str
        Gear radii in Eq. 3.6 order; columns of :attr:`radii`.
    params : ndarray
        ``(M, P)`` design parameters.
    bank : SpectrumBank
        Curve spectra, row-aligned with :attr:`params`.
    key : str
        Version key it was built under.
    build_seconds : float
        Time it took to build (0 when loaded from the cache is not known).
    radii : ndarray
        ``(M, G)`` integer radii in role order: the :attr:`roles` columns of :attr:`params`, rounded (derived, so
        the two never disagree).
    symmetry : ndarray
        ``(M,)`` rotational symmetry order of each row's pattern (derived from :attr:`radii`).
    """

    machine: str
    parameter_names: tuple[str, ...]
    roles: tuple[str, ...]
    params: np.ndarray
    bank: SpectrumBank
    key: str
    build_seconds: float = 0.0
    radii: np.ndarray = field(init=False, repr=False)
    symmetry: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        columns = [self.parameter_names.index(r) for r in self.roles]
        self.radii = np.rint(self.params[:, columns]).astype(np.int64)
        # the pattern's rotational symmetry order (DrawingMachine.symmetry_order): the leading radius over its gcd
        # with the lcm of the others; a Hoot-Nanny 6 / 4 / 3 has symmetry 1, not 6
        others = np.ones(len(self.radii), dtype=np.int64)
        for column in range(1, self.radii.shape[1]):
            others = np.lcm(others, self.radii[:, column])
        self.symmetry = self.radii[:, 0] // np.gcd(self.radii[:, 0], others)

    def __len__(self) -> int:
        return len(self.params)

    def design(self, row: int) -> dict[str, float]:
        """Row ``row`` as a parameter dict (radii as ints)."""
        values = {}
        for name, value in zip(self.parameter_names, self.params[row]):
            values[name] = int(round(value)) if name in self.roles else float(value)
        return values

    def rows_matching(self, hypotheses: Iterable[RadiiHypothesis]) -> np.ndarray:
        """Rows whose radii agree with at least one hypothesis (``None`` radii match anything)."""
        mask = np.zeros(len(self), dtype=bool)
        for hypothesis in hypotheses:
            radii = hypothesis.radii[: self.radii.shape[1]]
            match = np.ones(len(self), dtype=bool)
            for column, value in enumerate(radii):
                if value is not None:
                    match &= self.radii[:, column] == value
            mask |= match
        return np.flatnonzero(mask)

    def rows_with_symmetry(self, order: int) -> np.ndarray:
        """Rows whose pattern has rotational symmetry of order ``order``."""
        return np.flatnonzero(self.symmetry == order)

    def combinations(self) -> np.ndarray:
        """The distinct radii combinations, ``(C, G)``."""
        return np.unique(self.radii, axis=0)


def _anchor(machine, fixed: dict[str, float], rng: np.random.Generator, tries: int = 4096) -> dict[str, float] | None:
    """A feasible design with the given radii: the feasible random design nearest the middle of the feasible ones."""
    continuous = machine.continuous_names
    if not continuous:
        return dict(fixed) if machine.is_feasible(fixed) else None
    box = np.array([[machine.parameter(n).lower, machine.parameter(n).upper] for n in continuous])
    for _ in range(3):
        draws = box[:, 0] + rng.random((tries, len(continuous))) * (box[:, 1] - box[:, 0])
        rows = {n: draws[:, i] for i, n in enumerate(continuous)} | {n: np.full(tries, v) for n, v in fixed.items()}
        ok = machine.feasible_mask(rows)
        if ok.any():
            feasible = draws[ok]
            scale = np.maximum(feasible.std(axis=0), 1e-12)
            middle = np.median(feasible, axis=0)
            best = feasible[np.argmin((((feasible - middle) / scale) ** 2).sum(axis=1))]
            return dict(fixed) | {n: float(v) for n, v in zip(continuous, best)}
        # shrink the box towards the defaults: feasible sets can be thin slivers of a large box
        defaults = machine.defaults()
        centre = np.array([defaults[n] for n in continuous])
        box = np.column_stack([centre - (centre - box[:, 0]) / 4, centre + (box[:, 1] - centre) / 4])
    design = machine.defaults() | fixed
    return design if machine.is_feasible(design) else None


def feasible_grid(machine, design: dict[str, float], values: int, resolution: int = 513) -> list[dict[str, float]]:
    """A grid of designs around ``design`` whose every point is feasible.

    The continuous parameters are fixed one at a time: the feasible interval of the next one (earlier ones as in
    the grid points found so far, later ones as in ``design``) is split into ``values`` equal cells and their
    midpoints are taken, so the last parameter's values are feasible given all the others. The intervals are the
    machine's slider bounds (:meth:`feasible_interval`), here found for all grid points of a level at once with
    the batch :meth:`feasible_mask` on ``resolution`` values across the parameter's box: the run of feasible values
    holding the current value (else the longest run), shrunk by one grid step so that cell midpoints stay inside.
    """
    names = list(machine.parameter_names)
    level = np.array([[design[n] for n in names]], dtype=float)
    for name in machine.continuous_names:
        column = names.index(name)
        parameter = machine.parameter(name)
        xs = np.linspace(parameter.lower, parameter.upper, resolution)
        trial = np.repeat(level, resolution, axis=0)
        trial[:, column] = np.tile(xs, len(level))
        ok = machine.feasible_mask(trial).reshape(len(level), resolution)
        children = []
        for row, mask in zip(level, ok):
            if not mask.any():
                continue
            edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
            starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
            at = int(np.clip(np.searchsorted(xs, row[column]), 0, resolution - 1))
            holding = np.flatnonzero((starts <= at) & (stops >= at))
            run = int(holding[0]) if holding.size else int(np.argmax(stops - starts))
            lo, hi = xs[starts[run]], xs[stops[run]]
            step = xs[1] - xs[0]
            if hi - lo > 2 * step:
                lo, hi = lo + step, hi - step
            for j in range(values):
                child = row.copy()
                child[column] = lo + (j + 0.5) * (hi - lo) / values
                children.append(child)
        if not children:
            return []
        level = np.array(children)
    level = level[machine.feasible_mask(level)]
    return [{n: float(v) for n, v in zip(names, row)} for row in level]


def _arclength_resample_batch(curves: np.ndarray, n: int) -> np.ndarray:
    """Resample ``(k, m, 2)`` closed curves (last point == first) to ``n`` points uniform in arc length."""
    out = np.empty((len(curves), n, 2))
    for i, curve in enumerate(curves):
        seg = np.linalg.norm(np.diff(curve, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        s = np.arange(n) * (cum[-1] / n)
        out[i, :, 0] = np.interp(s, cum, curve[:, 0])
        out[i, :, 1] = np.interp(s, cum, curve[:, 1])
    return out


def curve_spectra(machine, rows: np.ndarray, points: int, harmonics: int) -> np.ndarray:
    """Low spectra (:func:`low_spectrum`) of designs' curves ``(k, P)``, sampled as the database samples them.

    Dense time sampling, then uniform arc length: 3-4x cheaper than the model's exact arc-length sampling.
    """
    dense = machine.sample_many(rows, n=4 * points + 1, spacing="time", check=False)
    return low_spectrum(_arclength_resample_batch(dense, points), harmonics)


def build_database(machine, settings: DatabaseSettings | None = None,
                   report: Reporter | None = None) -> CandidateDatabase:
    """Sample a machine's candidate designs and their curves (see the module docstring).

    Parameters
    ----------
    machine : DrawingMachine
        The model (from :func:`design.machines.get_machine`).
    settings : DatabaseSettings, optional
        Sampling settings (:func:`default_settings` of the machine by default).
    report : Reporter, optional
        Called with a :class:`common.progress.Progress` per radii combination (stage ``"grid"``) and per chunk of
        curves (stage ``"curves"``); a stop asked for ends the build there with :class:`common.progress.Cancelled`.
    """
    report = Reporter.of(report)
    settings = settings or default_settings(machine.name)
    start = time.perf_counter()
    roles = radius_roles(machine)
    rng = np.random.default_rng(settings.seed)
    combos = radius_combinations(machine, settings.max_radius, settings.max_other_radius)
    names = machine.parameter_names
    if settings.sampling == "uniform":
        from design.machines.feasible_sampling import uniform_feasible

        params, _ = uniform_feasible(machine, np.array(combos), roles, settings.samples, rng, report=report)
    else:
        designs: list[dict[str, float]] = []
        for i, combo in enumerate(combos):
            fixed = dict(zip(roles, combo))
            anchor = _anchor(machine, fixed, rng)
            if anchor is not None:
                designs.extend(feasible_grid(machine, anchor, settings.values_per_dimension))
            report("grid", i + 1, len(combos), f"{machine.name}: grid {i + 1}/{len(combos)} radii")
        params = np.array([[d[n] for n in names] for d in designs], dtype=float).reshape(len(designs), len(names))
    if not len(params):
        raise CandidateDatabaseError(f"{machine.name}: no feasible design found with radii up to {settings.max_radius}")
    spectra = np.zeros((len(params), 2 * settings.harmonics + 1), dtype=np.complex64)
    chunk = max(1, 500_000 // (16 * settings.points))  # small chunks: the dense arc-length pass is memory bound
    for begin in range(0, len(params), chunk):
        rows = params[begin : begin + chunk]
        spectra[begin : begin + len(rows)] = curve_spectra(machine, rows, settings.points, settings.harmonics)
        done = begin + len(rows)
        report("curves", done, len(params), f"{machine.name}: curves {done}/{len(params)}")
    key = version_key(machine, settings)
    return CandidateDatabase(
        machine.name, names, roles, params, SpectrumBank(spectra), key, time.perf_counter() - start
    )


def cache_path(cache_dir: str | Path, machine_name: str, key: str) -> Path:
    """The cache file of one machine's database under one version key."""
    return Path(cache_dir) / "sketch" / f"candidates-{machine_name}-{key}.npz"


def save_database(database: CandidateDatabase, path: Path) -> None:
    """Write a database atomically (temporary file, then rename)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    meta = json.dumps(
        {
            "machine": database.machine,
            "parameter_names": list(database.parameter_names),
            "roles": list(database.roles),
            "key": database.key,
            "build_seconds": database.build_seconds,
        }
    )
    handle, temporary = tempfile.mkstemp(dir=path.parent, suffix=".npz.part")
    try:
        with os.fdopen(handle, "wb") as stream:
            np.savez(stream, params=database.params, spectra=database.bank.spectra, meta=meta)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def read_database(path: Path) -> CandidateDatabase:
    """Read a database written by :func:`save_database`."""
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            return CandidateDatabase(
                meta["machine"],
                tuple(meta["parameter_names"]),
                tuple(meta["roles"]),
                data["params"],
                SpectrumBank(data["spectra"]),
                meta["key"],
                float(meta.get("build_seconds", 0.0)),
            )
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as error:
        raise CandidateDatabaseError(f"candidate database {path}: unreadable ({error})") from None


def load_database(
    machine,
    cache_dir: str | Path | None,
    settings: DatabaseSettings | None = None,
    report: Reporter | None = None,
) -> CandidateDatabase:
    """A machine's candidate database from the cache, built and cached first if missing or stale.

    Parameters
    ----------
    machine : DrawingMachine
        The model.
    cache_dir : path or None
        Cache directory (the station passes ``station.paths.cache_dir()``); ``None`` builds without caching.
    settings : DatabaseSettings, optional
        Sampling settings.
    report : Reporter, optional
        Called with a :class:`common.progress.Progress`: stage ``"build"`` when a database is to be built (no
        total), then the stages of :func:`build_database` (which stops there when asked). A database read from the
        cache reports nothing.
    """
    report = Reporter.of(report)
    settings = settings or default_settings(machine.name)
    if cache_dir is None:
        return build_database(machine, settings, report)
    key = version_key(machine, settings)
    path = cache_path(cache_dir, machine.name, key)
    if path.exists():
        try:
            database = read_database(path)
            if database.key == key and database.machine == machine.name:
                return database
        except CandidateDatabaseError:
            pass  # a damaged cache file is rebuilt
    report("build", 0, None, f"{machine.name}: building candidate database (once; cached in {path.parent})")
    database = build_database(machine, settings, report)
    save_database(database, path)
    for stale in path.parent.glob(f"candidates-{machine.name}-*.npz"):
        if stale != path:
            stale.unlink(missing_ok=True)
    return database


__all__ = [
    "DATABASE_FORMAT",
    "CandidateDatabase",
    "DatabaseSettings",
    "build_database",
    "curve_spectra",
    "default_settings",
    "farey",
    "feasible_grid",
    "load_database",
    "radius_combinations",
    "radius_roles",
    "version_key",
]
