"""The G-code GRBL machines speak, read: a small parser of the programs the station sends.

:func:`clean_line` strips comments and whitespace the way GRBL does; :func:`tokenize` splits a block into words;
:func:`interpret` runs the modal state machine over a program and returns a :class:`Toolpath` (segments with their
line index, rapid or feed, feed rate and spindle power) used for job pre-flight (extent), ETA estimates, resume from
line N (modal state), previews (:func:`drawn_polylines`) and by tests to read a job back. Writing programs (tool
paths) is :mod:`cam`'s.
"""
from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from drivers.errors import DriverError
from drivers.gcode_words import (
    NUMBER,
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
    "WorkOffsets",
    "clean_line",
    "drawn_polylines",
    "format_number",
    "interpret",
    "tokenize",
]


class GcodeError(DriverError, ValueError):
    """A G-code line cannot be parsed; the message quotes the line and its number."""


def clean_line(line: str) -> str:
    """The block GRBL sees: comments ``( )`` and ``;`` removed, whitespace removed, upper case.

    ``$`` system commands keep their case-insensitive text but lose whitespace too, as GRBL does.
    """
    if "(" in line or ";" in line:  # most lines of a job have no comment: the regular expression is skipped
        line = strip_comments(line)
    return "".join(line.split()).upper()


#: A word as :func:`drivers.gcode_words.iter_words` reads it (a letter and GRBL's number), to find them all at once.
_WORD = re.compile(r"([A-Z])(" + NUMBER.pattern + ")")


def tokenize(block: str) -> list[tuple[str, float]]:
    """Words of a cleaned block as ``(letter, value)``.

    Raises
    ------
    GcodeError
        If the block has text that is not a letter followed by a number.
    """
    words = _WORD.findall(block)
    if sum(len(letter) + len(number) for letter, number in words) == len(block):
        return [(letter, float(number)) for letter, number in words]  # the words cover the block: all valid
    try:
        return list(iter_words(block))
    except WordSyntaxError as error:
        raise GcodeError(f"cannot parse {block!r} at column {error.column + 1}: expected a letter and a number") \
            from None


def format_number(value: float, precision: int = 3) -> str:
    """``value`` as a G-code number: at most ``precision`` decimals, no trailing zeros, never ``-0``."""
    text = f"{value:.{precision}f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "", "-") else text


# ----------------------------------------------------------------------------------------------------------- parser

_MOTION = {0.0: 0, 1.0: 1, 2.0: 2, 3.0: 3, 38.2: 38, 38.3: 38, 38.4: 38, 38.5: 38, 80.0: 80}

#: Words that set or clear a work offset: the work coordinates a program's later moves are read in.
_OFFSET_WORDS = (10.0, 43.1, 49.0, 92.0, 92.1)


@dataclass(frozen=True)
class WorkOffsets:
    """GRBL's coordinate offsets as ``$#`` and ``$G`` report them (machine mm), so that :func:`interpret` follows a
    program that changes its work coordinates (``G54``-``G59``, ``G10 L2``/``L20``, ``G92``, ``G43.1``) or goes to a
    stored position (``G28``, ``G30``).

    ``systems`` maps 54..59 to their offsets (a missing one is 0), ``wcs`` is the active one, ``g92`` the G92 offset
    in force, ``tlo`` the tool length offset (Z), ``g28``/``g30`` the stored positions (None: not known).
    """

    systems: dict = field(default_factory=dict)
    wcs: int = 54
    g92: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tlo: float = 0.0
    g28: tuple[float, float, float] | None = None
    g30: tuple[float, float, float] | None = None

    @classmethod
    def from_report(cls, offsets: dict, parser_state: str = "") -> WorkOffsets:
        """From ``$#``'s lines as a mapping (``{"G54": (x, y, z), ..., "G92": (...), "TLO": (z,)}``) and ``$G``'s
        modal state (its ``G54``..``G59`` is the active system)."""
        def vector(name: str) -> tuple[float, float, float] | None:
            values = offsets.get(name)
            if values is None or len(values) < 3:
                return None
            return (float(values[0]), float(values[1]), float(values[2]))

        wcs = 54
        for word in parser_state.split():
            if word in ("G54", "G55", "G56", "G57", "G58", "G59"):
                wcs = int(word[1:])
        systems = {n: vector(f"G{n}") for n in range(54, 60) if vector(f"G{n}") is not None}
        tlo = offsets.get("TLO") or (0.0,)
        return cls(systems=systems, wcs=wcs, g92=vector("G92") or (0.0, 0.0, 0.0), tlo=float(tlo[0]),
                   g28=vector("G28"), g30=vector("G30"))


