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
import json
import os
import sys
import tempfile
import time
import zipfile
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from design.errors import DesignError
from design.sketch.distance import DEFAULT_HARMONICS, SpectrumBank, low_spectrum
from design.sketch.errors import CandidateDatabaseError, RetrievalSettingError
from design.sketch.fourier import RadiiHypothesis

#: Bump when the database layout or the way it is built changes.
DATABASE_FORMAT = 3

Progress = Callable[[str, float], None]


@dataclass(frozen=True)
class DatabaseSettings:
    """How a machine's candidates are sampled.

    Parameters
    ----------
    max_radius : int
        Order ``n`` of the Farey sequence: every gear radius is at most this.
    values_per_dimension : int
        Grid values per continuous parameter.
    points : int
        Points per curve (uniform in arc length) before the spectrum is taken.
    harmonics : int
        Harmonics kept per curve.
    seed : int
        Seed of the random search for a feasible anchor design per radii combination.
    """

    max_radius: int = 8
    values_per_dimension: int = 4
    points: int = 1024
    harmonics: int = DEFAULT_HARMONICS
    seed: int = 0

    def __post_init__(self) -> None:
        checks = [
            ("max_radius", self.max_radius, 1, 40),
            ("values_per_dimension", self.values_per_dimension, 1, 12),
            ("points", self.points, 64, 8192),
            ("harmonics", self.harmonics, 4, 1024),
        ]
        for name, value, lo, hi in checks:
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
                raise RetrievalSettingError(
                    f"candidate database: {name} must be an integer in [{lo}, {hi}], got {value!r}"
                )
        if 2 * self.harmonics + 1 > self.points:
            raise RetrievalSettingError(
                f"candidate database: harmonics must be below points / 2 = {self.points // 2}, got {self.harmonics}"
            )


