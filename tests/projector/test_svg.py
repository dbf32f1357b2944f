"""The SVG guide: exact output for a tiny guide, and structure, scale and decodable reference tags on a bigger one."""

from __future__ import annotations

import io
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from shapely.geometry import MultiPoint, Polygon

from projector.drawing import CARE_COLORS
from projector.errors import ProjectorError
from projector.guide import REFERENCE_TAG_IDS
from projector.samples import sample_guide, tiny_guide
from projector.svg import LAYERS, write_svg
from vision.detection import detect_tags

SVG = "{http://www.w3.org/2000/svg}"
INKSCAPE = "{http://www.inkscape.org/namespaces/inkscape}"


def head(size: int, title: str, desc: str) -> str:
    return ('<?xml version="1.0" encoding="utf-8" ?>\n<svg xmlns="http://www.w3.org/2000/svg" '
            'xmlns:ev="http://www.w3.org/2001/xml-events" xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape" '
            f'xmlns:xlink="http://www.w3.org/1999/xlink" baseProfile="full" height="{size}mm" version="1.1" '
            f'viewBox="0 0 {size} {size}" width="{size}mm">\n  <title>{title}</title>\n'
            f'  <desc>chaos-station assembly guide, 1:1, units: mm; guide plane (u, v) = {desc}</desc>\n  <defs/>\n')


def layer(name: str, body: str) -> str:
    opening = (f'  <g fill="none" id="layer-{name}" inkscape:groupmode="layer" inkscape:label="{name}" '
               f'stroke="#000000" stroke-width="0.25"')
    return f"{opening}/>\n" if not body else f"{opening}>\n{body}  </g>\n"


TAG_7_TEXT = ("M4.643,0.5 4.643,2.929 4.786,3.357 5.071,3.5 5.357,3.5 M4.214,1.5 5.214,1.5 M7.786,1.5 7.786,3.5 "
              "M7.786,1.929 7.5,1.643 7.214,1.5 6.786,1.5 6.5,1.643 6.214,1.929 6.071,2.357 6.071,2.643 6.214,3.071 "
              "6.5,3.357 6.786,3.5 7.214,3.5 7.5,3.357 7.786,3.071 M10.5,1.5 10.5,3.786 10.357,4.214 10.214,4.357 "
              "9.929,4.5 9.5,4.5 9.214,4.357 M10.5,1.929 10.214,1.643 9.929,1.5 9.5,1.5 9.214,1.643 8.929,1.929 "
              "8.786,2.357 8.786,2.643 8.929,3.071 9.214,3.357 9.5,3.5 9.929,3.5 10.214,3.357 10.5,3.071 "
              "M15.786,0.5 14.357,3.5 M13.786,0.5 15.786,0.5")

# (guide, options, exact output). The tiny guide: a 20 mm square from (20, 20) to (40, 40) mm, centre (30, 30),
# heading 0, tag 7 (10 mm) at its centre, x within +-2 mm (tight). Margin 10 mm: SVG x = u - 10, y = 50 - v.
CASES = [
    (tiny_guide(), {"layers": ["outlines"]},
     head(40, "tiny - top view", "(x + 10, 50 - y)") + layer("outlines", (
         '    <g id="outline-1" stroke="#000000">\n'
         '      <path d="M10,30 30,30 30,10 10,10Z"/>\n'  # the square
         '      <path d="M18.5,20 21.5,20 M20,21.5 20,18.5"/>\n'  # its centre cross
         '      <path d="M20,20 29.2,20 M28.5,18.425 32,20 28.5,21.575"/>\n'  # heading 0: a 12 mm arrow to +u
         '    </g>\n')) + "</svg>\n\n"),
    (tiny_guide(), {"layers": ["tolerances"]},
     head(40, "tiny - top view", "(x + 10, 50 - y)") + layer("tolerances", (
         '    <g id="tolerance-1" stroke="#d91c1c">\n'  # tight: red
         '      <path d="M8,30 8,10 32,10 32,30Z"/>\n'  # the square swept +-2 mm along u
         '    </g>\n')) + "</svg>\n\n"),
    (tiny_guide(), {"layers": ["tags"], "margin_mm": 0},
     head(20, "tiny - top view", "(x + 20, 40 - y)") + layer("tags", (
         '    <g id="tag-7">\n'
         '      <path d="M5,15 15,15 15,5 5,5Z"/>\n'  # its 10 mm square
         '      <path d="M5,15 8,15 5,12Z" fill="#000000" stroke="none"/>\n'  # its first corner: lower-left
         f'      <path d="{TAG_7_TEXT}"/>\n'  # "tag 7" above it, single-stroke
         '    </g>\n')) + "</svg>\n\n"),
    (tiny_guide(tag=False, tolerance=False), {"layers": ["tags", "tolerances"], "title": "t & <u>"},
     head(40, "t &amp; &lt;u&gt;", "(x + 10, 50 - y)") + layer("tolerances", "") + layer("tags", "") + "</svg>\n\n"),
]


@pytest.mark.parametrize(("guide", "options", "expected"), CASES)
def test_exact_output(guide, options, expected):
    stream = io.StringIO()
    write_svg(guide, stream, **options)
    assert stream.getvalue() == expected


