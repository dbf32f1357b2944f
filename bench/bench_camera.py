"""Camera twin benchmark: render time per 1080p frame (drivers.sim.camera_render) and the projector mapping it
feeds (calibration.projector_map) at full size.

Run with ``.venv/bin/python -m bench camera``. Environment: ``CAMERA_BENCH_FRAMES`` (frames timed per case, default
5). The detection time per frame and the whole check are the as-built check's benchmarks.

The scene is the issue's acceptance camera: 1080p, f = 1400 px, 1 m above the plane, four 40 mm reference tags, 24
parts with 30 mm tags on their top faces up to 50 mm above the plane, blur, noise and JPEG.
"""

from __future__ import annotations

import os
import time

import cv2
import numpy as np

from calibration.projector_map import GrayCodePlan, apply_homography, map_projector
from drivers.sim.camera_render import render
from drivers.sim.camera_scene import CameraModel, Occluder, PlaneScene, RenderOptions, TagItem
from drivers.sim.projector import SimulatedProjector

ACCEPTANCE = RenderOptions(blur_px=0.8, noise=2.0, jpeg_quality=90, seed=1)


def acceptance_scene(seed: int = 7, parts: int = 24) -> PlaneScene:
    """Reference tags near the view's corners and parts (a top face at a height with a tag on it)."""
    rng = np.random.default_rng(seed)
    references = tuple(TagItem(583 + n, (u, v), 40.0) for n, (u, v) in
                       enumerate(((-560.0, -300.0), (560.0, -300.0), (560.0, 300.0), (-560.0, 300.0))))
    tags, faces = [], []
    for n in range(parts):
        u, v = -450.0 + (n % 6) * 180.0 + rng.uniform(-20, 20), -200.0 + (n // 6) * 135.0 + rng.uniform(-15, 15)
        height, heading = float(rng.uniform(0, 50)), float(rng.uniform(0, 360))
        c, s = np.cos(np.radians(heading)), np.sin(np.radians(heading))
        box = np.array([[-30, -24], [30, -24], [30, 24], [-30, 24]], dtype=float) @ np.array([[c, s], [-s, c]])
        faces.append(Occluder(box + (u, v), height, tuple(int(x) for x in rng.integers(60, 200, 3))))
        tags.append(TagItem(n, (u, v), 30.0, heading, height))
    return PlaneScene(tags=references + tuple(tags), occluders=tuple(faces))


def timed(function, count: int) -> tuple[float, float, float]:
    """(first call, median of the next ``count``, their median CPU time: every thread of this process) in
    seconds. On a shared machine the wall time also counts other processes' turns; the CPU time does not."""
    start = time.perf_counter()
    function()
    first = time.perf_counter() - start
    times, cpu = [], []
    for _ in range(count):
        start, start_cpu = time.perf_counter(), time.process_time()
        function()
        times.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
    return first, float(np.median(times)), float(np.median(cpu))


def bench_render(count: int) -> None:
    camera = CameraModel.looking_down(height_mm=1000.0, dist_coeffs=(-0.05, 0.01, 0, 0, 0))
    scene = acceptance_scene()
    projector = SimulatedProjector("sim://projector?size=1280x800&area=-640,-400,640,400")
    projector.open()
    projector.show(np.random.default_rng(0).integers(0, 256, (800, 1280, 3), dtype=np.uint8))
    lit = PlaneScene(tags=scene.tags, occluders=scene.occluders, light=projector.light())
    print("render time per 1920x1080 frame (first: the lens grid or light tables are built and cached)")
    print(f"  {'case':<46} {'first s':>8} {'median s':>9} {'CPU s':>7}")
    cases = (("28 tags, 24 part faces, ss 3, blur/noise/JPEG", scene, ACCEPTANCE),
             ("same, supersample 2", scene, RenderOptions(blur_px=0.8, noise=2.0, jpeg_quality=90, supersample=2)),
             ("same + projector light (ss 3)", lit, ACCEPTANCE),
             ("empty plane, sharp, ss 3", PlaneScene(), RenderOptions()))
    for label, case_scene, options in cases:
        first, median, cpu = timed(lambda s=case_scene, o=options: render(s, camera, o), count)
        print(f"  {label:<46} {first:8.3f} {median:9.3f} {cpu:7.3f}")
    _image, truth = render(scene, camera, ACCEPTANCE)
    print(f"  visible tags in the acceptance scene: {sum(t.visible for t in truth)} of {len(truth)}; load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")


def bench_projector_mapping() -> None:
    width, height = 1280, 800
    corners = np.float32([[-0.5, -0.5], [width - 0.5, -0.5], [width - 0.5, height - 0.5], [-0.5, height - 0.5]])
    placement = cv2.getPerspectiveTransform(corners, np.float32([[-290, 200], [330, 215], [300, -190],
                                                                 [-270, -170]])).astype(float)
    projector = SimulatedProjector(f"sim://projector?size={width}x{height}")
    projector.place(placement)
    projector.open()
    camera = CameraModel.looking_down(target_mm=(10, 0), height_mm=1000.0, dist_coeffs=(-0.06, 0.02, 0, 0, 0),
                                      tilt_deg=8.0)
    rotation = camera.rotation
    table = np.linalg.inv(camera.camera_matrix @ np.column_stack([rotation[:, 0], rotation[:, 1], camera.tvec]))
    plan = GrayCodePlan((width, height), 8)
    start = time.perf_counter()
    images = []
    for number, (_name, pattern) in enumerate(plan.patterns()):
        projector.show(pattern)
        options = RenderOptions(blur_px=0.8, noise=2.0, jpeg_quality=90, exposure=0.6, supersample=2, seed=number)
        images.append(render(PlaneScene(light=projector.light()), camera, options)[0])
    rendered = time.perf_counter() - start
    start = time.perf_counter()
    result = map_projector(plan, images, table, camera.camera_matrix, camera.dist_coeffs)
    fitted = time.perf_counter() - start
    grid = np.stack(np.meshgrid(np.linspace(0, width - 1, 33), np.linspace(0, height - 1, 21)), -1).reshape(-1, 2)
    truth = np.linalg.norm(result.plane_from(grid) - apply_homography(placement, grid), axis=1)
    landing = result.landing_error_mm
    print(f"projector mapping, 1280x800 placed obliquely, 1080p camera (k1 -0.06, tilt 8 deg, blur, noise, JPEG): "
          f"{len(images)} frames rendered in {rendered:.1f} s, decoded and fitted in {fitted:.2f} s")
    print(f"  cells seen {result.cells['seen']}, inliers {result.cells['inliers']}; landing error at "
          f"{landing['check_points']} check points: p50 {landing['p50']:.3f} p95 {landing['p95']:.3f} max "
          f"{landing['max']:.3f} mm")
    print(f"  against the true placement (33 x 21 pixels): p50 {np.percentile(truth, 50):.3f} p95 "
          f"{np.percentile(truth, 95):.3f} max {truth.max():.3f} mm (goal p95 <= 0.5 mm)")


def example_frame(path: str = "docs/camera_sim_frame.png") -> None:
    """The camera check guide's frame (docs/guide/camera-check.md): 1280x720 (the acceptance camera's field of
    view), tilted 6 deg, k1 -0.05, a hand over one part, the projector showing rings and arrows; blur, noise,
    vignetting, JPEG 85 (which also keeps the PNG under 300 kB).
    ``python -c "from bench.bench_camera import example_frame; example_frame()"``."""
    from drivers.sim.projector import area_homography

    scene = acceptance_scene(seed=3, parts=18)
    projector = SimulatedProjector("sim://projector?size=1280x800")
    projector.place(area_homography((-640.0, -400.0, 640.0, 400.0), (1280, 800)))
    projector.open()
    frame = np.zeros((800, 1280, 3), np.uint8)

    def pixel(u: float, v: float) -> tuple[int, int]:
        return round(u + 640), round(400 - v)

    for tag in scene.tags[4:7]:
        u, v = tag.center_mm
        cv2.circle(frame, pixel(u + 55, v - 40), 36, (60, 255, 60), 4, cv2.LINE_AA)
        cv2.arrowedLine(frame, pixel(u + 22, v - 16), pixel(u + 41, v - 30), (255, 210, 40), 5, cv2.LINE_AA,
                        tipLength=0.4)
    projector.show(frame)
    hand = Occluder(np.array([[380, -330], [470, -300], [520, -180], [470, -120], [410, -150], [350, -260]], float),
                    90.0, (205, 160, 135))
    camera = CameraModel.looking_down(height_mm=1000.0, image_size=(1280, 720), focal_px=1400.0 * 1280 / 1920,
                                      dist_coeffs=(-0.05, 0.01, 0, 0, 0), tilt_deg=6.0)
    lit = PlaneScene(tags=scene.tags, occluders=(*scene.occluders, hand), light=projector.light())
    image, _truth = render(lit, camera, RenderOptions(blur_px=0.5, noise=0.6, vignetting=0.25, jpeg_quality=85,
                                                      seed=2))
    cv2.imwrite(path, cv2.cvtColor(image, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_PNG_COMPRESSION, 9])


def main() -> None:
    bench_render(int(os.environ.get("CAMERA_BENCH_FRAMES", "5")))
    bench_projector_mapping()


if __name__ == "__main__":
    main()
