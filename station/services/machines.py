"""Drawing-machine patterns as machine jobs: fit a pattern to a plotter's paper or a laser's bed and write G-code.

Used by ``station plot`` and the Machines screen's "plot the design" action.
"""

from __future__ import annotations

import math

from cam.plot import WriterOptions, fit_polylines, simplify_polylines, write_plot_gcode
from drivers.profiles import MachineProfile
from station.errors import ServiceError


def plot_job(polylines, profile: MachineProfile, size: float | None, tolerance: float | None, power: float = 0.3):
    """Fit, simplify and write: returns (gcode_text, fitted polylines, simplified polylines, options)."""
    import io

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
