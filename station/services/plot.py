"""Plots as pen-plotter artists make them: a document of layers, one pen each, from drawing-machine patterns and SVG
files, laid out on the paper, optimized with vpype and written as one G-code job with a pen change between layers.

What vpype brings: reading SVG (svgelements underneath: ``<use>``, ``<rect>``, CSS, units, transforms, hidden
layers), one plot layer per SVG layer or stroke colour, and the line optimizations (``linemerge``, ``reloop``,
``linesort``'s greedy nearest-neighbour order on vpype's ``LineIndex``, ``linesimplify``). What stays the station's:
the patterns, the layout on the profile's paper, the G-code writer (:mod:`drivers.gcode_layers`, pen lines and the
pen-change macro from the profile), the time estimate (the streamer's own G-code interpreter), pre-flight and
streaming.

Coordinates are work millimetres, the paper's front-left corner at the origin, y up (as the machine moves); SVG's
y-down page is turned so that the drawing reads as on screen with the paper's front edge at the bottom.

vpype is imported where it is used: it takes half a second to import, and every ``station`` command (``--help``
too) imports this module.
"""

from __future__ import annotations

import io
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from cam.layers import PenLayer, write_layers_gcode
from cam.plot import WriterOptions
from common.datafiles import parse_data
from common.progress import Reporter
from drivers.gcode import interpret
from drivers.gcode_layers import layer_marks
from drivers.grbl.planner import line_seconds
from drivers.profiles import MachineProfile
from station.errors import ServiceError, station_errors

__all__ = [
    "PALETTE",
    "Composition",
    "LayerSummary",
    "PatternSource",
    "PenSpec",
    "PlotDocument",
    "PlotLayer",
    "PlotResult",
    "SvgSource",
    "compose",
    "layered_gcode",
    "job_layers",
    "load_composition",
    "optimize",
    "plot",
    "read_svg_layers",
    "summarize",
    "write_preview_png",
]

#: Pens given to layers that name none, in order: (name, colour).
PALETTE = (("black", "#000000"), ("blue", "#1f77b4"), ("red", "#d62728"), ("green", "#2ca02c"),
           ("orange", "#ff7f0e"), ("purple", "#9467bd"), ("brown", "#8c564b"), ("pink", "#e377c2"))

#: SVG user units (CSS pixels, 96 per inch) in a millimetre: vpype reads SVG in pixels.
PX_PER_MM = 96.0 / 25.4

#: Curves of an SVG are cut into chords no longer than this (mm) when read.
SVG_QUANTIZATION = 0.1

#: Largest SVG file read (bytes): a drawing, not a map.
MAX_SVG_BYTES = 20_000_000

#: How close (mm) two path ends are to be merged into one path (vpype linemerge's default).
MERGE_TOLERANCE = 0.05

COMPOSITION = ("a plot composition: [[patterns]] (machine, design, set, size or scale, offset, rotation, layer), "
               "[[svg]] "
               "(file, by, scale, offset, rotation, layer) and [[layers]] (name, pen, color, width, feed)")


# ----------------------------------------------------------------------------------------------------------- model


@dataclass(frozen=True)
class PenSpec:
    """A layer's pen and settings as a composition names them (None: the palette's, the profile's)."""

    layer: str
    pen: str | None = None
    color: str | None = None
    width: float | None = None
    feed: float | None = None


@dataclass(frozen=True)
class PatternSource:
    """A drawing-machine pattern placed on the paper: ``size`` its largest side in mm, or ``scale`` mm per unit of
    the machine's lengths (gear radii: a pattern keeps its size against another of the same machine; neither: the
    largest that fits the drawable area), ``offset`` its centre from the paper's centre (mm), ``rotation`` degrees
    counter-clockwise, ``layer`` the plot layer it is drawn on (None: a layer of its own, named after ``label``)."""

    machine: str
    params: dict[str, Any] = field(default_factory=dict)
    size: float | None = None
    offset: tuple[float, float] = (0.0, 0.0)
    rotation: float = 0.0
    layer: str | None = None
    points: int = 4096
    label: str = ""
    polyline: np.ndarray | None = None  # the pattern's points when already sampled (a `station pattern` file)
    scale: float | None = None


