"""A job placed on the stock by camera, on the twins: how far the cut lands from where it was meant to be.

    python -m bench.bench_laser_placement [--sheets 12] [--seed 1] [--noise 2] [--blur 0.7] [--figure PNG]

The laser twin (virtual clock) engraves the four registration marks, the simulated camera over its bed sees them
(with the given pixel noise and blur) and the bed is registered (``station calibrate bed``); then, for each of
``--sheets`` sheets of stock laid on the bed at random places and turns (seeded), the camera finds the sheet, a
50 x 30 mm rectangle is placed 5 mm inside its lower-left corner along its edge, cut on the twin, and the corners
the twin burned are compared with where they were meant to be on the true sheet. It prints the registration's
residual and, per sheet, the largest corner error; the goal is within 0.5 mm. ``--figure`` writes the camera's
picture of the last sheet after the cut, with the outline and the sheet found drawn on it.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
from dataclasses import replace

import numpy as np

from cam.place import place_lines
from drivers.devices import resolve
from drivers.grbl import GrblConnection, Job, JobRunner
from station.services import bed

RECTANGLE = ["G21", "G90", "M4 S0", "G0 X0 Y0", "G1 X50 Y0 S1000 F900", "G1 X50 Y30", "G1 X0 Y30", "G1 X0 Y0",
             "M5 S0"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.bench_laser_placement",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--sheets", type=int, default=12)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--noise", type=float, default=2.0, help="camera noise, grey levels (default 2)")
    parser.add_argument("--blur", type=float, default=0.7, help="camera blur, pixels (default 0.7)")
    parser.add_argument("--figure", help="write the last sheet's picture here (PNG)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="placement-bench-") as home:
        # the twin's registration is kept in a data folder of its own, not over the station's laser's
        os.environ["CHAOS_STATION_HOME"] = home
        return run(args)


def run(args) -> int:
    rng = np.random.default_rng(args.seed)
    name = f"placement-bench-{args.seed}"
    laser_url = f"sim://grbl?profile=laser&clock=virtual&wire=0&name={name}"
    camera_url = f"{bed.SIM_BED_CAMERA}&laser={name}&noise={args.noise:g}&blur={args.blur:g}&seed={args.seed}"
    camera = resolve(camera_url).factory(camera_url)
    done = bed.calibrate_bed(bed.BedCalibrationRequest(port=laser_url, camera=camera_url))
    registration = done.registration
    print(f"bed registration: residual {registration.residual_rms_mm:.3f} mm RMS, {registration.residual_max_mm:.3f} "
          f"mm at most (16 corners; camera {camera_url})")
    errors, found_errors = [], []
    frame = picture = None
    with GrblConnection(laser_url) as conn:
        wco = conn.work_offset()
        for sheet in range(args.sheets):
            # a sheet of 90-200 x 70-150 mm somewhere on the bed's middle, turned up to 20 degrees either way
            width, height = rng.uniform(90, 200), rng.uniform(70, 150)
            angle = rng.uniform(-20, 20)
            u, v = rng.uniform(-170, 170 - width), rng.uniform(-170, 170 - height)
            # a fresh sheet: what the laser burned before lies on the sheets taken away
            view = replace(camera.bed_view, stock=(u, v, width, height, angle),
                           since=len(conn.port.machine.snapshot().executed))
            camera.bed_view = view
            with camera:
                frame = camera.grab()
            stock = bed.find_stock(frame, registration)
            truth = view.machine_from_plane(view.stock_corners())
            if stock is None:
                print(f"sheet {sheet + 1}: not found")
                continue
            found_errors.append(float(np.abs(stock - truth).max()))
            placement = bed.placement_on_stock(stock, wco, (0.0, 0.0), margin=5.0)
            before = len(conn.port.machine.snapshot().executed)
            result = JobRunner(conn, Job("rectangle", place_lines(RECTANGLE, placement), laser=True)).run()
            if not result.ok:
                print(f"sheet {sheet + 1}: {result.message}")
                continue
            burned = np.array([b.end[:2] for b in conn.port.machine.snapshot().executed[before:] if b.power > 0])
            theta = math.radians(angle)
            along = np.array([math.cos(theta), math.sin(theta)])
            across = np.array([-math.sin(theta), math.cos(theta)])
            meant = np.array([truth[0] + (5 + x) * along + (5 + y) * across
                              for x, y in ((50, 0), (50, 30), (0, 30), (0, 0))])
            error = float(np.linalg.norm(burned - meant, axis=1).max())
            errors.append(error)
            print(f"sheet {sheet + 1}: {width:.0f} x {height:.0f} mm turned {angle:+.1f} deg: sheet found within "
                  f"{found_errors[-1]:.3f} mm, cut within {error:.3f} mm of where it was meant", flush=True)
            if args.figure:  # before the cut, with the outline placed; after it, as the camera sees it
                outline = bed.placed_outline_machine(RECTANGLE, placement, wco)
                placed = bed.bed_picture(frame, registration, outline, stock_mm=stock)
                with camera:
                    after = camera.grab()
                picture = (placed, after)
    if errors:
        print(f"{len(errors)} sheets: cut within {max(errors):.3f} mm at worst, {np.mean(errors):.3f} mm on "
              f"average; sheet corners found within {max(found_errors):.3f} mm at worst")
    if args.figure and picture is not None:
        import cv2

        corners = registration.to_pixels(np.array(stock))
        left, top = (max(0, int(v) - 60) for v in corners.min(axis=0))
        right, bottom = (int(v) + 60 for v in corners.max(axis=0))
        panels = [image[top:bottom, left:right] for image in picture]
        gap = np.full((panels[0].shape[0], 12, 3), 255, dtype=np.uint8)
        cv2.imwrite(args.figure, cv2.cvtColor(np.hstack([panels[0], gap, panels[1]]), cv2.COLOR_RGB2BGR))
        print(f"wrote {args.figure}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
