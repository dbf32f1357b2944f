"""Plot jobs from plain numpy polylines: fitted to the paper, simplified, written as G-code with pen moves.

:func:`fit_polylines` scales and centres polylines on a box (the paper), :func:`simplify_polylines` reduces the vertex
count within a tolerance (Douglas-Peucker, by shapely), both plain numpy in, numpy out. :func:`write_plot_gcode`
writes polylines (``(n, 2)`` arrays in work millimetres) to a text stream with pen up/down (or laser on/off) commands
and feeds from :class:`WriterOptions`.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TextIO

import numpy as np

from drivers.gcode import GcodeError, format_number

__all__ = ["WriterOptions", "fit_polylines", "simplify_polylines", "write_plot_gcode"]


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
            s_value = format_number(power * profile.laser.max_power, 1)
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
    travel_feed = f" F{format_number(options.travel_feed, p)}" if options.travel_with_g1 else ""
    for polyline in polylines:
        points = np.asarray(polyline, dtype=float)
        if points.ndim != 2 or points.shape[1] != 2:
            raise GcodeError(f"polyline must be an (n, 2) array, got shape {points.shape}")
        if len(points) < 2:
            continue
        if not np.all(np.isfinite(points)):
            raise GcodeError("polyline has non-finite coordinates")
        x0, y0 = points[0]
        lines.append(f"{travel} X{format_number(x0, p)} Y{format_number(y0, p)}{travel_feed}")
        lines.extend(options.pen_down)
        first = True
        for x, y in points[1:]:
            feed = f" F{format_number(options.draw_feed, p)}" if first else ""
            lines.append(f"G1 X{format_number(x, p)} Y{format_number(y, p)}{feed}")
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
    # heavy: shapely (GEOS), deferred to the first simplification: `station --help` imports every command, and the
    # machine commands import this module
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
