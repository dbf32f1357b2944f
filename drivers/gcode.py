"""G-code for GRBL machines: a writer for plot jobs from plain numpy polylines, and a small parser.

Writer
------
:func:`write_plot_gcode` writes polylines (``(n, 2)`` arrays in work millimetres) to a text stream with pen
up/down (or laser on/off) commands and feeds from :class:`WriterOptions`. :func:`fit_polylines` scales and centres
polylines on a box (the paper), :func:`simplify_polylines` reduces the vertex count within a tolerance (Douglas-Peucker,
by shapely), both plain numpy in, numpy out.

Parser
------
:func:`clean_line` strips comments and whitespace the way GRBL does; :func:`tokenize` splits a block into words;
:func:`interpret` runs the modal state machine over a program and returns a :class:`Toolpath` (segments with their
line index, rapid or feed, feed rate and spindle power) used for job pre-flight (extent), ETA estimates, resume from
line N (modal state) and by tests to read a job back.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import TextIO

import numpy as np

from drivers.errors import DriverError
from drivers.gcode_words import (
    PLANE_AXES,
    WordSyntaxError,
    arc_chords,
    arc_sweep,
    iter_words,
    radius_arc_centre,
    strip_comments,
)

__all__ = [
    "GcodeError",
    "ModalState",
    "Toolpath",
    "WriterOptions",
    "clean_line",
    "drawn_polylines",
    "fit_polylines",
    "interpret",
    "simplify_polylines",
    "tokenize",
    "write_plot_gcode",
]


class GcodeError(DriverError, ValueError):
    """A G-code line cannot be parsed; the message quotes the line and its number."""


def clean_line(line: str) -> str:
    """The block GRBL sees: comments ``( )`` and ``;`` removed, whitespace removed, upper case.

    ``$`` system commands keep their case-insensitive text but lose whitespace too, as GRBL does.
    """
    return "".join(strip_comments(line).split()).upper()


def tokenize(block: str) -> list[tuple[str, float]]:
    """Words of a cleaned block as ``(letter, value)``.

    Raises
    ------
    GcodeError
        If the block has text that is not a letter followed by a number.
    """
    try:
        return list(iter_words(block))
    except WordSyntaxError as error:
        raise GcodeError(f"cannot parse {block!r} at column {error.column + 1}: expected a letter and a number") \
            from None


def _fmt(value: float, precision: int = 3) -> str:
    text = f"{value:.{precision}f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "", "-") else text


# ----------------------------------------------------------------------------------------------------------- writer


@dataclass(frozen=True)
class WriterOptions:
    """How :func:`write_plot_gcode` writes a job.

    Parameters
    ----------
    draw_feed, travel_feed : float
        Feeds (mm/min) for drawing moves (``G1``) and travels. Travels use ``G0`` (the machine's rapid rate) unless
        ``travel_with_g1`` is set, then ``G1`` at ``travel_feed``.
    pen_up, pen_down : sequence of str
        Lines that lift / lower the pen (or switch the laser off / on). For a laser in laser mode these are usually
        empty and ``header`` holds ``M4 S<power>``: ``G0`` travels are dark in laser mode.
    header, footer : sequence of str
        Lines before the first / after the last polyline (after the final pen up).
    precision : int
        Decimals of coordinates.
    home_at_end : bool
        Travel back to X0 Y0 at the end.
    comment : str
        A first comment line (``(...)``); empty for none.
    """

    draw_feed: float = 3000.0
    travel_feed: float = 6000.0
    pen_up: Sequence[str] = ("M3 S50", "G4 P0.15")
    pen_down: Sequence[str] = ("M3 S30", "G4 P0.15")
    header: Sequence[str] = ("G21", "G90", "G94")
    footer: Sequence[str] = ()
    precision: int = 3
    home_at_end: bool = True
    travel_with_g1: bool = False
    comment: str = ""

    @classmethod
    def from_profile(cls, profile, **overrides) -> WriterOptions:
        """Options for a :class:`drivers.profiles.MachineProfile`: pen commands for a plotter; for a laser, dark
        ``G0`` travels in laser mode with ``M4 S<power>`` (``overrides['power']``, a fraction, default 0.3)."""
        power = overrides.pop("power", 0.3)
        base = {"draw_feed": profile.plot.draw_feed, "travel_feed": profile.plot.travel_feed}
        if profile.kind == "laser":
            s_value = _fmt(power * profile.laser.max_power, 1)
            base.update(pen_up=(), pen_down=(), header=("G21", "G90", "G94", f"M4 S{s_value}"), footer=("M5 S0",))
        else:
            base.update(pen_up=tuple(profile.pen.up_commands()), pen_down=tuple(profile.pen.down_commands()))
        base.update(overrides)
        return cls(**base)


def write_plot_gcode(polylines: Iterable[np.ndarray], stream: TextIO, options: WriterOptions | None = None) -> int:
    """Write polylines as a G-code job to ``stream``.

    Parameters
    ----------
    polylines : iterable of (n, 2) arrays
        Work coordinates in mm. Polylines with fewer than 2 points are skipped.
    stream : text stream
    options : WriterOptions

    Returns
    -------
    int
        Number of lines written.
    """
    options = options or WriterOptions()
    p = options.precision
    lines: list[str] = []
    if options.comment:
        lines.append(f"({options.comment})")
    lines.extend(options.header)
    lines.extend(options.pen_up)
    travel = "G1" if options.travel_with_g1 else "G0"
    travel_feed = f" F{_fmt(options.travel_feed, p)}" if options.travel_with_g1 else ""
    for polyline in polylines:
        points = np.asarray(polyline, dtype=float)
        if points.ndim != 2 or points.shape[1] != 2:
            raise GcodeError(f"polyline must be an (n, 2) array, got shape {points.shape}")
        if len(points) < 2:
            continue
        if not np.all(np.isfinite(points)):
            raise GcodeError("polyline has non-finite coordinates")
        x0, y0 = points[0]
        lines.append(f"{travel} X{_fmt(x0, p)} Y{_fmt(y0, p)}{travel_feed}")
        lines.extend(options.pen_down)
        first = True
        for x, y in points[1:]:
            feed = f" F{_fmt(options.draw_feed, p)}" if first else ""
            lines.append(f"G1 X{_fmt(x, p)} Y{_fmt(y, p)}{feed}")
            first = False
        lines.extend(options.pen_up)
    if options.home_at_end:
        lines.append(f"{travel} X0 Y0{travel_feed}")
    lines.extend(options.footer)
    for line in lines:
        stream.write(line + "\n")
    return len(lines)


def fit_polylines(
    polylines: Sequence[np.ndarray], box: tuple[float, float, float, float], size: float | None = None
) -> list[np.ndarray]:
    """Scale (uniformly) and centre polylines on ``box = (xmin, ymin, xmax, ymax)``.

    ``size`` (mm) is the largest side of the result; by default the largest that fits the box. Raises
    :class:`GcodeError` if ``size`` does not fit or the drawing has no extent.
    """
    if not polylines:
        raise GcodeError("nothing to fit: no polylines")
    stacked = np.concatenate([np.asarray(p, dtype=float).reshape(-1, 2) for p in polylines])
    lo, hi = stacked.min(axis=0), stacked.max(axis=0)
    extent = hi - lo
    if not np.all(np.isfinite(extent)) or extent.max() <= 0:
        raise GcodeError("nothing to fit: the drawing has no extent")
    box_size = np.array([box[2] - box[0], box[3] - box[1]])
    fit = float(np.min(box_size / np.maximum(extent, 1e-12)))
    scale = fit if size is None else size / extent.max()
    if scale > fit * (1 + 1e-9):
        raise GcodeError(
            f"size {size:g} mm does not fit the drawable area {box_size[0]:g} x {box_size[1]:g} mm "
            f"(largest side at most {fit * extent.max():.1f} mm)"
        )
    centre_in = (lo + hi) / 2
    centre_out = np.array([(box[0] + box[2]) / 2, (box[1] + box[3]) / 2])
    return [(np.asarray(p, dtype=float).reshape(-1, 2) - centre_in) * scale + centre_out for p in polylines]


def simplify_polylines(polylines: Sequence[np.ndarray], tolerance: float) -> list[np.ndarray]:
    """Douglas-Peucker simplification (shapely) of each polyline: every removed vertex lies within ``tolerance``
    (mm) of the simplified path; endpoints are kept, so closed polylines stay closed."""
    from shapely import LineString

    out = []
    for polyline in polylines:
        points = np.asarray(polyline, dtype=float).reshape(-1, 2)
        if len(points) < 3 or tolerance <= 0:
            out.append(points.copy())
            continue
        keep = np.ones(len(points), dtype=bool)
        keep[1:] = np.any(np.abs(np.diff(points, axis=0)) > 0, axis=1)  # drop repeated points first
        points = points[keep]
        if len(points) < 3:
            out.append(points)
            continue
        simplified = LineString(points).simplify(tolerance, preserve_topology=False)
        coords = np.asarray(simplified.coords)
        if len(coords) < 2:  # degenerate closed ring: keep a minimal path
            coords = points[[0, len(points) // 2, -1]]
        out.append(coords)
    return out


# ----------------------------------------------------------------------------------------------------------- parser

_MOTION = {0.0: 0, 1.0: 1, 2.0: 2, 3.0: 3, 80.0: 80}


@dataclass
class ModalState:
    """The modal state after some lines of a program (what :func:`resume_preamble` rebuilds)."""

    motion: int = 0
    units_mm: bool = True
    absolute: bool = True
    feed: float = 0.0
    spindle: int = 5  # 3, 4 or 5
    power: float = 0.0
    wcs: int = 54
    plane: int = 17
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    position_known: bool = False

    def copy(self) -> ModalState:
        return replace(self, position=self.position.copy())

    def preamble(self, pen_up: Sequence[str] = ("M5",)) -> list[str]:
        """Lines that rebuild this state on a fresh machine before resuming: units, distance mode, coordinate
        system, tool lifted (pen up or laser off), travel to the position, spindle/laser state, feed."""
        lines = [f"G{21 if self.units_mm else 20} G90 G94 G{self.wcs} G{self.plane}"]
        lines.extend(pen_up)
        if self.position_known:
            x, y, z = self.position / (1.0 if self.units_mm else 25.4)
            lines.append(f"G0 X{_fmt(x)} Y{_fmt(y)}")
        if self.spindle in (3, 4):
            lines.append(f"M{self.spindle} S{_fmt(self.power)}")
        else:
            lines.append(f"M5 S{_fmt(self.power)}")
        if self.feed > 0:
            lines.append(f"F{_fmt(self.feed / (1.0 if self.units_mm else 25.4))}")
        if not self.absolute:
            lines.append("G91")
        return lines


@dataclass(frozen=True)
class Toolpath:
    """Straight segments of a program in work mm (arcs are split into short chords).

    Attributes
    ----------
    start, end : (m, 3) arrays
    line : (m,) int array
        0-based index of the program line that made each segment.
    rapid : (m,) bool array
    feed : (m,) float array
        mm/min (``nan`` for rapids: the machine's own rate).
    power : (m,) float array
        Spindle S in force with M3/M4 (0 with M5).
    states : list of ModalState
        Modal state *before* each line (length = number of lines + 1; the last one is after the program).
    dwell : (lines,) float array
        Seconds of ``G4`` dwell per line.
    commanded : (lines, 3) bool array
        Which of X, Y, Z each line names in a move (a pre-flight tells the job's own size from where the head
        happened to stand before the job first moved an axis).
    """

    start: np.ndarray
    end: np.ndarray
    line: np.ndarray
    rapid: np.ndarray
    feed: np.ndarray
    power: np.ndarray
    states: list
    dwell: np.ndarray
    commanded: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), dtype=bool))

    def extent(self, include_rapids: bool = True) -> tuple[np.ndarray, np.ndarray] | None:
        """``(lo, hi)`` of every visited point (3-vectors), or None for a program without motion."""
        if len(self.start) == 0:
            return None
        mask = np.ones(len(self.start), bool) if include_rapids else ~self.rapid
        if not mask.any():
            return None
        points = np.concatenate([self.start[mask], self.end[mask]])
        return points.min(axis=0), points.max(axis=0)

    def durations(self, rapid_rate: float = 6000.0) -> np.ndarray:
        """Estimated seconds per line at the commanded feeds (no acceleration), dwells included."""
        lengths = np.linalg.norm(self.end - self.start, axis=1)
        feed = np.where(self.rapid | ~np.isfinite(self.feed) | (self.feed <= 0), rapid_rate, self.feed)
        per_line = np.zeros(len(self.dwell))
        np.add.at(per_line, self.line, lengths / feed * 60.0)
        return per_line + self.dwell


def _arc_points(start, end, centre, clockwise: bool, axes=(0, 1), max_chord_error: float = 0.01):
    """Chord end points of an arc, each chord within ``max_chord_error`` (mm) of the circle."""
    a, b = axes
    r = math.hypot(start[a] - centre[0], start[b] - centre[1])
    t0, sweep = arc_sweep(start, end, centre, clockwise, axes, full_turn_below=1e-12)
    if r <= max_chord_error:
        n = 1
    else:
        step = 2 * math.acos(max(-1.0, 1 - max_chord_error / r))
        n = max(1, int(math.ceil(abs(sweep) / max(step, 1e-6))))
    return arc_chords(start, end, centre, r, t0, sweep, axes, n)


def interpret(
    lines: Sequence[str], start: Sequence[float] | None = None, wco: Sequence[float] | None = None
) -> Toolpath:
    """Run GRBL's modal state machine over ``lines`` (work coordinates).

    With ``wco`` (the work coordinate offset, machine = work + wco), ``G53`` moves in machine coordinates become
    segments too (so that a pre-flight checks them); without it they leave the position unknown.

    Supports G0/G1/G2/G3 (IJK or R), G4, G17-G19, G20/G21, G90/G91, G54-G59, G92 is ignored (rare in jobs), M3/M4/M5,
    F, S; ``$`` commands and unknown words are passed over (the machine will judge them).

    Raises
    ------
    GcodeError
        On a line that cannot be tokenized, naming its number.
    """
    state = ModalState()
    if start is not None:
        state.position = np.asarray(start, dtype=float).copy()
        state.position_known = True
    starts, ends, seg_line, rapid, feeds, powers = [], [], [], [], [], []
    states = []
    dwell = np.zeros(len(lines))
    commanded = np.zeros((len(lines), 3), dtype=bool)
    for index, raw in enumerate(lines):
        states.append(state.copy())
        block = clean_line(raw)
        if not block or block.startswith("$"):
            continue
        try:
            words = tokenize(block)
        except GcodeError as error:
            raise GcodeError(f"line {index + 1}: {error}") from None
        unit = 1.0 if state.units_mm else 25.4
        axis: dict[str, float] = {}
        offsets: dict[str, float] = {}
        radius = None
        dwell_p = None
        g_values = [v for letter, v in words if letter == "G"]
        for letter, value in words:
            if letter == "G":
                if value in (20.0, 21.0):
                    state.units_mm = value == 21.0
                    unit = 1.0 if state.units_mm else 25.4
                elif value in (90.0, 91.0):
                    state.absolute = value == 90.0
                elif value in _MOTION:
                    state.motion = _MOTION[value]
                elif value in (17.0, 18.0, 19.0):
                    state.plane = int(value)
                elif 54.0 <= value <= 59.0 and value == int(value):
                    state.wcs = int(value)
            elif letter == "M":
                if value in (3.0, 4.0, 5.0):
                    state.spindle = int(value)
                elif value in (2.0, 30.0):
                    state.spindle = 5
            elif letter == "S":
                state.power = value
            elif letter == "F":
                state.feed = value * unit
            elif letter in "XYZ":
                axis[letter] = value
            elif letter in "IJK":
                offsets[letter] = value
            elif letter == "R":
                radius = value
            elif letter == "P":
                dwell_p = value
        if 4.0 in g_values:
            dwell[index] = dwell_p or 0.0
            continue
        if 53.0 in g_values and wco is not None and axis and state.motion in (0, 1):
            commanded[index] = [name in axis for name in "XYZ"]
            target = state.position.copy()
            for i, name in enumerate("XYZ"):
                if name in axis:
                    target[i] = axis[name] * unit - wco[i]
            if state.position_known:
                starts.append(state.position.copy())
                ends.append(target.copy())
                seg_line.append(index)
                rapid.append(state.motion == 0)
                feeds.append(np.nan if state.motion == 0 else state.feed)
                powers.append(state.power if state.spindle in (3, 4) else 0.0)
                state.position = target
            continue
        if any(v in (10.0, 28.0, 30.0, 53.0, 92.0, 28.1, 30.1, 92.1) for v in g_values):
            # offsets and machine-coordinate moves: not part of a job's drawing; position becomes unknown
            if axis or any(v in (28.0, 30.0) for v in g_values):
                state.position_known = False
            continue
        if not axis or state.motion == 80:
            continue
        commanded[index] = [name in axis for name in "XYZ"]
        target = state.position.copy()
        for i, name in enumerate("XYZ"):
            if name in axis:
                target[i] = axis[name] * unit if state.absolute else target[i] + axis[name] * unit
        if state.motion in (0, 1):
            pieces = target[None, :]
        else:
            a, b = PLANE_AXES[state.plane]
            if radius is not None:
                r = radius * unit
                d = math.hypot(target[a] - state.position[a], target[b] - state.position[b])
                if d == 0 or d > 2 * abs(r) + 1e-6:
                    raise GcodeError(f"line {index + 1}: arc radius {radius} cannot reach the end point")
                centre = radius_arc_centre(state.position, target, r, state.motion == 2, (a, b))
            else:
                names = "IJK"
                centre = (
                    state.position[a] + offsets.get(names[a], 0.0) * unit,
                    state.position[b] + offsets.get(names[b], 0.0) * unit,
                )
            pieces = _arc_points(state.position, target, centre, state.motion == 2, (a, b))
        # from an unknown position (first move of a program) the segment is just its end point
        previous = state.position.copy() if state.position_known else pieces[-1].copy()
        if not state.position_known:
            pieces = pieces[-1:]
        for piece in pieces:
            if previous is not None:
                starts.append(previous)
                ends.append(piece.copy())
                seg_line.append(index)
                rapid.append(state.motion == 0)
                feeds.append(np.nan if state.motion == 0 else state.feed)
                powers.append(state.power if state.spindle in (3, 4) else 0.0)
            previous = piece.copy()
        state.position = target
        state.position_known = True
    states.append(state.copy())
    as_array = lambda rows: np.array(rows, dtype=float).reshape(-1, 3)  # noqa: E731
    return Toolpath(
        start=as_array(starts),
        end=as_array(ends),
        line=np.array(seg_line, dtype=int),
        rapid=np.array(rapid, dtype=bool),
        feed=np.array(feeds, dtype=float),
        power=np.array(powers, dtype=float),
        states=states,
        dwell=dwell,
        commanded=commanded,
    )


def drawn_polylines(
    lines: Sequence[str], pen_down: Sequence[str] | None = None, pen_up: Sequence[str] | None = None
) -> list[np.ndarray]:
    """Read back the drawn polylines (x, y) of a plot job: runs of consecutive feed moves (``G1``/arcs) with the
    tool down. With ``pen_down``/``pen_up`` (lines as written by the profile), the tool is down between them;
    without, a feed move with spindle on (M3/M4 and S > 0) draws (laser jobs)."""
    toolpath = interpret(lines)
    down_marks = {clean_line(x) for x in (pen_down or ()) if not clean_line(x).startswith("G4")}
    up_marks = {clean_line(x) for x in (pen_up or ()) if not clean_line(x).startswith("G4")}
    down_lines = np.zeros(len(lines) + 1, dtype=bool)
    is_down = False
    for index, raw in enumerate(lines):
        block = clean_line(raw)
        if pen_down is not None:
            if block in down_marks:
                is_down = True
            elif block in up_marks:
                is_down = False
        down_lines[index] = is_down
    polylines: list[list[np.ndarray]] = []
    current: list[np.ndarray] = []
    last_end = None
    for k in range(len(toolpath.start)):
        if pen_down is not None:
            drawing = down_lines[toolpath.line[k]] and not toolpath.rapid[k]
        else:
            drawing = (not toolpath.rapid[k]) and toolpath.power[k] > 0
        if drawing:
            if not current or last_end is None or np.any(np.abs(toolpath.start[k] - last_end) > 1e-9):
                if len(current) >= 2:
                    polylines.append(current)
                current = [toolpath.start[k][:2]]
            current.append(toolpath.end[k][:2])
            last_end = toolpath.end[k]
        else:
            if len(current) >= 2:
                polylines.append(current)
            current = []
            last_end = None
    if len(current) >= 2:
        polylines.append(current)
    return [np.array(p) for p in polylines]
