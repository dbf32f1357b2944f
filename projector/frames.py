"""Projected frames of an assembly guide: one frame per step, and a "calibrate first" frame (pure: no device).

A frame is drawn through a **homography** ``H`` (3 x 3) that maps the guide plane into the projector's image:
``(x, y, w) = H @ (u, v, 1)``, projector pixel ``(x / w, y / w)`` from guide-plane millimetres ``(u, v)`` (pixel
``(x, y)`` has its centre at those coordinates, x to the right, y down, row 0 at the top of the image). The next
issue's projector mapping measures it; its inverse takes a projector pixel to the guide plane.

Without a homography (None) the guide's extent is fitted to the screen with a margin, below the caption band: the
drawing's shape is right but its scale is not the guide's, and :class:`Frames` says so (``true_scale`` False) as does
every frame, on a line of its own.

Step frame ``k`` (1-based, the guide's assembly order): part ``k`` bright, with its tolerance (a box: the outline
swept over +-delta in u and v, and an arc of +-delta about its heading, coloured by its care level), its heading
arrow, the square where its tag goes, its name and step number; the parts of steps before ``k`` dimmed (static parts
bluish); the later parts not drawn. The reference tags on request. The calibrate frame shows the four reference tags
(tag36h11, in the upstream orientation of :mod:`vision.tags`) at their guide-plane positions over a millimetre
grid, for the camera to find.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from shapely.geometry.base import BaseGeometry

from projector.drawing import arc_points, placement_deltas, tolerance_zone
from projector.errors import ProjectorError
from projector.guide import Guide, GuidePlane, PartDrawing, PartKind, ReferenceTag, where_text
from projector.parameters import off_plane_text
from vision.tags import TAG_CELLS, tag_image

__all__ = ["Frames", "fit_homography", "render_calibrate", "render_frames", "render_step", "step_caption"]

#: Default projector size, and the margin of an un-calibrated fit (a fraction of the screen's smaller side).
DEFAULT_SIZE = (1280, 800)
FIT_MARGIN = 0.04
#: RGB colours (a projector on a board: light on black).
WHITE, BLACK = (255, 255, 255), (0, 0, 0)
CURRENT_FILL, CURRENT_EDGE = (40, 190, 255), (255, 255, 255)
PLACED_FILL, PLACED_EDGE = (38, 38, 38), (105, 105, 105)
STATIC_FILL, STATIC_EDGE = (24, 30, 52), (80, 100, 150)
ARROW = (255, 255, 150)
JIG_EDGE = (230, 160, 80)  # a laser-cut jig's footprint: the current part's, laid before the part
WARNING = (255, 140, 0)
GRID, GRID_MAJOR = (45, 45, 45), (90, 90, 90)
CARE_COLOURS = {"tight": (255, 60, 60), "normal": (255, 205, 0), "loose": (70, 235, 70), None: (190, 190, 190)}
#: Sub-pixel precision of OpenCV's drawing (coordinates times 2**SHIFT).
SHIFT = 4
NOT_TRUE = "SCALE IS NOT TRUE: projector not calibrated, the guide is fitted to the screen"


@dataclass(frozen=True)
class Frames:
    """The projected frames of a guide.

    Parameters
    ----------
    frames : tuple of ndarray
        One ``H x W x 3`` uint8 RGB frame per step: ``frames[k - 1]`` shows step ``k``.
    calibrate : ndarray
        The "calibrate first" frame (reference tags and grid).
    captions : tuple of str
        What each step frame says at its top (its first line).
    true_scale : bool
        True when drawn through a calibrated homography; False when fitted to the screen.
    homography : ndarray
        The 3 x 3 homography used: projector pixels ``~ H @ (u, v, 1)`` from guide-plane mm.
    size : tuple of int
        ``(width, height)`` in pixels.
    """

    frames: tuple[np.ndarray, ...]
    calibrate: np.ndarray
    captions: tuple[str, ...]
    true_scale: bool
    homography: np.ndarray
    size: tuple[int, int]


def render_frames(guide: Guide, size: tuple[int, int] = DEFAULT_SIZE, homography=None, *,
                  reference_tags: bool = False) -> Frames:
    """Every step frame of ``guide`` and its calibrate frame, at ``size`` ``(width, height)`` pixels.

    ``homography``: projector pixels from guide-plane mm (see the module docstring), or None to fit the guide to the
    screen (then ``true_scale`` is False and every frame says so). ``reference_tags`` draws the four reference tags
    on the step frames too.

    Raises
    ------
    ProjectorError
        A size that is not two whole numbers >= 64, a homography that is not an invertible 3 x 3 matrix or that puts
        part of the guide behind the projector.
    """
    canvas = _Canvas(guide, size, homography)
    frames = tuple(canvas.step(k, reference_tags) for k in range(1, len(guide.parts) + 1))
    captions = tuple(step_caption(part, len(guide.parts)) for part in guide.parts)
    return Frames(frames, canvas.calibrate(), captions, canvas.true_scale, canvas.homography, canvas.size)


def render_step(guide: Guide, step: int, size: tuple[int, int] = DEFAULT_SIZE, homography=None, *,
                reference_tags: bool = False) -> np.ndarray:
    """The frame of one step (1-based) only: what a screen stepping through the guide shows (see
    :func:`render_frames`)."""
    if isinstance(step, bool) or not isinstance(step, (int, np.integer)) or not 1 <= step <= len(guide.parts):
        raise ProjectorError(f"step: expected a whole number from 1 to {len(guide.parts)}, got {step!r}")
    return _Canvas(guide, size, homography).step(int(step), reference_tags)


def render_calibrate(guide: Guide, size: tuple[int, int] = DEFAULT_SIZE, homography=None) -> np.ndarray:
    """The "calibrate first" frame only (see :func:`render_frames`)."""
    return _Canvas(guide, size, homography).calibrate()


def fit_homography(extent_mm, size: tuple[int, int], top: float = 0.0, margin: float = FIT_MARGIN) -> np.ndarray:
    """The homography that fits ``extent_mm`` ``(u_min, v_min, u_max, v_max)`` into a screen of ``size``, below a
    band of ``top`` pixels, with a margin, centred, ``v`` up: a uniform scale, so shapes are right but not sizes."""
    u0, v0, u1, v1 = (float(v) for v in extent_mm)
    width, height = size
    pad = margin * min(width, height)
    span_u, span_v = max(u1 - u0, 1e-6), max(v1 - v0, 1e-6)
    scale = min((width - 2 * pad) / span_u, (height - top - 2 * pad) / span_v)
    cx, cy = width / 2 - 0.5, top + (height - top) / 2 - 0.5
    cu, cv = (u0 + u1) / 2, (v0 + v1) / 2
    return np.array([[scale, 0.0, cx - scale * cu], [0.0, -scale, cy + scale * cv], [0.0, 0.0, 1.0]])


def step_caption(part: PartDrawing, steps: int) -> str:
    """The first line of a step frame: ``"Step 3 of 7: place bottom_track (care: tight)"``."""
    verb = "place" if part.kind == PartKind.PLACED else "fix"
    care = f" (care: {part.care})" if part.care else ""
    return f"Step {part.step} of {steps}: {verb} {part.name}{care}"


def detail_caption(part: PartDrawing, view: str = "top") -> str:
    """The second line: where the part goes and its tolerances, then what the sheet cannot show (its height above
    the table, or depth in front of the board on a ``side`` view, and its tilt: :func:`off_plane_text`)."""
    text = f"{where_text(part)}, heading {part.heading_deg:.1f} deg"
    off = {s.name for s in part.settings if not s.in_plane}
    known = [t for t in part.tolerances if t.placement_delta is not None and t.parameter not in off]
    if known:
        text += ", tolerance " + ", ".join(f"{t.parameter.rsplit('.', 1)[-1]} +-{t.delta:.1f} {t.unit}" for t in known)
    elif part.kind == PartKind.PLACED:
        text += ", tolerance unknown"
    off_plane = off_plane_text(part, view)
    return f"{text}; {off_plane}" if off_plane else text


def apply_homography(homography: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Points ``(n, 2)`` mapped through ``homography`` (with the division)."""
    points = np.atleast_2d(np.asarray(points, dtype=float))
    mapped = np.column_stack([points, np.ones(len(points))]) @ homography.T
    return mapped[:, :2] / mapped[:, 2:3]


