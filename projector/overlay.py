"""The as-built check drawn over the guide: per misplaced part an arrow from where it is to where it must go and a
ring at the target, a label per checked part and a legend (pure: no device).

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

Words keep off the tags: the camera must still find the reference tags and the parts' own tags after a projected
check, and a maker must still see them in the camera's picture. Each label is tried at places around its part,
nearest first (:func:`check_layout`), and takes the first that stays inside the frame, off every tag square, the
caption, the legend and the labels placed before it, preferring places that cover no part; a label that had to move
away gets a leader line to its part. The legend (the four colours) takes the frame's corner that covers the fewest
parts.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np
from shapely import affinity
from shapely.geometry import LineString, Point, Polygon, box
from shapely.geometry.base import BaseGeometry
from shapely.ops import nearest_points, unary_union

from projector.drawing import must_move
from projector.frames import DEFAULT_SIZE, WHITE, _ascii, _Canvas, _cv2, _point, _rings
from projector.guide import Guide

__all__ = ["CAMERA_COLOURS", "LEGEND", "PROJECTOR_COLOURS", "CheckLayout", "Label", "check_layout", "draw_check",
           "misplaced", "render_check"]

#: Colours (RGB) on a projector (light on black) and over a camera frame (dark on a light table or sheet); ``text``
#: is the legend's words.
PROJECTOR_COLOURS = {"move": (255, 150, 30), "in_place": (70, 235, 70), "missing": (150, 150, 150),
                     "target": (255, 255, 255), "text": WHITE}
CAMERA_COLOURS = {"move": (235, 80, 0), "in_place": (0, 150, 40), "missing": (110, 110, 110), "target": (20, 80, 230),
                  "text": (30, 30, 30)}
#: The legend's rows: the colour's key, its words, whether its swatch is dashed (as a part not seen is drawn).
LEGEND = (("move", "where it stands", False), ("target", "where it must go", False),
          ("in_place", "in place", False), ("missing", "not seen", True))
#: The smallest target ring (mm).
RING_MM = 3.0
#: How far a label may stand from its part, in text lines beyond a small gap, tried nearest first.
LABEL_REACH = (0.0, 0.75, 1.5, 2.5, 4.0, 6.0, 9.0, 13.0)
#: Places up to this reach (lines) are first tried only where the label covers no part; then any reach, parts or not.
CLEAR_REACH = 4.0
#: A label further than this (lines) from its part gets a leader line to it.
LEADER_LINES = 0.6
#: A part's tag is a black square of ``tag_size_mm`` in a white border of one cell: 10 cells of the 8 across.
TAG_BORDER = 10 / 8
#: The text scale of the labels (of the frame's font), and of the legend.
LABEL_SCALE, MISSING_SCALE, LEGEND_SCALE = 0.8, 0.7, 0.7

Box = tuple[float, float, float, float]


@dataclass(frozen=True)
class Label:
    """A label as drawn: its words, colour, box ``(x0, y0, x1, y1)`` in pixels (y down), and its leader line's two
    ends (None: it stands beside its part)."""

    text: str
    colour: tuple[int, int, int]
    box: Box
    leader: tuple[tuple[float, float], tuple[float, float]] | None = None


@dataclass(frozen=True)
class CheckLayout:
    """Where a check drawing puts its words: the labels, the legend's box, the caption's band, and the tag squares
    (the reference tags, and each part's tag where it stands; ``(4, 2)`` pixel corners with their white border)
    that every word keeps off."""

    labels: tuple[Label, ...]
    legend: Box
    caption: Box
    tags: tuple[np.ndarray, ...]
    #: the width the caption's lines are broken to (None: the frame's)
    caption_room: float | None = None


def misplaced(check) -> bool:
    """Whether the check says the part must move (:func:`projector.drawing.must_move`: see the module notes)."""
    if not check.found or check.error is None:
        return False
    return must_move(check.error, check.within_tolerance)


def render_check(guide: Guide, checks: Sequence, size: tuple[int, int] = DEFAULT_SIZE, homography=None,
                 caption: Sequence[str] = ()) -> np.ndarray:
    """The projector frame after a check (``H x W x 3`` RGB uint8), with ``caption`` lines at its top."""
    canvas = _CheckCanvas(guide, size, homography)
    image = canvas._blank()
    for part in guide.parts:  # the layout, dim, for orientation
        canvas._edges(image, _rings(part.outline), (70, 70, 70), 1)
    lines = _caption(checks, caption)
    marks = canvas.marks(checks)
    canvas.draw(image, marks, canvas.lay_out(marks, lines))
    canvas._caption(image, lines)
    return image


def draw_check(image: np.ndarray, guide: Guide, checks: Sequence,
               project: Callable[[np.ndarray, float], np.ndarray], caption: Sequence[str] = ()) -> np.ndarray:
    """The check drawn over a camera frame (a copy, RGB): ``project(points_mm (n, 2), height_mm)`` gives their
    pixels (OpenCV's convention, pixel centres at integers). Outlines are drawn on the plane (h = 0: where each part
    stands on the sheet), as the projector draws them."""
    canvas = _camera_canvas(guide, image, project)
    out = np.array(image, dtype=np.uint8, copy=True)
    if out.ndim == 2:
        out = np.repeat(out[:, :, None], 3, axis=2)
    lines = [(line, WHITE) for line in caption]
    marks = canvas.marks(checks)
    layout = canvas.lay_out(marks, lines)
    canvas.draw(out, marks, layout)
    if lines:
        canvas._caption(out, lines, bottom=layout.caption[1] > 0, left=layout.caption[0], room=layout.caption_room)
    return out


def check_layout(guide: Guide, checks: Sequence, size: tuple[int, int] = DEFAULT_SIZE, homography=None, *,
                 project: Callable[[np.ndarray, float], np.ndarray] | None = None,
                 caption: Sequence[str] = ()) -> CheckLayout:
    """Where :func:`render_check` (or, given ``project``, :func:`draw_check` over a frame of ``size``) puts its
    labels and legend, and the tag squares they keep off."""
    if project is None:
        canvas = _CheckCanvas(guide, size, homography)
        lines = _caption(checks, caption)
    else:
        canvas = _camera_canvas(guide, np.zeros((size[1], size[0], 3), np.uint8), project)
        lines = [(line, WHITE) for line in caption]
    return canvas.lay_out(canvas.marks(checks), lines)


def _caption(checks: Sequence, caption: Sequence[str]) -> list[tuple[str, tuple]]:
    lines = list(caption) or [f"Check: {sum(misplaced(c) for c in checks)} part(s) to move"]
    return [(line, WHITE) for line in lines]


def _camera_canvas(guide: Guide, image: np.ndarray, project) -> _CheckCanvas:
    canvas = _CheckCanvas(guide, (int(image.shape[1]), int(image.shape[0])), None, project=project,
                          colours=CAMERA_COLOURS)
    canvas.true_scale = True  # the camera's frame: no projector scale to warn about
    return canvas


def _target(part, body: int | None) -> tuple:
    """Where a check's part (or its body ``body``: a run's domino) must be: its outline and origin on the plane."""
    if body is None:
        return part.outline, np.asarray(part.center_mm, dtype=float)
    tag = next(b for b in part.body_tags if b.body == body)
    here = Point(tag.center_mm)
    pieces = list(getattr(part.outline, "geoms", [part.outline]))  # the run's pieces: the body's is nearest its origin
    return min(pieces, key=here.distance), np.asarray(tag.center_mm, dtype=float)


@dataclass
class _Mark:
    """One checked part as drawn: its state (``move``, ``in_place`` or ``missing``), where it must go (outline and
    origin, mm), where it stands (misplaced parts), its target ring (mm) and its label's words."""

    check: object
    part: object
    state: str
    target: BaseGeometry
    centre: np.ndarray
    placed: BaseGeometry | None
    ring: np.ndarray | None
    text: str


