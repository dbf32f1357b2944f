"""Plots of layers: pen-up travel with vpype's line optimizations (linemerge, reloop, linesort) against the paths as
drawn, and what that does to the plotting time (the station's estimate, and the simulated GRBL's own clock, which
has acceleration).

Run with ``.venv/bin/python -m bench plot_layers``. Prints figures only (no timing assertions). Every random drawing
takes a seed.
"""

from __future__ import annotations

import time
from pathlib import Path
from tempfile import TemporaryDirectory

import numpy as np

from drivers.profiles import load_profile
from station.services import plot as plot_service
from station.services.designs import load_design
from station.services.machines import pattern_points as _sample

ROOT = Path(__file__).resolve().parents[1]
SEED = 0


def strokes_svg(path: Path, count: int, seed: int = SEED) -> Path:
    """A hatch texture as generative-art tools write it: ``count`` short strokes in random order, 180 x 180 mm."""
    rng = np.random.default_rng(seed)
    paths = []
    for _ in range(count):
        x, y = rng.uniform(10, 170, 2)
        angle = rng.uniform(0, np.pi)
        length = rng.uniform(3, 12)
        paths.append(f'<path d="M {x:.3f},{y:.3f} l {length * np.cos(angle):.3f},{length * np.sin(angle):.3f}"/>')
    path.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="180mm" height="180mm" viewBox="0 0 180 180">'
                    '<g style="fill:none;stroke:black">' + "".join(paths) + "</g></svg>", encoding="utf-8")
    return path


def fragments_svg(path: Path, pieces: int, seed: int = SEED) -> Path:
    """A Spirograph cut into ``pieces`` paths in random order and direction (an SVG exported by a drawing program
    that splits a long curve): linemerge joins them back into one path."""
    from design.machines import get_machine

    rng = np.random.default_rng(seed)
    model = get_machine("spirograph")
    points = model.sample(model.validate({"r_f": 10, "r_r": 7, "d": 5}), n=4096, spacing="arclength")
    points = (points - points.min(axis=0)) / np.ptp(points, axis=0).max() * 160 + 10
    cuts = np.linspace(0, len(points) - 1, pieces + 1).astype(int)
    parts = [points[a:b + 1] for a, b in zip(cuts[:-1], cuts[1:])]
    order = rng.permutation(len(parts))
    text = []
    for k in order:
        part = parts[k][::-1] if rng.random() < 0.5 else parts[k]
        text.append('<path d="M ' + " L ".join(f"{x:.3f},{y:.3f}" for x, y in part) + '"/>')
    path.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="180mm" height="180mm" viewBox="0 0 180 180">'
                    '<g style="fill:none;stroke:black">' + "".join(text) + "</g></svg>", encoding="utf-8")
    return path


def grid_composition(count: int, seed: int = SEED) -> plot_service.Composition:
    """``count`` small patterns on a grid, listed in random order: a sheet of variations."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(count)))
    cells = [(i, j) for i in range(side) for j in range(side)][:count]
    sources = []
    for k in rng.permutation(len(cells)):
        i, j = cells[k]
        d = float(rng.uniform(0.5, 2.9))
        sources.append(plot_service.PatternSource("spirograph", {"r_f": 5, "r_r": 3, "d": d}, size=150 / side * 0.8,
                                                  offset=((i - (side - 1) / 2) * 150 / side,
                                                          (j - (side - 1) / 2) * 150 / side),
                                                  layer="variations", points=1024))
    return plot_service.Composition(sources)


def sim_seconds(gcode: str) -> float | None:
    """The simulated GRBL's own time for a single-layer job (virtual clock: acceleration and all, run fast)."""
    from drivers.grbl import GrblConnection, Job, JobRunner

    with TemporaryDirectory() as folder:
        record = Path(folder) / "record.json"
        url = f"sim://grbl?profile=plotter&clock=virtual&record={record}"
        with GrblConnection(url) as conn:
            result = JobRunner(conn, Job.from_text("bench", gcode)).run_safely()
        if result.state != "done" or not record.is_file():
            return None
        import json

        executed = json.loads(record.read_text())["executed"]
        return float(executed[-1][4] - executed[0][4]) if executed else None


def main() -> None:
    profile = load_profile("plotter")
    with TemporaryDirectory() as folder:
        folder = Path(folder)
        scenarios = [
            ("three-pens.toml (example)", plot_service.load_composition(ROOT / "examples/plots/three-pens.toml",
                                                                         load_design)),
            ("hatch, 300 strokes", plot_service.Composition([plot_service.SvgSource(strokes_svg(
                folder / "h300.svg", 300))])),
            ("hatch, 2000 strokes", plot_service.Composition([plot_service.SvgSource(strokes_svg(
                folder / "h2000.svg", 2000))])),
            ("spirograph in 200 pieces", plot_service.Composition([plot_service.SvgSource(fragments_svg(
                folder / "frag.svg", 200))])),
            ("grid of 36 patterns", grid_composition(36)),
        ]
        print("pen-up travel and time, paths as drawn against vpype's linemerge + reloop + linesort "
              f"(seed {SEED}):")
        print(f"  {'drawing':<27} {'paths':>11} {'drawn mm':>9} {'travel as drawn':>16} {'sorted':>9} "
              f"{'ratio':>6} {'time as drawn':>14} {'sorted':>8} {'sim time':>15} {'opt. s':>7}")
        for name, composition in scenarios:
            as_drawn = plot_service.plot(composition, profile, sample=_sample, sort=False)
            start = time.perf_counter()
            optimized = plot_service.plot(composition, profile, sample=_sample, sort=True, seed=SEED)
            elapsed = time.perf_counter() - start
            paths = (sum(len(layer.polylines) for layer in as_drawn.document.layers),
                     sum(len(layer.polylines) for layer in optimized.document.layers))
            drawn = sum(layer.draw_mm for layer in optimized.layers)
            sim = ""
            if len(optimized.layers) == 1:
                a, b = sim_seconds(as_drawn.gcode), sim_seconds(optimized.gcode)
                if a is not None and b is not None:
                    sim = f"{plot_service.format_minutes(a)} > {plot_service.format_minutes(b)}"
            print(f"  {name:<27} {paths[0]:>5} > {paths[1]:<3} {drawn:>9.0f} {as_drawn.travel_mm:>14.0f} mm "
                  f"{optimized.travel_mm:>6.0f} mm {optimized.travel_mm / as_drawn.travel_mm:>6.2f} "
                  f"{plot_service.format_minutes(as_drawn.time_s):>14} "
                  f"{plot_service.format_minutes(optimized.time_s):>8} {sim:>15} {elapsed:>7.2f}")
        print("  (travel: G0 moves of the written job from the origin and back, pen-change parks included; time: the "
              "streamer's estimate at the commanded feeds; sim time: the simulated GRBL's clock, with acceleration; "
              "opt. s: compose + vpype + write)")


if __name__ == "__main__":
    main()
