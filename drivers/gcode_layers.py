"""The layer marks of a plot job of several layers, one pen each, read back from its G-code.

A layered job (written by :mod:`cam.layers`) is one G-code program: the header, then per layer a mark comment, for
every layer after the first the pen change (a message comment and the profile's pen-change lines, ``M0`` by default:
GRBL's program pause), and the layer's polylines with its own feed. GRBL ignores comments; the station reads them
back (:func:`layer_marks`) to say which layer a line belongs to, which pen to put in at a pause, and where a layer
starts (resume from a layer)::

    (layer 2/3 "hatch": pen "red 0.5 mm" #d62728)
    (pen change: put in pen "red 0.5 mm" for layer 2/3 "hatch", then resume)
    G0 X0 Y0
    M0

The mark's form lives here, beside its reader (:func:`mark_line`). The comments stay short (GRBL counts a line's
characters without its comments, but some senders do not).
"""
from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, replace

from drivers.gcode import GcodeError, clean_line, tokenize

__all__ = ["LayerMark", "layer_at", "layer_marks", "mark_line", "pause_lines", "safe_comment"]

_MARK = re.compile(r'^\(layer (\d+)/(\d+) "([^"]*)": pen "([^"]*)" (#[0-9a-fA-F]{6})\)\s*$')
_UNSAFE = re.compile(r'[()";\r\n]+')


def safe_comment(text: str, limit: int = 40) -> str:
    """A name as it can stand in a G-code comment: no parentheses, quotes, semicolons or line breaks."""
    return " ".join(_UNSAFE.sub(" ", str(text)).split())[:limit] or "-"


@dataclass(frozen=True)
class LayerMark:
    """A layer of a written job: 1-based ``number`` of ``count``, its name, pen and colour; ``line`` the 0-based
    index of its mark, ``pause`` the 0-based index of its pen change's ``M0`` (None: no pause before it)."""

    number: int
    count: int
    name: str
    pen: str
    color: str
    line: int
    pause: int | None = None

    @property
    def label(self) -> str:
        """``layer 2/3 "hatch" (pen "red 0.5 mm")``."""
        return f'layer {self.number}/{self.count} "{self.name}" (pen "{self.pen}")'

    def to_dict(self) -> dict:
        return {"number": self.number, "count": self.count, "name": self.name, "pen": self.pen,
                "color": self.color, "line": self.line + 1}


def mark_line(number: int, count: int, name: str, pen: str, color: str) -> str:
    """The mark comment of layer ``number`` of ``count``, as :func:`layer_marks` reads it back."""
    return f'(layer {number}/{count} "{safe_comment(name)}": pen "{safe_comment(pen)}" {_color(color)})'


def _color(text: str) -> str:
    text = str(text).strip()
    return text if re.fullmatch(r"#[0-9a-fA-F]{6}", text) else "#000000"


def layer_marks(lines: Sequence[str]) -> list[LayerMark]:
    """The layers of a job written by :func:`write_layers_gcode`, in order (empty for a job without marks)."""
    marks: list[LayerMark] = []
    for index, raw in enumerate(lines):
        if not raw.startswith("(layer "):
            continue
        match = _MARK.match(raw.strip())
        if match is None:
            continue
        number, count, name, pen, color = match.groups()
        marks.append(LayerMark(int(number), int(count), name, pen, color, index))
    pauses = pause_lines(lines)
    result = []
    for k, mark in enumerate(marks):
        end = marks[k + 1].line if k + 1 < len(marks) else len(lines)
        # the layer's pen change: a pause between its mark and its first drawing move
        pause = next((p for p in pauses if mark.line < p < end and not _draws_before(lines, mark.line, p)), None)
        result.append(replace(mark, pause=pause) if mark.number > 1 else mark)
    return result


def _draws_before(lines: Sequence[str], start: int, stop: int) -> bool:
    for raw in lines[start + 1:stop]:
        block = clean_line(raw)
        if block.startswith("G1") or block.startswith("G01"):
            return True
    return False


def pause_lines(lines: Sequence[str]) -> list[int]:
    """0-based indices of the program pauses (``M0``) of a job: where GRBL holds until cycle start."""
    found = []
    for index, raw in enumerate(lines):
        block = clean_line(raw)
        if "M" not in block or block.startswith("$"):
            continue
        try:
            words = tokenize(block)
        except GcodeError:
            continue
        if ("M", 0.0) in words:
            found.append(index)
    return found


def layer_at(marks: Sequence[LayerMark], line: int) -> LayerMark | None:
    """The layer the 0-based ``line`` belongs to (the last mark at or before it), or None before the first mark."""
    found = None
    for mark in marks:
        if mark.line <= line:
            found = mark
        else:
            break
    return found