def _rings(geometry: BaseGeometry) -> list[np.ndarray]:
    """Every ring (exteriors and holes) of a polygonal geometry, as ``(n, 2)`` arrays."""
    rings = []
    for polygon in getattr(geometry, "geoms", [geometry]):
        if polygon.is_empty or polygon.geom_type != "Polygon":
            continue
        rings.append(np.asarray(polygon.exterior.coords)[:, :2])
        rings.extend(np.asarray(hole.coords)[:, :2] for hole in polygon.interiors)
    return rings


def tolerance_box(part: PartDrawing, u_axis, v_axis) -> BaseGeometry | None:
    """The region the part's outline may cover within its position tolerances along the plane's axes (the sheets'
    :func:`projector.drawing.tolerance_zone`, so the projector and the paper show the same zone); None when it has
    no position tolerance on the plane."""
    plane = GuidePlane("", np.zeros(3), np.asarray(u_axis, float), np.asarray(v_axis, float),
                       np.cross(u_axis, v_axis))
    du, dv, _ = placement_deltas(part, plane)
    return tolerance_zone(part.outline, du, dv)


class _Canvas:
    """One guide drawn through one homography at one size."""

    def __init__(self, guide: Guide, size, homography) -> None:
        if (not isinstance(size, (tuple, list)) or len(size) != 2
                or not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v >= 64 for v in size)):
            raise ProjectorError(f"size: expected (width, height) in whole pixels >= 64, got {size!r}")
        self.guide = guide
        self.size = (int(size[0]), int(size[1]))
        width, height = self.size
        self.font = max(0.45, height / 1100)  # Hershey simplex: about 22 px tall at 1
        self.line = int(round(32 * self.font))
        self.thick = max(1, int(round(self.font * 2)))
        self.true_scale = homography is not None
        if homography is None:
            self.homography = fit_homography(guide.extent_mm, self.size, top=3.3 * self.line)
        else:
            self.homography = _checked_homography(homography, guide.extent_mm)

    # -- frames --

    def step(self, k: int, reference_tags: bool) -> np.ndarray:
        image = self._blank()
        if reference_tags:
            for tag in self.guide.reference_tags:
                self._tag(image, tag)
        for part in self.guide.parts[:k - 1]:
            static = part.kind == PartKind.STATIC
            self._fill(image, part.outline, STATIC_FILL if static else PLACED_FILL, 1.0)
            self._edges(image, _rings(part.outline), STATIC_EDGE if static else PLACED_EDGE, 1)
            self._text(image, str(part.step), self._px(part.center_mm)[0], PLACED_EDGE, 0.8, centre=True)
        part = self.guide.parts[k - 1]
        for jig in self.guide.jigs:  # the current part's jig first: it is laid before the part
            if jig.part == part.name:
                self._edges(image, _rings(jig.footprint), JIG_EDGE, self.thick)
                corner = self._px(np.asarray(jig.footprint.exterior.coords)).min(axis=0)
                self._text(image, f"jig {jig.id}", corner - np.array([0.0, 0.3 * self.line]), JIG_EDGE, 0.7)
        self._current(image, part)
        self._caption(image, [(step_caption(part, len(self.guide.parts)), WHITE),
                              (detail_caption(part, self.guide.view), WHITE)])
        return image

    def calibrate(self) -> np.ndarray:
        image = self._blank()
        self._grid(image)
        for tag in self.guide.reference_tags:
            self._tag(image, tag)
            self._tag_label(image, tag)
        ids = ", ".join(str(t.id) for t in self.guide.reference_tags)
        self._caption(image, [("CALIBRATE FIRST: the camera maps the projector to the guide plane from these tags",
                               WHITE), (f"reference tags {ids} (tag36h11) on a grid of {self._spacing():g} mm",
                                        WHITE)])
        return image

    # -- the parts of a frame --

    def _current(self, image: np.ndarray, part: PartDrawing) -> None:
        colour = CARE_COLOURS.get(part.care, CARE_COLOURS[None])
        box = tolerance_box(part, self.guide.plane.u_axis, self.guide.plane.v_axis)
        if box is not None:
            self._edges(image, _rings(box), colour, self.thick)
        self._fill(image, part.outline, CURRENT_FILL, 0.55)
        self._edges(image, _rings(part.outline), CURRENT_EDGE, self.thick + 1)
        center = np.asarray(part.center_mm, dtype=float)
        outline = np.vstack([center, *_rings(part.outline)])  # an empty outline still has its centre
        reach = max(10.0, float(np.max(np.linalg.norm(outline - center, axis=1))))
        heading = np.radians(part.heading_deg)
        _, _, delta = placement_deltas(part, self.guide.plane)
        if delta is not None:  # arcs the part's two ends may swing over, at its reach, with end ticks
            for side in (0.0, 180.0):
                arc = arc_points(center, 1.15 * reach, part.heading_deg + side, delta, 49)
                self._edges(image, [arc], colour, self.thick, closed=False)
                for end in np.radians(part.heading_deg + side + np.array([-delta, delta])):
                    direction = np.array([np.cos(end), np.sin(end)])
                    self._edges(image, [center + np.outer([1.05, 1.25], direction) * reach], colour, self.thick,
                                closed=False)
        tip = center + 0.9 * reach * np.array([np.cos(heading), np.sin(heading)])
        start, end = self._px(np.vstack([center, tip]))
        cv2 = _cv2()
        cv2.arrowedLine(image, _point(start), _point(end), ARROW, self.thick, cv2.LINE_AA, SHIFT, tipLength=0.2)
        for tagged in part.tag_views():
            half = tagged.tag_size_mm / 2
            square = np.array([[-half, -half], [half, -half], [half, half], [-half, half]])
            turn = np.radians(tagged.tag_heading_deg)
            c, s = np.cos(turn), np.sin(turn)
            square = square @ np.array([[c, s], [-s, c]]) + np.asarray(tagged.tag_center_mm, dtype=float)
            self._edges(image, [square], WHITE, self.thick)
            corner = self._px(square).max(axis=0)
            self._text(image, f"tag {tagged.tag_id}", corner, WHITE, 0.7)
        outline_px = self._px(outline)
        label = np.array([outline_px[:, 0].mean(), outline_px[:, 1].min() - 0.9 * self.line])
        self._text(image, f"{part.step}. {part.name}", label, WHITE, 1.0, centre=True)

    def _grid(self, image: np.ndarray) -> None:
        """Grid lines every :meth:`_spacing` mm over the guide's extent (every fifth brighter, labelled), and the
        extent's outline."""
        spacing = self._spacing()
        u0, v0, u1, v1 = self.guide.extent_mm
        us = spacing * np.arange(np.ceil(u0 / spacing), np.floor(u1 / spacing) + 1)
        vs = spacing * np.arange(np.ceil(v0 / spacing), np.floor(v1 / spacing) + 1)
        lines = [(np.array([[u, v0], [u, v1]]), u, "u") for u in us] + \
            [(np.array([[u0, v], [u1, v]]), v, "v") for v in vs]
        for line, value, axis in lines:
            major = round(value / spacing) % 5 == 0
            self._edges(image, [line], GRID_MAJOR if major else GRID, 1, closed=False)
            if major:  # labelled where the line enters the extent at its lower-left
                where = self._px(line[0])[0] + np.array([4, -6])
                self._text(image, f"{axis}={value:g}", where, GRID_MAJOR, 0.55)
        self._edges(image, [np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]])], GRID_MAJOR, 1)

    def _spacing(self) -> float:
        """A grid spacing (mm) giving 8 to 25 lines across the guide's longer side."""
        u0, v0, u1, v1 = self.guide.extent_mm
        span = max(u1 - u0, v1 - v0, 1.0)
        return next((s for s in (5, 10, 20, 25, 50, 100, 200, 250, 500, 1000) if span / s <= 25), 2000)

    def _tag(self, image: np.ndarray, tag: ReferenceTag) -> None:
        """A reference tag warped onto the frame, with one more white cell around it (light around the tag's own
        white border, so that the detector sees its black square on white whatever is drawn beside it)."""
        cv2 = _cv2()
        cell = tag.size_mm / 8  # the size is the black square's edge: 8 of the tag's 10 cells
        corners_px = self._px(np.asarray(tag.center_mm) + 6 * cell * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]))
        pixels_per_cell = int(np.clip(np.ceil(2 * np.ptp(corners_px, axis=0).max() / 12), 4, 64))
        source = np.pad(tag_image(tag.id, pixels_per_cell), pixels_per_cell, constant_values=255)
        step = cell / pixels_per_cell
        cu, cv = tag.center_mm
        half = (TAG_CELLS + 2) / 2 * cell
        # source pixel (x, y), centre at (x, y), to guide mm: row 0 is the tag's top (largest v)
        from_source = np.array([[step, 0, cu - half + 0.5 * step], [0, -step, cv + half - 0.5 * step], [0, 0, 1]])
        x0, y0 = np.maximum(np.floor(corners_px.min(axis=0)) - 2, 0).astype(int)
        x1, y1 = np.minimum(np.ceil(corners_px.max(axis=0)) + 3, self.size).astype(int)
        if x1 <= x0 or y1 <= y0:
            return
        shift = np.array([[1, 0, -x0], [0, 1, -y0], [0, 0, 1]], dtype=float)
        matrix = shift @ self.homography @ from_source
        box = (int(x1 - x0), int(y1 - y0))
        warped = cv2.warpPerspective(source, matrix, box, flags=cv2.INTER_LINEAR, borderValue=0)
        alpha = cv2.warpPerspective(np.full_like(source, 255), matrix, box, flags=cv2.INTER_LINEAR,
                                    borderValue=0)[:, :, None] / 255.0
        region = image[y0:y1, x0:x1]
        region[:] = np.round(region * (1 - alpha) + warped[:, :, None] * alpha).astype(np.uint8)

    def _tag_label(self, image: np.ndarray, tag: ReferenceTag) -> None:
        """The tag's id beside it, on the side towards the guide's middle (the screen's edge may be close)."""
        u0, v0, u1, v1 = self.guide.extent_mm
        centre, middle = self._px(np.array([tag.center_mm, [(u0 + u1) / 2, (v0 + v1) / 2]]))
        corners = self._px(np.asarray(tag.center_mm) + 0.75 * tag.size_mm * np.array([[-1, -1], [1, -1], [1, 1],
                                                                                       [-1, 1]]))
        towards = (middle - centre) / max(float(np.linalg.norm(middle - centre)), 1e-9)
        reach = float(np.max(np.abs((corners - centre) @ towards))) + 0.8 * self.line
        self._text(image, str(tag.id), centre + reach * towards, WHITE, 0.7, centre=True)

    def _caption_lines(self, lines: list[tuple[str, tuple]], room: float | None = None) -> list[tuple[str, tuple]]:
        """The caption's lines as drawn: a frame not at true scale says so on a line of its own, and a line wider
        than ``room`` pixels (default the frame's width) goes on over the next lines, broken between words."""
        lines = list(lines) if self.true_scale else [*lines, (NOT_TRUE, WARNING)]
        cv2 = _cv2()
        room = (self.size[0] if room is None else room) - self.line
        drawn = []
        for text, colour in lines:
            row = ""
            for word in _ascii(text).split(" "):
                wider = f"{row} {word}" if row else word
                if row and cv2.getTextSize(wider, cv2.FONT_HERSHEY_SIMPLEX, self.font, self.thick)[0][0] > room:
                    drawn.append((row, colour))
                    row = "  " + word  # a line going on is indented
                else:
                    row = wider
            drawn.append((row, colour))
        return drawn

    def _caption_box(self, lines: list[tuple[str, tuple]], bottom: bool = False, left: float = 0,
                     room: float | None = None) -> tuple[int, int, int, int]:
        """The pixels ``(x0, y0, x1, y1)`` the caption's dark band covers: at the top of the frame (``bottom``: at
        its foot), from ``left``, its lines broken to ``room`` pixels (default the frame's width); what else is
        drawn keeps off it."""
        lines = self._caption_lines(lines, room)
        if not lines:
            return 0, 0, 0, 0
        cv2 = _cv2()
        height = min(int(self.line * (len(lines) + 0.4)), self.size[1])
        width = max(cv2.getTextSize(_ascii(t), cv2.FONT_HERSHEY_SIMPLEX, self.font, self.thick)[0][0]
                    for t, _ in lines) + self.line
        top = self.size[1] - height if bottom else 0
        left = int(left)
        return left, top, min(left + width, self.size[0]), top + height

    def _caption(self, image: np.ndarray, lines: list[tuple[str, tuple]], bottom: bool = False, left: float = 0,
                 room: float | None = None) -> None:
        x0, top, x1, end = self._caption_box(lines, bottom, left, room)
        lines = self._caption_lines(lines, room)
        image[top:end, x0:x1] //= 4  # a dark band under the words, over what may lie there
        for row, (text, colour) in enumerate(lines):
            self._text(image, text, np.array([x0 + self.line / 2, top + self.line * (row + 1)]), colour, 1.0)

    # -- drawing primitives (pixel space) --

    def _blank(self) -> np.ndarray:
        return np.zeros((self.size[1], self.size[0], 3), dtype=np.uint8)

    def _px(self, points_mm) -> np.ndarray:
        return apply_homography(self.homography, points_mm)

    def _fill(self, image: np.ndarray, outline: BaseGeometry, colour, alpha: float) -> None:
        """Fill ``outline`` (holes stay empty), blended over the image with ``alpha``, within its bounding box."""
        cv2 = _cv2()
        rings = [self._px(ring) for ring in _rings(outline)]
        if not rings:
            return
        stacked = np.vstack(rings)
        x0, y0 = np.maximum(np.floor(stacked.min(axis=0)) - 1, 0).astype(int)
        x1, y1 = np.minimum(np.ceil(stacked.max(axis=0)) + 2, self.size).astype(int)
        if x1 <= x0 or y1 <= y0:
            return
        mask = np.zeros((y1 - y0, x1 - x0), dtype=np.uint8)
        cv2.fillPoly(mask, [_fixed(ring - [x0, y0]) for ring in rings], 255, cv2.LINE_AA, SHIFT)
        weight = (mask[:, :, None] / 255.0) * alpha
        region = image[y0:y1, x0:x1]
        region[:] = np.round(region * (1 - weight) + np.asarray(colour) * weight).astype(np.uint8)

    def _edges(self, image: np.ndarray, rings_mm: list[np.ndarray], colour, thickness: int,
               closed: bool = True) -> None:
        cv2 = _cv2()
        cv2.polylines(image, [_fixed(self._px(ring)) for ring in rings_mm], closed, colour, thickness, cv2.LINE_AA,
                      SHIFT)

    def _text(self, image: np.ndarray, text: str, where: np.ndarray, colour, scale: float,
              centre: bool = False) -> None:
        cv2 = _cv2()
        text = _ascii(text)
        font = self.font * scale
        thickness = max(1, int(round(self.thick * scale)))
        (width, height), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, font, thickness)
        x, y = (float(where[0]) - width / 2, float(where[1]) + height / 2) if centre else (where[0], where[1])
        cv2.putText(image, text, (int(round(x)), int(round(y))), cv2.FONT_HERSHEY_SIMPLEX, font, colour, thickness,
                    cv2.LINE_AA)


