"""The as-built check drawn over the guide: per misplaced part an arrow from where it is to where it must go and a
ring at the target (pure: no device).

Two surfaces, one drawing: :func:`render_check` draws a projector frame (the geometry and homography of
:func:`projector.frames.render_step`: projector pixel ``~ H @ (u, v, 1)``, fitted to the screen without a
calibration, and said), :func:`draw_check` draws the same over a camera frame through a function that maps plane
points ``(u, v)`` at a height to the camera's pixels (the camera's pose from the reference tags).

The checked parts come as objects with ``name``, ``tag_id``, ``found``, ``measured_center_mm``,
``measured_heading_deg``, ``error`` (``du, dv, distance, dheading``, measured minus designed), ``within_tolerance``,
``tolerance`` (``du, dv, dheading``) and optionally ``owner`` and ``body`` (a run's domino checked in the run's
stead): :class:`calibration.check.PartCheck` (projector does not import calibration). A part is
*misplaced* when it is out of its tolerance, or has none and is off by 1 mm or 1 degree or more: it is drawn where it
stands (orange), where it must go (white), with an arrow between and a ring round the target as wide as its tolerance
(at least 3 mm). A part in place is drawn green; a part whose tag was not seen, dashed grey, marked "not seen".
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from shapely import affinity

from projector.frames import DEFAULT_SIZE, WHITE, _ascii, _Canvas, _cv2, _point, _rings
from projector.guide import Guide

__all__ = ["draw_check", "misplaced", "render_check"]

#: Colours (RGB) on a projector (light on black) and over a camera frame (dark on a light table or sheet).
PROJECTOR_COLOURS = {"move": (255, 150, 30), "in_place": (70, 235, 70), "missing": (150, 150, 150),
                     "target": (255, 255, 255)}
CAMERA_COLOURS = {"move": (235, 80, 0), "in_place": (0, 150, 40), "missing": (110, 110, 110), "target": (20, 80, 230)}
#: Off by at least this much, a part without a tolerance is drawn as misplaced.
UNTOLERATED_MM, UNTOLERATED_DEG = 1.0, 1.0
#: The smallest target ring (mm).
RING_MM = 3.0


def misplaced(check) -> bool:
    """Whether the check says the part must move (see the module notes)."""
    if not check.found or check.error is None:
        return False
    if check.within_tolerance is not None:
        return not check.within_tolerance
    return check.error[2] >= UNTOLERATED_MM or abs(check.error[3]) >= UNTOLERATED_DEG


def render_check(guide: Guide, checks: Sequence, size: tuple[int, int] = DEFAULT_SIZE, homography=None,
                 caption: Sequence[str] = ()) -> np.ndarray:
    """The projector frame after a check (``H x W x 3`` RGB uint8), with ``caption`` lines at its top."""
    canvas = _CheckCanvas(guide, size, homography)
    image = canvas._blank()
    for part in guide.parts:  # the layout, dim, for orientation
        canvas._edges(image, _rings(part.outline), (70, 70, 70), 1)
    canvas.draw(image, checks)
    lines = list(caption) or [f"Check: {sum(misplaced(c) for c in checks)} part(s) to move"]
    canvas._caption(image, [(line, WHITE) for line in lines])
    return image


def draw_check(image: np.ndarray, guide: Guide, checks: Sequence,
               project: Callable[[np.ndarray, float], np.ndarray], caption: Sequence[str] = ()) -> np.ndarray:
    """The check drawn over a camera frame (a copy, RGB): ``project(points_mm (n, 2), height_mm)`` gives their
    pixels (OpenCV's convention, pixel centres at integers). Outlines are drawn on the plane (h = 0: where each part
    stands on the sheet), as the projector draws them."""
    canvas = _CheckCanvas(guide, (int(image.shape[1]), int(image.shape[0])), None, project=project,
                          colours=CAMERA_COLOURS)
    out = np.array(image, dtype=np.uint8, copy=True)
    if out.ndim == 2:
        out = np.repeat(out[:, :, None], 3, axis=2)
    canvas.draw(out, checks)
    if caption:
        canvas.true_scale = True  # the camera's frame: no projector scale to warn about
        canvas._caption(out, [(line, WHITE) for line in caption])
    return out


def _target(part, body: int | None) -> tuple:
    """Where a check's part (or its body ``body``: a run's domino) must be: its outline and origin on the plane."""
    if body is None:
        return part.outline, np.asarray(part.center_mm, dtype=float)
    from shapely.geometry import Point

    tag = next(b for b in part.body_tags if b.body == body)
    here = Point(tag.center_mm)
    pieces = list(getattr(part.outline, "geoms", [part.outline]))  # the run's pieces: the body's is nearest its origin
    return min(pieces, key=here.distance), np.asarray(tag.center_mm, dtype=float)


class _CheckCanvas(_Canvas):
    """A frame canvas whose points go through the homography, or through a camera projection at a height."""

    def __init__(self, guide: Guide, size, homography, project=None, colours=None) -> None:
        super().__init__(guide, size, homography)
        self.project = project
        self.colours = colours or PROJECTOR_COLOURS

    def _px(self, points_mm) -> np.ndarray:
        if self.project is None:
            return super()._px(points_mm)
        return np.asarray(self.project(np.atleast_2d(np.asarray(points_mm, dtype=float)), 0.0),
                          dtype=float).reshape(-1, 2)

    def draw(self, image: np.ndarray, checks: Sequence) -> None:
        parts = {p.name: p for p in self.guide.parts}
        cv2 = _cv2()
        MOVE, IN_PLACE, MISSING, TARGET = (self.colours[k] for k in ("move", "in_place", "missing", "target"))
        for check in checks:
            part = parts.get(getattr(check, "owner", check.name))
            if part is None:
                continue
            outline, centre = _target(part, getattr(check, "body", None))
            if not check.found:
                self._dashed(image, _rings(outline), MISSING)
                below = self._px(np.vstack(_rings(outline) or [centre[None, :]]))
                where = np.array([below[:, 0].mean(), below[:, 1].max() + 0.9 * self.line])
                self._text(image, f"{check.name}: tag {check.tag_id} not seen", where, MISSING, 0.7, centre=True)
                continue
            du, dv, distance, dheading = check.error
            if not misplaced(check):
                self._edges(image, _rings(outline), IN_PLACE, self.thick + 1)
                self._text(image, f"{check.name} ok", self._px(centre)[0], IN_PLACE, 0.7, centre=True)
                continue
            placed = affinity.translate(affinity.rotate(outline, dheading, origin=tuple(centre)), du, dv)
            self._edges(image, _rings(outline), TARGET, self.thick)
            self._edges(image, _rings(placed), MOVE, self.thick + 1)
            tolerance = [t for t in check.tolerance[:2] if t is not None]
            ring = max(RING_MM, min(tolerance) if tolerance else RING_MM)
            circle = centre + ring * np.column_stack([np.cos(np.linspace(0, 2 * np.pi, 49)),
                                                      np.sin(np.linspace(0, 2 * np.pi, 49))])
            self._edges(image, [circle], TARGET, self.thick + 1)
            start, end = self._px(np.vstack([np.asarray(check.measured_center_mm), centre]))
            if np.linalg.norm(end - start) >= 4:
                cv2.arrowedLine(image, _point(start), _point(end), MOVE, self.thick + 1, cv2.LINE_AA, 4,
                                tipLength=min(0.4, 12.0 / max(float(np.linalg.norm(end - start)), 1.0)))
            words = f"{check.name}: {distance:.1f} mm" + (f", {abs(dheading):.1f} deg" if abs(dheading) >= 0.1 else "")
            above = self._px(np.vstack(_rings(placed) or [centre[None, :]]))
            label = np.array([above[:, 0].mean(), above[:, 1].min() - 0.9 * self.line])
            self._text(image, _ascii(words), label, MOVE, 0.8, centre=True)

    def _dashed(self, image: np.ndarray, rings, colour, dash_px: float = 8.0) -> None:
        """Rings drawn as dashes of ``dash_px`` pixels (a part that was not seen: where it should be)."""
        cv2 = _cv2()
        for ring in rings:
            pixels = self._px(ring)
            for a, b in zip(pixels[:-1], pixels[1:]):
                pieces = max(1, int(np.linalg.norm(b - a) // dash_px))
                stops = a + np.linspace(0.0, 1.0, pieces + 1)[:, None] * (b - a)
                for start, end in zip(stops[:-1:2], stops[1::2]):
                    cv2.line(image, _point(start), _point(end), colour, self.thick, cv2.LINE_AA, 4)
