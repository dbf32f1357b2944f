"""A whole as-built check's time (the goal: <= 0.5 s per frame) and how well it reads a moved part.

For BALLRUN (side view, no model) and SIMPLE (top view, with its fitted model): frames of the camera twin (1080p,
f = 1400 px, 1 m above the guide's middle, blur 0.8 px, noise 2, JPEG 90) of the parts with one tagged part moved
by a random offset (up to 10 mm, 5 degrees; seeded). Timed per frame: the check of one frame (tag detection, the
plane, the part tags at their heights, every part's error and instruction, the as-built layout and the model's
scores) with a detector made per check and with one detector reused; the guide, made once per session, is timed
apart. Printed: median and worst times, and the moved part's position (mm) and heading (deg) errors, p95 and max.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

FRAMES = 6
SEED = 19
CASES = (("ballrun", "success", "goblet"),
         ("simple", str(Path(__file__).resolve().parents[1] / "tests" / "data" / "robust"
                        / "simple-layout-with-model.json"), "track"))


def main() -> None:
    from calibration.intrinsics import CameraIntrinsics
    from drivers.sim.camera_render import render
    from drivers.sim.camera_scene import CameraModel, RenderOptions
    from station.services import check as service
    from vision.detection import TagDetector

    rng = np.random.default_rng(SEED)
    options = RenderOptions(blur_px=0.8, noise=2.0, jpeg_quality=90, seed=SEED)
    print(f"{'scenario':<9} {'guide s':>7} {'check s median/max':>19} {'reused det. s':>14} {'pos err p95/max mm':>19} "
          f"{'turn err p95/max':>17}")
    for scenario, layout, part in CASES:
        start = time.perf_counter()
        job = service.prepare_check(scenario, layout)
        guide_time = time.perf_counter() - start
        u0, v0, u1, v1 = job.guide.extent_mm
        camera = CameraModel.looking_down(target_mm=((u0 + u1) / 2, (v0 + v1) / 2), height_mm=1000.0)
        intrinsics = CameraIntrinsics(camera.camera_matrix, camera.dist_coeffs, camera.image_size)
        frames = []
        for _ in range(FRAMES):
            offset = (*rng.uniform(-10, 10, 2), rng.uniform(-5, 5))
            image, _ = render(service.sim_scene(job.guide, {part: offset}), camera, options)
            frames.append((offset, image))
        fresh, reused, position, turn = [], [], [], []
        detector = TagDetector()
        for offset, image in frames:
            start = time.perf_counter()
            report = service.check_frame(job, image, intrinsics).report
            fresh.append(time.perf_counter() - start)
            start = time.perf_counter()
            service.check_frame(job, image, intrinsics, detector=detector)
            reused.append(time.perf_counter() - start)
            moved = next(p for p in report.parts if p.name == part)
            position.append(float(np.hypot(moved.error[0] - offset[0], moved.error[1] - offset[1])))
            turn.append(abs(moved.error[3] - offset[2]))
        print(f"{scenario:<9} {guide_time:>7.2f} {np.median(fresh):>10.3f}/{max(fresh):<8.3f} "
              f"{np.median(reused):>14.3f} {np.percentile(position, 95):>10.2f}/{max(position):<8.2f} "
              f"{np.percentile(turn, 95):>8.2f}/{max(turn):<8.2f}")
    print(f"goal: a whole check <= 0.5 s per frame; {FRAMES} frames per scenario, seed {SEED}")
