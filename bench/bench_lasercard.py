"""Laser test cards on the twins: how well ``station calibrate material`` reads a card the laser twin burned and the
camera twin photographed, against the twin's truth.

For each material of the built-in laser profile that engraves dark on light (plywood, MDF, cardboard), the default
card (5 powers x 5 feeds) is burned once per seed; each burned card is photographed at several camera resolutions
(pixels per card millimetre) and noise levels, and read. Figures per row: the kerf read from the comb against the
twin's truth (error, and the reported uncertainty), the cut lines seen through against the truth (a line opened
less than one camera pixel may go either way and is left out), the chosen cut cell against the one the truth gives,
and the times. Rows are appended to ``LASERCARD_BENCH_OUT`` (JSON lines, default ``lasercard-bench.jsonl``) and a
row already there is not run again (the campaign resumes).

Run with ``.venv/bin/python -m bench lasercard``; ``LASERCARD_BENCH_SEEDS`` (default 3).
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from calibration.lasercard import read_card
from drivers.sim.laser_burn import burn_gcode, line_kerf, photograph, sim_material
from station.services import lasertest

MATERIALS = ("plywood_3mm", "mdf_3mm", "cardboard_2mm")
RESOLUTIONS = (8.0, 12.0, 20.0)
NOISES = (2.0, 6.0)
#: The camera's blur (Gaussian sigma, frame pixels): a sharp photo, and one a little out of focus.
BLURS = (0.7, 1.5)


def truth_choice(manifest, material) -> str | None:
    """The cut cell the station's rule picks when it knows the truth (fastest feed through, one power step up)."""
    through = [c for c in manifest.cells if line_kerf(material, c.power, c.feed, manifest.cut_passes) > 0]
    if not through:
        return None
    fastest = max(c.feed for c in through)
    at_feed = sorted((c for c in through if c.feed == fastest), key=lambda c: c.power)
    return (at_feed[1] if len(at_feed) > 1 else at_feed[0]).name


def main() -> None:
    out = Path(os.environ.get("LASERCARD_BENCH_OUT", "lasercard-bench.jsonl"))
    seeds = int(os.environ.get("LASERCARD_BENCH_SEEDS", "3"))
    done = set()
    if out.exists():
        for line in out.read_text().splitlines():
            row = json.loads(line)
            done.add((row["material"], row["seed"], row["px_per_mm"], row["noise"], row.get("blur_px", 0.7)))
    print(f"{'material':<14} {'seed':>4} {'px/mm':>5} {'noise':>5} {'blur':>4} {'kerf':>7} {'truth':>7} {'error':>7} "
          f"{'u':>6} {'through ok':>10} {'cut cell':>9} {'read s':>6}")
    with tempfile.TemporaryDirectory() as folder:
        os.environ.setdefault("CHAOS_STATION_HOME", folder)
        for name in MATERIALS:
            card = lasertest.make_card("laser", name)
            card_json = lasertest.write_card(card, Path(folder) / name)["json"]
            manifest = lasertest.read_card_manifest(card_json)
            material = sim_material(name)
            power, feed, passes = manifest.comb
            truth = line_kerf(material, power, feed, passes)
            chosen_truth = truth_choice(manifest, material)
            x0, y0 = manifest.data["offset_mm"]
            width, height = manifest.card_mm
            for seed in range(seeds):
                if all((name, seed, px, noise, blur) in done for px in RESOLUTIONS for noise in NOISES
                       for blur in BLURS):
                    continue
                started = time.perf_counter()
                sheet = burn_gcode(card.gcode.splitlines(), material, (x0, y0, x0 + width, y0 + height),
                                   px_per_mm=16.0, seed=seed)
                burn_s = time.perf_counter() - started
                for px, noise, blur in ((p, n, b) for p in RESOLUTIONS for n in NOISES for b in BLURS):
                    if (name, seed, px, noise, blur) in done:
                        continue
                    started = time.perf_counter()
                    frame, _ = photograph(sheet, px_per_mm=px, noise=noise, seed=seed, blur_px=blur,
                                          angle_deg=float(np.random.default_rng(seed).uniform(-20, 20)))
                    photo_s = time.perf_counter() - started
                    started = time.perf_counter()
                    reading = read_card(frame, manifest)
                    read_s = time.perf_counter() - started
                    choice = lasertest.choose_settings(reading, manifest)
                    wrong = [c.name for c, cell in zip(reading.cells, manifest.cells)
                             if (line_kerf(material, cell.power, cell.feed, manifest.cut_passes) >= 1.0 / px
                                 and not c.through)
                             or (line_kerf(material, cell.power, cell.feed, manifest.cut_passes) == 0
                                 and c.through)]
                    row = {"material": name, "seed": seed, "px_per_mm": px, "noise": noise, "blur_px": blur,
                           "kerf_mm": reading.kerf_mm, "kerf_truth_mm": round(truth, 4),
                           "kerf_error_mm": None if reading.kerf_mm is None else round(reading.kerf_mm - truth, 4),
                           "kerf_uncertainty_mm": reading.kerf_uncertainty_mm, "tag_fit_mm": reading.residual_mm,
                           "through_wrong": wrong, "cut_cell": choice.cut_cell, "cut_cell_truth": chosen_truth,
                           "engrave_cell": choice.engrave_cell, "burn_s": round(burn_s, 2),
                           "photo_s": round(photo_s, 2), "read_s": round(read_s, 2)}
                    with out.open("a") as stream:
                        stream.write(json.dumps(row) + "\n")
                    error = "-" if row["kerf_error_mm"] is None else f"{row['kerf_error_mm']:+.4f}"
                    print(f"{name:<14} {seed:>4} {px:>5g} {noise:>5g} {blur:>4g} {reading.kerf_mm or 0:>7.4f} "
                          f"{truth:>7.4f} "
                          f"{error:>7} {reading.kerf_uncertainty_mm or 0:>6.4f} "
                          f"{'yes' if not wrong else ','.join(wrong):>10} "
                          f"{'same' if choice.cut_cell == chosen_truth else str(choice.cut_cell):>9} {read_s:>6.2f}",
                          flush=True)


if __name__ == "__main__":
    main()
