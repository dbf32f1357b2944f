"""Simulator calibration recovers hidden material values, seeded.

Trials are made by the simulator itself under hidden material values with 1 mm / 1 degree placement errors
(:func:`station.services.world.synthetic_trials`), written in the trial log's export format, read back and fitted with
the default settings (:class:`calibration.sim_fit.FitSettings`). Targets: friction within ±5 % from 10 runs with event
times and from 30 runs with outcomes only; restitution within ±15 %; the held-out Brier score of the success
probability improves. Scenarios: SLIDE (a block on a tilted plank, friction) and BOUNCE (a ball dropped on a plate,
restitution), tests/data/calibration. About 2-4 minutes per seed on one core. Draws docs/sim_calibration.png: each
fit's candidates (the first seed's).

Run: ``python -m bench.bench_sim_calibration [--seeds 0,1,2] [--prior-width W]`` (0: maximum likelihood) or
``python -m bench sim_calibration`` (seed 0, the default prior).
"""

from __future__ import annotations

import functools
import time
from pathlib import Path

import numpy as np

from calibration.sim_fit import FitSettings

DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "calibration"

#: (label, scenario file, hidden values, designed layouts' range, runs, with times, tolerance)
CASES = [
    ("friction, 10 timed runs", "slide.toml", {"wood.friction": 0.55}, (27.0, 37.0), 10, True, 0.05),
    ("friction, 30 runs, outcomes only", "slide.toml", {"wood.friction": 0.55}, (25.0, 36.0), 30, False, 0.05),
    ("restitution, 10 timed runs", "bounce.toml", {"rubber.restitution": 0.72}, (0.035, 0.15), 10, True, 0.15),
    ("restitution, 30 runs, outcomes only", "bounce.toml", {"rubber.restitution": 0.72}, (0.03, 0.12), 30, False,
     0.15),
]


def _map(v: float, lo: float, hi: float, a: float, b: float) -> float:
    """``v`` in [lo, hi] to [a, b] (a picture's pixels)."""
    return a + (v - lo) / (hi - lo if hi > lo else 1.0) * (b - a)


FIGURE = Path(__file__).resolve().parents[1] / "docs" / "sim_calibration.png"


