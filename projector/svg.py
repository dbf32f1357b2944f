"""The guide as an SVG for a laser or a plotter to mark a board directly: millimetres, one layer per kind.

The document is ``W mm x H mm`` with a ``viewBox`` in mm (one user unit is one millimetre): the guide's extent plus a
margin. ``v`` is up on the guide plane and down in SVG, so ``y = top - v``; the document's description gives the
mapping back to guide-plane (u, v) mm. One Inkscape layer per kind, in this order:

- ``outlines``: each part's outline (placed parts black, static parts grey and hatched), its centre cross and
  heading arrow, and the footprint of each laser-cut jig the steps use (brown, dashed);
- ``tolerances``: the tolerance zone and the heading's arc of each part, coloured by care (red tight, orange normal,
  green loose);
- ``tags``: where each part's tag goes (its square, first corner filled, its id), not a decodable tag;
- ``reference_tags``: the four reference tags, their black cells filled, at their exact size;
- ``labels``: each part's number in a circle, its name and a leader line, in a single-stroke font (a plotter can
  draw them).

Lines are hairlines (0.25 mm) without fill, except the reference tags' black cells and the tags' first corners.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TextIO

import numpy as np
from shapely.geometry import LineString

from projector import drawing as shapes
from projector.errors import ProjectorError
from projector.guide import Guide, PartKind

__all__ = ["LAYERS", "write_svg"]

#: The layers, in drawing order.
LAYERS = ("outlines", "tolerances", "tags", "reference_tags", "labels")
INKSCAPE_NS = "http://www.inkscape.org/namespaces/inkscape"
STROKE_MM = 0.25


def _n(value: float) -> str:
    text = f"{value:.3f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def _signed(value: float) -> str:
    return f"- {_n(-value)}" if value < 0 else f"+ {_n(value)}"


class _Frame:
    """Guide-plane mm to SVG user units (mm): x = u - left, y = top - v."""

    def __init__(self, guide: Guide, margin_mm: float) -> None:
        u0, v0, u1, v1 = guide.extent_mm
        self.left, self.top = u0 - margin_mm, v1 + margin_mm
        self.width, self.height = u1 - u0 + 2 * margin_mm, v1 - v0 + 2 * margin_mm

    def path(self, polylines: Iterable, closed: bool) -> str:
        parts = []
        for points in polylines:
            points = np.asarray(points, dtype=float)
            if closed and len(points) > 1 and np.allclose(points[0], points[-1]):
                points = points[:-1]
            xy = " ".join(f"{_n(u - self.left)},{_n(self.top - v)}" for u, v in points)
            parts.append(f"M{xy}" + ("Z" if closed else ""))
        return " ".join(parts)


def _hex(rgb) -> str:
    return "#" + "".join(f"{round(255 * c):02x}" for c in rgb)


def write_svg(guide: Guide, stream: TextIO, *, layers: Iterable[str] = LAYERS, margin_mm: float = 10.0,
              title: str | None = None) -> None:
    """Write the guide as an SVG document (mm) to a text stream.

    Parameters
    ----------
    guide : Guide
        What to draw.
    stream : text stream
        Where the document goes.
    layers : iterable of str
        Which layers to write (of :data:`LAYERS`; always in that order).
    margin_mm : float
        White kept round the guide's extent.
    title : str or None
        The document's title (default: the scenario and its view).
    """
    import svgwrite

    wanted = list(layers)
    unknown = [name for name in wanted if name not in LAYERS]
    if unknown:
        raise ProjectorError(f"svg layers: expected some of {', '.join(LAYERS)}, got {', '.join(map(repr, unknown))}")
    if not isinstance(margin_mm, (int, float)) or not 0 <= margin_mm <= 1000:
        raise ProjectorError(f"svg margin_mm: expected a number of millimetres from 0 to 1000, got {margin_mm!r}")
    frame = _Frame(guide, float(margin_mm))
    drawing = svgwrite.Drawing(size=(f"{_n(frame.width)}mm", f"{_n(frame.height)}mm"),
                               viewBox=f"0 0 {_n(frame.width)} {_n(frame.height)}", debug=False)
    drawing.attribs["xmlns:inkscape"] = INKSCAPE_NS
    drawing.set_desc(
        title=title if title is not None else f"{guide.scenario} - {guide.view} view",
        desc=f"chaos-station assembly guide, 1:1, units: mm; guide plane (u, v) = (x {_signed(frame.left)}, "
             f"{_n(frame.top)} - y)")
    draw = {"outlines": _outlines, "tolerances": _tolerances, "tags": _tags, "reference_tags": _reference_tags,
            "labels": _labels}
    for name in LAYERS:
        if name not in wanted:
            continue
        layer = drawing.g(id=f"layer-{name}", fill="none", stroke="#000000", stroke_width=_n(STROKE_MM))
        layer.attribs["inkscape:groupmode"] = "layer"
        layer.attribs["inkscape:label"] = name
        draw[name](drawing, layer, guide, frame)
        drawing.add(layer)
    drawing.write(stream, pretty=True)
    stream.write("\n")


def _rings(geometry) -> list[np.ndarray]:
    return [np.asarray(ring.coords) for polygon in shapes.polygons(geometry)
            for ring in (polygon.exterior, *polygon.interiors)]


def _outlines(drawing, layer, guide: Guide, frame: _Frame) -> None:
    for jig in guide.jigs:  # a laser-cut jig's footprint, where the maker lays it (brown, dashed)
        group = drawing.g(id=f"jig-{jig.id}", stroke="#8c5a26", stroke_dasharray="2,1")
        group.add(drawing.path(d=frame.path(_rings(jig.footprint), closed=True)))
        layer.add(group)
    for part in guide.parts:
        static = part.kind == PartKind.STATIC
        group = drawing.g(id=f"outline-{part.step}", stroke="#808080" if static else "#000000")
        group.add(drawing.path(d=frame.path(_rings(part.outline), closed=True)))
        if static:
            hatching = shapes.hatch_segments(part.outline)
            if hatching:
                group.add(drawing.path(d=frame.path(hatching, closed=False)))
        u, v = part.center_mm
        group.add(drawing.path(d=frame.path([[(u - 1.5, v), (u + 1.5, v)], [(u, v - 1.5), (u, v + 1.5)]], False)))
        if not static:
            shaft, head = shapes.arrow(part.center_mm, part.heading_deg, shapes.heading_length(part))
            group.add(drawing.path(d=frame.path([shaft, [head[1], head[0], head[2]]], closed=False)))
        layer.add(group)


def _tolerances(drawing, layer, guide: Guide, frame: _Frame) -> None:
    for part in guide.parts:
        du, dv, dtheta = shapes.placement_deltas(part, guide.plane)
        zone = shapes.tolerance_zone(part.outline, du, dv)
        if zone is None and dtheta is None:
            continue
        group = drawing.g(id=f"tolerance-{part.step}", stroke=_hex(shapes.care_color(part.care)))
        if zone is not None:
            group.add(drawing.path(d=frame.path(_rings(zone), closed=True)))
        if dtheta is not None:
            length = shapes.heading_length(part)
            arc = shapes.arc_points(part.center_mm, length, part.heading_deg, max(dtheta, 0.5))
            group.add(drawing.path(d=frame.path([arc], closed=False)))
        layer.add(group)


def _square(center, size: float, heading_deg: float) -> np.ndarray:
    half = size / 2
    corners = np.array([[-half, -half], [half, -half], [half, half], [-half, half]])
    c, s = np.cos(np.radians(heading_deg)), np.sin(np.radians(heading_deg))
    return corners @ np.array([[c, s], [-s, c]]) + np.asarray(center, dtype=float)


def _tags(drawing, layer, guide: Guide, frame: _Frame) -> None:
    from design.fabrication.labels import text_polylines

    for part in (view for each in guide.parts for view in each.tag_views()):
        group = drawing.g(id=f"tag-{part.tag_id}")
        square = _square(part.tag_center_mm, part.tag_size_mm, part.tag_heading_deg)
        group.add(drawing.path(d=frame.path([square], closed=True)))
        corner = np.array([square[0], square[0] + 0.3 * (square[1] - square[0]),
                           square[0] + 0.3 * (square[3] - square[0])])
        group.add(drawing.path(d=frame.path([corner], closed=True), fill="#000000", stroke="none"))
        strokes = text_polylines(f"tag {part.tag_id}", min(3.0, 0.3 * part.tag_size_mm))
        c, s = np.cos(np.radians(part.heading_deg)), np.sin(np.radians(part.heading_deg))
        above = np.array([0.0, part.tag_size_mm / 2 + 2.5])
        rotation = np.array([[c, s], [-s, c]])
        strokes = [(stroke + above) @ rotation + part.tag_center_mm for stroke in strokes]
        if strokes:
            group.add(drawing.path(d=frame.path(strokes, closed=False)))
        layer.add(group)


def _reference_tags(drawing, layer, guide: Guide, frame: _Frame) -> None:
    for tag in guide.reference_tags:
        runs = [[(u0, v0), (u1, v0), (u1, v1), (u0, v1)]
                for u0, v0, u1, v1 in shapes.tag_black_rects(tag.id, tag.center_mm, tag.size_mm)]
        layer.add(drawing.path(id=f"reference-tag-{tag.id}", d=frame.path(runs, closed=True), fill="#000000",
                               stroke="none"))


def _labels(drawing, layer, guide: Guide, frame: _Frame) -> None:
    from design.fabrication.labels import text_polylines

    labels = shapes.place_labels(guide)
    for part in guide.parts:
        label = labels[part.name]
        group = drawing.g(id=f"label-{part.step}")
        strokes = [shapes.arc_points(label.circle, label.radius, 0.0, 180.0, 49)]
        if label.leader is not None:
            # From the label's edge, not across its text (the PDF hides it under the label's white box).
            leader = LineString(label.leader).difference(label.box)
            strokes += [np.asarray(line.coords) for line in getattr(leader, "geoms", [leader])
                        if not line.is_empty and line.length > 0.3]
        number = text_polylines(str(label.number), shapes.CIRCLE_MM * 0.45)
        strokes += [s + label.circle for s in number]
        lines = [(label.name, shapes.NAME_MM, 0.0)]
        if label.detail or label.off_plane:  # the name above the middle, the tolerance and the height below it
            lines = [(label.name, shapes.NAME_MM, 0.5 + shapes.NAME_MM / 2)]
            below = -0.2 - shapes.DETAIL_MM / 2
            for text in (label.detail, label.off_plane):
                if text:
                    lines.append((text, shapes.DETAIL_MM, below))
                    below -= shapes.DETAIL_MM + 0.6
        for text, height, dy in lines:
            # The single-stroke font is ASCII: spell out the two signs a tolerance uses.
            written = text_polylines(text.replace("\u00b1", "+-").replace("\u00b0", " deg"), height)
            if not written:
                continue
            left = min(float(s[:, 0].min()) for s in written)
            strokes += [s + (label.text[0] - left, label.text[1] + dy) for s in written]
        group.add(drawing.path(d=frame.path(strokes, closed=False)))
        layer.add(group)
