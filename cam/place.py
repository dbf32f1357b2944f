"""A G-code job moved and turned on the bed: every point ``p`` of the job's own work coordinates goes to
``R(angle) @ p + (x, y)`` (a rotation about the job's work zero, counter-clockwise seen from above, then an offset).

Why rewrite the program rather than set a work offset (``G10 L2``) and a rotation: GRBL has no coordinate rotation,
and a rewritten file is a normal job the pre-flight checks against the machine's travel where it will really run.

What is moved: the X and Y words of motion in the XY plane (``G0``, ``G1``, ``G2``, ``G3``, in absolute ``G90`` and
relative ``G91`` distance, millimetres or inches), and an arc's ``I``/``J`` (its centre, relative to its start as
GRBL takes it) turn with it; an ``R`` arc keeps its radius and direction (a rotation keeps both). A rotated line that
names only one of X and Y gets the other too (a rotation mixes them), from the position the program is at.

What is refused, with the line named (a :class:`drivers.gcode.GcodeError`): arcs in another plane (``G18``,
``G19``: a turned XZ arc is no arc GRBL can run), machine coordinates (``G53``), work offset changes (``G10``,
``G92``, ``G54``-``G59``: the placement is the job's work offset), a ``G28``/``G30`` with an intermediate point,
and, when turning, a move that names one axis before the program said where the other is.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from drivers.gcode import GcodeError, clean_line, format_number, tokenize

__all__ = ["Placement", "place_lines"]

_REFUSED_G = {53.0: "G53 moves in machine coordinates", 10.0: "G10 sets a work offset",
              92.0: "G92 sets a work offset", 92.1: "G92.1 clears a work offset",
              **{float(n): f"G{n} selects another work coordinate system" for n in range(55, 60)}}
_MOTION = (0.0, 1.0, 2.0, 3.0)


@dataclass(frozen=True)
class Placement:
    """Where the job goes: its work zero to ``(x, y)`` (mm, work coordinates), turned by ``angle`` degrees
    counter-clockwise about it."""

    x: float = 0.0
    y: float = 0.0
    angle: float = 0.0

    def __post_init__(self) -> None:
        for name in ("x", "y", "angle"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise GcodeError(f"placement {name}: expected a finite number, got {value!r}")

    @property
    def identity(self) -> bool:
        return self.x == 0 and self.y == 0 and self.angle % 360 == 0

    def apply(self, x: float, y: float) -> tuple[float, float]:
        """Where the job's point ``(x, y)`` lands (mm)."""
        c, s = math.cos(math.radians(self.angle)), math.sin(math.radians(self.angle))
        return c * x - s * y + self.x, s * x + c * y + self.y

    def turn(self, dx: float, dy: float) -> tuple[float, float]:
        """A relative vector turned (no offset)."""
        c, s = math.cos(math.radians(self.angle)), math.sin(math.radians(self.angle))
        return c * dx - s * dy, s * dx + c * dy

    @classmethod
    def parse(cls, text: str) -> Placement:
        """``X,Y,ANGLE`` (mm, mm, degrees; ANGLE optional); a :class:`GcodeError` naming what is wrong."""
        parts = [p.strip() for p in str(text).split(",")]
        if len(parts) not in (2, 3):
            raise GcodeError(f"placement: expected X,Y or X,Y,ANGLE (mm, mm, degrees), got {text!r}")
        try:
            values = [float(p) for p in parts]
        except ValueError:
            raise GcodeError(f"placement: expected X,Y or X,Y,ANGLE as numbers (mm, mm, degrees), got {text!r}") \
                from None
        if not all(math.isfinite(v) for v in values):
            raise GcodeError(f"placement: expected finite numbers X,Y,ANGLE, got {text!r}")
        return cls(*values)


def _word_text(letter: str, value: float) -> str:
    return letter + format_number(value, 4)


