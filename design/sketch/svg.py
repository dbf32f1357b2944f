"""SVG sketches: a drawing's shapes as strokes (see :func:`design.sketch.load_sketch`), read by svgelements.

svgelements (the reader vpype plots SVG with) resolves what drawing programs write: ``<use>`` references, ``<rect>``,
``<circle>``, ``<ellipse>``, ``<line>``, ``<polyline>``, ``<polygon>`` and paths, transforms on every group, CSS
styles, units (``width="210mm"``) and the view box; hidden elements (``display:none``, ``visibility:hidden``: an
Inkscape layer switched off) are left out, as are ``<text>``, ``<defs>`` and clip paths. A sketch is in millimetres
when the drawing's size is given in physical units (mm, cm, in, pt, pc; Inkscape's default), else in the drawing's
pixels (CSS px, its view box's units when it has no size), y up.

Curves (cubic and quadratic Béziers, elliptical arcs) are flattened into :data:`BEZIER_STEPS` points each (arcs twice
as many); entity declarations are refused (no billion laughs), as are files over
:data:`~design.sketch.strokes.MAX_FILE_BYTES`. Path data is checked first by a small tokenizer of our own: svgelements
reads a broken ``d`` up to the error without a word, and a sketch should say what is wrong with it.
"""

from __future__ import annotations

import io
import re
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import numpy as np
import svgelements

from design.sketch.errors import SketchFileError
from design.sketch.strokes import MAX_STROKES, Sketch, check_file_size, make_sketch

#: Points per curve segment when SVG Bezier curves are flattened (elliptical arcs get twice as many).
BEZIER_STEPS = 16

#: Millimetres per physical unit of a drawing's size.
_MM_PER_UNIT = {"mm": 1.0, "cm": 10.0, "q": 0.25, "in": 25.4, "pt": 25.4 / 72, "pc": 25.4 / 6}

_PHYSICAL = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(mm|cm|in|pt|pc|q)\s*$", re.IGNORECASE)


def _mm_per_px(size: str | None, pixels: float) -> float | None:
    """Millimetres per pixel of svgelements' output for a drawing ``size`` (``"210mm"``) of ``pixels`` pixels:
    from the two, not from a constant, since svgelements rounds a millimetre to 0.0393701 in. None for a size
    without physical units."""
    match = _PHYSICAL.match(size or "")
    if match is None or not pixels:
        return None
    return float(match.group(1)) * _MM_PER_UNIT[match.group(2).lower()] / pixels


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


def _check_path_data(d: str, where: str) -> None:
    """Refuse path data svgelements would read only partly: text that is no command or number, numbers before the
    first command, a command without all its numbers."""
    tokens = _TOKEN.findall(d)
    rest = _TOKEN.sub("", d).replace(",", " ").strip()
    if rest:
        raise SketchFileError(f"{where}: unexpected text {rest[:20]!r} in path data")
    command = ""
    i = 0
    while i < len(tokens):
        letter, number = tokens[i]
        if letter:
            command = letter
            i += 1
            if command in "Zz":
                continue
        elif not command:
            raise SketchFileError(f"{where}: path data must start with a command letter, got {number!r}")
        nargs = _ARGS[command.upper()]
        for _ in range(nargs):
            if i >= len(tokens) or tokens[i][0]:
                raise SketchFileError(f"{where}: command {command!r} expects {nargs} numbers")
            i += 1
        if command in "Mm":
            command = "l" if command == "m" else "L"  # further pairs are implicit line-tos


def _flatten(path: svgelements.Path) -> list[np.ndarray]:
    """Polylines of an svgelements path (one per subpath): lines as they are, curves and arcs flattened."""
    subpaths: list[np.ndarray] = []
    current: list[np.ndarray] = []
    for segment in path:
        if isinstance(segment, svgelements.Move):
            if len(current) > 1:
                subpaths.append(np.concatenate(current))
            current = [np.array([[segment.end.x, segment.end.y]])]
            continue
        if not current:
            current = [np.array([[segment.start.x, segment.start.y]])]
        if isinstance(segment, (svgelements.Line, svgelements.Close)):
            current.append(np.array([[segment.end.x, segment.end.y]]))
            if isinstance(segment, svgelements.Close):
                subpaths.append(np.concatenate(current))
                current = []
        else:
            steps = 2 * BEZIER_STEPS if isinstance(segment, svgelements.Arc) else BEZIER_STEPS
            current.append(np.asarray(segment.npoint(np.linspace(0.0, 1.0, steps + 1)[1:]), dtype=float))
    if len(current) > 1:
        subpaths.append(np.concatenate(current))
    return subpaths


def parse_path_data(d: str, where: str) -> list[np.ndarray]:
    """Polylines of an SVG path ``d`` attribute (one per subpath); curves and arcs are flattened."""
    _check_path_data(d, where)
    return _flatten(svgelements.Path(d))


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def load_svg(path: Path, symmetry: int | None, center: object) -> Sketch:
    """A sketch from an SVG file: every visible shape (see the module's notes) is a stroke, in mm when the drawing's
    size has physical units, flipped to y up; the centre defaults to the drawing's page centre (see
    :func:`design.sketch.files.load_sketch`)."""
    text = _read_text(path, "SVG")
    if "<!ENTITY" in text:
        raise SketchFileError(f"{path}: SVG with entity declarations is not accepted; expected a plain SVG drawing")
    try:
        root = ElementTree.fromstring(text)
    except ElementTree.ParseError as error:
        raise SketchFileError(f"{path}: invalid SVG/XML: {error}") from None
    if _local(root.tag) != "svg":
        raise SketchFileError(f"{path}: root element must be <svg>, got <{_local(root.tag)}>")
    for number, element in enumerate(e for e in root.iter() if _local(e.tag) == "path"):
        _check_path_data(element.get("d", ""), f"{path}: <path> #{number + 1}")
    try:
        drawing = svgelements.SVG.parse(io.StringIO(text), reify=True, ppi=svgelements.DEFAULT_PPI)
    except Exception as error:  # noqa: BLE001 - svgelements raises many kinds on odd input: one line naming the file
        raise SketchFileError(f"{path}: cannot read the SVG ({type(error).__name__}: {error})") from None
    unit = (_mm_per_px(root.get("width"), float(drawing.width or 0.0))
            or _mm_per_px(root.get("height"), float(drawing.height or 0.0)) or 1.0)
    strokes: list[np.ndarray] = []
    for element in drawing.elements():
        if not isinstance(element, svgelements.Shape) or isinstance(element, svgelements.Text):
            continue
        if element.values.get("visibility") in ("hidden", "collapse"):
            continue
        for points in _flatten(svgelements.Path(element)):
            if len(points):
                strokes.append(points * unit)
                if len(strokes) > MAX_STROKES:
                    raise SketchFileError(f"{path}: more than {MAX_STROKES} strokes; expected a hand-drawn sketch")
    if not strokes:
        raise SketchFileError(f"{path}: no strokes found; expected <path>, <polyline>, <polygon> or <line> elements")
    flip = np.array([1.0, -1.0])  # SVG y points down; a sketch is y up
    strokes = [s * flip for s in strokes]
    if center is None:
        width, height = float(drawing.width or 0.0), float(drawing.height or 0.0)
        if width > 0 and height > 0:
            center = [width * unit / 2, -height * unit / 2]
        else:
            allpts = np.concatenate(strokes)
            center = ((allpts.min(axis=0) + allpts.max(axis=0)) / 2).tolist()
    return make_sketch(strokes, symmetry=symmetry, center=center, source=str(path))
