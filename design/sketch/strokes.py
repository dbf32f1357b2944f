"""Sketch input: strokes (from a file, :mod:`design.sketch.files`, or from a drawing pad), validated, and symmetrized.

A sketch is a few rough strokes (polylines) of the pattern a maker wants, optionally with a rotational symmetry
order ``k``: with ``k > 1`` every stroke is copied ``k`` times around the sketch centre (thesis, section 3.4.1).

Coordinates are mathematical (y up). SVG files are in screen coordinates (y down); they are flipped on load so that
a pattern keeps its handedness.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from design.sketch.errors import RetrievalSettingError, SketchError, SketchFileError

#: Largest sketch file read (bytes). A hand-drawn sketch is a few kilobytes; anything this big is not one.
MAX_FILE_BYTES = 2_000_000
#: Most strokes in one sketch (before symmetry copies).
MAX_STROKES = 500
#: Most points over all strokes (before symmetry copies).
MAX_POINTS = 200_000
#: Largest coordinate accepted (any unit): beyond, squared distances overflow.
MAX_COORDINATE = 1e12
#: Largest symmetry order accepted.
MAX_SYMMETRY = 64


@dataclass(frozen=True)
class Sketch:
    """Validated strokes of a sketch.

    Parameters
    ----------
    strokes : tuple of ndarray
        Each an ``(n, 2)`` float array, ``n >= 1``, finite, without consecutive duplicate points.
    symmetry : int
        Rotational symmetry order ``k >= 1`` (1: no symmetry).
    center : ndarray
        Centre of the symmetry copies, ``(2,)``.
    source : str
        Where the sketch came from, for messages.
    """

    strokes: tuple[np.ndarray, ...]
    symmetry: int = 1
    center: np.ndarray = field(default_factory=lambda: np.zeros(2))
    source: str = "sketch"

    @property
    def n_points(self) -> int:
        """Number of points over all strokes."""
        return int(sum(len(s) for s in self.strokes))

    def with_symmetry(self, symmetry: int | None, center: tuple[float, float] | np.ndarray | None = None) -> Sketch:
        """The same strokes with another symmetry order and/or centre (``None`` keeps the current one)."""
        k = self.symmetry if symmetry is None else check_symmetry(symmetry)
        c = self.center if center is None else _check_center(center, self.source)
        return Sketch(self.strokes, k, c, self.source)

    def symmetrized(self) -> list[np.ndarray]:
        """The strokes and their ``k - 1`` rotated copies around :attr:`center`, copies that coincide removed."""
        return symmetrize(list(self.strokes), self.symmetry, self.center)


def check_symmetry(symmetry: object) -> int:
    """A symmetry order as an int in ``[1, MAX_SYMMETRY]``, or :class:`RetrievalSettingError`."""
    if isinstance(symmetry, bool) or not isinstance(symmetry, (int, np.integer, float)):
        raise RetrievalSettingError(
            f"sketch: symmetry order must be an integer in [1, {MAX_SYMMETRY}], got {symmetry!r}"
        )
    if isinstance(symmetry, float) and not symmetry.is_integer():
        raise RetrievalSettingError(
            f"sketch: symmetry order must be an integer in [1, {MAX_SYMMETRY}], got {symmetry!r}"
        )
    k = int(symmetry)
    if not 1 <= k <= MAX_SYMMETRY:
        raise RetrievalSettingError(f"sketch: symmetry order must be an integer in [1, {MAX_SYMMETRY}], got {k}")
    return k


def _check_center(center: object, source: str) -> np.ndarray:
    try:
        c = np.asarray(center, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise SketchError(f"{source}: center must be two numbers [x, y], got {center!r}") from None
    if c.shape != (2,) or not np.all(np.isfinite(c)):
        raise SketchError(f"{source}: center must be two finite numbers [x, y], got {center!r}")
    return c


def make_sketch(
    strokes: object,
    symmetry: int | None = 1,
    center: object = None,
    source: str = "sketch",
) -> Sketch:
    """Validate raw strokes into a :class:`Sketch`.

    Parameters
    ----------
    strokes : sequence of sequences of [x, y]
        The strokes; a single stroke may also be given as an ``(n, 2)`` array inside a list.
    symmetry : int, optional
        Rotational symmetry order (``None`` or 1: none).
    center : [x, y], optional
        Centre of the symmetry copies; the origin when not given.
    source : str
        Name used in error messages (a file name, ``"sketch pad"``, ...).

    Raises
    ------
    SketchError
        Empty sketch, a point that is not two finite numbers, too many strokes or points, all points coincident or
        on one line, every stroke a copy of another.
    """
    k = 1 if symmetry is None else check_symmetry(symmetry)
    c = np.zeros(2) if center is None else _check_center(center, source)
    if isinstance(strokes, np.ndarray) and strokes.ndim == 2:
        strokes = [strokes]
    if not isinstance(strokes, (list, tuple)):
        raise SketchError(
            f"{source}: strokes must be a list of strokes (each a list of [x, y]), got {type(strokes).__name__}"
        )
    if len(strokes) == 0:
        raise SketchError(f"{source}: the sketch is empty; expected at least one stroke of [x, y] points")
    if len(strokes) > MAX_STROKES:
        raise SketchError(f"{source}: {len(strokes)} strokes is too many; expected at most {MAX_STROKES}")
    clean: list[np.ndarray] = []
    total = 0
    for index, stroke in enumerate(strokes):
        points = _stroke_array(stroke, index, source)
        total += len(points)
        if total > MAX_POINTS:
            raise SketchError(f"{source}: more than {MAX_POINTS} points; expected a hand-drawn sketch, resample it")
        if len(points) == 0:
            continue
        keep = np.ones(len(points), dtype=bool)
        keep[1:] = np.any(np.diff(points, axis=0) != 0.0, axis=1)
        clean.append(points[keep])
    if not clean:
        raise SketchError(f"{source}: every stroke is empty; expected at least one stroke of [x, y] points")
    clean = _drop_duplicate_strokes(clean)
    allpoints = np.concatenate(clean)
    distinct = np.unique(allpoints, axis=0)
    if len(distinct) < 2:
        raise SketchError(
            f"{source}: the sketch is a single point {distinct[0].tolist()}; expected strokes that outline a pattern"
        )
    _check_extent(np.concatenate(symmetrize(clean, k, c)), source, k)
    return Sketch(tuple(clean), k, c, source)


def _stroke_array(stroke: object, index: int, source: str) -> np.ndarray:
    where = f"{source}: stroke {index}"
    if isinstance(stroke, dict):
        stroke = stroke.get("points", stroke.get("stroke"))
    try:
        points = np.asarray(stroke, dtype=float)
    except (TypeError, ValueError):
        raise SketchError(f"{where} must be a list of [x, y] number pairs, got {_short(stroke)}") from None
    if points.size == 0:
        return np.zeros((0, 2))
    if points.ndim != 2 or points.shape[1] != 2:
        raise SketchError(f"{where} must be a list of [x, y] number pairs, got {_short(stroke)}")
    bad = ~np.all(np.isfinite(points), axis=1)
    if np.any(bad):
        first = int(np.argmax(bad))
        raise SketchError(f"{where}, point {first}: coordinates must be finite numbers, got {points[first].tolist()}")
    huge = np.any(np.abs(points) > MAX_COORDINATE, axis=1)
    if np.any(huge):
        first = int(np.argmax(huge))
        raise SketchError(
            f"{where}, point {first}: coordinates must be at most {MAX_COORDINATE:g} in size, "
            f"got {points[first].tolist()}"
        )
    return points


def _short(value: object, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _drop_duplicate_strokes(strokes: list[np.ndarray]) -> list[np.ndarray]:
    """Drop strokes identical to an earlier one (also when drawn backwards): tracing twice means nothing more."""
    kept: list[np.ndarray] = []
    for stroke in strokes:
        duplicate = any(
            other.shape == stroke.shape and (np.array_equal(other, stroke) or np.array_equal(other[::-1], stroke))
            for other in kept
        )
        if not duplicate:
            kept.append(stroke)
    return kept


def _check_extent(points: np.ndarray, source: str, k: int) -> None:
    centred = points - points.mean(axis=0)
    singular = np.linalg.svd(centred, compute_uv=False)
    if singular[0] <= 1e-12 * max(1.0, float(np.abs(points).max())):
        raise SketchError(f"{source}: all points coincide; expected strokes that outline a pattern")
    if len(singular) < 2 or singular[1] <= 1e-9 * singular[0]:
        hint = "" if k > 1 else " (or give a symmetry order)"
        raise SketchError(f"{source}: all points lie on one straight line; expected a closed 2D pattern{hint}")


def rotation(angle: float) -> np.ndarray:
    """The 2x2 matrix of a rotation by ``angle`` radians."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s], [s, c]])


