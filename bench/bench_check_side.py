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
part, its own ray casting of the parts' shapes, Pillow's rasteriser and blur): the row marked "independent".

Both draw every part and jig stand of the scene graph in front of the board, hiding what they stand before: a frame
may show fewer tags. Counted: frames with a board tag hidden (the plane then from the other three), frames with no
plane (fewer than three board tags: nothing measured), face tags not read; what the station said about each; and on
how many frames the two renderers hide the same tags (each renderer's own truth: a tag wholly in the frame with no
sample hidden).

Goal: p95 height <= 0.5 mm, p95 tilt <= 0.5 deg. ``python -m bench.bench_check_side [--placements N] [--seed S]
[--scenarios simple,causalityswitch_ball] [--tilt DEG]`` (``--tilt -20``: the camera raised 255 mm, looking down
at the board over the parts).
"""

from __future__ import annotations

import argparse
import math
import sys
from collections import Counter

import numpy as np

from bench.side_render import independent_side_frame
from calibration.asbuilt import PlanePose, as_built_layout, part_plane_pose
from projector.board import side_board
from station.services import check as service
from station.services import check_side

URL = ("sim://camera?view=side&height=700&size=1920x1080&f=1400&blur=0.8&noise=2&jpeg=90&target={u},{v}&seed={seed}"
       "&tilt={tilt}")
DISTANCE_MM = 700.0
MOVES = {"z": 0.005, "roll": 3.0, "pitch": 3.0, "x": 0.003, "y": 0.003}


def _p95(values) -> float:
    return float(np.percentile(np.abs(values), 95)) if len(values) else float("nan")


def run(scenario: str, placements: int, seed: int, independent: bool = False, tilt: float = 0.0) -> dict:
    job = service.prepare_check(scenario, "success", jigs=True)
    board = side_board(job.guide)
    targets = check_side.side_targets(job, board)
    names = list(job.scenario.design_space.names)
    lower = np.asarray(job.scenario.design_space.lower, float)
    upper = np.asarray(job.scenario.design_space.upper, float)
    rng = np.random.default_rng(seed)
    heights, tilts, params, missed = [], [], {}, 0
    board_hidden, no_plane, said, visible = 0, 0, Counter(), []
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
        seen = {}
        if independent:
            picture, lens = independent_side_frame(job, board, x, aim_mm=aim, seed=seed * 1000 + i,
                                                   rise_mm=DISTANCE_MM * math.tan(math.radians(-tilt)),
                                                   visibility=seen)
        else:
            url = URL.format(u=f"{aim[0]:.1f}", v=f"{aim[1]:.1f}", seed=seed * 1000 + i, tilt=f"{tilt:g}")
            truth_list = []
            picture, lens = check_side.side_frame(job, board, targets, url, layout=x, truth=truth_list)
            seen = {t.tag_id: t.visible for t in truth_list}
        visible.append(seen)
        side = check_side.measure_side(job, board, targets, picture, lens, camera="side")
        missing = side.measurement.missing_reference_ids
        board_hidden += bool(missing) and side.measurement.plane is not None
        no_plane += side.measurement.plane is None
        for line in check_side._board_lines(missing, side.hidden, side.measurement.plane is None):
            said[line] += 1
        truth = part_plane_pose(job.scenario, x, board.plane, [t.part for t in targets])
        for check in side.checks:
            if not check.found:
                missed += 1
                said[check.instruction] += 1
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
            "frames": placements, "missed": missed, "board_hidden": board_hidden, "no_plane": no_plane,
            "said": said, "visible": visible,
            "height_p95": _p95(heights), "height_max": float(np.max(np.abs(heights))) if heights else math.nan,
            "tilt_p95": _p95(tilts), "tilt_max": float(np.max(np.abs(tilts))) if tilts else math.nan,
            "params": {n: (_p95(v), float(np.max(np.abs(v)))) for n, v in params.items()}}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="bench_check_side", description=__doc__.splitlines()[0])
    parser.add_argument("--placements", type=int, default=30)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--scenarios", default="simple,causalityswitch_ball")
    parser.add_argument("--tilt", type=float, default=0.0,
                        help="deg the side camera stands below its aim (negative: above, looking down)")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    print(f"side camera {DISTANCE_MM:g} mm from the board, tilt {args.tilt:g} deg")
    print("scenario                          tags  frames  missed  plane from 3  no plane  height p95 / max mm  "
          "tilt p95 / max deg  fitted parameters p95 / max")
    for scenario in args.scenarios.split(","):
        rows = [run(scenario, args.placements, args.seed, independent, args.tilt) for independent in (False, True)]
        for row in rows:
            fitted = ", ".join(f"{n} {p:.3f} / {m:.3f}" for n, (p, m) in row["params"].items())
            print(f"{row['scenario']:<33} {row['targets']:<5} {row['frames']:<7} {row['missed']:<7} "
                  f"{row['board_hidden']:<13} {row['no_plane']:<9} "
                  f"{row['height_p95']:.3f} / {row['height_max']:.3f}        {row['tilt_p95']:.3f} / "
                  f"{row['tilt_max']:.3f}       {fitted}", flush=True)
            for line, count in row["said"].most_common(8):
                print(f"    {count} x {line}")
        twin, other = (row["visible"] for row in rows)
        same = sum(a == b for a, b in zip(twin, other, strict=True))
        print(f"  hidden tags: the two renderers agree on {same} of {len(twin)} frames", flush=True)
        for n, (a, b) in enumerate(zip(twin, other, strict=True)):
            if a != b:
                print(f"    frame {n}: twin hides {sorted(k for k, v in a.items() if not v)}, independent hides "
                      f"{sorted(k for k, v in b.items() if not v)}")


if __name__ == "__main__":
    main()