@dataclass
class ModalState:
    """The modal state after some lines of a program (what :meth:`preamble` rebuilds).

    ``position`` is in the work coordinates in force (what the program's own numbers mean there). ``shift`` says how
    far those lie from the work coordinates the program started in (a point at ``position`` is at ``position +
    shift`` there), after the program's ``G92``, ``G10``, ``G54``-``G59`` or ``G43.1``; ``frame_known`` is False once
    an offset was set where the head's position was not known (after a probe, or a ``G28`` to an unknown place), and
    ``offsets_used`` True once the program set or cleared ``G92`` or a tool length offset (both cleared by a reset).
    """

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
    g92: np.ndarray = field(default_factory=lambda: np.zeros(3))
    tlo: float = 0.0
    shift: np.ndarray = field(default_factory=lambda: np.zeros(3))
    frame_known: bool = True
    offsets_used: bool = False

    def copy(self) -> ModalState:
        return replace(self, position=self.position.copy(), g92=self.g92.copy(), shift=self.shift.copy())

    def _snapshot(self) -> ModalState:
        # what :func:`interpret` keeps per line: it replaces the arrays and never writes into them, so they are
        # shared (a dataclass replace and three copies per line cost more than the rest of the line)
        snapshot = object.__new__(ModalState)
        snapshot.__dict__.update(self.__dict__)
        return snapshot

    @property
    def rebuildable(self) -> bool:
        """Whether :meth:`preamble` can rebuild the work offsets of this state on a reset machine (GRBL's reset
        clears ``G92`` and the tool length offset): they were set where the head's position was known."""
        return not self.offsets_used or (self.frame_known and (self.position_known or not np.any(self.g92)))

    def preamble(self, pen_up: Sequence[str] = ("M5",)) -> list[str]:
        """Lines that rebuild this state on a fresh machine before resuming: units, distance mode, coordinate
        system, tool lifted (pen up or laser off), the program's own ``G92`` and tool length offsets (GRBL's reset
        clears them; see :attr:`rebuildable`), travel to the position, spindle/laser state, feed."""
        unit = 1.0 if self.units_mm else 25.4
        lines = [f"G{21 if self.units_mm else 20} G90 G94 G{self.wcs} G{self.plane}"]
        lines.extend(pen_up)
        g92 = np.where(np.abs(self.g92) > 1e-9, self.g92, 0.0)
        if self.offsets_used:
            lines.append("G92.1")  # start from the offsets a reset leaves, whatever the machine had
            if self.tlo:
                lines.append(f"G43.1 Z{format_number(self.tlo / unit)}")
        if self.position_known:
            # with G92 cleared the position reads shifted by it; G92 then makes it read as the program's again
            x, y, z = (self.position + g92) / unit
            lines.append(f"G0 X{format_number(x)} Y{format_number(y)}" + (f" Z{format_number(z)}" if g92[2] else ""))
            if np.any(g92):
                lines.append("G92 " + " ".join(f"{name}{format_number(self.position[i] / unit)}"
                                               for i, name in enumerate("XYZ") if g92[i]))
        if self.spindle in (3, 4):
            lines.append(f"M{self.spindle} S{format_number(self.power)}")
        else:
            lines.append(f"M5 S{format_number(self.power)}")
        if self.feed > 0:
            lines.append(f"F{format_number(self.feed / unit)}")
        if not self.absolute:
            lines.append("G91")
        return lines