@dataclass(frozen=True)
class SvgSource:
    """An SVG file on the paper: each of its layers (``by="layer"``) or stroke colours (``by="color"``) a plot layer,
    or all of it on ``layer``. Its drawing keeps its own millimetres times ``scale``, its centre at ``offset`` from
    the paper's centre, turned by ``rotation`` degrees (vpype's ``layout`` centres a drawing the same way)."""

    path: Path
    by: str = "layer"
    scale: float = 1.0
    offset: tuple[float, float] = (0.0, 0.0)
    rotation: float = 0.0
    layer: str | None = None


@dataclass
class Composition:
    """What to plot: the sources in order and the pens of named layers."""

    sources: list[PatternSource | SvgSource] = field(default_factory=list)
    pens: list[PenSpec] = field(default_factory=list)


@dataclass
class PlotLayer:
    """A layer of a plot: its pen (name, colour, width in mm), its drawing feed (mm/min, None: the profile's) and
    its paths ((n, 2) work mm)."""

    name: str
    pen: str
    color: str
    width: float = 0.3
    feed: float | None = None
    polylines: list[np.ndarray] = field(default_factory=list)


@dataclass
class PlotDocument:
    """The layers in plotting order, on a paper of ``paper`` (width, height) mm with its drawable ``box``."""

    layers: list[PlotLayer]
    paper: tuple[float, float]
    box: tuple[float, float, float, float]


@station_errors
@dataclass(frozen=True)
class LayerSummary:
    """A written layer: paths and points, drawing and travel (mm, travel from the previous layer's end included),
    the estimated time (s, the streamer's estimate: commanded feeds, the machine's rapid rate, dwells, no
    acceleration), and the 1-based G-code lines of its mark and of its pen change's pause (None: none)."""

    number: int
    name: str
    pen: str
    color: str
    paths: int
    points: int
    draw_mm: float
    travel_mm: float
    time_s: float
    line: int
    pause_line: int | None

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


@station_errors
@dataclass
class PlotResult:
    """A written plot: the G-code, the document as written (optimized), the writer's options and the layers'
    summaries."""

    gcode: str
    document: PlotDocument
    options: WriterOptions
    layers: list[LayerSummary]

    @property
    def travel_mm(self) -> float:
        return float(sum(layer.travel_mm for layer in self.layers))

    @property
    def time_s(self) -> float:
        return float(sum(layer.time_s for layer in self.layers))


# ----------------------------------------------------------------------------------------------------------- files


def _number(value: Any, where: str, *, positive: bool = False, minimum: float | None = None) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ServiceError(f"{where}: expected a number, got {value!r:.40}")
    if positive and value <= 0:
        raise ServiceError(f"{where}: expected a number > 0, got {value!r}")
    if minimum is not None and value < minimum:
        raise ServiceError(f"{where}: expected a number >= {minimum:g}, got {value!r}")
    return float(value)


def _pair(value: Any, where: str) -> tuple[float, float]:
    if not isinstance(value, list) or len(value) != 2:
        raise ServiceError(f"{where}: expected [x, y] in mm, got {value!r:.40}")
    return (_number(value[0], f"{where}[0]"), _number(value[1], f"{where}[1]"))


