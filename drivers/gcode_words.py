"""The words of a G-code block and the geometry of its arcs, shared by the G-code reader and the simulated GRBL.

:mod:`drivers.gcode` (the job writer's reader: pre-flight, ETA, resume) and :mod:`drivers.sim.grbl.gcode` (the
simulated controller) read the same blocks. What they share lives here: removing comments, splitting a block into
``(letter, value)`` words one at a time, and an arc's centre, sweep and chord points. What differs stays with each:
the reader raises :class:`drivers.gcode.GcodeError` naming the column, the simulated controller answers with GRBL's
error numbers and divides arcs as GRBL's ``mc_arc`` does.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator, Sequence

import numpy as np

COMMENT = re.compile(r"\([^)]*\)|;.*$")
"""A ``( ... )`` comment, or a ``;`` comment to the end of the line."""

NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)")
"""A word's value as GRBL reads it: optional sign, digits with an optional point (``1``, ``1.``, ``.5``)."""

#: Which two axes (indices of X, Y, Z) span the plane selected by G17, G18 and G19.
PLANE_AXES = {17: (0, 1), 18: (2, 0), 19: (1, 2)}


class WordSyntaxError(ValueError):
    """Text in a block that is not a letter followed by a number.

    Attributes
    ----------
    column : int
        0-based index in the block where the bad word starts.
    expected : str
        ``"letter"`` (the character there is not A-Z) or ``"number"`` (a letter without a valid number after it).
    """

    def __init__(self, block: str, column: int, expected: str) -> None:
        super().__init__(f"cannot parse {block!r} at column {column + 1}: expected a {expected}")
        self.column = column
        self.expected = expected


def strip_comments(line: str) -> str:
    """``line`` without its ``( )`` and ``;`` comments (whitespace and case untouched)."""
    return COMMENT.sub("", line)


def iter_words(block: str) -> Iterator[tuple[str, float]]:
    """The words of a cleaned (upper-case, no whitespace) block as ``(letter, value)``, one at a time.

    A generator, so that a caller that rejects a word (GRBL: an unsupported letter is error:20) does so before a
    later word's syntax error is seen, as GRBL, which reads left to right, does.

    Raises
    ------
    WordSyntaxError
        At the first place that is not a letter A-Z followed by a number.
    """
    position = 0
    while position < len(block):
        letter = block[position]
        if not ("A" <= letter <= "Z"):
            raise WordSyntaxError(block, position, "letter")
        match = NUMBER.match(block, position + 1)
        if match is None:
            raise WordSyntaxError(block, position, "number")
        yield letter, float(match.group(0))
        position = match.end()


def radius_arc_centre(start: Sequence[float], end: Sequence[float], radius: float, clockwise: bool,
                      axes: tuple[int, int]) -> tuple[float, float]:
    """Centre (in the plane ``axes``) of the arc of ``radius`` from ``start`` to ``end`` (``R`` format).

    A negative radius picks the arc of more than half a turn, as in GRBL. The caller checks first that the end
    point differs from the start and is within reach (each with its own tolerance); here a slightly too short
    radius counts as exactly half the chord.
    """
    a, b = axes
    dx, dy = end[a] - start[a], end[b] - start[b]
    chord = math.hypot(dx, dy)
    height = math.sqrt(max(radius * radius - chord * chord / 4, 0.0))
    sign = -1 if clockwise ^ (radius < 0) else 1
    return start[a] + dx / 2 - sign * height * dy / chord, start[b] + dy / 2 + sign * height * dx / chord


def arc_sweep(start: Sequence[float], end: Sequence[float], centre: tuple[float, float], clockwise: bool,
              axes: tuple[int, int], full_turn_below: float) -> tuple[float, float]:
    """``(start angle, signed sweep)`` in radians of the arc around ``centre`` in the plane ``axes``.

    A sweep whose magnitude in the arc's direction is at most ``full_turn_below`` (the same point again) is a full
    turn.
    """
    a, b = axes
    t0 = math.atan2(start[b] - centre[1], start[a] - centre[0])
    t1 = math.atan2(end[b] - centre[1], end[a] - centre[0])
    sweep = t1 - t0
    if clockwise and sweep >= -full_turn_below:
        sweep -= 2 * math.pi
    elif not clockwise and sweep <= full_turn_below:
        sweep += 2 * math.pi
    return t0, sweep


def arc_chords(start: Sequence[float], end: Sequence[float], centre: tuple[float, float], radius: float,
               t0: float, sweep: float, axes: tuple[int, int], segments: int) -> np.ndarray:
    """The ``(segments, 3)`` end points of an arc's chords: on the circle of ``radius`` around ``centre`` in the
    plane ``axes``, the third axis moving linearly (a helix); the last point is ``end`` itself."""
    a, b = axes
    angles = t0 + sweep * np.arange(1, segments + 1) / segments
    points = np.repeat(np.asarray(start, float)[None, :], segments, axis=0)
    points[:, a] = centre[0] + radius * np.cos(angles)
    points[:, b] = centre[1] + radius * np.sin(angles)
    linear = 3 - a - b
    points[:, linear] = start[linear] + (end[linear] - start[linear]) * np.arange(1, segments + 1) / segments
    points[-1] = end
    return points
