"""Sketch input: strokes from JSON or SVG files or from a drawing pad, validated, and symmetrized.

A sketch is a few rough strokes (polylines) of the pattern a maker wants, optionally with a rotational symmetry
order ``k``: with ``k > 1`` every stroke is copied ``k`` times around the sketch centre (thesis, section 3.4.1).

Coordinates are mathematical (y up). SVG files are in screen coordinates (y down); they are flipped on load so that
a pattern keeps its handedness.
"""

from __future__ import annotations

import json
import math
import re
import xml.etree.ElementTree as ElementTree
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
#: Points per curve segment when SVG Bezier curves and arcs are flattened.
BEZIER_STEPS = 16


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


# ----------------------------------------------------------------------------------------------------------- files


def _read_text(path: Path, kind: str) -> str:
    size = path.stat().st_size
    if size > MAX_FILE_BYTES:
        raise SketchFileError(
            f"{path}: {kind} sketch of {size / 1e6:.1f} MB is too large; "
            f"expected at most {MAX_FILE_BYTES / 1e6:.0f} MB (a hand-drawn sketch is a few kilobytes)"
        )
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as error:
        raise SketchFileError(f"{path}: not UTF-8 text ({error.reason} at byte {error.start})") from None


def load_sketch(path: str | Path, symmetry: int | None = None, center: object = None) -> Sketch:
    """Read a sketch from a ``.json`` or ``.svg`` file.

    Parameters
    ----------
    path : path
        The file. JSON: either a list of strokes (each a list of ``[x, y]``) or an object
        ``{"strokes": [...], "symmetry": k, "center": [x, y]}``. SVG: every ``path``, ``polyline``, ``polygon``,
        ``line``, ``circle`` and ``ellipse`` element (with their transforms) is a stroke.
    symmetry : int, optional
        Overrides the file's symmetry order.
    center : [x, y], optional
        Overrides the file's centre (JSON default: the origin; SVG default: the centre of the view box).

    Raises
    ------
    SketchFileError
        Unknown extension, file too large, malformed JSON / SVG (message names the file and field).
    SketchError
        The strokes themselves are unusable (see :func:`make_sketch`).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".json":
        return _load_json(path, symmetry, center)
    if suffix == ".svg":
        return _load_svg(path, symmetry, center)
    raise SketchFileError(f"{path}: unknown sketch format {suffix or 'none'!r}; expected .json or .svg")


def _load_json(path: Path, symmetry: int | None, center: object) -> Sketch:
    text = _read_text(path, "JSON")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as error:
        raise SketchFileError(
            f"{path}: invalid JSON at line {error.lineno} column {error.colno}: {error.msg}"
        ) from None
    except RecursionError:
        raise SketchFileError(f"{path}: invalid JSON: arrays nested too deeply to read") from None
    file_symmetry: object = None
    file_center: object = None
    if isinstance(data, dict):
        unknown = sorted(set(data) - {"strokes", "symmetry", "center", "comment", "title"})
        if unknown:
            raise SketchFileError(f"{path}: unknown field(s) {unknown}; expected strokes, symmetry, center")
        if "strokes" not in data:
            raise SketchFileError(f"{path}: field 'strokes' is missing; expected a list of strokes of [x, y] points")
        strokes = data["strokes"]
        file_symmetry = data.get("symmetry")
        file_center = data.get("center")
    elif isinstance(data, list):
        strokes = data
    else:
        raise SketchFileError(
            f"{path}: expected a list of strokes or an object with 'strokes', got {type(data).__name__}"
        )
    if not isinstance(strokes, list):
        raise SketchFileError(f"{path}: field 'strokes' must be a list of strokes, got {type(strokes).__name__}")
    if file_symmetry is not None and symmetry is None:
        try:
            check_symmetry(file_symmetry)
        except RetrievalSettingError as error:
            raise SketchFileError(f"{path}: field 'symmetry': {error}") from None
    k = symmetry if symmetry is not None else file_symmetry
    c = center if center is not None else file_center
    return make_sketch(strokes, symmetry=k, center=c, source=str(path))


# ------------------------------------------------------------------------------------------------------------- SVG

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_TOKEN = re.compile(rf"([MmLlHhVvCcSsQqTtAaZz])|({_NUMBER})")
_TRANSFORM = re.compile(r"(matrix|translate|scale|rotate|skewX|skewY)\s*\(([^)]*)\)")
_ARGS = {"M": 2, "L": 2, "H": 1, "V": 1, "C": 6, "S": 4, "Q": 4, "T": 2, "A": 7, "Z": 0}


def _svg_float(text: str | None, where: str, default: float | None = None) -> float:
    if text is None:
        if default is None:
            raise SketchFileError(f"{where} is missing")
        return default
    match = re.match(rf"\s*({_NUMBER})", text)
    if not match:
        raise SketchFileError(f"{where} must be a number, got {text!r}")
    return float(match.group(1))


def _parse_transform(text: str | None, where: str) -> np.ndarray:
    """The 3x3 affine matrix of an SVG ``transform`` attribute."""
    matrix = np.eye(3)
    if not text:
        return matrix
    for name, args in _TRANSFORM.findall(text):
        values = [float(v) for v in re.findall(_NUMBER, args)]
        m = np.eye(3)
        try:
            if name == "matrix":
                a, b, c, d, e, f = values
                m = np.array([[a, c, e], [b, d, f], [0, 0, 1]])
            elif name == "translate":
                m[0, 2] = values[0]
                m[1, 2] = values[1] if len(values) > 1 else 0.0
            elif name == "scale":
                m[0, 0] = values[0]
                m[1, 1] = values[1] if len(values) > 1 else values[0]
            elif name == "rotate":
                angle = math.radians(values[0])
                r = np.eye(3)
                r[:2, :2] = rotation(angle)
                if len(values) == 3:
                    cx, cy = values[1], values[2]
                    t1, t2 = np.eye(3), np.eye(3)
                    t1[:2, 2] = (cx, cy)
                    t2[:2, 2] = (-cx, -cy)
                    r = t1 @ r @ t2
                m = r
            elif name == "skewX":
                m[0, 1] = math.tan(math.radians(values[0]))
            elif name == "skewY":
                m[1, 0] = math.tan(math.radians(values[0]))
        except (ValueError, IndexError):
            raise SketchFileError(f"{where}: transform {name}({args}) has the wrong number of values") from None
        matrix = matrix @ m
    return matrix


def _cubic(p0, p1, p2, p3) -> np.ndarray:
    t = np.linspace(0.0, 1.0, BEZIER_STEPS + 1)[1:, None]
    return (1 - t) ** 3 * p0 + 3 * (1 - t) ** 2 * t * p1 + 3 * (1 - t) * t**2 * p2 + t**3 * p3


def _quadratic(p0, p1, p2) -> np.ndarray:
    t = np.linspace(0.0, 1.0, BEZIER_STEPS + 1)[1:, None]
    return (1 - t) ** 2 * p0 + 2 * (1 - t) * t * p1 + t**2 * p2


def _arc(p0, rx, ry, phi_deg, large, sweep, p1) -> np.ndarray:
    """Points of an SVG elliptical arc (endpoint parameterization, SVG 1.1 appendix F.6)."""
    if rx == 0 or ry == 0 or np.allclose(p0, p1):
        return np.asarray([p1])
    rx, ry = abs(rx), abs(ry)
    phi = math.radians(phi_deg)
    cos_p, sin_p = math.cos(phi), math.sin(phi)
    dx, dy = (p0 - p1) / 2.0
    x1 = cos_p * dx + sin_p * dy
    y1 = -sin_p * dx + cos_p * dy
    scale = (x1 / rx) ** 2 + (y1 / ry) ** 2
    if scale > 1:
        rx, ry = rx * math.sqrt(scale), ry * math.sqrt(scale)
    num = rx**2 * ry**2 - rx**2 * y1**2 - ry**2 * x1**2
    den = rx**2 * y1**2 + ry**2 * x1**2
    coef = math.sqrt(max(num, 0.0) / den) if den > 0 else 0.0
    if large == sweep:
        coef = -coef
    cxp, cyp = coef * rx * y1 / ry, -coef * ry * x1 / rx
    cx = cos_p * cxp - sin_p * cyp + (p0[0] + p1[0]) / 2
    cy = sin_p * cxp + cos_p * cyp + (p0[1] + p1[1]) / 2
    theta1 = math.atan2((y1 - cyp) / ry, (x1 - cxp) / rx)
    theta2 = math.atan2((-y1 - cyp) / ry, (-x1 - cxp) / rx)
    delta = theta2 - theta1
    if sweep and delta < 0:
        delta += 2 * math.pi
    elif not sweep and delta > 0:
        delta -= 2 * math.pi
    t = theta1 + delta * np.linspace(0.0, 1.0, 2 * BEZIER_STEPS + 1)[1:]
    x = cx + rx * np.cos(t) * cos_p - ry * np.sin(t) * sin_p
    y = cy + rx * np.cos(t) * sin_p + ry * np.sin(t) * cos_p
    return np.column_stack([x, y])


def parse_path_data(d: str, where: str) -> list[np.ndarray]:
    """Polylines of an SVG path ``d`` attribute (one per subpath); curves and arcs are flattened."""
    tokens = _TOKEN.findall(d)
    rest = _TOKEN.sub("", d).replace(",", " ").strip()
    if rest:
        raise SketchFileError(f"{where}: unexpected text {rest[:20]!r} in path data")
    subpaths: list[np.ndarray] = []
    current: list[np.ndarray] = []
    pos = np.zeros(2)
    start = np.zeros(2)
    last_control: np.ndarray | None = None
    last_command = ""
    command = ""
    i = 0
    while i < len(tokens):
        letter, number = tokens[i]
        if letter:
            command = letter
            i += 1
            if command in "Zz":
                if current:
                    current.append(start.copy()[None])
                    subpaths.append(np.concatenate(current))
                    current = []
                pos = start.copy()
                last_command = "Z"
                continue
        elif not command:
            raise SketchFileError(f"{where}: path data must start with a command letter, got {number!r}")
        upper = command.upper()
        nargs = _ARGS[upper]
        args = []
        for _ in range(nargs):
            if i >= len(tokens) or tokens[i][0]:
                raise SketchFileError(f"{where}: command {command!r} expects {nargs} numbers")
            args.append(float(tokens[i][1]))
            i += 1
        relative = command.islower()
        base = pos if relative else np.zeros(2)
        if upper == "M":
            if current:
                subpaths.append(np.concatenate(current))
            pos = base + args
            start = pos.copy()
            current = [pos[None].copy()]
            command = "l" if relative else "L"  # further pairs are implicit line-tos
            last_control = None
        elif upper in "LHVT":
            if upper == "L":
                new = base + args
            elif upper == "H":
                new = np.array([args[0] + (pos[0] if relative else 0.0), pos[1]])
            elif upper == "V":
                new = np.array([pos[0], args[0] + (pos[1] if relative else 0.0)])
            else:
                control = 2 * pos - last_control if last_command in "QT" and last_control is not None else pos
                new = base + args
                current.append(_quadratic(pos, control, new))
                last_control = control
                pos = new
                last_command = upper
                continue
            current.append(new[None])
            pos = new
            last_control = None
        elif upper in "CS":
            if upper == "C":
                c1, c2, new = base + args[0:2], base + args[2:4], base + args[4:6]
            else:
                c1 = 2 * pos - last_control if last_command in "CS" and last_control is not None else pos
                c2, new = base + args[0:2], base + args[2:4]
            if not current:
                current = [pos[None].copy()]
            current.append(_cubic(pos, c1, c2, new))
            last_control, pos = c2, new
        elif upper == "Q":
            c1, new = base + args[0:2], base + args[2:4]
            if not current:
                current = [pos[None].copy()]
            current.append(_quadratic(pos, c1, new))
            last_control, pos = c1, new
        elif upper == "A":
            new = base + args[5:7]
            if not current:
                current = [pos[None].copy()]
            current.append(_arc(pos, args[0], args[1], args[2], bool(args[3]), bool(args[4]), new))
            pos = new
            last_control = None
        last_command = upper
    if current:
        subpaths.append(np.concatenate(current))
    return subpaths


def _points_attribute(text: str | None, where: str) -> np.ndarray:
    values = [float(v) for v in re.findall(_NUMBER, text or "")]
    if len(values) % 2:
        raise SketchFileError(f"{where}: attribute 'points' must hold x,y pairs, got an odd count {len(values)}")
    return np.asarray(values, dtype=float).reshape(-1, 2)


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _load_svg(path: Path, symmetry: int | None, center: object) -> Sketch:
    text = _read_text(path, "SVG")
    if "<!ENTITY" in text:
        raise SketchFileError(f"{path}: SVG with entity declarations is not accepted; expected a plain SVG drawing")
    try:
        root = ElementTree.fromstring(text)
    except ElementTree.ParseError as error:
        raise SketchFileError(f"{path}: invalid SVG/XML: {error}") from None
    if _local(root.tag) != "svg":
        raise SketchFileError(f"{path}: root element must be <svg>, got <{_local(root.tag)}>")
    strokes: list[np.ndarray] = []

    def visit(element: ElementTree.Element, matrix: np.ndarray, depth: int) -> None:
        tag = _local(element.tag)
        where = f"{path}: <{tag}> #{len(strokes)}"
        if tag in {"defs", "clipPath", "mask", "symbol", "metadata", "title", "desc", "style", "text"}:
            return
        matrix = matrix @ _parse_transform(element.get("transform"), where)
        found: list[np.ndarray] = []
        if tag == "path":
            found = parse_path_data(element.get("d", ""), where)
        elif tag in {"polyline", "polygon"}:
            pts = _points_attribute(element.get("points"), where)
            if tag == "polygon" and len(pts):
                pts = np.vstack([pts, pts[:1]])
            found = [pts]
        elif tag == "line":
            found = [
                np.array(
                    [
                        [
                            _svg_float(element.get("x1"), f"{where} x1", 0.0),
                            _svg_float(element.get("y1"), f"{where} y1", 0.0),
                        ],
                        [
                            _svg_float(element.get("x2"), f"{where} x2", 0.0),
                            _svg_float(element.get("y2"), f"{where} y2", 0.0),
                        ],
                    ]
                )
            ]
        elif tag in {"circle", "ellipse"}:
            cx = _svg_float(element.get("cx"), f"{where} cx", 0.0)
            cy = _svg_float(element.get("cy"), f"{where} cy", 0.0)
            if tag == "circle":
                rx = ry = _svg_float(element.get("r"), f"{where} r")
            else:
                rx = _svg_float(element.get("rx"), f"{where} rx")
                ry = _svg_float(element.get("ry"), f"{where} ry")
            angle = np.linspace(0.0, 2 * np.pi, 4 * BEZIER_STEPS + 1)
            found = [np.column_stack([cx + rx * np.cos(angle), cy + ry * np.sin(angle)])]
        for pts in found:
            if len(pts):
                homogeneous = np.column_stack([pts, np.ones(len(pts))]) @ matrix.T
                strokes.append(homogeneous[:, :2])
                if len(strokes) > MAX_STROKES:
                    raise SketchFileError(f"{path}: more than {MAX_STROKES} strokes; expected a hand-drawn sketch")
        if depth < 64:
            for child in element:
                visit(child, matrix, depth + 1)

    visit(root, np.eye(3), 0)
    if not strokes:
        raise SketchFileError(f"{path}: no strokes found; expected <path>, <polyline>, <polygon> or <line> elements")
    flip = np.array([1.0, -1.0])  # SVG y points down; a sketch is y up
    strokes = [s * flip for s in strokes]
    if center is None:
        view_box = [float(v) for v in re.findall(_NUMBER, root.get("viewBox", ""))]
        if len(view_box) == 4:
            center = [view_box[0] + view_box[2] / 2, -(view_box[1] + view_box[3] / 2)]
        elif root.get("width") and root.get("height"):
            center = [_svg_float(root.get("width"), "width") / 2, -_svg_float(root.get("height"), "height") / 2]
        else:
            allpts = np.concatenate(strokes)
            center = ((allpts.min(axis=0) + allpts.max(axis=0)) / 2).tolist()
    return make_sketch(strokes, symmetry=symmetry, center=center, source=str(path))