def place_lines(lines: Sequence[str], placement: Placement) -> list[str]:
    """``lines`` with their XY motion placed (module docstring); lines without XY motion are kept as they are.

    Raises
    ------
    GcodeError
        A line that cannot be placed, naming its 1-based number and why.
    """
    if placement.identity:
        return list(lines)
    turning = placement.angle % 360 != 0
    out: list[str] = []
    absolute, inches, plane, motion = True, False, 17, 0.0
    known = [False, False]  # whether the program has said where X and Y are (its own coordinates)
    position = [0.0, 0.0]  # the job's own XY (mm) once known
    for number, raw in enumerate(lines, start=1):
        block = clean_line(raw)
        if not block or block.startswith("$") or block.startswith("%"):
            out.append(raw)
            continue
        words = tokenize(block)
        g_values = [v for letter, v in words if letter == "G"]
        for g in g_values:
            if g in _REFUSED_G:
                raise GcodeError(f"line {number} ({block}): {_REFUSED_G[g]}; a placed job cannot have it (the "
                                 "placement is the job's work offset)")
            if g in (90.0, 91.0):
                absolute = g == 90.0
            elif g in (20.0, 21.0):
                inches = g == 20.0
            elif g in (17.0, 18.0, 19.0):
                plane = int(g)
            elif g in _MOTION or g == 80.0 or 38.0 <= g < 39.0:
                motion = g
        has_xy = any(letter in "XY" for letter, _ in words)
        homing = any(g in (28.0, 30.0) for g in g_values)
        if homing:
            if has_xy:
                raise GcodeError(f"line {number} ({block}): G28/G30 with an intermediate point cannot be placed; "
                                 "remove its X/Y words")
            known = [False, False]  # the head goes to a stored machine position: the job's own XY is lost
            out.append(raw)
            continue
        arc = motion in (2.0, 3.0) and (has_xy or any(letter in "IJKR" for letter, _ in words))
        if arc and plane != 17:
            raise GcodeError(f"line {number} ({block}): an arc in the {'XZ' if plane == 18 else 'YZ'} plane "
                             f"(G{plane}) cannot be turned or moved in XY; write it in G17")
        if not has_xy and not arc:
            out.append(raw)
            continue
        unit = 25.4 if inches else 1.0
        given = {letter: value * unit for letter, value in words if letter in "XYIJ"}
        if absolute:
            if turning and not all(known[i] or "XY"[i] in given for i in range(2)):
                missing = "Y" if "X" in given else "X"
                raise GcodeError(f"line {number} ({block}): moves {'X' if missing == 'Y' else 'Y'} alone before "
                                 f"the job says where {missing} is; a turned job needs both: add {missing} to it")
            own = [given.get("XY"[i], position[i]) for i in range(2)]
            new_xy = placement.apply(*own)
        else:
            delta = [given.get("X", 0.0), given.get("Y", 0.0)]
            own = [position[i] + delta[i] for i in range(2)]
            new_xy = placement.turn(*delta)
        new_ij = placement.turn(given.get("I", 0.0), given.get("J", 0.0))
        write_y = turning or "Y" in given
        write_x = turning or "X" in given
        write_ij = "I" in given or "J" in given
        decimals = 4 if inches else 3
        rebuilt: list[str] = []
        for letter, value in words:
            if letter in "XYIJ":
                continue
            rebuilt.append(_word_text(letter, value))
        coordinates = []
        if write_x:
            coordinates.append("X" + format_number(new_xy[0] / unit, decimals))
        if write_y:
            coordinates.append("Y" + format_number(new_xy[1] / unit, decimals))
        if write_ij:
            if turning or "I" in given:
                coordinates.append("I" + format_number(new_ij[0] / unit, decimals))
            if turning or "J" in given:
                coordinates.append("J" + format_number(new_ij[1] / unit, decimals))
        # the coordinates go after the G/M words of the line and before F/S, as writers put them
        head = [w for w in rebuilt if w[0] in "GMN"]
        tail = [w for w in rebuilt if w[0] not in "GMN"]
        out.append(" ".join(head + coordinates + tail))
        for i in range(2):
            if absolute:
                if "XY"[i] in given:
                    position[i], known[i] = own[i], True
            elif known[i]:
                position[i] = own[i]
    return out