@dataclass(frozen=True)
class Toolpath:
    """Straight segments of a program (arcs are split into short chords), in the work coordinates the program
    starts in: a program that moves its work coordinates (``G92``, ``G10 L2``/``L20``, ``G54``-``G59``) has its later
    segments placed where they run (machine = these + the work offset the program started with).

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

    def offset_lines(self) -> list[int]:
        """0-based lines that moved the work coordinates (the ``shift`` of the state after them changed)."""
        return [index for index in range(len(self.states) - 1)
                if np.any(np.abs(self.states[index + 1].shift - self.states[index].shift) > 1e-9)
                or self.states[index + 1].frame_known != self.states[index].frame_known]

    def unplaced_line(self) -> int | None:
        """The first 0-based line whose motion runs where the interpreter cannot tell (an offset was set where the
        head's position was unknown), or None."""
        for index in self.line:
            if not self.states[index + 1].frame_known:
                return int(index)
        return None


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


class _Frames:
    """The work coordinate systems while a program is read: the G54..G59 table (``G10`` changes it), ``G92`` and
    the tool length offset (in the state), and ``shift``, the offset in force less the one the program started with.
    Without :class:`WorkOffsets` the table starts at 0: shifts are then still right, absolute offsets are not."""

    def __init__(self, offsets: WorkOffsets | None, state: ModalState) -> None:
        offsets = offsets or WorkOffsets()
        self.table = {n: np.array(offsets.systems.get(n, (0.0, 0.0, 0.0)), dtype=float) for n in range(54, 60)}
        self.stored = {28.0: offsets.g28, 30.0: offsets.g30}
        state.wcs = offsets.wcs
        state.g92 = np.array(offsets.g92, dtype=float)
        state.tlo = float(offsets.tlo)
        self.origin = self.total(state)

    def total(self, state: ModalState) -> np.ndarray:
        """The work offset in force (machine = work + this)."""
        return self.table[state.wcs] + state.g92 + np.array([0.0, 0.0, state.tlo])

    def moved(self, state: ModalState, before: np.ndarray) -> None:
        """The offset in force changed from ``before`` (the machine did not move): the position reads differently."""
        after = self.total(state)
        state.position = state.position - (after - before)
        state.shift = after - self.origin


def interpret(
    lines: Sequence[str], start: Sequence[float] | None = None, wco: Sequence[float] | None = None,
    offsets: WorkOffsets | None = None,
) -> Toolpath:
    """Run GRBL's modal state machine over ``lines`` (work coordinates).

    ``start`` is where the head stands (work mm); ``wco`` the work coordinate offset in force (machine = work +
    wco): with it, ``G53`` moves in machine coordinates and ``G28``/``G30`` to stored positions (from ``offsets``)
    become segments too (so that a pre-flight checks them); without, they leave the position unknown. ``offsets``
    (``$#``, ``$G``) lets a change of coordinate system (``G54``-``G59``, ``G10 L2``) place the moves after it;
    ``G92``, ``G92.1``, ``G10 L20`` and ``G43.1``/``G49`` are followed with or without it (they move the work
    coordinates relative to where the head stands).

    Supports G0/G1/G2/G3 (IJK or R), G38.x (a probe: the position is unknown after it), G4, G17-G19, G20/G21,
    G90/G91, G54-G59, G10 L2/L20, G28/G30 (+ .1), G53, G92/G92.1, G43.1/G49, M3/M4/M5, F, S; ``$`` commands and unknown
    words are passed over (the machine will judge them).

    Raises
    ------
    GcodeError
        On a line that cannot be tokenized, naming its number.
    """
    state = ModalState()
    frames = _Frames(offsets, state)
    if start is not None:
        state.position = np.asarray(start, dtype=float).copy()
        state.position_known = True
    starts, ends, seg_line, rapid, feeds, powers = [], [], [], [], [], []
    states = []
    dwell = np.zeros(len(lines))
    commanded = np.zeros((len(lines), 3), dtype=bool)

    def segment(index: int, a: np.ndarray, b: np.ndarray, is_rapid: bool) -> None:
        starts.append(a + state.shift)
        ends.append(b + state.shift)
        seg_line.append(index)
        rapid.append(is_rapid)
        feeds.append(np.nan if is_rapid else state.feed)
        powers.append(state.power if state.spindle in (3, 4) else 0.0)

    def go_to_machine(index: int, machine: dict[int, float]) -> None:
        """A rapid/feed move to machine coordinates (``G53``, ``G28``, ``G30``); needs ``wco``."""
        target = state.position.copy()
        for i, value in machine.items():
            target[i] = value - wco[i] - state.shift[i]
        if state.position_known:
            segment(index, state.position.copy(), target, state.motion != 1)
        state.position = target

    for index, raw in enumerate(lines):
        states.append(state._snapshot())
        block = clean_line(raw)
        if not block or block.startswith("$"):
            continue
        try:
            words = tokenize(block)
        except GcodeError as error:
            raise GcodeError(f"line {index + 1}: {error}") from None
        unit = 1.0 if state.units_mm else 25.4
        axis: dict[str, float] = {}
        offsets_ijk: dict[str, float] = {}
        radius = None
        values: dict[str, float] = {}
        g_values = [v for letter, v in words if letter == "G"]
        wcs = state.wcs
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
                offsets_ijk[letter] = value
            elif letter == "R":
                radius = value
            else:
                values[letter] = value
        if state.wcs != wcs:  # a G54..G59 in this block: the same place reads in the new system
            frames.moved(state, frames.table[wcs] + state.g92 + np.array([0.0, 0.0, state.tlo]))
        if 4.0 in g_values:
            dwell[index] = values.get("P") or 0.0
            continue
        if any(v in _OFFSET_WORDS for v in g_values):
            _set_offsets(state, frames, g_values, axis, values, unit)
            if 10.0 in g_values or 92.0 in g_values or 43.1 in g_values:
                continue  # their axis words are the offset's; after G92.1 or G49 they are a move, as in GRBL
        homing = next((v for v in g_values if v in (28.0, 30.0)), None)
        if 53.0 in g_values and wco is not None and axis and state.motion in (0, 1):
            commanded[index] = [name in axis for name in "XYZ"]
            go_to_machine(index, {i: axis[name] * unit for i, name in enumerate("XYZ") if name in axis})
            continue
        if 53.0 in g_values or homing is not None:
            stored = frames.stored[homing] if homing is not None else None
            if homing is not None and axis:
                # G28/G30 X.. Y..: a rapid to that work point first, then those axes alone to the stored position
                commanded[index] = [name in axis for name in "XYZ"]
                target = _target(state, axis, unit)
                if state.position_known:
                    segment(index, state.position.copy(), target, True)
                state.position = target
            if stored is not None and wco is not None and state.position_known:
                named = [i for i, name in enumerate("XYZ") if name in axis] or [0, 1, 2]
                motion, state.motion = state.motion, 0
                go_to_machine(index, {i: stored[i] for i in named})
                state.motion = motion
            elif axis or homing is not None:
                state.position_known = False
            continue
        if any(v in (28.1, 30.1) for v in g_values):
            if wco is not None and state.position_known:
                frames.stored[28.0 if 28.1 in g_values else 30.0] = tuple(state.position + state.shift + wco)
            else:
                frames.stored[28.0 if 28.1 in g_values else 30.0] = None
        if not axis or state.motion == 80:
            continue
        commanded[index] = [name in axis for name in "XYZ"]
        target = _target(state, axis, unit)
        if state.motion in (0, 1, 38):
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
                    state.position[a] + offsets_ijk.get(names[a], 0.0) * unit,
                    state.position[b] + offsets_ijk.get(names[b], 0.0) * unit,
                )
            pieces = _arc_points(state.position, target, centre, state.motion == 2, (a, b))
        # from an unknown position (first move of a program) the segment is just its end point
        previous = state.position.copy() if state.position_known else pieces[-1].copy()
        if not state.position_known:
            pieces = pieces[-1:]
        for piece in pieces:
            segment(index, previous, piece.copy(), state.motion == 0)
            previous = piece.copy()
        state.position = target
        # a probe stops where it touches, anywhere up to its target
        state.position_known = state.motion != 38
    states.append(state._snapshot())
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


