"""ρ_l's ball means (``design.robust.robustness.ball_means``): counts per smallest holding radius, then a running sum,
against the direct boolean (centres, radii, points) test it replaced.

ρ_g, the start candidates' density ranking and the predicted robustness all go through ``ball_means``: means of
values over balls of 31 radii around each centre. Figures: time of each at sizes from the station's (74 start
successes among a 284-layout start) to the thesis's evaluation sets (100K-1M layouts), the ratio, the largest
difference of the results, and the peak memory of a call (tracemalloc).
"""

from __future__ import annotations

import time
import tracemalloc

import numpy as np
from scipy.spatial.distance import cdist

from design.robust import RobustnessSettings
from design.robust.robustness import _ball_radii, ball_means

#: (label, centres, points, dimension)
SIZES = [
    ("start candidates (CAUSALITYSWITCH)", 74, 284, 4),
    ("all start successes, large start", 2000, 8192, 8),
    ("one layout, thesis-size evaluation set", 1, 1_000_000, 8),
]


def boolean_cube(centres, points, values, radii, chunk=256):
    """The plain way, the reference the others are checked and timed against: a boolean per centre, radius and
    point."""
    result = np.empty((len(centres), len(radii)))
    for begin in range(0, len(centres), chunk):
        inside = cdist(centres[begin:begin + chunk], points)[:, None, :] <= radii[None, :, None]
        counts = inside.sum(axis=-1)
        mass = inside @ values
        result[begin:begin + chunk] = np.divide(mass, counts, out=np.zeros_like(mass), where=counts > 0)
    return result


def best_of(function, args, repeats=3):
    """Best time of ``repeats`` calls, the result, and the peak memory the call allocated (MB, numpy's included)."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        out = function(*args)
        times.append(time.perf_counter() - start)
    tracemalloc.start()
    function(*args)
    peak = tracemalloc.get_traced_memory()[1] / 1e6
    tracemalloc.stop()
    return min(times), out, peak


def main() -> None:
    _, radii = _ball_radii(RobustnessSettings())
    rng = np.random.default_rng(0)
    print(f"{'size':40s} {'centres':>8s} {'points':>9s} {'cube s':>8s} {'running s':>9s} {'ratio':>6s} "
          f"{'max diff':>9s} {'cube peak MB':>12s} {'running peak MB':>15s}")
    for label, m, n, d in SIZES:
        centres, points = rng.uniform(size=(m, d)), rng.uniform(size=(n, d))
        values = (rng.uniform(size=n) < 0.3).astype(float)
        repeats = 1 if m * n > 10_000_000 else 3
        args = (centres, points, values, radii)
        cube_s, cube, cube_mb = best_of(boolean_cube, args, repeats)
        running_s, running, running_mb = best_of(ball_means, args, repeats)
        print(f"{label:40s} {m:8d} {n:9d} {cube_s:8.3f} {running_s:9.3f} {cube_s / running_s:5.1f}x "
              f"{np.abs(cube - running).max():9.1e} {cube_mb:12.0f} {running_mb:15.0f}")


if __name__ == "__main__":
    main()
