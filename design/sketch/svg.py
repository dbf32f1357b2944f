"""SVG sketches: a drawing's path data, shapes and transforms as strokes (see :func:`design.sketch.load_sketch`).

Curves (cubic and quadratic Béziers, elliptical arcs) are flattened into :data:`BEZIER_STEPS` points each; entity
declarations are refused (no billion laughs), as are files over :data:`~design.sketch.strokes.MAX_FILE_BYTES`.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import numpy as np

from design.sketch.errors import SketchFileError
from design.sketch.strokes import MAX_STROKES, Sketch, check_file_size, make_sketch, rotation

#: Points per curve segment when SVG Bezier curves and arcs are flattened.
BEZIER_STEPS = 16


def _read_text(path: Path, kind: str) -> str:
    check_file_size(path, kind)
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as error:
        raise SketchFileError(f"{path}: not UTF-8 text ({error.reason} at byte {error.start}); "
                              f"expected an {kind} sketch") from None


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


def load_svg(path: Path, symmetry: int | None, center: object) -> Sketch:
    """A sketch from an SVG file: every path, polyline, polygon, line, circle and ellipse (transforms applied) is a
    stroke, flipped to y up; the centre defaults to the view box's (see :func:`design.sketch.strokes.load_sketch`)."""
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
