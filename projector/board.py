"""The side camera's reference board: a printed sheet standing upright behind the parts of a table guide.

A camera above the table sees positions and turns on the table; heights and tilts are square to it. A second camera
in front of the table, facing a vertical board behind the parts, sees them in the board's plane: a part's (or its
jig's) tag facing that camera is measured at its depth in front of the board exactly as a top tag is measured at its
height above the table (:mod:`calibration.measure`).

The board's plane (:class:`SideBoard`'s ``plane``, a :class:`~projector.guide.GuidePlane` of view ``"side"``):
``u`` is the table guide's ``u`` (so the board's millimetres along it are the guide's), ``v`` is the height above
the table, the normal points from the board towards the parts and the maker. The sheet stands on the table with its
lower edge on it (so its ``v`` is the height above the table), its face along the guide-plane line
``v = line_v_mm``, its centre mark at ``u = center_u_mm``. Its four tags take the ids under the table's reference
tags (:data:`BOARD_TAG_IDS`), so neither camera mistakes one board for the other.

**Where along u.** The side camera sees a board tag only where nothing stands between them. The guide assumes the
camera :data:`SIDE_CAMERA_MM` in front of the board facing the middle of the board and of the jig stands whose face
tags it reads (as the simulated camera aims itself), level with the board's middle (the lowest a side camera
stands) or raised :data:`SIDE_CAMERA_RISE_MM` over it (the station's own, looking down 20 deg). The centre is the
whole millimetre nearest the middle of the guide's extent, within that extent (the board stays behind the parts) and
within a sheet's width of every jig stand whose face tag the side camera reads (the heights are carried from the
board's plane to the tag: far off, a small error of the plane's tilt grows into millimetres), where both columns of
tags stand clear, as the camera sees them, of every part's and jig stand's footprint (:data:`CLEAR_MM` of room):
nothing in front of them, whatever its height. Where no such place is, the one (every :data:`HIDDEN_STEP_MM`) that
leaves the fewest board tags behind the parts themselves (their solids, a part on a stand carried down to the table
by its plate) from the raised camera, then from the level one, then with the fewest tags a part comes within
:data:`CLEAR_MM` of (raised, then level), the nearest to the middle of the best; :attr:`SideBoard.hidden` and
:attr:`SideBoard.hidden_raised` name what hides which tag, which the guide's words say.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from os import PathLike

import numpy as np
import shapely
from shapely.geometry import box

from common.words import listed
from projector.errors import ProjectorError
from projector.guide import REFERENCE_TAG_IDS, Guide, GuidePlane, ReferenceTag
from projector.pdf_marks import BOLD, FONT, INK, draw_scale_bar, draw_tag
from projector.tiling import PAPERS, PRINTABLE_MM

__all__ = ["BOARD_GAP_MM", "BOARD_TAG_IDS", "BOARD_TAG_MM", "CLEAR_MM", "SIDE_CAMERA_MM", "SideBoard", "side_board",
           "write_board_pdf"]

#: The board's reference tags: the four ids just under the table's (583-586), out of the jigs' range.
BOARD_TAG_IDS = tuple(range(REFERENCE_TAG_IDS[0] - 4, REFERENCE_TAG_IDS[0]))
#: The board tags' black squares (mm): as large as the table's, so that a camera 700 mm away finds the plane to a
#: tenth of a millimetre from four tags on one sheet.
BOARD_TAG_MM = 40.0
#: How far behind the far edge of everything the guide draws the board's face stands (mm): room for a hand.
BOARD_GAP_MM = 30.0
#: How far in front of the board the guide assumes the side camera (mm): where its figures were measured
#: (docs/results/2026-12-05-side-camera.md).
SIDE_CAMERA_MM = 700.0
#: Room between a board tag's column (its white border) and a footprint in front of it, as the camera sees them
#: (mm): the camera set up a little off the board's centre, a part set a little off its outline.
CLEAR_MM = 10.0
#: The step of the places tried when none is clear (mm).
HIDDEN_STEP_MM = 5.0
#: How far above the board's middle the station's side camera stands by default (mm): 700 mm away looking down 20
#: degrees (station.services.check_cameras.SIDE_CAMERA), 700 tan 20 deg.
SIDE_CAMERA_RISE_MM = 255.0


@dataclass(frozen=True)
class SideBoard:
    """Where the reference board stands and what is printed on it (module notes).

    Attributes
    ----------
    plane : GuidePlane
        The board's plane in the scene (view ``"side"``).
    line_v_mm : float
        The guide-plane line ``v = line_v_mm`` its face stands on.
    center_u_mm : float
        Where its centre mark stands along ``u``.
    sheet_mm : tuple of float
        The sheet's width and height (landscape).
    paper : str
    reference_tags : tuple of ReferenceTag
        The four tags, centres in the board's (u, height) mm.
    hidden : tuple of (int, tuple of str)
        Where no place leaves every tag clear (module notes): each board tag the parts hide from a side camera level
        with the board's middle, and the parts that do; empty when none.
    hidden_raised : tuple of (int, tuple of str)
        The same from the side camera raised :data:`SIDE_CAMERA_RISE_MM` (the station's own, looking down 20 deg).
    """

    plane: GuidePlane
    line_v_mm: float
    center_u_mm: float
    sheet_mm: tuple[float, float]
    paper: str
    reference_tags: tuple[ReferenceTag, ...]
    hidden: tuple[tuple[int, tuple[str, ...]], ...] = ()
    hidden_raised: tuple[tuple[int, tuple[str, ...]], ...] = ()

    @property
    def extent_mm(self) -> tuple[float, float, float, float]:
        """``(u0, 0, u1, height)`` of the sheet on the board's plane."""
        w, h = self.sheet_mm
        return (self.center_u_mm - w / 2.0, 0.0, self.center_u_mm + w / 2.0, h)

    def words(self) -> str:
        """How to stand it, in the maker's words (and, where the parts hide some of its tags, which and what to do)."""
        words = (f"stand the board sheet upright behind the parts, its lower edge on the table, its printed face "
                 f"towards you along the line v = {self.line_v_mm:.0f} mm of the guide, its centre mark at "
                 f"u = {self.center_u_mm:.0f} mm; the side camera faces it from in front of the table")
        if not self.hidden and not self.hidden_raised:
            return words
        seen = [f"seen level with the board's middle, {_hiding(self.hidden)}"] if self.hidden else []
        if self.hidden_raised:
            seen.append(f"even raised {SIDE_CAMERA_RISE_MM:.0f} mm (looking down 20 deg), {_hiding(self.hidden_raised)}"
                        ": the side camera finds the board's plane from three of its tags")
        else:
            seen.append(f"so raise the side camera to look over them ({SIDE_CAMERA_RISE_MM:.0f} mm over the board's "
                        "middle, looking down 20 deg, it sees every tag; it measures from any height)")
        return f"{words}; no place along the table leaves all its tags clear of the parts: {', '.join(seen)}"

    def manifest(self) -> dict:
        """The board in the guide's manifest (``side_board``)."""
        return {"view": "side", "line_v_mm": round(self.line_v_mm, 3), "center_u_mm": round(self.center_u_mm, 3),
                "paper": self.paper, "sheet_mm": [round(s, 3) for s in self.sheet_mm],
                "reference_tags": [{"id": t.id, "center_mm": [round(c, 3) for c in t.center_mm],
                                    "size_mm": round(t.size_mm, 3)} for t in self.reference_tags],
                "hidden_tags": {str(tag_id): list(names) for tag_id, names in self.hidden},
                "hidden_tags_raised": {str(tag_id): list(names) for tag_id, names in self.hidden_raised},
                "words": self.words()}


def side_board(guide: Guide, paper: str = "a4") -> SideBoard | None:
    """The reference board of a table guide (None for a board guide: its own plane is vertical already)."""
    if guide.view != "top":
        return None
    if paper not in PAPERS:
        raise ProjectorError(f"paper: expected one of {', '.join(PAPERS)}, got {paper!r}")
    short, long = PAPERS[paper]
    u0, _, u1, v1 = guide.extent_mm
    line_v = float(v1) + BOARD_GAP_MM
    half = BOARD_TAG_MM * 10.0 / 8.0 / 2.0  # the tag with its white border
    inset = PRINTABLE_MM + half  # inside the printable area
    reach = long / 2.0 - inset
    heights = (inset, short - inset)
    stands = [j for j in guide.jigs if j.kind == "stand"]
    footprints = [p.outline for p in guide.parts] + [j.footprint for j in stands]
    middle = round((float(u0) + float(u1)) / 2.0)
    read = [j.footprint.bounds for j in stands if j.face_tag_id is not None and not j.footprint.is_empty]

    def camera_u(centre: float) -> float:  # the middle of the board and the stands whose face tags it reads
        return (min([centre - long / 2.0, *(b[0] for b in read)])
                + max([centre + long / 2.0, *(b[2] for b in read)])) / 2.0

    # behind the parts, and within a sheet's width of every face tag it carries the heights of (further off, the
    # board's plane carried out to the tag turns a small error of its tilt into millimetres)
    low, high = float(u0), float(u1)
    if read:
        low, high = max(low, max(b[2] for b in read) - long), min(high, min(b[0] for b in read) + long)
        if low > high:
            low, high = float(u0), float(u1)

    def centres(step: float) -> list[float]:  # the places tried, nearest the middle first
        places = np.arange(math.ceil(low / step) * step, high + 1e-9, step)
        return sorted((float(c) for c in places), key=lambda c: (abs(c - middle), c)) or [float(middle)]

    centre_u = _clear_centre(centres(1.0), reach, half, footprints, line_v, camera_u)
    hidden: tuple = ()
    raised: tuple = ()
    if centre_u is None:
        carried = {j.part for j in stands}
        solids = [(p.name, np.asarray(solid, float), p.name in carried) for p in guide.parts for solid in p.solids_mm]
        centre_u, hidden, raised = _least_hidden(centres(HIDDEN_STEP_MM), reach, half, heights, solids, line_v,
                                                 short, camera_u)
    plane = guide.plane
    origin = plane.to_world(np.array([[0.0, line_v]]))[0]
    board_plane = GuidePlane("side", origin, np.asarray(plane.u_axis, float), np.asarray(plane.normal, float),
                             -np.asarray(plane.v_axis, float))
    corners = ((-1, heights[0]), (1, heights[0]), (1, heights[1]), (-1, heights[1]))
    tags = tuple(ReferenceTag(tag_id, (centre_u + su * reach, h), BOARD_TAG_MM)
                 for tag_id, (su, h) in zip(BOARD_TAG_IDS, corners))
    return SideBoard(board_plane, line_v, float(centre_u), (long, short), paper, tags, hidden, raised)


def _clear_centre(centres, reach: float, half: float, footprints, line_v: float, camera_u) -> float | None:
    """The first of ``centres`` where both columns of tags (at ``centre +- reach``, ``half`` wide each side) stand
    clear of every footprint as a camera at ``camera_u(centre)`` sees it (module notes); None when there is none."""
    corners = [np.asarray(g.exterior.coords, float) for f in footprints if not f.is_empty
               for g in getattr(f, "geoms", [f]) if hasattr(g, "exterior")]
    if not corners:
        return centres[0] if centres else None
    starts = np.cumsum([0] + [len(c) for c in corners[:-1]])
    points = np.concatenate(corners)
    scale = _magnified(points[:, 1], line_v)
    for centre in centres:
        eye = camera_u(centre)
        seen = eye + (points[:, 0] - eye) * scale
        low, high = np.minimum.reduceat(seen, starts) - CLEAR_MM, np.maximum.reduceat(seen, starts) + CLEAR_MM
        columns = [(centre + side * reach - half, centre + side * reach + half) for side in (-1, 1)]
        if not any(np.any((low < t1) & (t0 < high)) for t0, t1 in columns):
            return float(centre)
    return None


def _least_hidden(centres, reach: float, half: float, heights, solids, line_v: float, board_height: float,
                  camera_u) -> tuple[float, tuple, tuple]:
    """The one of ``centres`` that leaves the fewest board tags behind the parts' ``solids`` (``(name, points (u, v,
    h) mm, on a stand)``) from a camera at ``camera_u(centre)`` raised :data:`SIDE_CAMERA_RISE_MM` over the board's
    middle (the station's own), then from one level with it, then the fewest with a part within :data:`CLEAR_MM` of
    them seen from each in turn (a camera set up a little elsewhere, a part set a little higher), the first of the
    best; and which tags they hide there from each: ``(centre, level, raised)``, each ``((tag id, names), ...)``."""
    points, names, starts = [], [], [0]
    for name, solid, on_stand in solids:
        if on_stand:  # its stand's plate fills the space under it down to the table
            solid = np.vstack([solid, solid * [1.0, 1.0, 0.0]])
        points.append(solid)
        names.append(name)
        starts.append(starts[-1] + len(solid))
    if not names:
        return centres[0], (), ()
    points, starts = np.concatenate(points), starts[:-1]
    ends = [*starts[1:], len(points)]
    u = points[:, 0]
    scale = _magnified(points[:, 1], line_v)
    tags = list(zip(BOARD_TAG_IDS, (-1, 1, 1, -1), (heights[0], heights[0], heights[1], heights[1])))
    room = half + CLEAR_MM
    views = []
    for camera_h in (board_height / 2.0 + SIDE_CAMERA_RISE_MM, board_height / 2.0):
        seen_h = camera_h + (points[:, 2] - camera_h) * scale  # the same wherever along u the camera stands
        low_h, high_h = np.minimum.reduceat(seen_h, starts), np.maximum.reduceat(seen_h, starts)
        views.append((seen_h, {tag_id: (high_h >= h - room) & (low_h <= h + room) for tag_id, _, h in tags}))

    def hidden_from(centre: float, seen_u, low_u, high_u, seen_h, in_band) -> tuple[tuple, int]:
        hidden, near = [], 0
        for tag_id, side, h in tags:
            middle_u = centre + side * reach
            square = box(middle_u - half, h - half, middle_u + half, h + half)
            before, close = [], False
            for k in np.flatnonzero(in_band[tag_id] & (high_u >= middle_u - room) & (low_u <= middle_u + room)):
                hull = shapely.MultiPoint(np.column_stack([seen_u[starts[k]:ends[k]],
                                                           seen_h[starts[k]:ends[k]]])).convex_hull
                if names[k] not in before and hull.intersects(square):
                    before.append(names[k])
                close = close or hull.distance(square) < CLEAR_MM
            if before:
                hidden.append((tag_id, tuple(before)))
            near += close
        return tuple(hidden), near

    best = None
    for centre in centres:
        eye = camera_u(centre)
        seen_u = eye + (u - eye) * scale
        low_u, high_u = np.minimum.reduceat(seen_u, starts), np.maximum.reduceat(seen_u, starts)
        (raised, near_raised), (level, near) = (hidden_from(centre, seen_u, low_u, high_u, *view) for view in views)
        score = (len(raised), len(level), near_raised, near)
        if best is None or score < best[0]:
            best = (score, float(centre), level, raised)
            if score == (0, 0, 0, 0):
                break
    return best[1], best[2], best[3]


def _magnified(v, line_v: float):
    """How much larger than on the board a thing at ``v`` (mm, in front of the board's face at ``line_v``) looks
    from the side camera :data:`SIDE_CAMERA_MM` in front of the board: what it hides of the board, from the
    camera's place, is its outline scaled by this."""
    return SIDE_CAMERA_MM / np.maximum(SIDE_CAMERA_MM - (line_v - v), 1.0)


def _hiding(hidden) -> str:
    """``"`a` and `b` hide board tag 580"``: what hides which tags, in words."""
    hiders = list(dict.fromkeys(name for _, names in hidden for name in names))
    return f"{listed([f'`{n}`' for n in hiders])} hide{'s' if len(hiders) == 1 else ''} {_board_tags(hidden)}"


def _board_tags(hidden) -> str:
    """``"board tags 579 and 580"``: the tags of ``hidden`` (``((tag id, names), ...)``)."""
    return f"board tag{'s' if len(hidden) > 1 else ''} {listed([str(tag_id) for tag_id, _ in hidden])}"


def write_board_pdf(board: SideBoard, path: str | PathLike, title: str = "") -> None:
    """The board sheet at 1:1 (landscape): its four tags, the centre mark on its lower edge, a 100 mm scale bar and
    how to stand it."""
    from reportlab.lib.units import mm
    from reportlab.pdfgen.canvas import Canvas

    w, h = board.sheet_mm
    canvas = Canvas(str(path), pagesize=(w * mm, h * mm))
    canvas.scale(mm, mm)
    u0 = board.center_u_mm - w / 2.0
    for tag in board.reference_tags:
        draw_tag(canvas, tag.id, (tag.center_mm[0] - u0, tag.center_mm[1]), tag.size_mm)
        canvas.setFillColorRGB(*INK)
        canvas.setFont(FONT, 2.4)
        canvas.drawCentredString(tag.center_mm[0] - u0, tag.center_mm[1] - tag.size_mm * 0.625 - 3.0,
                                 f"board tag {tag.id}")
    canvas.setStrokeColorRGB(*INK)
    canvas.setLineWidth(0.3)
    path_mark = canvas.beginPath()  # the centre mark: a triangle pointing down at the lower edge
    path_mark.moveTo(w / 2.0, 0.0)
    path_mark.lineTo(w / 2.0 - 3.0, 5.0)
    path_mark.lineTo(w / 2.0 + 3.0, 5.0)
    path_mark.close()
    canvas.drawPath(path_mark, stroke=1, fill=1)
    canvas.setFont(BOLD, 4.0)
    canvas.drawCentredString(w / 2.0, h - 20.0, "SIDE CAMERA BOARD" + (f": {title}" if title else ""))
    canvas.setFont(FONT, 2.8)
    lines = [f"centre mark at u = {board.center_u_mm:.0f} mm; face along v = {board.line_v_mm:.0f} mm of the guide",
             "lower edge of this sheet ON THE TABLE (heights are measured from it); the sheet upright and flat",
             "print at actual size (100 %), not \u201cfit to page\u201d; units: mm"]
    if board.hidden:  # what the guide could not place it clear of
        lines.append(f"the parts hide {_board_tags(board.hidden)} from a camera level with this sheet's middle: "
                     "raise the side camera to look over them")
    if board.hidden_raised:
        lines.append(f"even from the side camera raised {SIDE_CAMERA_RISE_MM:.0f} mm the parts hide "
                     f"{_board_tags(board.hidden_raised)}")
    for i, line in enumerate(lines):
        canvas.drawCentredString(w / 2.0, h - 28.0 - 4.0 * i, line)
    draw_scale_bar(canvas, w / 2.0 - 50.0, 20.0)
    canvas.showPage()
    canvas.save()
