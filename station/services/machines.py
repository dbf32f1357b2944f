"""Drawing machines from the faces: their patterns (``station machines``, ``station pattern``) and those patterns as
machine jobs (fit to a plotter's paper or a laser's bed, G-code written: ``station plot``, the Machines screen's
"plot the design" action).
"""

from __future__ import annotations

import io
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from cam.plot import WriterOptions, fit_polylines, simplify_polylines, write_plot_gcode
from design.datafiles import load_json
from design.machines import declared_machine_names, get_machine, machine_names, shapes_to_jsonable
from design.machines.render import shape_polylines, write_png, write_svg
from drivers.gcode import interpret
from drivers.grbl.planner import line_seconds
from drivers.profiles import MachineProfile
from station.errors import ServiceError, station_errors

__all__ = ["declared_machine_names", "describe_machines", "job_seconds", "machine_name", "pattern_document",
           "pattern_mechanism", "pattern_points", "plot_job", "read_pattern", "sample_pattern", "write_pattern"]

#: Colours of a pattern picture: the curve, and the machine's parts drawn over it.
PATTERN_COLOR = "#1f3b73"
MECHANISM_COLOR = "#c0392b"


@station_errors
def describe_machines() -> list[dict[str, Any]]:
    """Every drawing machine's description (name, title, parameters with kind, default, bounds and meaning)."""
    return [get_machine(name).describe() for name in machine_names()]


@station_errors
def pattern_document(machine: str, params: dict[str, float], points: int, spacing: str) -> dict[str, Any]:
    """The JSON document of ``station pattern --json``: one closed period of ``machine``'s pattern with ``params``
    (checked against the machine's constraints; missing ones take their defaults) as ``points`` points spaced
    uniformly in ``spacing`` (``"arclength"`` or ``"time"``)."""
    model = get_machine(machine)
    values = model.validate(params)
    curve = model.sample(values, n=points, spacing=spacing)
    return {
        "machine": model.name,
        "params": values,
        "period": model.period(values),
        "turns": model.turns(values),
        "symmetry_order": model.symmetry_order(values),
        "spacing": spacing,
        "points": curve.tolist(),
    }


@station_errors
def pattern_mechanism(machine: str, params: dict[str, float], t: float) -> tuple[list, list]:
    """The machine's parts at time ``t``: the shapes, and the same as JSON."""
    shapes = get_machine(machine).mechanism(params, t)
    return shapes, shapes_to_jsonable(shapes)


@station_errors
def write_pattern(path: Path, suffix: str, document: dict[str, Any], shapes, size: int, *, to_jsonable) -> None:
    """Write the pattern of :func:`pattern_document` (and the mechanism's ``shapes``, if any) as SVG, PNG or JSON
    (``suffix``); ``to_jsonable`` turns the document into plain JSON values."""
    if suffix == ".json":
        with path.open("w", encoding="utf-8") as stream:
            json.dump(to_jsonable(document), stream, allow_nan=False)
            stream.write("\n")
        return
    polylines = [np.asarray(document["points"], dtype=float)]
    colors = [PATTERN_COLOR]
    if shapes:
        parts = shape_polylines(shapes)
        polylines += parts
        colors += [MECHANISM_COLOR] * len(parts)
    if suffix == ".svg":
        with path.open("w", encoding="utf-8") as stream:
            write_svg(stream, polylines, size=size, colors=colors, title=f"{document['machine']} pattern")
    else:
        with path.open("wb") as stream:
            write_png(stream, polylines, size=size, colors=colors)


@station_errors
def machine_name(name: str) -> str:
    """The drawing machine's own name (an alias or another case resolved); an unknown one is refused naming the
    known ones."""
    return get_machine(name).name


@station_errors
def sample_pattern(machine: str, params: dict[str, Any], points: int = 4096) -> tuple[np.ndarray, dict[str, Any]]:
    """The pattern of ``machine`` with ``params`` (checked, defaults filled in) as ``points`` samples spaced
    evenly along it; returns the points and the full parameters."""
    model = get_machine(machine)
    values = model.validate(params)
    return np.asarray(model.sample(values, n=points, spacing="arclength"), dtype=float), values


@station_errors
def read_pattern(path: str | Path) -> tuple[np.ndarray, dict[str, Any]]:
    """A pattern written by ``station pattern --json``: its points and ``{"machine", "params"}``.

    Raises
    ------
    ServiceError
        Naming the file first, and what is wrong in it.
    """
    path = Path(path)
    expected = "the JSON of `station pattern --json` with a 'points' list"
    document = load_json(path, expected)
    if not isinstance(document, dict) or "points" not in document:
        raise ServiceError(f"{path}: expected {expected}", field="pattern", value=str(path))
    try:
        points = np.asarray(document["points"], dtype=float)
    except (TypeError, ValueError):
        raise ServiceError(f"{path}: 'points' must be a list of [x, y] numbers", field="pattern",
                           value=str(path)) from None
    if points.ndim != 2 or points.shape[1] != 2 or len(points) < 2 or not np.all(np.isfinite(points)):
        raise ServiceError(f"{path}: 'points' must be at least two finite [x, y] pairs, got shape {points.shape}",
                           field="pattern", value=str(path))
    return points, {"machine": document.get("machine", ""), "params": document.get("params", {})}


@station_errors
def pattern_points(source) -> np.ndarray:
    """The samples of a :class:`station.services.plot.PatternSource` (``plot(..., sample=pattern_points)``)."""
    return sample_pattern(source.machine, source.params, source.points)[0]


@station_errors
def job_seconds(gcode: str, profile: MachineProfile) -> float:
    """How long a written job takes on the profile's machine, as GRBL's planner runs it (the streamer's ETA)."""
    lines = gcode.splitlines()
    return float(line_seconds(interpret(lines), lines, profile.grbl_settings, laser_mode=profile.is_laser).sum())


@station_errors
def plot_job(polylines, profile: MachineProfile, size: float | None, tolerance: float | None, power: float = 0.3):
    """Fit, simplify and write: returns (gcode_text, fitted polylines, simplified polylines, options)."""
    if profile.kind == "plotter":
        paper = profile.paper
        box = (paper.margin, paper.margin, paper.width - paper.margin, paper.height - paper.margin)
    else:
        x0, y0, x1, y1 = profile.work_bounds()
        margin = 5.0
        box = (x0 + margin, y0 + margin, x1 - margin, y1 - margin)
    tolerance = profile.plot.tolerance if tolerance is None else tolerance
    # written so that NaN fails them too (every comparison with NaN is false)
    if not 0 <= tolerance < math.inf:
        raise ServiceError(f"tolerance must be >= 0 mm, got {tolerance}", field="tolerance", value=tolerance)
    if size is not None and not 0 < size < math.inf:
        raise ServiceError(f"size must be positive (mm), got {size}", field="size", value=size)
    if not 0 < power <= 1:
        raise ServiceError(f"power must be a fraction in (0, 1], got {power}", field="power", value=power)
    fitted = fit_polylines(polylines, box, size)
    simplified = simplify_polylines(fitted, tolerance)
    # the comment marks a pen plot, so that `station send` can warn before it goes to a laser (M3 S<n> lifts a pen
    # servo, and fires a laser at that power)
    kind = "pen plot" if profile.kind == "plotter" else "plot"
    options = WriterOptions.from_profile(profile, power=power, comment=f"chaos-station {kind} job for {profile.name}")
    stream = io.StringIO()
    write_plot_gcode(simplified, stream, options)
    return stream.getvalue(), fitted, simplified, options