class _CheckCanvas(_Canvas):
    """A frame canvas whose points go through the homography, or through a camera projection at a height."""

    def __init__(self, guide: Guide, size, homography, project=None, colours=None) -> None:
        super().__init__(guide, size, homography)
        self.project = project
        self.colours = colours or PROJECTOR_COLOURS

    def _px(self, points_mm) -> np.ndarray:
        return self._px_at(points_mm, 0.0)

    def _px_at(self, points_mm, height_mm: float) -> np.ndarray:
        """Pixels of plane points at a height above the plane (a camera sees a raised tag off its footprint; the
        projector's homography draws on the plane)."""
        if self.project is None:
            return super()._px(points_mm)
        return np.asarray(self.project(np.atleast_2d(np.asarray(points_mm, dtype=float)), float(height_mm)),
                          dtype=float).reshape(-1, 2)

    # -- what is drawn --

    def marks(self, checks: Sequence) -> list[_Mark]:
        """The checked parts of the guide (others are left out), misplaced ones first: they get the nearest places
        for their labels."""
        parts = {p.name: p for p in self.guide.parts}
        marks = []
        for check in checks:
            part = parts.get(getattr(check, "owner", check.name))
            if part is None:
                continue
            outline, centre = _target(part, getattr(check, "body", None))
            if not check.found:
                marks.append(_Mark(check, part, "missing", outline, centre, None, None,
                                   f"{check.name}: tag {check.tag_id} not seen"))
                continue
            du, dv, distance, dheading = check.error
            if not misplaced(check):
                marks.append(_Mark(check, part, "in_place", outline, centre, None, None, f"{check.name} ok"))
                continue
            placed = affinity.translate(affinity.rotate(outline, dheading, origin=tuple(centre)), du, dv)
            tolerance = [t for t in check.tolerance[:2] if t is not None]
            ring = max(RING_MM, min(tolerance) if tolerance else RING_MM)
            circle = centre + ring * np.column_stack([np.cos(np.linspace(0, 2 * np.pi, 49)),
                                                      np.sin(np.linspace(0, 2 * np.pi, 49))])
            words = f"{check.name}: {distance:.1f} mm" + (f", {abs(dheading):.1f} deg" if abs(dheading) >= 0.1 else "")
            marks.append(_Mark(check, part, "move", outline, centre, placed, circle, words))
        order = {"move": 0, "missing": 1, "in_place": 2}
        return sorted(marks, key=lambda mark: order[mark.state])

    def draw(self, image: np.ndarray, marks: Sequence[_Mark], layout: CheckLayout) -> None:
        """The outlines, arrows and rings of ``marks``, then the words where ``layout`` put them."""
        cv2 = _cv2()
        colour = self.colours
        for mark in marks:
            if mark.state == "missing":
                self._dashed(image, _rings(mark.target), colour["missing"])
            elif mark.state == "in_place":
                self._edges(image, _rings(mark.target), colour["in_place"], self.thick + 1)
            else:
                self._edges(image, _rings(mark.target), colour["target"], self.thick)
                self._edges(image, _rings(mark.placed), colour["move"], self.thick + 1)
                self._edges(image, [mark.ring], colour["target"], self.thick + 1)
                start, end = self._arrow(mark)
                if np.linalg.norm(end - start) >= 4:
                    cv2.arrowedLine(image, _point(start), _point(end), colour["move"], self.thick + 1, cv2.LINE_AA, 4,
                                    tipLength=min(0.4, 12.0 / max(float(np.linalg.norm(end - start)), 1.0)))
        for label in layout.labels:
            if label.leader is not None:
                cv2.line(image, _point(np.asarray(label.leader[0])), _point(np.asarray(label.leader[1])),
                         label.colour, max(1, self.thick - 1), cv2.LINE_AA, 4)
        for label, mark in zip(layout.labels, marks):
            self._backing(image, label.box)
            scale = MISSING_SCALE if mark.state != "move" else LABEL_SCALE
            x0, _, _, y1 = label.box
            pad, baseline = self._text_metrics(label.text, scale)[2:]
            self._text(image, label.text, np.array([x0 + pad, y1 - pad - baseline]), label.colour, scale)
        self._legend(image, layout.legend)

    def _arrow(self, mark: _Mark) -> np.ndarray:
        return self._px(np.vstack([np.asarray(mark.check.measured_center_mm, dtype=float), mark.centre]))

    # -- where the words go --

    def lay_out(self, marks: Sequence[_Mark], caption: list[tuple[str, tuple]]) -> CheckLayout:
        """The legend in the corner covering the fewest parts, then each mark's label at the nearest free place."""
        tags = tuple(self._tag_squares(marks))
        margin = max(2.0, 0.15 * self.line)
        hard = [Polygon(square).buffer(margin) for square in tags]
        soft = unary_union(self._part_areas(marks))
        caption_box, room = self._caption_place(caption, unary_union(hard), soft)
        if caption_box[2] > 0:
            hard.append(box(*caption_box).buffer(margin))
        legend = self._place_legend(unary_union(hard), soft)
        hard.append(box(*legend).buffer(margin))
        taken = unary_union(hard)
        labels = []
        for mark in marks:
            label = self._place_label(mark, taken, soft)
            labels.append(label)
            taken = taken.union(box(*label.box).buffer(margin))
        return CheckLayout(tuple(labels), legend, caption_box, tags, room)

    def _caption_place(self, caption: list[tuple[str, tuple]], hard: BaseGeometry,
                       soft: BaseGeometry) -> tuple[Box, float | None]:
        """The caption's band and the width its lines are broken to: at the top of the frame; over a camera frame
        (where the reference tags may lie at the frame's edges) the first of the top, the foot, and the widest gap
        between the tags at the top or the foot that covers the fewest tags, then the fewest parts. A projector's
        fit leaves the top free for it."""
        top = self._caption_box(caption)
        if self.project is None or top[2] <= 0:
            return top, None
        width, height = self.size
        margin = max(4.0, 0.3 * self.line)
        places = [(False, 0.0, None), (True, 0.0, None)]
        for bottom in (False, True):
            edge = [b for b in (getattr(hard, "geoms", None) or [hard]) if not b.is_empty
                    and (b.bounds[3] > 0.7 * height if bottom else b.bounds[1] < 0.3 * height)]
            stops = sorted([(0.0, 0.0)] + [(b.bounds[0], b.bounds[2]) for b in edge] + [(width, width)])
            gaps, reach = [], 0.0
            for start, end in stops:
                if start - reach > 8 * self.line:
                    gaps.append((reach, start))
                reach = max(reach, end)
            if gaps:
                left, right = max(gaps, key=lambda gap: gap[1] - gap[0])
                places.append((bottom, left + margin, right - left - 2 * margin))

        def covered(place):
            drawn = box(*self._caption_box(caption, *place))
            return drawn.intersection(hard).area, drawn.intersection(soft).area

        bottom, left, room = min(places, key=covered)
        return self._caption_box(caption, bottom, left, room), room

    def _tag_squares(self, marks: Sequence[_Mark]) -> Iterator[np.ndarray]:
        """Pixel corners of every tag square: the reference tags, each checked part's tag where it stands (where it
        should be when not seen), and the tags of parts not checked where they should be."""
        for tag in self.guide.reference_tags:
            yield self._px_at(_square(tag.center_mm, TAG_BORDER * tag.size_mm, 0.0), 0.0)
        checked = set()
        for mark in marks:
            check = mark.check
            checked.add(mark.part.name)
            for view in mark.part.tag_views():
                if view.tag_id != check.tag_id:
                    continue
                centre, heading = np.asarray(view.tag_center_mm, dtype=float), view.tag_heading_deg
                if check.found and check.error is not None:
                    du, dv, _, dheading = check.error
                    turn = np.radians(dheading)
                    c, s = np.cos(turn), np.sin(turn)
                    centre = mark.centre + np.array([[c, -s], [s, c]]) @ (centre - mark.centre) + np.array([du, dv])
                    heading += dheading
                yield self._px_at(_square(centre, TAG_BORDER * view.tag_size_mm, heading), view.tag_height_mm)
        for part in self.guide.parts:
            if part.name in checked:
                continue
            for view in part.tag_views():
                yield self._px_at(_square(view.tag_center_mm, TAG_BORDER * view.tag_size_mm, view.tag_heading_deg),
                                  view.tag_height_mm)

    def _part_areas(self, marks: Sequence[_Mark]) -> list[BaseGeometry]:
        """What a label had better not cover: every part where it must go, where misplaced ones stand, their target
        rings and arrows (pixels)."""
        areas = [self._area(part.outline) for part in self.guide.parts]
        for mark in marks:
            if mark.state == "move":
                areas += [self._area(mark.placed), Polygon(self._px(mark.ring)).buffer(0)]
                areas.append(LineString(self._arrow(mark)).buffer(self.thick + 2))
        return [area for area in areas if not area.is_empty]

    def _area(self, outline: BaseGeometry) -> BaseGeometry:
        polygons = [Polygon(self._px(ring)).buffer(0) for ring in _rings(outline)]
        return unary_union([p for p in polygons if not p.is_empty]) if polygons else Polygon()

    def _place_label(self, mark: _Mark, taken: BaseGeometry, soft: BaseGeometry) -> Label:
        colour = self.colours[mark.state]
        scale = MISSING_SCALE if mark.state != "move" else LABEL_SCALE
        width, height, _, _ = self._text_metrics(mark.text, scale)
        anchor = self._area(mark.placed if mark.placed is not None else mark.target)
        if anchor.is_empty:
            anchor = Point(self._px(mark.centre)[0])
        candidates = list(self._candidates(anchor, (width, height)))
        frame = box(0, 0, *self.size)
        inside = [(reach, number, spot) for number, (reach, spot) in enumerate(candidates) if frame.contains(spot)]

        def nearest(spots):  # the nearest to the part (in quarter lines), then the first tried
            return min(spots, key=lambda s: (round(4 * s[2].distance(anchor) / self.line), s[1]), default=None)

        chosen = nearest([s for s in inside if s[0] <= CLEAR_REACH and not s[2].intersects(taken)
                          and not s[2].intersects(soft)])
        chosen = chosen or nearest([s for s in inside if not s[2].intersects(taken)])
        if chosen is not None:
            spot = chosen[2]
        else:  # nowhere free: the place covering the least, kept inside the frame
            kept = [_inside(spot, self.size) for _, spot in candidates]
            spot = min(kept, key=lambda s: (s.intersection(taken).area, s.intersection(soft).area))
        leader = None
        if spot.distance(anchor) > LEADER_LINES * self.line:
            start, end = nearest_points(spot, anchor)
            leader = ((start.x, start.y), (end.x, end.y))
        return Label(mark.text, colour, tuple(float(v) for v in spot.bounds), leader)

    def _candidates(self, anchor: BaseGeometry, size: tuple[float, float]) -> Iterator[tuple[float, BaseGeometry]]:
        """Places for a label of ``size`` around a part's pixel ``anchor`` (its outline), by reach: above, below,
        beside, at the corners of its bounds, above or below shifted half a label aside, and against its top,
        bottom, left and right points (a slanted part's bounds are far from most of it)."""
        x0, y0, x1, y1 = anchor.bounds
        width, height = size
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        hull = anchor.convex_hull
        points = np.asarray(hull.exterior.coords if hull.geom_type == "Polygon" else [(cx, cy)], dtype=float)
        top, bottom = points[np.argmin(points[:, 1])], points[np.argmax(points[:, 1])]
        left, right = points[np.argmin(points[:, 0])], points[np.argmax(points[:, 0])]
        for reach in LABEL_REACH:
            gap = (0.25 + reach) * self.line
            west, north, east, south = x0 - gap, y0 - gap, x1 + gap, y1 + gap
            for x, y in ((cx - width / 2, north - height), (cx - width / 2, south), (east, cy - height / 2),
                         (west - width, cy - height / 2), (east, north - height), (west - width, north - height),
                         (east, south), (west - width, south), (cx - 0.15 * width, north - height),
                         (cx - 0.85 * width, north - height), (cx - 0.15 * width, south),
                         (cx - 0.85 * width, south), (top[0] - width / 2, top[1] - gap - height),
                         (bottom[0] - width / 2, bottom[1] + gap), (left[0] - gap - width, left[1] - height / 2),
                         (right[0] + gap, right[1] - height / 2)):
                yield reach, box(x, y, x + width, y + height)

    def _text_metrics(self, text: str, scale: float) -> tuple[float, float, float, float]:
        """A label's box ``(width, height)`` in pixels with its padding, the padding and the text's baseline."""
        cv2 = _cv2()
        thickness = max(1, int(round(self.thick * scale)))
        (width, height), baseline = cv2.getTextSize(_ascii(text), cv2.FONT_HERSHEY_SIMPLEX, self.font * scale,
                                                    thickness)
        pad = max(2.0, 0.12 * self.line)
        return width + 2 * pad, height + baseline + 2 * pad, pad, float(baseline)

    # -- the legend --

    def _legend_size(self) -> tuple[float, float, float]:
        """The legend's ``(width, height)`` and the height of a row."""
        sizes = [self._text_metrics(words, LEGEND_SCALE) for _, words, _ in LEGEND]
        row = max(s[1] for s in sizes)
        swatch = 1.6 * self.line
        pad = 0.3 * self.line
        return pad + swatch + pad + max(s[0] for s in sizes) + pad, row * len(LEGEND) + 2 * pad, row

    def _place_legend(self, hard: BaseGeometry, soft: BaseGeometry) -> Box:
        """The legend's box: the first corner (then edge middle) covering no tag, caption or part, else the one
        covering the least."""
        width, height, _ = self._legend_size()
        screen_w, screen_h = self.size
        edge = max(4.0, 0.3 * self.line)
        top = edge
        spots = [(edge, screen_h - edge - height), (screen_w - edge - width, screen_h - edge - height),
                 (screen_w - edge - width, top), (edge, top), ((screen_w - width) / 2, screen_h - edge - height),
                 ((screen_w - width) / 2, top), (edge, (screen_h - height) / 2),
                 (screen_w - edge - width, (screen_h - height) / 2)]
        boxes = [_inside(box(x, y, x + width, y + height), self.size) for x, y in spots]
        best = min(boxes, key=lambda b: (b.intersection(hard).area, b.intersection(soft).area))
        return tuple(float(v) for v in best.bounds)

    def _legend(self, image: np.ndarray, where: Box) -> None:
        cv2 = _cv2()
        x0, y0, x1, y1 = where
        self._backing(image, where, strong=True)
        cv2.rectangle(image, _point(np.array([x0, y0])), _point(np.array([x1, y1])), self.colours["missing"], 1,
                      cv2.LINE_AA, 4)
        _, _, row = self._legend_size()
        pad = 0.3 * self.line
        swatch = 1.6 * self.line
        for number, (key, words, dashed) in enumerate(LEGEND):
            middle = y0 + pad + (number + 0.5) * row
            line = np.array([[x0 + pad, middle], [x0 + pad + swatch, middle]])
            if dashed:
                self._dashed_pixels(image, line, self.colours[key], thickness=self.thick + 1)
            else:
                cv2.line(image, _point(line[0]), _point(line[1]), self.colours[key], self.thick + 1, cv2.LINE_AA, 4)
            _, height, text_pad, baseline = self._text_metrics(words, LEGEND_SCALE)
            glyph = height - baseline - 2 * text_pad
            self._text(image, words, np.array([x0 + 2 * pad + swatch + text_pad, middle + glyph / 2]),
                       self.colours["text"], LEGEND_SCALE)

    def _backing(self, image: np.ndarray, where: Box, strong: bool = False) -> None:
        """Quiet the pixels under words: darker on a projector (light on black), lighter over a camera frame."""
        x0, y0, x1, y1 = (int(round(v)) for v in where)
        x0, y0 = max(x0, 0), max(y0, 0)
        x1, y1 = min(x1, self.size[0]), min(y1, self.size[1])
        if x1 <= x0 or y1 <= y0:
            return
        region = image[y0:y1, x0:x1]
        if self.colours is PROJECTOR_COLOURS:
            region //= 4
        else:
            keep = 0.15 if strong else 0.4
            region[:] = np.round(region * keep + 255 * (1 - keep)).astype(np.uint8)

    # -- primitives --

    def _dashed(self, image: np.ndarray, rings, colour, dash_px: float = 8.0) -> None:
        """Rings drawn as dashes of ``dash_px`` pixels (a part that was not seen: where it should be)."""
        for ring in rings:
            self._dashed_pixels(image, self._px(ring), colour, dash_px)

    def _dashed_pixels(self, image: np.ndarray, pixels: np.ndarray, colour, dash_px: float = 8.0,
                       thickness: int | None = None) -> None:
        cv2 = _cv2()
        for a, b in zip(pixels[:-1], pixels[1:]):
            pieces = max(1, int(np.linalg.norm(b - a) // dash_px))
            stops = a + np.linspace(0.0, 1.0, pieces + 1)[:, None] * (b - a)
            for start, end in zip(stops[:-1:2], stops[1::2]):
                cv2.line(image, _point(start), _point(end), colour, thickness or self.thick, cv2.LINE_AA, 4)


def _square(centre, side: float, heading_deg: float) -> np.ndarray:
    """The corners (4, 2) of a square of ``side`` mm about ``centre``, turned by ``heading_deg``."""
    half = side / 2
    corners = np.array([[-half, -half], [half, -half], [half, half], [-half, half]])
    turn = np.radians(heading_deg)
    c, s = np.cos(turn), np.sin(turn)
    return corners @ np.array([[c, s], [-s, c]]) + np.asarray(centre, dtype=float)


def _inside(spot: BaseGeometry, size: tuple[int, int]) -> BaseGeometry:
    """A box moved (not resized, unless larger than the frame) to lie inside a frame of ``size``."""
    x0, y0, x1, y1 = spot.bounds
    width, height = min(x1 - x0, size[0]), min(y1 - y0, size[1])
    x = min(max(x0, 0.0), size[0] - width)
    y = min(max(y0, 0.0), size[1] - height)
    return box(x, y, x + width, y + height)
