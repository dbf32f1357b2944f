"""Sketch files: a JSON sketch read here, an SVG drawing by :mod:`design.sketch.svg`, both to a validated
:class:`~design.sketch.strokes.Sketch`.

SVG files are in screen coordinates (y down); they are flipped on load so that a pattern keeps its handedness.
"""

from __future__ import annotations

from pathlib import Path

from design.datafiles import parse_json
from design.sketch.errors import RetrievalSettingError, SketchFileError
from design.sketch.strokes import Sketch, check_file_size, check_symmetry, make_sketch
from design.sketch.svg import load_svg

__all__ = ["JSON_SKETCH", "load_sketch"]

#: What a JSON sketch should be, the end of the message for a file that is not JSON.
JSON_SKETCH = 'a list of strokes of finite [x, y] points, or {"strokes": [...], "symmetry": K, "center": [x, y]}'



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
        return load_svg(path, symmetry, center)
    raise SketchFileError(f"{path}: unknown sketch format {suffix or 'none'!r}; expected .json or .svg")


def _load_json(path: Path, symmetry: int | None, center: object) -> Sketch:
    check_file_size(path, "JSON")
    data = parse_json(path.read_bytes(), str(path), JSON_SKETCH,
                      error=lambda detail: SketchFileError(f"{path}: {detail}"))
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
