"""The check overlay: where a misplaced part is drawn, its target ring, a part not seen, a part in place."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from shapely import affinity
from shapely.geometry import Point, Polygon, box

from projector.frames import apply_homography
from projector.overlay import (
    CAMERA_COLOURS,
    LEGEND,
    PROJECTOR_COLOURS,
    check_layout,
    draw_check,
    misplaced,
    render_check,
)
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


def _moved(guide, name, du, dv, dheading=0.0, within=False):
    """A check of part ``name`` found moved by (du, dv) mm and turned dheading deg."""
    part = guide.part(name)
    return Checked(name, True, (part.center_mm[0] + du, part.center_mm[1] + dv), part.heading_deg + dheading,
                   (du, dv, float(np.hypot(du, dv)), dheading), within, (6.0, 6.0, None), part.tag_id)


def _crowded(guide):
    """Parts close together: the cup pushed up beside the upper-left reference tag, the track pushed down onto the
    lever, the lever nudged up under it (drawn with their labels above them, the cup's lands on the tag and the
    track's on the lever's)."""
    return [_moved(guide, "catch_cup", -45.0, 95.0), _moved(guide, "top_track", -20.0, -100.0, 2.0),
            _moved(guide, "lever & <arm>", 0.0, 20.0, 5.0)]


def _tag_squares(guide, checks):
    """The squares (with their white border) of the reference tags and of each checked part's tag where the part
    stands, in pixels through H: worked out here from the checks, not taken from the layout."""
    squares = []
    for tag in guide.reference_tags:
        half = 0.625 * tag.size_mm
        squares.append(Polygon(apply_homography(H, np.asarray(tag.center_mm) + half * np.array(
            [[-1, -1], [1, -1], [1, 1], [-1, 1]]))))
    for check in checks:
        part = guide.part(check.name)
        du, dv, _, dheading = check.error
        half = 0.625 * part.tag_size_mm
        square = Point(part.tag_center_mm).buffer(half, cap_style="square")
        square = affinity.translate(affinity.rotate(square, dheading, origin=part.center_mm), du, dv)
        squares.append(Polygon(apply_homography(H, np.asarray(square.exterior.coords))))
    return squares


#: A caption of two long lines (broken over several): its band at the top of the frame would cover the top tags.
CAPTION = ["physical success on the table 0.69 (95 %: 0.55-0.80): expect 1.5 attempts (1.3-1.8) (as placed, 48 "
           "simulations)", "3 of 3 tagged parts measured, 3 to move (3 with no tolerance on the sheet), 2 to check "
           "by eye"]


def test_labels_keep_off_each_other_the_tags_and_the_frame_edge():
    guide = sample_guide()
    checks = _crowded(guide)
    squares = _tag_squares(guide, checks)
    frame = box(0, 0, 1000, 720)
    for project in (None, lambda points, height: apply_homography(H, points)):  # the projector, a camera frame
        layout = check_layout(guide, checks, (1000, 720), H, project=project, caption=CAPTION)
        labels = [box(*label.box) for label in layout.labels]
        assert [label.text for label in layout.labels] == ["catch_cup: 105.1 mm", "top_track: 102.0 mm, 2.0 deg",
                                                           "lever & <arm>: 20.0 mm, 5.0 deg"]
        for number, label in enumerate(labels):
            assert frame.contains(label)
            assert not any(label.intersects(other) for other in labels[number + 1:])
            assert not any(label.intersects(square) for square in squares)
            assert not label.intersects(box(*layout.caption)) and not label.intersects(box(*layout.legend))
        legend = box(*layout.legend)
        assert frame.contains(legend) and not any(legend.intersects(square) for square in squares)
        if project is not None:  # over a camera frame the caption finds a band off the tags too
            assert not any(box(*layout.caption).intersects(square) for square in squares)
        hulls = [Polygon(apply_homography(H, np.asarray(p.outline.convex_hull.exterior.coords))) for p in guide.parts]
        assert not any(legend.intersects(hull) for hull in hulls)  # a place free of parts was found
        for label, drawn in zip(layout.labels, labels):  # beside its part, or a leader line reaching it
            part = guide.part(label.text.split(":")[0])
            check = next(c for c in checks if c.name == part.name)
            placed = affinity.translate(affinity.rotate(part.outline, check.error[3], origin=part.center_mm),
                                        *check.error[:2])
            where = Polygon(apply_homography(H, np.asarray(placed.convex_hull.exterior.coords)))
            if label.leader is None:
                assert drawn.distance(where) <= 25
            else:
                assert where.distance(Point(label.leader[1])) < 1.0 and drawn.distance(Point(label.leader[0])) < 1.0


def test_a_camera_frame_keeps_its_reference_tags_clear_of_ink():
    guide = sample_guide()
    frame = np.full((720, 1000, 3), 200, dtype=np.uint8)
    drawn = draw_check(frame, guide, _crowded(guide), lambda points, height: apply_homography(H, points),
                       caption=CAPTION)
    mask = np.zeros((720, 1000), dtype=np.uint8)
    for tag in guide.reference_tags:
        half = 0.625 * tag.size_mm
        corners = apply_homography(H, np.asarray(tag.center_mm) + half * np.array([[-1, -1], [1, -1], [1, 1],
                                                                                   [-1, 1]]))
        cv2.fillPoly(mask, [np.round(corners).astype(np.int32)], 1)
    assert mask.sum() > 10000  # the tags are (mostly) in the frame
    assert np.array_equal(drawn[mask > 0], frame[mask > 0])


def test_the_legend_names_the_colours():
    guide = sample_guide()
    image = render_check(guide, _crowded(guide), (1000, 720), H)
    x0, y0, x1, y1 = (int(v) for v in check_layout(guide, _crowded(guide), (1000, 720), H).legend)
    swatches = image[y0:y1, x0:x0 + (x1 - x0) // 4].reshape(-1, 3).astype(int)
    for key, _, _ in LEGEND:  # a swatch of each colour, at the legend's left
        assert np.any(np.abs(swatches - PROJECTOR_COLOURS[key]).sum(axis=1) < 30), key
    assert [words for _, words, _ in LEGEND] == ["where it stands", "where it must go", "in place", "not seen"]


def test_a_caption_line_wider_than_the_frame_goes_on_below():
    guide = sample_guide()
    line = "the physical success on the table is 0.69 (0.55-0.80): expect 1.5 attempts; " * 3
    small = np.array([[1.0, 0.0, 150.0], [0.0, -1.0, 360.0], [0.0, 0.0, 1.0]])  # at true scale: no warning line
    image = render_check(guide, [], (640, 400), small, caption=[line.strip(), "second line"])
    band = image[:120]
    assert not np.any(band[:, -4:] > 100)  # no word runs off the right edge
    rows = np.flatnonzero((band > 100).any(axis=(1, 2)))
    assert rows.max() - rows.min() > 3 * 14  # more than the two lines given (14 px each): the first went on below
