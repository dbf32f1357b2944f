"""Export of a nested sheet: laser paths as plain polylines, SVG in millimetres, PNG preview.

SVG conventions for laser software (LightBurn, LaserGRBL, Inkscape + plugins): the document is ``W mm × H mm`` with a
``viewBox`` in mm (1 user unit = 1 mm); one Inkscape layer per operation, drawn in the order to run them
(``engrave`` first, then ``cut``); hairline strokes, no fill, red for cut and blue for engrave. The sheet's y axis
points up from its front-left corner (like the laser's), so the SVG flips y.
"""

from __future__ import annotations

import io
from typing import TextIO

import numpy as np
from PIL import Image, ImageDraw
from shapely.geometry import Polygon

from design.fabrication.nesting import Sheet

__all__ = ["part_cut_paths", "sheet_paths", "write_svg", "render_png", "CUT_COLOR", "ENGRAVE_COLOR"]

CUT_COLOR = "#ff0000"
ENGRAVE_COLOR = "#0000ff"
INKSCAPE_NS = "http://www.inkscape.org/namespaces/inkscape"


def _closed(ring) -> np.ndarray:
    coords = np.asarray(ring.coords, dtype=float)
    if len(coords) and not np.array_equal(coords[0], coords[-1]):
        coords = np.vstack([coords, coords[:1]])
    return coords


def part_cut_paths(cut_shape: Polygon) -> tuple[list[np.ndarray], np.ndarray]:
    """``(inner contours, outer contour)`` of one kerf-compensated part as closed ``(n, 2)`` polylines."""
    return [_closed(hole) for hole in cut_shape.interiors], _closed(cut_shape.exterior)


def sheet_paths(sheet: Sheet, tolerance: float = 0.01) -> dict[str, list]:
    """Plain polylines of a sheet grouped by operation.

    ``tolerance`` (mm): contours are simplified within it (Douglas-Peucker, topology kept); the default is a tenth
    of a laser spot, and removes the generation's near-duplicate vertices.

    Returns
    -------
    dict
        ``{"engrave": [polyline, ...], "cut": [(inner contours, outer contour) per part, ...]}``, mm, sheet
        coordinates. Label strokes are engraved; each part's holes are cut before its outline.
    """
    engrave = [np.asarray(stroke, dtype=float) for part in sheet.parts for stroke in part.engrave]
    cut = [part_cut_paths(shape.simplify(tolerance) if tolerance > 0 else shape) for shape in sheet.cut_shapes]
    return {"engrave": engrave, "cut": cut}


def _path_data(polyline: np.ndarray, height: float, closed: bool) -> str:
    xy = np.column_stack([polyline[:, 0], height - polyline[:, 1]])
    if closed and len(xy) > 1 and np.allclose(xy[0], xy[-1]):
        xy = xy[:-1]
    text = " ".join(f"{x:.4f},{y:.4f}" for x, y in xy)
    return f"M {text}" + (" Z" if closed else "")


def write_svg(sheet: Sheet, stream: TextIO, title: str = "chaos-station parts") -> None:
    """Write the sheet as an SVG (mm) with one layer per operation: ``engrave`` (labels) then ``cut``."""
    import svgwrite

    drawing = svgwrite.Drawing(size=(f"{sheet.width:g}mm", f"{sheet.height:g}mm"),
                               viewBox=f"0 0 {sheet.width:g} {sheet.height:g}", debug=False)
    drawing.attribs["xmlns:inkscape"] = INKSCAPE_NS
    drawing.set_desc(title=title, desc=f"sheet {sheet.width:g}x{sheet.height:g} mm, kerf {sheet.kerf:g} mm "
                                         f"(compensated), gap {sheet.gap:g} mm; units: mm")
    paths = sheet_paths(sheet)
    for name, color in (("engrave", ENGRAVE_COLOR), ("cut", CUT_COLOR)):
        layer = drawing.g(id=f"layer-{name}", fill="none", stroke=color, stroke_width="0.1")
        layer.attribs["inkscape:groupmode"] = "layer"
        layer.attribs["inkscape:label"] = name
        if name == "engrave":
            for stroke in paths["engrave"]:
                layer.add(drawing.path(d=_path_data(stroke, sheet.height, closed=False)))
        else:
            for part, (inner, outer) in zip(sheet.parts, paths["cut"]):
                group = drawing.g(id=f"part-{_slug(part.name)}")
                for contour in [*inner, outer]:
                    group.add(drawing.path(d=_path_data(contour, sheet.height, closed=True)))
                layer.add(group)
        drawing.add(layer)
    drawing.write(stream, pretty=True)


def _slug(name: str) -> str:
    return "".join(c if c.isalnum() else "-" for c in name.lower())


def render_png(sheet: Sheet, max_pixels: int = 1600, travel: list[np.ndarray] | None = None) -> bytes:
    """A PNG preview of the sheet: material in wood colour, holes cut out, cut paths red, labels blue.

    ``travel``, optional: the laser's travel moves (polylines) drawn thin and grey.
    """
    scale = max_pixels / max(sheet.width, sheet.height)
    width, height = int(round(sheet.width * scale)) + 1, int(round(sheet.height * scale)) + 1
    image = Image.new("RGB", (width, height), (250, 250, 247))
    draw = ImageDraw.Draw(image)

    def px(xy: np.ndarray) -> list[tuple[float, float]]:
        return [(float(x * scale), float(height - 1 - y * scale)) for x, y in xy]

    draw.rectangle([0, 0, width - 1, height - 1], outline=(120, 120, 120))
    for part in sheet.parts:
        for geom in getattr(part.shape, "geoms", [part.shape]):
            draw.polygon(px(np.asarray(geom.exterior.coords)), fill=(222, 184, 135))
            for hole in geom.interiors:
                draw.polygon(px(np.asarray(hole.coords)), fill=(250, 250, 247))
    for path in travel or []:
        draw.line(px(path), fill=(160, 160, 160), width=1)
    line = max(1, int(round(scale * 0.25)))
    for shape in sheet.cut_shapes:
        for ring in [shape.exterior, *shape.interiors]:
            draw.line(px(_closed(ring)), fill=(220, 0, 0), width=line)
    for part in sheet.parts:
        for stroke in part.engrave:
            draw.line(px(stroke), fill=(0, 0, 220), width=line)
    buffer = io.BytesIO()
    image.save(buffer, format="PNG")
    return buffer.getvalue()
