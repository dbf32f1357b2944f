"""Plot jobs of several layers, one pen each, written as one G-code program with a pen change between layers.

Per layer: its mark (:func:`drivers.gcode_layers.mark_line`, which the streamer reads back to pause and resume by
layer), for every layer after the first the pen change (a message comment and the profile's pen-change lines,
``M0`` by default: GRBL's program pause), and the layer's polylines with its own feed.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TextIO

import numpy as np

from cam.plot import WriterOptions, write_plot_gcode
from drivers.gcode import GcodeError, clean_line, tokenize
from drivers.gcode_layers import mark_line, safe_comment

__all__ = ["DEFAULT_PEN_CHANGE", "PenLayer", "write_layers_gcode"]

#: The pen-change lines when a profile names none: GRBL's program pause (cycle start ``~`` resumes).
DEFAULT_PEN_CHANGE = ("M0",)


@dataclass(frozen=True)
class PenLayer:
    """One layer of a plot: its name, the pen that draws it (what the maker puts in, and its colour for previews),
    its polylines (``(n, 2)`` work mm) and its drawing feed (mm/min; None: the writer's)."""

    name: str
    pen: str
    color: str = "#000000"
    polylines: Sequence[np.ndarray] = field(default_factory=tuple)
    draw_feed: float | None = None


def write_layers_gcode(layers: Sequence[PenLayer], stream: TextIO, options: WriterOptions | None = None,
                       pen_change: Sequence[str] = DEFAULT_PEN_CHANGE) -> int:
    """Write ``layers`` as one job: ``options``' header, each layer's mark, a pen change before every layer after the
    first (a message comment, then ``pen_change``'s lines), the layer's polylines with its feed, the footer.

    ``pen_change`` empty writes no pause (a laser has no pen to change). Returns the number of lines written.
    """
    options = options or WriterOptions()
    count = len(layers)
    if count == 0:
        raise GcodeError("nothing to write: no layers")
    for line in pen_change:
        tokenize(clean_line(line))  # a bad macro line is refused before any G-code is written
    written = 0
    for index, layer in enumerate(layers):
        name, pen = safe_comment(layer.name), safe_comment(layer.pen)
        mark = mark_line(index + 1, count, layer.name, layer.pen, layer.color)
        head: list[str] = [options.comment and f"({options.comment})", *options.header, *options.pen_up] \
            if index == 0 else []
        head = [line for line in head if line]
        head.append(mark)
        if index > 0 and pen_change:
            head.append(f'(pen change: put in pen "{pen}" for layer {index + 1}/{count} "{name}", then resume)')
            head.extend(pen_change)
        for line in head:
            stream.write(line + "\n")
        written += len(head)
        last = index == count - 1
        body = replace(options, comment="", header=(), pen_up=options.pen_up, home_at_end=last and options.home_at_end,
                       footer=options.footer if last else (),
                       draw_feed=layer.draw_feed if layer.draw_feed is not None else options.draw_feed)
        written += _write_body(layer.polylines, stream, body)
    return written


def _write_body(polylines, stream: TextIO, options: WriterOptions) -> int:
    """The polylines of one layer: :func:`write_plot_gcode` without its opening pen lift (the pen is up already)."""
    buffer = io.StringIO()
    write_plot_gcode(polylines, buffer, options)
    lines = buffer.getvalue().splitlines()
    lines = lines[len(options.pen_up):]  # write_plot_gcode lifts the pen first: it is up since the last layer
    for line in lines:
        stream.write(line + "\n")
    return len(lines)
