"""Sketch input: JSON/SVG loading, validation with clear errors, symmetry copies."""

from __future__ import annotations

import json

import numpy as np
import pytest

from design.errors import DesignError
from design.sketch.errors import RetrievalSettingError, SketchError, SketchFileError
from design.sketch.files import load_sketch
from design.sketch.strokes import MAX_FILE_BYTES, make_sketch, symmetrize
from design.sketch.svg import parse_path_data


def square(n: int = 10) -> list[list[float]]:
    return [[0, 0], [1, 0], [1, 1], [0, 1], [0, 0.5]][:n]


def test_json_list_and_object_forms(tmp_path):
    a = tmp_path / "a.json"
    a.write_text(json.dumps([square()]))
    b = tmp_path / "b.json"
    b.write_text(json.dumps({"strokes": [square()], "symmetry": 3, "center": [0.5, 0.5]}))
    sa, sb = load_sketch(a), load_sketch(b)
    assert sa.symmetry == 1 and len(sa.strokes) == 1
    assert sb.symmetry == 3 and np.allclose(sb.center, [0.5, 0.5])
    assert load_sketch(b, symmetry=5).symmetry == 5


@pytest.mark.parametrize(
    ("strokes", "words"),
    [
        ([], "empty"),
        ([[]], "empty"),
        ([[[1.0, 2.0]]], "single point"),
        ([[[1.0, 2.0], [1.0, 2.0], [1.0, 2.0]]], "single point"),
        ([[[0, 0], [1, float("nan")], [2, 2]]], "point 1"),
        ([[[0, 0], [1e308, 0], [0, 1e308]]], "at most"),
        ([[[0, 0], [1, 1], [2, 2]], [[0, 0], [1, 1], [2, 2]]], "straight line"),
        ([[[0, 0], [1, 1], [2, 2]], [[2, 2], [1, 1], [0, 0]]], "straight line"),
        ([[[0, 0, 1], [1, 1, 1]]], "[x, y]"),
        ([["a", "b"]], "[x, y]"),
        ("not strokes", "list of strokes"),
    ],
)
def test_bad_sketches_get_clear_errors(strokes, words):
    with pytest.raises(SketchError) as info:
        make_sketch(strokes, source="pad")
    assert words in str(info.value)
    assert str(info.value).startswith("pad")


def test_duplicate_strokes_are_dropped():
    stroke = [[0, 0], [1, 0], [1, 1]]
    sketch = make_sketch([stroke, stroke, stroke[::-1]])
    assert len(sketch.strokes) == 1


def test_bad_symmetry_order():
    for bad in (0, -2, 2.5, "3", True, 1000):
        with pytest.raises(RetrievalSettingError, match="symmetry order"):
            make_sketch([square()], symmetry=bad)


def test_bad_files(tmp_path):
    cases = {
        "x.txt": ("hello", "unknown sketch format"),
        "bad.json": ("{not json", "bad.json: not valid JSON (Expecting property name enclosed in double quotes "
                                  "at line 1 column 2); expected a list of strokes"),
        "field.json": (json.dumps({"strokez": []}), "unknown field"),
        "missing.json": (json.dumps({"symmetry": 3}), "'strokes' is missing"),
        "sym.json": (json.dumps({"strokes": [square()], "symmetry": 0}), "field 'symmetry'"),
        "bad.svg": ("<svg><path d='M 0 0 L'/></svg>", "expects 2 numbers"),
        "notsvg.svg": ("<html/>", "root element must be <svg>"),
        "broken.svg": ("<svg><path", "invalid SVG"),
        "empty.svg": ("<svg xmlns='http://www.w3.org/2000/svg'></svg>", "no strokes"),
        "entity.svg": ("<!DOCTYPE svg [<!ENTITY a 'b'>]><svg/>", "entity"),
    }
    for name, (text, words) in cases.items():
        path = tmp_path / name
        path.write_text(text)
        with pytest.raises(DesignError) as info:
            load_sketch(path)
        assert words in str(info.value), name
        assert name in str(info.value)


def test_ten_megabyte_svg_is_refused_before_parsing(tmp_path):
    path = tmp_path / "huge.svg"
    with path.open("w") as stream:
        stream.write("<svg xmlns='http://www.w3.org/2000/svg'>")
        line = "<path d='M 0 0 L 10 10 L 20 0'/>\n"
        stream.write(line * (10_000_000 // len(line) + 1))
        stream.write("</svg>")
    assert path.stat().st_size > MAX_FILE_BYTES
    with pytest.raises(SketchFileError, match="too large"):
        load_sketch(path)


def test_svg_shapes_transforms_and_y_flip(tmp_path):
    path = tmp_path / "s.svg"
    path.write_text(
        "<svg xmlns='http://www.w3.org/2000/svg' viewBox='0 0 100 100'>"
        "<g transform='translate(10,0)'><path d='M 0 10 L 20 10 l 0 20 H 0 Z'/></g>"
        "<polyline points='50,50 60,60 70,50'/>"
        "<circle cx='80' cy='80' r='5'/>"
        "<path d='M 0 0 C 10 0 10 10 20 10 Q 30 10 30 20 A 5 5 0 0 1 40 20'/>"
        "</svg>"
    )
    sketch = load_sketch(path, symmetry=4)
    assert len(sketch.strokes) == 4
    first = sketch.strokes[0]
    assert np.allclose(first[0], [10, -10])  # translated, y flipped
    assert np.allclose(first[-1], first[0])  # Z closes the subpath
    assert np.allclose(sketch.center, [50, -50])  # view box centre
    arc_end = sketch.strokes[3][-1]
    assert np.allclose(arc_end, [40, -20])


def test_path_parser_relative_commands():
    (poly,) = parse_path_data("m 1 1 l 1 0 v 1 h -1 z", "t")
    assert np.allclose(poly, [[1, 1], [2, 1], [2, 2], [1, 2], [1, 1]])


def test_symmetry_copies_rotate_around_centre_and_drop_retracing_copies():
    stroke = np.array([[1.0, 0.0], [1.5, 0.2]])
    copies = symmetrize([stroke], 4, np.zeros(2))
    assert len(copies) == 4
    assert np.allclose(copies[1][0], [0.0, 1.0])
    centred = symmetrize([stroke], 2, np.array([1.0, 0.0]))
    assert np.allclose(centred[1][1], [0.5, -0.2])
    # a whole circle around the centre with k = 4: every copy retraces it, only the stroke itself is kept
    angle = np.linspace(0, 2 * np.pi, 97)
    circle = np.column_stack([np.cos(angle), np.sin(angle)])
    assert len(symmetrize([circle], 4, np.zeros(2))) == 1
    # ... also with a sampling that does not line up with the rotation
    odd = np.column_stack([np.cos(angle * 0.999 + 0.1), np.sin(angle * 0.999 + 0.1)])
    assert len(symmetrize([odd], 5, np.zeros(2))) == 1
