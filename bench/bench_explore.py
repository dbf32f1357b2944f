"""Guided exploration: time of one invariant-subspace update per machine, of a release (re-projection + update), and
of PoI detection on a 5000-segment curve; before/after pictures with PoIs.

Run with ``.venv/bin/python -m bench explore``. Prints figures only (no timing assertions). The issue's goal: one
subspace update of the Hoot-Nanny in <= 0.5 s on a 2-core machine; the thesis re-simulated 5^k full curves per update.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

import bench
from design.explore import CURVATURE, Explorer, OverConstrainedError, detect_pois
from design.explore.poi import detect_curvature_maxima, detect_self_intersections
from design.explore.render import write_png
from design.machines import get_machine

#: One case per machine, like the rows of Figure 3.15 (a curvature maximum frozen in place or in curvature).
CASES = [
    ("spirograph", {"r_f": 7, "r_r": 3, "d": 2.0}, "radial"),
    ("elliptic_spirograph", None, "curvature"),
    ("cycloid_drawing_machine", None, "position"),
    ("hoot_nanny", None, "position"),
    ("hoot_nanny", None, "curvature"),
]
REPEATS = 5


def best_time(function, repeats: int = REPEATS) -> float:
    """:func:`bench.best_time`, :data:`REPEATS` times by default."""
    return bench.best_time(function, repeats)


def brute_force_crossings(points: np.ndarray, chunk: int = 500) -> int:
    """All segment pairs, vectorized in chunks: the baseline that the STRtree avoids."""
    p, e = points[:-1], points[1:]
    r = e - p
    m = len(p)
    count = 0
    for start in range(0, m, chunk):
        i = np.arange(start, min(start + chunk, m))[:, None]
        j = np.arange(m)[None, :]
        valid = (j > i + 1) & ~((i == 0) & (j == m - 1))
        den = r[i, 0] * r[j, 1] - r[i, 1] * r[j, 0]
        qx, qy = p[j, 0] - p[i, 0], p[j, 1] - p[i, 1]
        with np.errstate(all="ignore"):
            u = (qx * r[j, 1] - qy * r[j, 0]) / den
            v = (qx * r[i, 1] - qy * r[i, 0]) / den
        count += int(np.sum(valid & (np.abs(den) > 1e-12) & (u >= 0) & (u < 1) & (v >= 0) & (v < 1)))
    return count


def main() -> None:
    out_dir = Path(tempfile.gettempdir()) / "chaos-station-bench-explore"
    out_dir.mkdir(parents=True, exist_ok=True)

    print("PoI detection on a 5000-segment curve (Hoot-Nanny default, 5001 points):")
    model = get_machine("hoot_nanny")
    params = model.defaults()
    t = np.linspace(0.0, model.period(params), 5001)
    curve = model.curve(params, t)
    pois = detect_pois(curve, t)
    n_max = sum(p.kind == CURVATURE for p in pois)
    t_all = best_time(lambda: detect_pois(curve, t))
    t_max = best_time(lambda: detect_curvature_maxima(curve, t))
    t_int = best_time(lambda: detect_self_intersections(curve, t))
    t_brute = best_time(lambda: brute_force_crossings(curve), repeats=2)
    print(f"  {n_max} curvature maxima, {len(pois) - n_max} crossings")
    print(f"  all PoIs {t_all * 1e3:.1f} ms (curvature maxima {t_max * 1e3:.1f} ms, crossings {t_int * 1e3:.1f} ms)")
    print(
        f"  all-pairs crossing test (vectorized numpy) {t_brute * 1e3:.0f} ms: STRtree is {t_brute / t_int:.0f}x faster"
    )

    print(
        "\nOne invariant-subspace update (grid + pull + batch tracking + WPCA), one release (move 1.0 + "
        "re-projection + update):"
    )
    print(
        f"  {'machine':<24} {'invariant':<10} {'k':>2} {'dim':>3} {'samples':>7} {'update':>9} {'release':>9} "
        f"{'thesis-style est.':>18} {'error after':>12} {'shape change':>12}"
    )
    for name, params, kind in CASES:
        explorer = Explorer(name, params)
        maxima = [p.id for p in explorer.pois if p.kind == CURVATURE]
        try:
            invariant = explorer.add_invariant(kind, [maxima[0]])
        except OverConstrainedError as error:
            print(f"  {name:<24} {kind:<10} over-constrained: {error}")
            continue
        k = len(explorer.names)
        update = best_time(lambda explorer=explorer: explorer._recompute_subspace(previous=explorer.basis))
        # Thesis-style cost: 5^k full curves sampled and analysed for PoIs (one curve timed, times 5^k).
        one_curve = best_time(
            lambda explorer=explorer: detect_pois(explorer.sample(n=explorer.n_points), explorer._times), repeats=3
        )
        estimate = one_curve * 5**k
        before_curve, before_pois = explorer.curve, explorer.pois
        s = explorer.sliders[0]
        value = 1.0 if s.upper >= 1.0 else -1.0
        start = time.perf_counter()
        explorer.move(0, value)
        result = explorer.release()
        release = time.perf_counter() - start
        error = result.errors_after[invariant.label]
        print(
            f"  {name:<24} {kind:<10} {k:>2} {len(explorer.sliders):>3} {explorer.subspace.n_samples:>7} "
            f"{update * 1e3:>7.0f}ms {release * 1e3:>7.0f}ms {estimate:>7.1f}s ({estimate / update:>5.0f}x) "
            f"{error:>12.2e} {result.shape_change:>11.2%}"
        )
        frozen = [i for ids in explorer.invariant_pois().values() for i in ids if i is not None]
        path = out_dir / f"{name}_{kind}.png"
        with path.open("wb") as stream:
            write_png(
                stream,
                [before_curve, explorer.curve],
                [before_pois, explorer.pois],
                highlight=frozen,
                title=f"{name}: {invariant.label}, slider 0 moved by {value:+g}",
            )

    print("\nPlain thesis grid (pull=False) vs pulled samples, Hoot-Nanny, position of the first curvature maximum:")
    for pull in (True, False):
        explorer = Explorer("hoot_nanny", pull=pull)
        maxima = [p.id for p in explorer.pois if p.kind == CURVATURE]
        try:
            explorer.add_invariant("position", [maxima[0]])
            print(
                f"  pull={pull!s:<5}: {explorer.subspace.n_good - 1} of {explorer.subspace.n_samples} neighbouring "
                f"samples above sigma_inv, {len(explorer.sliders)} slider(s) (the constraints leave at most 3)"
            )
        except OverConstrainedError:
            print(f"  pull={pull!s:<5}: over-constrained (no grid sample but the design itself above sigma_inv)")
    print(f"\npictures (before in yellow, after in blue, frozen PoIs in red): {out_dir}")
