"""The check overlay: where a misplaced part is drawn, its target ring, a part not seen, a part in place."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from projector.frames import apply_homography
from projector.overlay import CAMERA_COLOURS, PROJECTOR_COLOURS, draw_check, misplaced, render_check
from projector.samples import sample_guide

#: 2 px per mm, v up, the sample guide (about -60..420 x -60..290 mm) inside 1000 x 720 pixels.
H = np.array([[2.0, 0.0, 140.0], [0.0, -2.0, 620.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class Checked:  # calibration.check.PartCheck's fields the overlay reads
    name: str
    found: bool
    measured_center_mm: tuple | None
    measured_heading_deg: float | None
    error: tuple | None
    within_tolerance: bool | None
    tolerance: tuple = (None, None, None)
    tag_id: int | None = None


def _near(image, point_px, colour, radius=3) -> bool:
    x, y = np.round(point_px).astype(int)
    patch = image[y - radius:y + radius + 1, x - radius:x + radius + 1].reshape(-1, 3).astype(int)
    return bool(np.any(np.abs(patch - colour).sum(axis=1) < 60))


def test_a_misplaced_part_gets_its_outline_where_it_is_a_ring_where_it_goes():
    guide = sample_guide()
    cup = guide.part("catch_cup")  # centre (40, 120), tolerance 6 mm along u
    moved = (cup.center_mm[0] + 20.0, cup.center_mm[1] - 10.0)
    checks = [Checked("catch_cup", True, moved, 0.0, (20.0, -10.0, 22.4, 0.0), False, (6.0, 4.5, None)),
              Checked("top_track", False, None, None, None, None),
              Checked("lever & <arm>", True, (60.0, 40.0), 12.0, (0.0, 0.0, 0.0, 0.0), True)]
    assert misplaced(checks[0]) and not misplaced(checks[1]) and not misplaced(checks[2])
    image = render_check(guide, checks, (1000, 720), H, caption=["predicted success as placed: 0.71"])
    colours = PROJECTOR_COLOURS
    ring = apply_homography(H, [(cup.center_mm[0] + 4.5, cup.center_mm[1])])[0]  # the tighter tolerance: 4.5 mm
    assert _near(image, ring, colours["target"])
    # the cup's outline moved with it: its lower-left corner (20, 105) is now at (40, 95)
    assert _near(image, apply_homography(H, [(40.0, 95.0)])[0], colours["move"])
    assert not _near(image, apply_homography(H, [(20.0, 105.0)])[0], colours["move"])
    track = guide.part("top_track")
    corner = np.asarray(track.outline.exterior.coords[0])
    assert _near(image, apply_homography(H, [corner])[0], colours["missing"], radius=4)
    lever = np.asarray(guide.part("lever & <arm>").outline.exterior.coords[0])
    assert _near(image, apply_homography(H, [lever])[0], colours["in_place"])


def test_the_same_drawing_goes_over_a_camera_frame():
    guide = sample_guide()
    cup = guide.part("catch_cup")
    frame = np.full((720, 1000, 3), 230, dtype=np.uint8)
    checks = [Checked("catch_cup", True, (cup.center_mm[0] + 20.0, cup.center_mm[1]), 0.0,
                      (20.0, 0.0, 20.0, 0.0), False, (6.0, None, None))]
    seen = []

    def project(points, height):
        seen.append(height)
        return apply_homography(H, points)

    drawn = draw_check(frame, guide, checks, project)
    assert drawn.shape == frame.shape and np.all(frame == 230)  # a copy: the frame itself is kept
    ring = apply_homography(H, [(cup.center_mm[0] + 6.0, cup.center_mm[1])])[0]
    assert _near(drawn, ring, CAMERA_COLOURS["target"]) and set(seen) == {0.0}  # drawn on the plane
