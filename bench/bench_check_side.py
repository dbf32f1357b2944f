"""Height and tilt accuracy of the side camera on the camera twin.

The side camera 700 mm in front of the board (``sim://camera?view=side&height=700``), 1080p, f = 1400 px, blur
0.8 px, noise 2 grey levels, JPEG 90; the board's four 40 mm tags; each jig stand's 20 mm face tag. Over seeded
placements of the layout (the carried part moved in its design parameters: height +-5 mm, tilt +-3 deg, along the
table +-3 mm, uniformly, and the camera aimed a little off the board's middle), the side scene is placed by the scene
graph at the moved layout and the check's measurement is scored against it:

- height: the part's origin on the board's plane (its height above the table), measured minus true (mm);
- tilt: its turn on the board's plane (the tilt), measured minus true (deg);
- the fitted design parameters (the height parameter in mm, the tilt parameter in deg) against the moved layout's.

The same placements are rendered a second time by :mod:`bench.side_render`, which shares no code or convention with
the twin or the station's board-plane arithmetic (its own look-at camera and pinhole, the tag carried in 3-D with the
part, Pillow's rasteriser and blur): the row marked "independent".

Goal: p95 height <= 0.5 mm, p95 tilt <= 0.5 deg. ``python -m bench.bench_check_side [--placements N] [--seed S]
[--scenarios simple,causalityswitch_ball]``.
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np

from bench.side_render import independent_side_frame
from calibration.asbuilt import PlanePose, as_built_layout, part_plane_pose
from projector.board import side_board
from station.services import check as service
from station.services import check_side

URL = "sim://camera?view=side&height=700&size=1920x1080&f=1400&blur=0.8&noise=2&jpeg=90&target={u},{v}&seed={seed}"
MOVES = {"z": 0.005, "roll": 3.0, "pitch": 3.0, "x": 0.003, "y": 0.003}


def _p95(values) -> float:
    return float(np.percentile(np.abs(values), 95)) if len(values) else float("nan")


def run(scenario: str, placements: int, seed: int, independent: bool = False) -> dict:
    job = service.prepare_check(scenario, "success", jigs=True)
    board = side_board(job.guide)
    targets = check_side.side_targets(job, board)
    names = list(job.scenario.design_space.names)
    lower = np.asarray(job.scenario.design_space.lower, float)
    upper = np.asarray(job.scenario.design_space.upper, float)
    rng = np.random.default_rng(seed)
    heights, tilts, params, missed = [], [], {}, 0
    u0, v0, u1, v1 = board.extent_mm
    for i in range(placements):
        x = np.array(job.layout.x, dtype=float)
        for target in targets:
            for name in next(p for p in job.guide.parts if p.name == target.part).parameters:
                key = name.rsplit(".", 1)[1]
                if key in MOVES:
                    k = names.index(name)
                    x[k] = float(np.clip(x[k] + rng.uniform(-1, 1) * MOVES[key], lower[k], upper[k]))
        aim = ((u0 + u1) / 2 + rng.uniform(-40, 40), (v0 + v1) / 2 + rng.uniform(-30, 30))
        if independent:
            picture, lens = independent_side_frame(job, board, x, aim_mm=aim, seed=seed * 1000 + i)
        else:
            url = URL.format(u=f"{aim[0]:.1f}", v=f"{aim[1]:.1f}", seed=seed * 1000 + i)
            picture, lens = check_side.side_frame(job, board, targets, url, layout=x)
        side = check_side.measure_side(job, board, targets, picture, lens, camera="side")
        truth = part_plane_pose(job.scenario, x, board.plane, [t.part for t in targets])
        for check in side.checks:
            if not check.found:
                missed += 1
                continue
            true = truth[check.name]
            heights.append(check.measured_center_mm[1] - true.center_mm[1])
            turn = (check.measured_heading_deg - true.heading_deg + 180.0) % 360.0 - 180.0
            tilts.append(turn)
        # the design parameters the side view fits (given the others at their true values, as the top view gives)
        poses = {c.name: c for c in side.checks if c.found}
        fitted = as_built_layout(job.scenario, x, board.plane,
                                 {n: PlanePose(c.measured_center_mm, c.measured_heading_deg) for n, c in poses.items()},
                                 {p.name: tuple(n for n in p.parameters if n.rsplit(".", 1)[1] in ("z", "roll",
                                                                                                   "pitch"))
                                  for p in job.guide.parts})
        for name in fitted.measured:
            k = names.index(name)
            error = (fitted.unclipped[k] - x[k]) * (1000.0 if name.rsplit(".", 1)[1] in "xyz" else 1.0)
            params.setdefault(name, []).append(error)
    return {"scenario": scenario + (" independent" if independent else ""), "targets": len(targets),
            "frames": placements, "missed": missed,
            "height_p95": _p95(heights), "height_max": float(np.max(np.abs(heights))) if heights else math.nan,
            "tilt_p95": _p95(tilts), "tilt_max": float(np.max(np.abs(tilts))) if tilts else math.nan,
            "params": {n: (_p95(v), float(np.max(np.abs(v)))) for n, v in params.items()}}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="bench_check_side", description=__doc__.splitlines()[0])
    parser.add_argument("--placements", type=int, default=30)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--scenarios", default="simple,causalityswitch_ball")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    print("scenario                          tags  frames  missed  height p95 / max mm  tilt p95 / max deg  "
          "fitted parameters p95 / max")
    for scenario, independent in ((s, i) for s in args.scenarios.split(",") for i in (False, True)):
        row = run(scenario, args.placements, args.seed, independent)
        fitted = ", ".join(f"{n} {p:.3f} / {m:.3f}" for n, (p, m) in row["params"].items())
        print(f"{row['scenario']:<33} {row['targets']:<5} {row['frames']:<7} {row['missed']:<7} "
              f"{row['height_p95']:.3f} / {row['height_max']:.3f}        {row['tilt_p95']:.3f} / {row['tilt_max']:.3f}"
              f"       {fitted}", flush=True)


if __name__ == "__main__":
    main()