def _text(value: Any, where: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise ServiceError(f"{where}: expected a non-empty text, got {value!r:.40}")
    return value.strip()


def _color(value: Any, where: str) -> str:
    text = _text(value, where)
    if not (len(text) == 7 and text.startswith("#") and all(c in "0123456789abcdefABCDEF" for c in text[1:])):
        raise ServiceError(f"{where}: expected a colour as #rrggbb, got {text!r:.40}")
    return text.lower()


def _table(data: dict, key: str, where: str) -> list[dict]:
    value = data.get(key, [])
    if not isinstance(value, list) or not all(isinstance(item, dict) for item in value):
        raise ServiceError(f"{where}: '{key}' must be a list of tables ([[{key}]]), got {value!r:.40}")
    return value


def _keys(table: dict, allowed: set[str], where: str) -> None:
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise ServiceError(f"{where}: unknown field {unknown[0]!r}; expected one of {', '.join(sorted(allowed))}")


@station_errors
def load_composition(path: str | Path, load_design: Callable[[Path, str], dict] | None = None) -> Composition:
    """A composition file (TOML, or JSON with the same fields; see :data:`COMPOSITION`). Files it names (designs,
    SVGs) are relative to its folder; ``load_design(path, machine)`` reads a design file (the CLI's reader).

    Raises
    ------
    ServiceError
        Naming the file, the entry and the field: ``comp.toml: patterns[2].size: expected a number > 0, got -3``.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as error:
        raise ServiceError(f"{path}: cannot read the composition ({error.strerror or error})") from None
    data = parse_data(raw, str(path), COMPOSITION, error=lambda detail: ServiceError(f"{path}: {detail}"))
    if not isinstance(data, dict):
        raise ServiceError(f"{path}: expected {COMPOSITION}")
    _keys(data, {"patterns", "svg", "layers"}, str(path))
    folder = path.parent
    composition = Composition()
    for k, table in enumerate(_table(data, "layers", str(path)), start=1):
        where = f"{path}: layers[{k}]"
        _keys(table, {"name", "pen", "color", "width", "feed"}, where)
        composition.pens.append(PenSpec(
            layer=_text(table.get("name"), f"{where}.name"),
            pen=_text(table["pen"], f"{where}.pen") if "pen" in table else None,
            color=_color(table["color"], f"{where}.color") if "color" in table else None,
            width=_number(table["width"], f"{where}.width", positive=True) if "width" in table else None,
            feed=_number(table["feed"], f"{where}.feed", positive=True) if "feed" in table else None))
    entries: list[tuple[int, str, dict]] = []
    # patterns first, then SVGs, each in the file's order (the layers' order is the [[layers]] tables', then as
    # sources first draw on them)
    for kind in ("patterns", "svg"):
        for k, table in enumerate(_table(data, kind, str(path)), start=1):
            entries.append((k, kind, table))
    if not entries:
        raise ServiceError(f"{path}: nothing to plot; expected at least one [[patterns]] or [[svg]] entry")
    for k, kind, table in entries:
        where = f"{path}: {kind}[{k}]"
        placement = {
            "offset": _pair(table["offset"], f"{where}.offset") if "offset" in table else (0.0, 0.0),
            "rotation": _number(table.get("rotation", 0.0), f"{where}.rotation"),
            "layer": _text(table["layer"], f"{where}.layer") if "layer" in table else None,
        }
        if kind == "patterns":
            _keys(table, {"machine", "design", "set", "size", "scale", "offset", "rotation", "layer", "points"}, where)
            if "size" in table and "scale" in table:
                raise ServiceError(f"{where}: give size (mm, its largest side) or scale (mm per unit), not both")
            machine = _text(table.get("machine"), f"{where}.machine")
            params: dict[str, Any] = {}
            if "design" in table:
                design = folder / _text(table["design"], f"{where}.design")
                if load_design is None:
                    raise ServiceError(f"{where}.design: no design reader given")
                params.update(load_design(design, machine))
            values = table.get("set", {})
            if not isinstance(values, dict):
                raise ServiceError(f"{where}.set: expected a table of name = value, got {values!r:.40}")
            params.update({name: _number(v, f"{where}.set.{name}") for name, v in values.items()})
            points = table.get("points", 4096)
            if isinstance(points, bool) or not isinstance(points, int) or not 16 <= points <= 200_000:
                raise ServiceError(f"{where}.points: expected an integer in [16, 200000], got {points!r:.40}")
            composition.sources.append(PatternSource(
                machine=machine, params=params, points=points, label=machine,
                size=_number(table["size"], f"{where}.size", positive=True) if "size" in table else None,
                scale=_number(table["scale"], f"{where}.scale", positive=True) if "scale" in table else None,
                **placement))
        else:
            _keys(table, {"file", "by", "scale", "offset", "rotation", "layer"}, where)
            by = table.get("by", "layer")
            if by not in ("layer", "color"):
                raise ServiceError(f"{where}.by: expected 'layer' or 'color', got {by!r:.40}")
            composition.sources.append(SvgSource(
                path=folder / _text(table.get("file"), f"{where}.file"), by=by,
                scale=_number(table.get("scale", 1.0), f"{where}.scale", positive=True), **placement))
    return composition


@station_errors
def read_svg_layers(path: str | Path, by: str = "layer") -> list[PlotLayer]:
    """The visible layers of an SVG file (vpype's reader): one per SVG layer (a top-level group, its Inkscape label
    its name) or per stroke colour, in mm with y up, each with the colour and width its strokes have there.

    Raises
    ------
    ServiceError
        The file is missing, too large, declares entities, or is not an SVG drawing vpype can read.
    """
    import vpype as vp  # deferred: see the module's notes

    path = Path(path)
    if not path.is_file():
        raise ServiceError(f"{path}: no such SVG file", field="svg", value=str(path))
    if path.stat().st_size > MAX_SVG_BYTES:
        raise ServiceError(f"{path}: {path.stat().st_size} bytes; expected an SVG drawing under "
                           f"{MAX_SVG_BYTES // 1_000_000} MB", field="svg", value=str(path))
    head = path.read_bytes()
    if b"<!ENTITY" in head:
        raise ServiceError(f"{path}: SVG with entity declarations is not accepted; expected a plain SVG drawing",
                           field="svg", value=str(path))
    try:
        if by == "color":
            document = vp.read_svg_by_attributes(str(path), ["stroke"], quantization=SVG_QUANTIZATION * PX_PER_MM,
                                                 crop=False)
        else:
            document = vp.read_multilayer_svg(str(path), quantization=SVG_QUANTIZATION * PX_PER_MM, crop=False)
    except Exception as error:  # noqa: BLE001 - svgelements and ElementTree raise many kinds: one line naming the file
        raise ServiceError(f"{path}: not an SVG drawing vpype can read ({type(error).__name__}: {error}); "
                           "expected an SVG file", field="svg", value=str(path)) from None
    height = float(document.page_size[1]) / PX_PER_MM if document.page_size else 0.0
    layers = []
    for layer_id, lines in sorted(document.layers.items()):
        polylines = []
        for line in lines:
            if len(line) < 2:
                continue
            xy = np.column_stack([line.real, line.imag]) / PX_PER_MM
            xy[:, 1] = height - xy[:, 1]  # the page's top edge at the back of the paper
            polylines.append(xy)
        if not polylines:
            continue
        color = lines.property(vp.METADATA_FIELD_COLOR)
        width = lines.property(vp.METADATA_FIELD_PEN_WIDTH)
        name = lines.property(vp.METADATA_FIELD_NAME) or (
            f"{path.stem} {color.as_hex()[:7]}" if by == "color" and color is not None else f"{path.stem} {layer_id}")
        hex_color = color.as_hex()[:7] if color is not None else "#000000"
        layers.append(PlotLayer(name=str(name), pen=str(name), color=hex_color,
                                width=float(width) / PX_PER_MM if width else 0.3, polylines=polylines))
    return layers


# ----------------------------------------------------------------------------------------------------------- layout


def _rotate(polylines: Sequence[np.ndarray], degrees: float, centre: np.ndarray) -> list[np.ndarray]:
    if not degrees:
        return [np.asarray(p, dtype=float) for p in polylines]
    a = math.radians(degrees)
    turn = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    return [(np.asarray(p, dtype=float) - centre) @ turn.T + centre for p in polylines]


def _bounds(polylines: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    stacked = np.concatenate([np.asarray(p, dtype=float).reshape(-1, 2) for p in polylines])
    return stacked.min(axis=0), stacked.max(axis=0)


@station_errors
def drawable_box(profile: MachineProfile) -> tuple[tuple[float, float], tuple[float, float, float, float]]:
    """The paper (width, height) and its drawable box (xmin, ymin, xmax, ymax) in work mm: a plotter's paper less
    its margin; a laser's bed less 5 mm."""
    if profile.kind == "plotter" and profile.paper is not None:
        paper = profile.paper
        return (paper.width, paper.height), (paper.margin, paper.margin, paper.width - paper.margin,
                                             paper.height - paper.margin)
    x0, y0, x1, y1 = profile.work_bounds()
    return (x1 - x0, y1 - y0), (x0 + 5.0, y0 + 5.0, x1 - 5.0, y1 - 5.0)


def _place(polylines: list[np.ndarray], scale: float | None, size: float | None, offset, rotation: float,
           box, what: str) -> list[np.ndarray]:
    """Turn about the drawing's centre, scale (by ``scale``, or to ``size`` mm largest side, or to fit ``box``) and
    centre at the box's centre plus ``offset``."""
    lo, hi = _bounds(polylines)
    turned = _rotate(polylines, rotation, (lo + hi) / 2)
    lo, hi = _bounds(turned)
    extent = hi - lo
    if not np.all(np.isfinite(extent)) or extent.max() <= 0:
        raise ServiceError(f"{what}: the drawing has no extent")
    box_size = np.array([box[2] - box[0], box[3] - box[1]])
    if scale is None:
        fit = float(np.min(box_size / np.maximum(extent, 1e-12)))
        scale = fit if size is None else size / float(extent.max())
    centre_in = (lo + hi) / 2
    centre_out = np.array([(box[0] + box[2]) / 2 + offset[0], (box[1] + box[3]) / 2 + offset[1]])
    return [(p - centre_in) * scale + centre_out for p in turned]


def _check_inside(polylines: list[np.ndarray], box, what: str, field_name: str) -> None:
    lo, hi = _bounds(polylines)
    over = max(box[0] - lo[0], box[1] - lo[1], hi[0] - box[2], hi[1] - box[3])
    if over > 1e-6:
        raise ServiceError(
            f"{what} reaches {over:.1f} mm past the paper's drawable area ({box[0]:g}..{box[2]:g} x "
            f"{box[1]:g}..{box[3]:g} mm); expected a smaller size or scale, or an offset that keeps it inside",
            field=field_name, value=over)


@station_errors
def compose(composition: Composition, profile: MachineProfile,
            sample: Callable[[PatternSource], np.ndarray] | None = None) -> PlotDocument:
    """Lay the composition's sources out on the profile's paper as a document of layers.

    ``sample(source)`` gives a pattern's points (the caller's drawing-machine models); a source with ``polyline``
    set needs none. Layers come in the order the composition's ``[[layers]]`` name them, then as sources first
    draw on them; a layer with nothing to draw is left out.

    Raises
    ------
    ServiceError
        A source that does not fit the drawable area, an SVG that cannot be read, nothing to draw.
    """
    paper, box = drawable_box(profile)
    layers: dict[str, PlotLayer] = {}
    specs = {spec.layer: spec for spec in composition.pens}
    for spec in composition.pens:
        layers.setdefault(spec.layer, PlotLayer(spec.layer, spec.layer, ""))

    def layer(name: str, color: str | None = None, width: float | None = None) -> PlotLayer:
        if name not in layers:
            layers[name] = PlotLayer(name, name, color or "", width or 0.3)
        found = layers[name]
        if color and not found.color:
            found.color = color
        return found

    counts: dict[str, int] = {}
    for k, source in enumerate(composition.sources, start=1):
        if isinstance(source, PatternSource):
            what = f"pattern {k} ({source.label or source.machine})"
            points = source.polyline if source.polyline is not None else sample(source)
            placed = _place([np.asarray(points, dtype=float)], source.scale, source.size, source.offset,
                            source.rotation, box, what)
            _check_inside(placed, box, what, "scale" if source.scale is not None else "size")
            base = source.layer or source.label or source.machine
            name = base
            if source.layer is None:
                counts[base] = counts.get(base, 0) + 1
                name = base if counts[base] == 1 else f"{base} {counts[base]}"
            layer(name).polylines.extend(placed)
        else:
            what = f"SVG {source.path}"
            svg_layers = read_svg_layers(source.path, source.by)
            if not svg_layers:
                raise ServiceError(f"{source.path}: no visible paths to plot", field="svg", value=str(source.path))
            everything = [p for svg_layer in svg_layers for p in svg_layer.polylines]
            placed = _place(everything, source.scale, None, source.offset, source.rotation, box, what)
            _check_inside(placed, box, what, "scale")
            start = 0
            for svg_layer in svg_layers:
                count = len(svg_layer.polylines)
                target = layer(source.layer or svg_layer.name, svg_layer.color, svg_layer.width)
                target.polylines.extend(placed[start:start + count])
                start += count
    kept = [found for found in layers.values() if found.polylines]
    if not kept:
        raise ServiceError("nothing to plot: every layer is empty")
    used = {found.color for found in kept if found.color} | {spec.color for spec in specs.values() if spec.color}
    palette = iter([entry for entry in PALETTE if entry[1] not in used] + list(PALETTE))
    for found in kept:
        spec = specs.get(found.name)
        pen_name = None
        if spec is not None and spec.color:
            found.color = spec.color
        if not found.color:
            pen_name, found.color = next(palette)
        found.pen = spec.pen if spec is not None and spec.pen else (pen_name or found.pen)
        if spec is not None:
            found.width = spec.width or found.width
            found.feed = spec.feed
    return PlotDocument(kept, paper, box)


# ----------------------------------------------------------------------------------------------------------- vpype


@station_errors
def optimize(document: PlotDocument, *, merge: bool = True, sort: bool = True, reloop: bool = True,
             tolerance: float = 0.0, seed: int = 0, report: Reporter | None = None) -> PlotDocument:
    """vpype's line optimizations per layer: ``linemerge`` (ends within :data:`MERGE_TOLERANCE`), ``reloop`` (the
    seam of each closed path moved to a random vertex drawn from ``seed``: the pen's mark at the seam does not line
    up across a pattern), ``linesort`` (greedy nearest path end next, paths reversed when that is nearer; the first
    layer starts from the origin, each later one where the previous ended), ``linesimplify`` (within ``tolerance``
    mm; 0 keeps every point). ``report`` hears of each layer (stage ``"optimize"``) and may stop between them."""
    import vpype as vp  # deferred: see the module's notes

    report = Reporter.of(report)
    rng = np.random.default_rng(seed)
    position = 0j
    layers = []
    for number, layer in enumerate(document.layers):
        report("optimize", number, len(document.layers), f"optimizing layer {number + 1} of {len(document.layers)}")
        lines = vp.LineCollection([p[:, 0] + 1j * p[:, 1] for p in layer.polylines if len(p) >= 2])
        if merge:
            lines.merge(tolerance=MERGE_TOLERANCE, flip=True)
        if reloop:
            for index, line in enumerate(lines.lines):
                if len(line) > 3 and abs(line[-1] - line[0]) <= MERGE_TOLERANCE:
                    lines.lines[index] = vp.reloop(line, int(rng.integers(len(line) - 1)))
        if sort and len(lines) > 0:
            lines = _linesort(lines, position)
        if tolerance > 0 and len(lines) > 0:
            simplified = lines.as_mls().simplify(tolerance=tolerance, preserve_topology=False)
            lines = vp.LineCollection(simplified)
        if len(lines):
            position = lines.lines[-1][-1]
        polylines = [np.column_stack([line.real, line.imag]) for line in lines if len(line) >= 2]
        layers.append(replace(layer, polylines=polylines))
    return PlotDocument(layers, document.paper, document.box)


def _linesort(lines, start: complex):
    """vpype's ``linesort`` (greedy, with reversal) on its ``LineIndex``, from ``start`` (the pen's position)."""
    import vpype as vp

    index = vp.LineIndex(list(lines), reverse=True)
    ordered = vp.LineCollection()
    position = start
    while len(index) > 0:
        found, reverse = index.find_nearest(position)
        line = index.pop(found)
        if line is None:
            continue
        if reverse:
            line = np.flip(line)
        ordered.append(line)
        position = line[-1]
    return ordered


# ----------------------------------------------------------------------------------------------------------- G-code


@station_errors
def writer_options(profile: MachineProfile, power: float = 0.3) -> WriterOptions:
    """The G-code writer's options for ``profile`` (pen lines for a plotter, dark travels for a laser)."""
    kind = "pen plot" if profile.kind == "plotter" else "plot"
    return WriterOptions.from_profile(profile, power=power, comment=f"chaos-station {kind} job for {profile.name}")


@station_errors
def layered_gcode(document: PlotDocument, profile: MachineProfile, power: float = 0.3) -> tuple[str, WriterOptions]:
    """The document as one G-code job: a plotter changes pens between layers (the profile's ``[pen] change``
    lines, ``M0`` by default, after a message comment); a laser has no pen and runs its layers one after another."""
    options = writer_options(profile, power)
    change = tuple(profile.pen.change) if profile.kind == "plotter" and profile.pen is not None else ()
    layers = [PenLayer(layer.name, layer.pen, layer.color, layer.polylines, layer.feed) for layer in document.layers]
    stream = io.StringIO()
    write_layers_gcode(layers, stream, options, change)
    return stream.getvalue(), options


@station_errors
def line_times(lines: Sequence[str], toolpath, profile: MachineProfile) -> np.ndarray:
    """Seconds per line of a job on the profile's machine, as GRBL's planner runs it (:mod:`drivers.grbl.planner`:
    the streamer's ETA is the same figure)."""
    return line_seconds(toolpath, lines, profile.grbl_settings, laser_mode=profile.is_laser)


@station_errors
def job_layers(lines: Sequence[str], profile: MachineProfile) -> list[LayerSummary]:
    """The layers of a written job (its marks) with their drawing, travel and estimated time, read from the G-code
    with the streamer's interpreter (so the figures are those of the job that runs); empty for a job without marks.
    Paths and points count the pen-down runs."""
    lines = list(lines)
    marks = layer_marks(lines)
    if not marks:
        return []
    toolpath = interpret(lines, start=(0.0, 0.0, 0.0))
    per_line = line_times(lines, toolpath, profile)
    lengths = np.linalg.norm(toolpath.end - toolpath.start, axis=1)
    result = []
    for k, mark in enumerate(marks):
        first = 0 if k == 0 else mark.line
        last = marks[k + 1].line if k + 1 < len(marks) else len(lines)
        in_layer = (toolpath.line >= first) & (toolpath.line < last)
        drawing = in_layer & ~toolpath.rapid
        # a path starts at every feed segment that does not continue the one before it
        index = np.flatnonzero(drawing)
        starts = 0
        if len(index):
            joined = np.all(np.abs(toolpath.start[index[1:]] - toolpath.end[index[:-1]]) < 1e-9, axis=1) & (
                np.diff(index) == 1)
            starts = 1 + int(np.count_nonzero(~joined))
        result.append(LayerSummary(
            number=mark.number, name=mark.name, pen=mark.pen, color=mark.color, paths=starts,
            points=int(len(index) + starts), draw_mm=float(lengths[drawing].sum()),
            travel_mm=float(lengths[in_layer & toolpath.rapid].sum()), time_s=float(per_line[first:last].sum()),
            line=mark.line + 1, pause_line=None if mark.pause is None else mark.pause + 1))
    return result


@station_errors
def summarize(gcode: str, document: PlotDocument, profile: MachineProfile) -> list[LayerSummary]:
    """Per layer of the written job: :func:`job_layers`, with the paths and points the document has (a job without
    marks is one layer)."""
    lines = gcode.splitlines()
    layers = job_layers(lines, profile)
    if not layers and document.layers:
        layer = document.layers[0]
        toolpath = interpret(lines, start=(0.0, 0.0, 0.0))
        lengths = np.linalg.norm(toolpath.end - toolpath.start, axis=1)
        per_line = line_times(lines, toolpath, profile)
        layers = [LayerSummary(1, layer.name, layer.pen, layer.color, 0, 0, float(lengths[~toolpath.rapid].sum()),
                               float(lengths[toolpath.rapid].sum()), float(per_line.sum()), 1, None)]
    return [replace(summary, paths=len(layer.polylines), points=int(sum(len(p) for p in layer.polylines)))
            for summary, layer in zip(layers, document.layers)]


@station_errors
def plot(composition: Composition, profile: MachineProfile, *, sample=None, sort: bool = True,
         tolerance: float | None = None, power: float = 0.3, seed: int = 0,
         report: Reporter | None = None) -> PlotResult:
    """Compose, optimize (vpype; ``sort=False`` keeps the paths as drawn, merged and sorted neither), write and
    summarize a plot. ``report`` hears of each step (stages ``"compose"``, ``"optimize"``, ``"write"``); a stop
    asked for ends the work between two (:class:`common.progress.Cancelled`)."""
    tolerance = profile.plot.tolerance if tolerance is None else tolerance
    if not 0 <= tolerance < math.inf:
        raise ServiceError(f"tolerance must be >= 0 mm, got {tolerance}", field="tolerance", value=tolerance)
    if not 0 < power <= 1:
        raise ServiceError(f"power must be a fraction in (0, 1], got {power}", field="power", value=power)
    report = Reporter.of(report)
    report("compose", 0, 1, "placing the drawings")
    document = compose(composition, profile, sample)
    document = optimize(document, merge=sort, sort=sort, reloop=sort, tolerance=tolerance, seed=seed, report=report)
    report("write", 0, 1, "writing the G-code")
    gcode, options = layered_gcode(document, profile, power)
    report("write", 1, 1, "written")
    return PlotResult(gcode, document, options, summarize(gcode, document, profile))


# ----------------------------------------------------------------------------------------------------------- preview


@station_errors
def format_minutes(seconds: float) -> str:
    """``12:05`` (minutes and seconds), ``1:02:05`` from an hour on."""
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


@station_errors
def write_preview_png(result: PlotResult, target, size: int = 1200) -> None:
    """The plot as a picture: the paper and its drawable area, each layer in its pen's colour, the pen-up travel
    as thin grey lines, and a legend with each layer's pen, paths, drawing, travel and time."""
    from PIL import Image, ImageDraw, ImageFont

    document = result.document
    width_mm, height_mm = document.paper
    legend_h = 28 + 22 * len(result.layers)
    scale = (size - 40) / max(width_mm, height_mm)
    w_px, h_px = int(width_mm * scale) + 40, int(height_mm * scale) + 40 + legend_h
    image = Image.new("RGB", (w_px, h_px), "#e8e8e8")
    draw = ImageDraw.Draw(image)

    def to_px(points: np.ndarray) -> list[tuple[float, float]]:
        return [(20 + x * scale, 20 + (height_mm - y) * scale) for x, y in points]

    draw.rectangle([20, 20, 20 + width_mm * scale, 20 + height_mm * scale], fill="white", outline="#999999")
    x0, y0, x1, y1 = document.box
    draw.rectangle([*to_px(np.array([[x0, y1]]))[0], *to_px(np.array([[x1, y0]]))[0]], outline="#dddddd")
    # the travel the job makes (the pen-change park moves too), read from its G-code as the streamer reads it
    toolpath = interpret(result.gcode.splitlines(), start=(0.0, 0.0, 0.0))
    for k in np.flatnonzero(toolpath.rapid):
        draw.line(to_px(np.array([toolpath.start[k, :2], toolpath.end[k, :2]])), fill="#b0b0b0", width=1)
    for layer in document.layers:
        pen_px = max(1, int(round(layer.width * scale)))
        for polyline in layer.polylines:
            draw.line(to_px(polyline), fill=layer.color, width=pen_px, joint="curve")
    try:
        font = ImageFont.load_default(size=15)
    except TypeError:  # Pillow before 10.1 has one size
        font = ImageFont.load_default()
    top = int(height_mm * scale) + 48
    draw.text((20, top - 4), f"total {format_minutes(result.time_s)} (estimate), travel {result.travel_mm:.0f} mm "
              "(grey)", fill="black", font=font)
    for k, layer in enumerate(result.layers):
        y = top + 20 + 22 * k
        draw.rectangle([20, y + 2, 44, y + 14], fill=layer.color)
        pause = f", pause at line {layer.pause_line}" if layer.pause_line else ""
        draw.text((52, y), f"{layer.number}. {layer.name}: pen {layer.pen}, {layer.paths} paths, "
                  f"{layer.draw_mm:.0f} mm drawn, {layer.travel_mm:.0f} mm travel, {format_minutes(layer.time_s)}"
                  f"{pause}", fill="black", font=font)
    image.save(target, format="PNG")