def _target(state: ModalState, axis: dict[str, float], unit: float) -> np.ndarray:
    """Where a move's axis words go, in the work coordinates in force (absolute or relative)."""
    target = state.position.copy()
    for i, name in enumerate("XYZ"):
        if name in axis:
            target[i] = axis[name] * unit if state.absolute else target[i] + axis[name] * unit
    return target


def _set_offsets(state: ModalState, frames: _Frames, g_values: list[float], axis: dict[str, float],
                 values: dict[str, float], unit: float) -> None:
    """``G10 L2``/``L20``, ``G92``, ``G92.1``, ``G43.1``, ``G49`` as GRBL's ``gc_execute_line`` applies them."""
    before = frames.total(state)
    named = [(i, axis[name] * unit) for i, name in enumerate("XYZ") if name in axis]
    if 10.0 in g_values:
        number = int(values.get("P", 0))
        system = state.wcs if number == 0 else 53 + number
        if system not in frames.table:
            return  # GRBL answers error:29; nothing changes
        level = values.get("L")
        data = frames.table[system].copy()
        for i, value in named:
            if level == 2:
                data[i] = value
            elif level == 20:
                # the head's place reads as ``value`` in that system: WCS = MPos - G92 - TLO - value
                machine = state.position[i] + before[i]
                data[i] = machine - state.g92[i] - (state.tlo if i == 2 else 0.0) - value
        if level == 20 and named and not state.position_known and system == state.wcs:
            state.frame_known = False
        frames.table[system] = data
    if 92.0 in g_values and named:
        state.offsets_used = True
        state.g92 = state.g92.copy()  # the states kept per line share their arrays: never written in place
        for i, value in named:
            # the head's place reads as ``value``: G92 = MPos - WCS - TLO - value
            state.g92[i] = state.position[i] + state.g92[i] - value
        if not state.position_known:
            state.frame_known = False
    if 92.1 in g_values:
        state.offsets_used = True
        state.g92 = np.zeros(3)
    if 43.1 in g_values and "Z" in axis:
        state.offsets_used = True
        state.tlo = axis["Z"] * unit
    if 49.0 in g_values:
        state.offsets_used = True
        state.tlo = 0.0
    frames.moved(state, before)


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