def draw_fit(fits: list[tuple[str, object, float]], path: Path = FIGURE) -> Path:
    """One panel per fit of one value: the candidates' log-likelihood against the value, the hidden value (dashed),
    the fitted one and its 95 % interval (band). Drawn with Pillow, like the robustness plots."""
    from PIL import Image, ImageDraw, ImageFont

    width, height = 480, 300
    image = Image.new("RGB", (width * 2, height * ((len(fits) + 1) // 2)), "white")
    draw = ImageDraw.Draw(image, "RGBA")
    font = ImageFont.load_default()
    for k, (label, fit, truth) in enumerate(fits):
        x0, y0 = (k % 2) * width, (k // 2) * height
        left, right, top, bottom = x0 + 60, x0 + width - 20, y0 + 40, y0 + height - 45
        (p,) = fit.parameters
        values, ll = fit.evaluated[:, 0], fit.evaluated_log_likelihood
        lo_v, hi_v = p.range
        lo_l, hi_l = float(np.min(ll)), float(np.max(ll))
        hi_l += 0.05 * (hi_l - lo_l + 1e-9)
        sx = functools.partial(_map, lo=lo_v, hi=hi_v, a=left, b=right)
        sy = functools.partial(_map, lo=lo_l, hi=hi_l, a=bottom, b=top)
        draw.rectangle([sx(p.interval[0]), top, sx(p.interval[1]), bottom], fill=(214, 39, 40, 50))
        draw.rectangle([left, top, right, bottom], outline=(0, 0, 0))
        for v, l in zip(values, ll):
            draw.ellipse([sx(v) - 3, sy(l) - 3, sx(v) + 3, sy(l) + 3], fill=(31, 119, 180))
        for y in np.arange(top, bottom, 8):
            draw.line([sx(truth), y, sx(truth), y + 4], fill=(0, 0, 0), width=2)
        draw.line([sx(p.value), top, sx(p.value), bottom], fill=(214, 39, 40), width=2)
        draw.text((left, y0 + 8), f"{label}", fill=(0, 0, 0), font=font)
        draw.text((left, y0 + 22), f"hidden {truth:g} (dashed), fitted {p.value:.3f} [{p.interval[0]:.3f}, "
                  f"{p.interval[1]:.3f}] (red)", fill=(90, 90, 90), font=font)
        for v in np.linspace(lo_v, hi_v, 6):
            draw.text((sx(v) - 10, bottom + 6), f"{v:.2f}", fill=(0, 0, 0), font=font)
        draw.text(((left + right) / 2 - 40, bottom + 24), p.name, fill=(0, 0, 0), font=font)
        for v in np.linspace(lo_l, hi_l, 4):
            draw.text((x0 + 8, sy(v) - 6), f"{v:.0f}", fill=(0, 0, 0), font=font)
        draw.text((x0 + 8, bottom + 24), "log-lik.", fill=(90, 90, 90), font=font)
    image.save(path, optimize=True)
    return path


def run_case(label, file, hidden, span, runs, times, tolerance, seed: int = 0,
             prior_width: float | None = FitSettings.prior_width, fits: list | None = None) -> bool:
    from calibration.sim_fit import fit_simulator
    from calibration.sim_trials import export_trials, fit_trials
    from design.contraption import load_scenario
    from station.services.world import synthetic_trials
    from station.services.world import trials_export as export

    scenario = load_scenario(DATA / file)
    rng = np.random.default_rng(100 + seed)
    layouts = [[v] for v in rng.uniform(*span, runs)]
    raw = export(synthetic_trials(scenario, layouts, hidden, seed=200 + seed, times=times))
    trials = fit_trials(export_trials(raw), {scenario.name: scenario})
    start = time.perf_counter()
    fit = fit_simulator(trials, scenario.uncertain_parameters(),
                        settings=FitSettings(seed=seed, prior_width=prior_width or None))
    seconds = time.perf_counter() - start
    ok = True
    print(f"  {label} ({scenario.name}, seed {seed}): {fit.trials} fitted + {fit.held_out} held out, "
          f"{fit.simulations} simulations, {seconds:.0f} s")
    for p in fit.parameters:
        truth = hidden[p.name]
        error = (p.value - truth) / truth
        inside = p.interval[0] <= truth <= p.interval[1]
        good = abs(error) <= tolerance
        ok &= good
        print(f"    {p.name}: hidden {truth:.3f}, file {p.before:.3f}, fitted {p.value:.4f} ({error:+.1%}; target "
              f"±{tolerance:.0%}: {'ok' if good else 'MISSED'}), 95 % interval [{p.interval[0]:.4f}, "
              f"{p.interval[1]:.4f}] {'holds' if inside else 'misses'} the hidden value")
    if fit.brier_before is not None:
        better = fit.brier_after < fit.brier_before
        ok &= better or fit.brier_before == 0.0
        print(f"    held-out Brier {fit.brier_before:.4f} -> {fit.brier_after:.4f} "
              f"({'improves' if better else 'does not improve'})")
    print(f"    log-likelihood {fit.log_likelihood_before:.1f} -> {fit.log_likelihood_after:.1f}")
    if fits is not None:
        fits.append((label, fit, next(iter(hidden.values()))))
    return ok


def main(argv: list[str] | None = None) -> None:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0", help="seeds, e.g. 0,1,2 (the figure is drawn for the first)")
    parser.add_argument("--prior-width", type=float, default=FitSettings.prior_width,
                        help="the fit's prior width, a share of each range (default %(default)s; 0: none)")
    args = parser.parse_args([] if argv is None else argv)
    seeds = [int(s) for s in args.seeds.split(",")]
    print(f"bench_sim_calibration: seeds {seeds}, prior width {args.prior_width or 'none (maximum likelihood)'}")
    fits: list = []
    results = []
    for seed in seeds:
        results += [run_case(*case, seed=seed, prior_width=args.prior_width, fits=fits if seed == seeds[0] else None)
                    for case in CASES]
    print(f"  recovery: {sum(results)} of {len(results)} fits met their targets")
    print(f"  wrote {draw_fit(fits)}")


if __name__ == "__main__":
    import sys

    main(sys.argv[1:])