def symmetrize(strokes: list[np.ndarray], k: int, center: np.ndarray) -> list[np.ndarray]:
    """Copy each stroke ``k`` times by rotations of ``2 pi j / k`` around ``center``; copies that retrace kept
    strokes are dropped.

    A copy retraces a kept stroke when a stroke is itself symmetric (e.g. a whole circle around the centre drawn
    with ``k`` given): 90 % of its points lie within half a point spacing of the kept strokes' points. Keeping it
    would make the closed tour go round the same curve ``k`` times.
    """
    from scipy.spatial import cKDTree

    if k <= 1:
        return [np.asarray(s, dtype=float) for s in strokes]
    center = np.asarray(center, dtype=float)
    kept: list[np.ndarray] = []
    tree = None
    for j in range(k):
        rot = rotation(2.0 * math.pi * j / k)
        for stroke in strokes:
            copy = (stroke - center) @ rot.T + center
            if tree is not None and len(copy) >= 2:
                spacing = np.median(np.linalg.norm(np.diff(copy, axis=0), axis=1))
                near, _ = tree.query(copy, distance_upper_bound=0.5 * spacing + 1e-12)
                if np.mean(np.isfinite(near)) >= 0.9:
                    continue
            kept.append(copy)
        tree = cKDTree(np.concatenate(kept))
    return kept


# ------------------------------------------------------------------------------------------------------ file size


def check_file_size(path: Path, kind: str) -> None:
    """Refuse a sketch file larger than :data:`MAX_FILE_BYTES` before reading it."""
    size = path.stat().st_size
    if size > MAX_FILE_BYTES:
        raise SketchFileError(
            f"{path}: {kind} sketch of {size / 1e6:.1f} MB is too large; "
            f"expected at most {MAX_FILE_BYTES / 1e6:.0f} MB (a hand-drawn sketch is a few kilobytes)"
        )