#: Default settings per machine: richer radii for the cheap machines, smaller for the Hoot-Nanny whose five
#: continuous parameters already give 4^5 = 1024 designs per radii triple.
DEFAULT_SETTINGS: dict[str, DatabaseSettings] = {
    "spirograph": DatabaseSettings(max_radius=12),
    "elliptic_spirograph": DatabaseSettings(max_radius=10),
    "cycloid_drawing_machine": DatabaseSettings(max_radius=7),
    "hoot_nanny": DatabaseSettings(max_radius=4),
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


def radius_combinations(machine, max_radius: int) -> list[tuple[int, ...]]:
    """Coprime radii combinations in role order (see :func:`radius_roles`) within the parameters' bounds.

    Two gears: every Farey fraction ``a/b`` of ``F_n`` in both orientations. More gears: every other gear is coprime
    with the leading one (A.62), each pair again a Farey fraction.
    """
    roles = radius_roles(machine)
    pairs = set()
    for a, b in farey(max_radius):
        pairs.add((a, b))
        pairs.add((b, a))
    bounds = [(machine.parameter(n).lower, machine.parameter(n).upper) for n in roles]
    combos: list[tuple[int, ...]] = []
    if len(roles) == 1:
        combos = [(r,) for r in range(1, max_radius + 1)]
    elif len(roles) == 2:
        combos = sorted(pairs)
    else:
        by_lead: dict[int, list[int]] = {}
        for lead, other in sorted(pairs):
            by_lead.setdefault(lead, []).append(other)
        import itertools

        for lead, others in sorted(by_lead.items()):
            for rest in itertools.product(others, repeat=len(roles) - 1):
                combos.append((lead,) + rest)
    return [c for c in combos if all(lo <= r <= hi for r, (lo, hi) in zip(c, bounds))]


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
    """The cache key: database format, settings and model fingerprint."""
    payload = json.dumps(
        {"format": DATABASE_FORMAT, "settings": asdict(settings), "model": model_fingerprint(machine)}, sort_keys=True
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
    radii : ndarray
        ``(M, G)`` integer radii in role order.
    bank : SpectrumBank
        Curve spectra, row-aligned with :attr:`params`.
    key : str
        Version key it was built under.
    build_seconds : float
        Time it took to build (0 when loaded from the cache is not known).
    """

    machine: str
    parameter_names: tuple[str, ...]
    roles: tuple[str, ...]
    params: np.ndarray
    radii: np.ndarray
    bank: SpectrumBank
    key: str
    build_seconds: float = 0.0

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


def feasible_grid(machine, design: dict[str, float], values: int) -> list[dict[str, float]]:
    """A grid of designs around ``design`` whose every point is feasible.

    The continuous parameters are fixed one at a time: the feasible interval of the next one (others as in the
    designs found so far, later ones as in ``design``) is split into ``values`` equal cells and their midpoints are
    taken, so the last parameter's values are always feasible given all the others.
    """
    level = [dict(design)]
    for name in machine.continuous_names:
        nxt = []
        for point in level:
            try:
                lo, hi = machine.feasible_interval(point, name, grid=65, tolerance=1e-7)
            except DesignError:
                continue
            for j in range(values):
                nxt.append(point | {name: lo + (j + 0.5) * (hi - lo) / values})
        level = nxt
    return [p for p in level if machine.is_feasible(p)]


def build_database(
    machine, settings: DatabaseSettings | None = None, progress: Progress | None = None
) -> CandidateDatabase:
    """Sample a machine's candidate designs and their curves (see the module docstring).

    Parameters
    ----------
    machine : DrawingMachine
        The model (from :func:`design.machines.get_machine`).
    settings : DatabaseSettings, optional
        Sampling settings (:func:`default_settings` of the machine by default).
    progress : callable, optional
        ``progress(message, fraction)`` called as the build goes.
    """
    settings = settings or default_settings(machine.name)
    start = time.perf_counter()
    roles = radius_roles(machine)
    rng = np.random.default_rng(settings.seed)
    combos = radius_combinations(machine, settings.max_radius)
    designs: list[dict[str, float]] = []
    for i, combo in enumerate(combos):
        fixed = dict(zip(roles, combo))
        anchor = _anchor(machine, fixed, rng)
        if anchor is not None:
            designs.extend(feasible_grid(machine, anchor, settings.values_per_dimension))
        if progress:
            progress(f"{machine.name}: grid {i + 1}/{len(combos)} radii", 0.3 * (i + 1) / len(combos))
    if not designs:
        raise CandidateDatabaseError(f"{machine.name}: no feasible design found with radii up to {settings.max_radius}")
    names = machine.parameter_names
    params = np.array([[d[n] for n in names] for d in designs], dtype=float)
    radii = np.rint(params[:, [names.index(r) for r in roles]]).astype(np.int64)
    spectra = np.zeros((len(params), 2 * settings.harmonics + 1), dtype=np.complex64)
    chunk = max(1, 2_000_000 // (16 * settings.points))
    for begin in range(0, len(params), chunk):
        rows = params[begin : begin + chunk]
        curves = machine.sample_many(rows, n=settings.points + 1, spacing="arclength", check=False)[:, :-1]
        spectra[begin : begin + len(rows)] = low_spectrum(curves, settings.harmonics)
        if progress:
            progress(
                f"{machine.name}: curves {begin + len(rows)}/{len(params)}",
                0.3 + 0.7 * (begin + len(rows)) / len(params),
            )
    key = version_key(machine, settings)
    return CandidateDatabase(
        machine.name, names, roles, params, radii, SpectrumBank(spectra), key, time.perf_counter() - start
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
            np.savez(stream, params=database.params, radii=database.radii, spectra=database.bank.spectra, meta=meta)
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
                data["radii"],
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
    progress: Progress | None = None,
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
    progress : callable, optional
        ``progress(message, fraction)``.
    """
    settings = settings or default_settings(machine.name)
    if cache_dir is None:
        return build_database(machine, settings, progress)
    key = version_key(machine, settings)
    path = cache_path(cache_dir, machine.name, key)
    if path.exists():
        try:
            database = read_database(path)
            if database.key == key and database.machine == machine.name:
                return database
        except CandidateDatabaseError:
            pass  # a damaged cache file is rebuilt
    if progress:
        progress(f"{machine.name}: building candidate database (once; cached in {path.parent})", 0.0)
    database = build_database(machine, settings, progress)
    save_database(database, path)
    for stale in path.parent.glob(f"candidates-{machine.name}-*.npz"):
        if stale != path:
            stale.unlink(missing_ok=True)
    return database


def stderr_progress(message: str, fraction: float) -> None:
    """A simple progress reporter on stderr (for command-line use)."""
    print(f"\r{message} ({100 * fraction:3.0f}%)", end="\n" if fraction >= 1 else "", file=sys.stderr, flush=True)


__all__ = [
    "DATABASE_FORMAT",
    "CandidateDatabase",
    "DatabaseSettings",
    "build_database",
    "default_settings",
    "farey",
    "feasible_grid",
    "load_database",
    "radius_combinations",
    "radius_roles",
    "version_key",
]