def _checked_homography(homography, extent_mm) -> np.ndarray:
    """``homography`` as a float 3 x 3 with the guide's extent in front of the projector (w > 0), or one line."""
    matrix = np.asarray(homography, dtype=float) if not isinstance(homography, str) else np.zeros(0)
    if matrix.shape != (3, 3) or not np.isfinite(matrix).all() or abs(np.linalg.det(matrix)) < 1e-12:
        raise ProjectorError(f"homography: expected an invertible 3 x 3 matrix (projector pixels from guide mm), "
                             f"got {np.shape(homography) if not isinstance(homography, str) else repr(homography)}")
    u0, v0, u1, v1 = extent_mm
    corners = np.array([[u0, v0, 1], [u1, v0, 1], [u1, v1, 1], [u0, v1, 1]], dtype=float)
    w = corners @ matrix[2]
    if not (np.all(w > 0) or np.all(w < 0)):
        raise ProjectorError("homography: part of the guide's extent maps behind the projector (its w changes sign)")
    return matrix if w[0] > 0 else -matrix


def _fixed(points: np.ndarray) -> np.ndarray:
    """Pixel coordinates as OpenCV's fixed-point integers (``SHIFT`` fractional bits)."""
    return np.round(np.asarray(points) * (1 << SHIFT)).astype(np.int32)


def _point(point: np.ndarray) -> tuple[int, int]:
    """One fixed-point pixel as OpenCV's ``(x, y)`` tuple."""
    x, y = _fixed(point)
    return int(x), int(y)


def _ascii(text: str) -> str:
    """OpenCV's Hershey fonts draw ASCII only."""
    return text.encode("ascii", "replace").decode("ascii")


def _cv2():
    import cv2

    return cv2
