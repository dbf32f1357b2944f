"""A sketch drawn in Inkscape reads as the same strokes as the JSON sketch of them: transforms on layers and groups,
a size in mm over a view box of other units, a ``<rect>``, a ``<use>`` of a shape in ``<defs>``, a hidden layer and
a text label left out."""

from __future__ import annotations

import json

import numpy as np

from design.sketch import load_sketch

# The strokes in mm on the page (x right, y down), in document order.
STROKES_MM = [
    [[10, 10], [30, 10], [30, 20]],                            # a path in the layer (translated)
    [[60, 15], [60, 25]],                                      # a path in a rotated group
    [[50, 30], [70, 30], [70, 40], [50, 40], [50, 30]],        # a <rect>
    [[90, 55], [95, 55], [92.5, 59], [90, 55]],                # a <use> of a triangle in <defs>
]

# 200 x 100 mm drawn on a 400 x 200 view box: two user units per mm, as a document scaled in Inkscape has.
INKSCAPE_SVG = """<?xml version="1.0" encoding="UTF-8" standalone="no"?>
<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink"
     xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape"
     xmlns:sodipodi="http://sodipodi.sourceforge.net/DTD/sodipodi-0.dtd"
     width="200mm" height="100mm" viewBox="0 0 400 200" version="1.1" id="svg1">
  <sodipodi:namedview id="namedview1" inkscape:document-units="mm"/>
  <defs id="defs1">
    <path id="triangle" d="M 0,0 L 10,0 L 5,8 Z" style="fill:none;stroke:#000000"/>
  </defs>
  <g inkscape:label="Layer 1" inkscape:groupmode="layer" id="layer1" transform="translate(20,10)">
    <path d="m 0,10 h 40 v 20" style="fill:none;stroke:#000000;stroke-width:0.5"/>
    <g id="g1" transform="rotate(90)">
      <path d="M 20,-100 L 40,-100" style="fill:none;stroke:#000000"/>
    </g>
    <rect x="80" y="50" width="40" height="20" style="fill:none;stroke:#000000"/>
    <use xlink:href="#triangle" transform="translate(160,100)"/>
    <text x="0" y="180">sketch</text>
  </g>
  <g inkscape:label="guides" inkscape:groupmode="layer" id="layer2" style="display:none">
    <path d="M 0,0 L 400,200" style="fill:none;stroke:#ff0000"/>
  </g>
</svg>
"""


def test_an_inkscape_svg_reads_as_the_json_sketch_of_the_same_strokes(tmp_path):
    svg = tmp_path / "inkscape.svg"
    svg.write_text(INKSCAPE_SVG)
    as_json = tmp_path / "same.json"
    # the JSON sketch in mm, y up, centred on the page as an SVG sketch is by default
    as_json.write_text(json.dumps({"strokes": [[[x, -y] for x, y in stroke] for stroke in STROKES_MM],
                                   "center": [100, -50]}))
    from_svg, from_json = load_sketch(svg), load_sketch(as_json)
    assert len(from_svg.strokes) == len(from_json.strokes) == 4
    for a, b in zip(from_svg.strokes, from_json.strokes):
        assert a.shape == b.shape
        assert np.allclose(a, b, rtol=0, atol=1e-9)
    assert np.allclose(from_svg.center, from_json.center, rtol=0, atol=1e-9)