@pytest.fixture(scope="module")
def sample():
    guide = sample_guide()
    stream = io.StringIO()
    write_svg(guide, stream)
    return guide, ET.fromstring(stream.getvalue())


def numbers(d: str) -> list[np.ndarray]:
    """The subpaths of a path's d (M x,y x,y ... [Z]) as (n, 2) arrays."""
    return [np.array([[float(v) for v in p.split(",")] for p in sub.replace("Z", "").split()])
            for sub in re.findall(r"M([^M]+)", d)]


def test_size_in_mm_and_one_layer_per_kind(sample):
    guide, root = sample
    u0, v0, u1, v1 = guide.extent_mm
    assert root.get("width") == f"{u1 - u0 + 20:g}mm" and root.get("height") == f"{v1 - v0 + 20:g}mm"
    assert root.get("viewBox") == f"0 0 {u1 - u0 + 20:g} {v1 - v0 + 20:g}"
    layers = [g for g in root.findall(f"{SVG}g")]
    assert [g.get(f"{INKSCAPE}label") for g in layers] == list(LAYERS)
    assert all(g.get(f"{INKSCAPE}groupmode") == "layer" and g.get("id") == f"layer-{g.get(f'{INKSCAPE}label')}"
               for g in layers)


def to_guide(xy: np.ndarray, guide) -> np.ndarray:
    u0, _, _, v1 = guide.extent_mm
    return np.column_stack([xy[:, 0] + u0 - 10, v1 + 10 - xy[:, 1]])  # v up on the plane: y flipped


def test_outlines_come_back_to_the_parts_on_the_plane(sample):
    guide, root = sample
    outlines = root.find(f"{SVG}g[@id='layer-outlines']")
    for part in guide.parts:
        group = outlines.find(f"{SVG}g[@id='outline-{part.step}']")
        rings = [to_guide(r, guide) for r in numbers(group.find(f"{SVG}path").get("d"))]
        if part.name == "domino_run":
            assert len(rings) == 5  # one outline per domino
            continue
        drawn = Polygon(rings[0], rings[1:])
        assert drawn.symmetric_difference(part.outline).area < 0.01 * part.outline.area
        if part.name == "catch_cup":  # the U stays a U
            assert drawn.area < 0.6 * MultiPoint(rings[0]).convex_hull.area
        assert (group.get("stroke") == "#808080") == (str(part.kind) == "static")


def test_tolerances_are_coloured_by_care(sample):
    guide, root = sample
    tolerances = root.find(f"{SVG}g[@id='layer-tolerances']")
    for part in guide.parts:
        group = tolerances.find(f"{SVG}g[@id='tolerance-{part.step}']")
        if part.care is None:
            assert group is None
            continue
        rgb = CARE_COLORS[part.care]
        assert group.get("stroke") == "#" + "".join(f"{round(255 * c):02x}" for c in rgb)


def test_reference_tags_decode_at_their_places_when_rasterized(sample):
    guide, root = sample
    scale = 8.0  # px per mm
    width, height = (float(root.get(k)[:-2]) for k in ("width", "height"))
    image = np.full((int(height * scale), int(width * scale)), 255, dtype=np.uint8)
    for path in root.find(f"{SVG}g[@id='layer-reference_tags']").findall(f"{SVG}path"):
        assert path.get("fill") == "#000000"
        for rect in numbers(path.get("d")):
            (x0, y0), (x1, y1) = np.round(rect.min(axis=0) * scale).astype(int), np.round(rect.max(axis=0) * scale)
            image[y0:int(y1), x0:int(x1)] = 0
    found = {t.tag_id: t for t in detect_tags(image)}  # pupil-apriltags
    assert sorted(found) == list(REFERENCE_TAG_IDS)
    for tag in guide.reference_tags:
        centre = to_guide(np.array([found[tag.id].center]) / scale, guide)[0]
        assert np.abs(centre - tag.center_mm).max() < 0.2
        corners = to_guide(found[tag.id].corners / scale, guide)
        assert np.ptp(corners[:, 0]) == pytest.approx(tag.size_mm, abs=0.3)
        assert corners[0, 0] < centre[0] and corners[0, 1] < centre[1]  # first corner lower-left: not mirrored


def test_labels_are_single_stroke_paths(sample):
    guide, root = sample
    labels = root.find(f"{SVG}g[@id='layer-labels']")
    assert len(labels.findall(f"{SVG}g")) == len(guide.parts)
    assert not list(root.iter(f"{SVG}text"))  # a plotter draws paths: no font needed
    for group in labels.findall(f"{SVG}g"):
        assert len(numbers(group.find(f"{SVG}path").get("d"))) > 3  # circle, number and name strokes


@pytest.mark.parametrize(("options", "message"), [
    ({"layers": ["outlines", "grid"]}, "svg layers: expected some of outlines, tolerances, tags, reference_tags, "
                                       "labels, got 'grid'"),
    ({"margin_mm": -1}, "svg margin_mm: expected a number of millimetres from 0 to 1000, got -1"),
])
def test_bad_options_are_one_line(options, message):
    with pytest.raises(ProjectorError, match=re.escape(message)):
        write_svg(tiny_guide(), io.StringIO(), **options)
