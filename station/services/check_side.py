"""The side camera of a table check: the board it faces, the tags it reads, what it measures.

Used by :mod:`station.services.check_cameras` (``station check --camera TOP --camera SIDE``) and the simulated world.
The geometry is :mod:`projector.board` (where the reference board stands) and :mod:`calibration.side` (a tag on the
board's plane carries a part's height and tilt); this module finds the tags the side camera can read in a guide job
(each jig stand's face tag: a track or a plank is too thin for a tag of its own), measures a side frame, and refines the
top check's as-built layout with what the side view measured (the parameters the top view could not: heights, tilts). It
also hands the simulated camera its side scene: the board's tags and the jigs' face tags where the parts stand (moved by
``--sim-side-offset`` or by the simulated world's placement).

A view's camera is told apart by what it sees: a simulated camera by its ``view=`` option, a real one by the
reference tags in its frame (the board's 579-582 make it the side camera).
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from calibration.intrinsics import to_gray
from calibration.measure import measure
from common.words import listed
from drivers.sim.camera import parse_camera_options
from drivers.sim.camera_scene import ImageItem, Occluder, PlaneScene, Solid, TagItem
from station.errors import ServiceError, station_errors
from station.services import calibrate
from station.services.check_scene import aim_camera, twin_intrinsics
from vision.detection import TagDetector

__all__ = ["SideView", "hidden_as_built", "measure_side", "merge_as_built", "plane_json", "side_lines", "side_overlay",
           "side_scene", "side_targets", "view_of_frame"]


#: The fewest board tags the side camera finds the board's plane from: two side by side leave the board's tilt
#: about their line loosely held (heights off by up to 0.75 mm on the twin: docs/results/2026-12-05-side-camera.md).
SIDE_MIN_REFERENCE_TAGS = 3


@station_errors
@dataclass(frozen=True)
class SideView:
    """A side frame measured: the board, the targets, the side guide, the measurement and its checks."""

    board: object
    targets: tuple
    guide: object
    measurement: object
    checks: tuple
    camera: str = ""
    image: object = None
    intrinsics: object = None
    #: Each tag the camera should have read and did not: what stands between it and the camera (part names, "jig
    #: J1"), the parts of :attr:`as_built` where a camera measured them, every other one as designed; empty when
    #: nothing known does (covered, out of the frame).
    hidden: Mapping[int, tuple[str, ...]] = field(default_factory=dict)
    #: The camera's pose on the board's frame, found even from too few board tags for a plane (None: not found).
    pose: object = None
    #: The tags it should have read and did not (board tags, face tags), what :attr:`hidden` is worked out for.
    unread: tuple[int, ...] = ()
    #: The parts :attr:`hidden` places where the check measured them (:func:`hidden_as_built`); none: the design's.
    as_built: tuple[str, ...] = ()

    def plane_json(self) -> dict | None:
        """The board's plane as CHECK.json's ``views`` give a plane (None when none was found)."""
        return plane_json(self.measurement.plane)


@station_errors
def side_targets(job, board) -> list:
    """The tags the side camera reads in ``job`` (a guide job with its jigs): each jig stand's face tag whose face
    looks at the camera (within :data:`calibration.side.FACING_DEG` of the board's normal), as a
    :class:`~calibration.side.SideTarget` of the part it carries."""
    from calibration.asbuilt import part_plane_pose  # heavy: scipy, shapely
    from calibration.side import FACING_DEG, SideTarget  # heavy: scipy, shapely

    planned = getattr(job, "jigs", None)
    if board is None or planned is None:
        return []
    plane = board.plane
    normal = np.asarray(plane.normal, float)
    targets = []
    for jig in planned.plan.jigs:
        if jig.face_tag_id is None or jig.face_frame is None or jig.support is None:
            continue
        origin, x_axis, y_axis, face = (np.asarray(v, float) for v in jig.face_frame)
        if float(face @ normal) < math.cos(math.radians(FACING_DEG)):
            continue  # seen edge-on or from behind: another camera's

        def board_point(xy, origin=origin, x_axis=x_axis, y_axis=y_axis) -> np.ndarray:
            world = origin + (float(xy[0]) * x_axis + float(xy[1]) * y_axis) / 1000.0
            return plane.to_plane(world[None, :])[0]

        tag_world = origin + (jig.face_tag_center_mm[0] * x_axis + jig.face_tag_center_mm[1] * y_axis) / 1000.0
        depth = 1000.0 * float((tag_world - np.asarray(plane.origin, float)) @ normal)
        up = np.array([float(y_axis @ plane.u_axis), float(y_axis @ plane.v_axis)])
        tag_heading = math.degrees(math.atan2(-up[0], up[1]))
        a, b = (board_point(p) for p in jig.support)
        lower = a if a[1] <= b[1] else b
        left, right = (a, b) if a[0] <= b[0] else (b, a)
        tilt = math.degrees(math.atan2(right[1] - left[1], right[0] - left[0]))
        pose = part_plane_pose(job.scenario, job.layout.x, plane, [jig.part])[jig.part]
        tag_centre = board_point(jig.face_tag_center_mm)

        def ring(coords, board_point=board_point) -> tuple:
            return tuple(tuple(float(c) for c in board_point(p)) for p in list(coords)[:-1])

        silhouette = tuple(ring(g.exterior.coords) for g in getattr(jig.silhouette, "geoms", [jig.silhouette])
                           if not g.is_empty and hasattr(g, "exterior"))
        targets.append(SideTarget(jig.part, jig.id, int(jig.face_tag_id), float(jig.face_tag_size_mm),
                                  (float(tag_centre[0]), float(tag_centre[1])), depth, tag_heading,
                                  tuple(pose.center_mm), float(pose.heading_deg),
                                  (float(lower[0]), float(lower[1])), tilt, ring(jig.outline.exterior.coords),
                                  silhouette))
    return targets


def _side_guide(job, board, targets):
    from calibration.side import side_guide  # heavy: scipy, shapely

    return side_guide(job.guide, board, targets)


@station_errors
def side_scene(job, board, targets, offsets: Mapping[str, Sequence[float]] | None = None, *,
               layout=None, occluded: Sequence[int] = ()):
    """What the simulated side camera sees: the board's tags and every target's tag on the board's plane, a part
    moved by ``offsets[part] = (du, up, deg)`` on that plane (rigidly about its origin: ``--sim-side-offset``) or
    placed as the design parameters ``layout`` put it (a simulated world's parts as placed); the tags ``occluded``
    covered by a hand. In front of the board, every part's collision bodies and every jig stand's plate and base as
    solids (:func:`_scene_solids`): what stands between the camera and a tag hides it, as in a real photo. Simulation
    only.

    Raises
    ------
    ServiceError
        An offset of a part the side camera reads no tag of (``sim_side_offset``).
    """
    offsets = dict(offsets or {})
    known = {t.part for t in targets}
    unknown = sorted(set(offsets) - known)
    if unknown:
        raise ServiceError(f"sim_side_offset: the side camera reads no tag of {unknown[0]!r}; it reads: "
                           f"{', '.join(sorted(known)) or 'none (no jig stand faces it)'}", field="sim_side_offset",
                           value=unknown[0])
    if layout is not None:
        offsets.update(_layout_moves(job, board, targets, layout))
    tags = [TagItem(t.id, tuple(t.center_mm), t.size_mm) for t in board.reference_tags]
    occluders = [Occluder(_hand(t.center_mm, t.size_mm), 5.0) for t in board.reference_tags if t.id in occluded]
    for target in targets:
        du, dv, turn = offsets.get(target.part, (0.0, 0.0, 0.0))
        c, s = math.cos(math.radians(turn)), math.sin(math.radians(turn))
        offset = np.subtract(target.tag_center_mm, target.center_mm)
        centre = np.asarray(target.center_mm) + [du, dv] + [c * offset[0] - s * offset[1],
                                                            s * offset[0] + c * offset[1]]
        tags.append(TagItem(target.tag_id, (float(centre[0]), float(centre[1])), target.tag_size_mm,
                            target.tag_heading_deg + turn, target.tag_depth_mm))
        if target.tag_id in occluded:
            occluders.append(Occluder(_hand(centre, target.tag_size_mm), target.tag_depth_mm + 5.0))
    u0, v0, u1, v1 = board.extent_mm
    sheet = np.full((8, 8, 3), 246, dtype=np.uint8)  # the white sheet on the board, under its tags
    images = (ImageItem(sheet, np.array([[u0, v1], [u1, v1], [u1, v0], [u0, v0]], float)),)
    x = np.asarray(job.layout.x if layout is None else layout, float)
    solids = _scene_solids(job, board, targets, offsets if layout is None else {}, offsets, x)
    return PlaneScene(tags=tuple(tags), images=images, occluders=tuple(occluders), background=(176, 150, 118),
                      solids=tuple(solid for _, solid in solids))


def _layout_moves(job, board, targets, layout) -> dict[str, tuple[float, float, float]]:
    """Each target's part as the design parameters ``layout`` put it, as a move on the board's plane from where the
    guide puts it: ``{part: (du, dv, deg)}``."""
    from calibration.asbuilt import part_plane_pose  # heavy: scipy, shapely

    placed = part_plane_pose(job.scenario, np.asarray(layout, float), board.plane, sorted({t.part for t in targets}))
    return {t.part: (placed[t.part].center_mm[0] - t.center_mm[0], placed[t.part].center_mm[1] - t.center_mm[1],
                     _wrap(placed[t.part].heading_deg - t.heading_deg)) for t in targets}


#: The solids' colours in the side scene: jig plates and bases (birch plywood), parts by kind (else grey).
PLATE_COLOR = (214, 180, 132)
BASE_COLOR = (196, 160, 112)
PART_COLORS = {"Ball": (168, 170, 178), "DominoRun": (178, 62, 52), "Box": (150, 116, 84), "Track": (112, 118, 128)}


def _scene_solids(job, board, targets, part_moves: Mapping, stand_moves: Mapping, x) -> list[tuple[str, Solid]]:
    """The side scene's solids, each with the name of what it is (a part's, ``"jig J1"``), on the board's frame
    ((u, v) on it, h its depth in front of it, mm): every part's collision bodies at layout ``x`` (the scene
    graph's, each piece convex), a target's part also moved on the board's plane by ``part_moves[part]``; every jig
    stand's plate (its outline, as thick as the sheet it is cut from) and its base lying on the table. A plate whose
    face tag the camera reads is moved with its tag by ``stand_moves[part]`` (on the board's plane, its face where
    the tag is drawn: its own plate never hides it; its base follows along the table); any other stand is carried
    with its part as the scene graph moves it."""
    import shapely  # heavy: shapely (with the design modules below)

    from design.contraption.geometry import world_poses
    from design.contraption.primitives import body_specs
    from design.jigs.section import part_solids

    plane = board.plane
    origin, normal = np.asarray(plane.origin, float), np.asarray(plane.normal, float)

    def on_board(world_m) -> np.ndarray:
        world_m = np.asarray(world_m, float).reshape(-1, 3)
        return np.column_stack([plane.to_plane(world_m), 1000.0 * (world_m - origin) @ normal])

    def move(points, target, moves) -> np.ndarray:
        du, dv, turn = moves.get(target.part, (0.0, 0.0, 0.0))
        c, s = math.cos(math.radians(turn)), math.sin(math.radians(turn))
        moved = np.array(points, float)
        offset = moved[:, :2] - target.center_mm
        moved[:, :2] = np.asarray(target.center_mm) + [du, dv] + offset @ np.array([[c, s], [-s, c]])
        return moved

    def triangles(polygon) -> list[np.ndarray]:
        """A flat outline's convex pieces: its triangles' corners (3, 2)."""
        return [np.asarray(t.exterior.coords)[:3] for t in shapely.constrained_delaunay_triangles(polygon).geoms]

    scenario = job.scenario
    frames = world_poses(scenario.objects, scenario.transforms(x, checked=False))
    by_part = {t.part: t for t in targets}
    solids = []
    for obj in scenario.objects:
        specs = body_specs(obj) if obj.type != "Plane" else ()
        if not specs:
            continue
        pieces = [on_board(solid.points) for solid in part_solids((frames[obj.name] * spec.pose, spec)
                                                                    for spec in specs)]
        if obj.name in by_part and obj.name in part_moves:
            pieces = [move(piece, by_part[obj.name], part_moves) for piece in pieces]
        solids.append((obj.name, Solid(tuple(pieces), PART_COLORS.get(obj.type, (120, 124, 132)))))
    planned = getattr(job, "jigs", None)
    designed = world_poses(scenario.objects, scenario.transforms(np.asarray(job.layout.x, float), checked=False))
    top = job.guide.plane
    for jig in planned.plan.jigs if planned is not None else ():
        if jig.kind != "stand" or jig.face_frame is None:
            continue
        t = float(jig.thickness_mm)
        target = next((candidate for candidate in targets if candidate.via == jig.id), None)
        base = [np.vstack([top.to_world(corners, 0.0), top.to_world(corners, t)])  # world metres
                for corners in triangles(jig.footprint)]
        if target is not None and target.plate_mm:
            face = target.tag_depth_mm
            plate = [move(np.vstack([np.column_stack([corners, np.full(3, face - t)]),
                                     np.column_stack([corners, np.full(3, face)])]), target, stand_moves)
                     for corners in triangles(shapely.Polygon(target.plate_mm))]
            along = stand_moves.get(target.part, (0.0, 0.0, 0.0))[0]
            base = [on_board(piece) + [along, 0.0, 0.0] for piece in base]
        else:
            corner, x_axis, y_axis, facing = (np.asarray(v, float) for v in jig.face_frame)
            carry = frames[jig.part] * designed[jig.part].inverse()
            plate = []
            for corners in triangles(jig.outline):  # jig frame (x, y) mm; the plate lies behind its engraved face
                face = corner + (corners[:, :1] * x_axis + corners[:, 1:2] * y_axis) / 1000.0
                plate.append(on_board(carry.apply(np.vstack([face, face - t / 1000.0 * facing]))))
            base = [on_board(carry.apply(piece)) for piece in base]
        solids.append((f"jig {jig.id}", Solid(tuple(plate), PLATE_COLOR)))
        solids.append((f"jig {jig.id}", Solid(tuple(base), BASE_COLOR)))
    return solids


def _hand(centre, size_mm: float) -> np.ndarray:
    """A hand over a tag: a square a little larger than the tag with its border."""
    half = 0.8 * float(size_mm)
    return np.array([[-half, -half], [half, -half], [half, half], [-half, half]]) + np.asarray(centre, float)


def _wrap(angle: float) -> float:
    angle = (float(angle) + 180.0) % 360.0 - 180.0
    return 180.0 if angle == -180.0 else angle


@station_errors
def view_of_frame(image, board) -> str:
    """``"side"`` when the frame shows at least two of the board's tags, else ``"top"`` (a real camera's view)."""
    if board is None:
        return "top"
    seen = {t.tag_id for t in TagDetector(2.0, 2).detect(to_gray(np.asarray(image)))}
    return "side" if len(seen & {t.id for t in board.reference_tags}) >= 2 else "top"


@station_errors
def measure_side(job, board, targets, image, intrinsics, previous=None, camera: str = "") -> SideView:
    """Measure a side frame: the board's plane from its tags, each target's tag at its depth, the checks in the side
    camera's words (:func:`calibration.side.side_view_checks`)."""
    from calibration.check import part_tags, reference_tags  # heavy: scipy, shapely

    if not targets:
        raise ServiceError("camera: the side camera has nothing to read: no jig stand of this layout faces it (use "
                           "the guide's jigs: --jigs)", field="camera", value=camera)
    guide = _side_guide(job, board, targets)
    measurement = measure(np.asarray(image), intrinsics, reference_tags(guide), part_tags(guide), previous)
    pose = measurement.plane  # the camera's pose even from too few tags: it tells what stands in front of a tag
    missing = set(measurement.missing_reference_ids)
    if pose is not None:
        missing |= {t.tag_id for t in targets} - {tag.tag_id for tag in measurement.tags}
    if pose is not None and len(pose.reference_ids) < SIDE_MIN_REFERENCE_TAGS:
        measurement = replace(measurement, plane=None, tags=())
    hidden = _hidden_tags(job, board, targets, pose, missing, job.layout.x)
    return SideView(board, tuple(targets), guide, measurement, _side_checks(guide, measurement, targets, hidden),
                    camera, np.asarray(image), intrinsics, hidden, pose, tuple(sorted(missing)))


@station_errors
def hidden_as_built(job, side: SideView, layout, measured: Sequence[str]) -> SideView:
    """``side`` with what hides each tag it did not read worked out again from where the check found the parts:
    ``layout`` (the as-built layout, unclipped) for the parts a camera measured (a parameter of theirs in
    ``measured``), the design for every other part; its unread tags' instructions say so."""
    x = np.asarray(job.layout.x, float).copy()
    names = list(job.scenario.design_space.names)
    at = [names.index(name) for name in measured]
    x[at] = np.asarray(layout, float)[at]
    placed = tuple(p.name for p in job.guide.parts if set(p.parameters) & set(measured))
    hidden = _hidden_tags(job, side.board, side.targets, side.pose, side.unread, x)
    return replace(side, hidden=hidden, checks=_side_checks(side.guide, side.measurement, side.targets, hidden),
                   as_built=placed)


def _side_checks(guide, measurement, targets, hidden) -> tuple:
    """The side view's checks in the side camera's words, a tag it did not read saying why (what hides it)."""
    from calibration.check import check_parts  # heavy: scipy, shapely
    from calibration.side import side_view_checks  # heavy: scipy, shapely

    checks, _ = check_parts(guide, measurement)
    via = {t.part: t.via for t in targets}
    checks = [replace(c, view="side", via=via.get(c.name, "")) for c in side_view_checks(checks, targets)]
    return tuple(c if c.found else replace(c, instruction=_unread(c, measurement, hidden, via)) for c in checks)


def _unread(check, measurement, hidden, via) -> str:
    """Why a part's face tag gave no number, and what to do, in one line naming the tag."""
    jig = f" (jig {via[check.name]})" if via.get(check.name) else ""
    if measurement.plane is None:
        also = f"; it is hidden too: {_names(hidden[check.tag_id], 'stands')} in front" if hidden.get(check.tag_id) \
            else ""
        return (f"`{check.name}`: tag {check.tag_id}{jig} not measured: the side camera found too few board tags "
                f"(missing {', '.join(map(str, measurement.missing_reference_ids))}){also}")
    if hidden.get(check.tag_id):
        who = _names(hidden[check.tag_id], "stands")
        return (f"`{check.name}`: tag {check.tag_id}{jig} hidden: {who} between the side camera and it; raise the side "
                "camera to look over it")
    return check.instruction


def _board_lines(missing: Sequence[int], hidden: Mapping[int, Sequence[str]], no_plane: bool) -> list[str]:
    """One line per board tag not seen (what hides it, if the design says), and one when they leave no plane."""
    notes = []
    for tag_id in missing:
        if hidden.get(tag_id):
            who = _names(hidden[tag_id], "stands")
            notes.append(f"side view: board tag {tag_id} hidden: {who} between the side camera and it")
        else:
            notes.append(f"side view: board tag {tag_id} not seen (covered, or outside the frame?)")
    if no_plane:
        what = sorted({name for tag_id in missing for name in hidden.get(tag_id, ())})
        move = (f"raise the side camera to look over {_names(what)} (it measures from any height)" if what
                else "uncover them and aim the side camera at the whole board")
        notes.append(f"side view: no plane: {SIDE_MIN_REFERENCE_TAGS} of the board's 4 tags are needed (missing "
                     f"{', '.join(map(str, missing))}); no height measured: {move}")
    return notes


def _names(names, verb: str = "") -> str:
    """```a```, ```a`` and ``b``` and the verb, if any, agreeing with them (``stands``/``stand``)."""
    words = [n if n.startswith("jig ") else f"`{n}`" for n in names]
    text = listed(words)
    if not verb:
        return text
    plural = {"stands": "stand"}
    return f"{text} {plural.get(verb, verb) if len(words) > 1 else verb}"


def _hidden_tags(job, board, targets, pose, missing, layout) -> dict[int, tuple[str, ...]]:
    """For each tag id in ``missing``: the parts and jigs that stand between the side camera (at ``pose``, the
    board's plane as found, even from too few tags) and the tag, seen from the camera's centre, the parts where the
    design parameters ``layout`` put them (a jig stand the side camera reads moved with its part, as
    :func:`side_scene` draws it); empty without a pose (the camera's place is then unknown)."""
    from shapely.geometry import MultiPoint, Polygon  # heavy: shapely

    if pose is None or not missing:
        return {}
    rotation = cv2.Rodrigues(np.asarray(pose.rvec, float))[0]
    camera = -rotation.T @ np.asarray(pose.tvec, float)  # its centre on the board's frame (u, v, depth) mm
    squares = {t.id: (t.center_mm, t.size_mm, 0.0, 0.0) for t in board.reference_tags}
    squares.update({t.tag_id: (t.tag_center_mm, t.tag_size_mm, t.tag_heading_deg, t.tag_depth_mm) for t in targets})
    layout = np.asarray(layout, float)
    solids = _scene_solids(job, board, targets, {}, _layout_moves(job, board, targets, layout), layout)
    hidden = {}
    for tag_id in sorted(missing):
        if tag_id not in squares or camera[2] <= 0:
            continue
        centre, size, heading, depth = squares[tag_id]
        turn = math.radians(heading)
        half = 0.625 * size  # with its white border
        corners = [(c * math.cos(turn) - r * math.sin(turn), c * math.sin(turn) + r * math.cos(turn))
                   for c, r in ((-half, -half), (half, -half), (half, half), (-half, half))]
        square = Polygon(np.asarray(centre, float) + corners)
        names = []
        for name, solid in solids:
            for piece in solid.pieces:
                seen = _in_front(np.asarray(piece, float), depth, camera)
                if len(seen) >= 3 and MultiPoint(seen).convex_hull.intersects(square):
                    names.append(name)
                    break
        hidden[tag_id] = tuple(dict.fromkeys(names))
    return hidden


def _in_front(points: np.ndarray, depth: float, camera: np.ndarray) -> np.ndarray:
    """The part of a convex piece (its hull points, board frame mm) between the depth ``depth`` and the camera, seen
    from the camera's centre on the plane at that depth ((u, v) mm: what of that plane it hides)."""
    h = points[:, 2]
    near, far = points[(h > depth) & (h < camera[2])], points[h <= depth]
    if not len(near):
        return np.zeros((0, 2))
    t = (depth - far[:, 2])[None, :] / (near[:, None, 2] - far[None, :, 2])
    cut = (far[None, :, :] + t[..., None] * (near[:, None, :] - far[None, :, :])).reshape(-1, 3)
    every = np.vstack([near, cut]) if len(far) else near
    scale = (camera[2] - depth) / (camera[2] - every[:, 2])
    return camera[:2] + scale[:, None] * (every[:, :2] - camera[:2])


@station_errors
def merge_as_built(job, top, side: SideView):
    """The top check's as-built layout (:class:`calibration.asbuilt.AsBuilt`) with what the side view measured:
    each part's parameters the top view did not measure fitted to its pose on the board's plane."""
    from calibration.asbuilt import AsBuilt, PlanePose, as_built_layout  # heavy: scipy, shapely

    scenario = job.scenario
    poses = {c.name: PlanePose(c.measured_center_mm, c.measured_heading_deg) for c in side.checks if c.found}
    if not poses:  # the side view measured nothing: what the top view measured stands
        return top, {n: "top" for n in top.measured}
    free = {p.name: tuple(n for n in p.parameters if n not in top.measured) for p in job.guide.parts}
    fitted = as_built_layout(scenario, top.unclipped, side.board.plane, poses, free)
    names = list(scenario.design_space.names)
    lower = np.asarray(scenario.design_space.lower, float)
    upper = np.asarray(scenario.design_space.upper, float)
    measured = tuple(n for n in names if n in top.measured or n in fitted.measured)
    unclipped = np.asarray(fitted.unclipped, float)
    clipped = tuple(n for n in names if n in measured and not lower[names.index(n)] <= unclipped[names.index(n)]
                    <= upper[names.index(n)])
    residual = {**top.residual, **{f"{k} (side)": v for k, v in fitted.residual.items()}}
    merged = AsBuilt(np.clip(unclipped, lower, upper), measured, tuple(n for n in names if n not in measured),
                     clipped, residual, unclipped)
    by = {n: "top" for n in top.measured}
    by.update({n: "side" for n in fitted.measured})
    return merged, {n: by[n] for n in names if n in by}


@station_errors
def side_frame(job, board, targets, url: str, *, offsets=None, occluded: Sequence[int] = (), layout=None,
               seed: int | None = None, intrinsics=None, name: str | None = "camera-side", truth: list | None = None):
    """A frame from the side camera at ``url`` and how to read it: ``(image, intrinsics)``. A simulated camera is
    handed :func:`side_scene` first (aimed over the board and the tags it reads unless its URL sets a ``target``);
    the intrinsics: the file ``intrinsics``, else camera ``name``'s saved calibration, else a simulated camera's
    own, else guessed (``name`` None: a simulated camera's own lens, no saved calibration read). A list ``truth``
    is given a simulated camera's truth of every tag in the frame (benches).

    Raises
    ------
    ServiceError
        Simulation offsets (or a simulated world's layout) for a real camera (``sim_side_offset``).
    """
    camera = calibrate.open_camera(url)
    try:
        simulated = hasattr(camera, "set_scene")
        if (offsets or occluded or layout is not None) and not simulated:
            raise ServiceError("sim_side_offset: simulation offsets go with a simulated camera (sim://camera) only",
                               field="sim_side_offset", value=url)
        if simulated:
            camera.set_scene(side_scene(job, board, targets, offsets, layout=layout, occluded=occluded))
            if "target=" not in url:
                aim_camera(camera, _side_guide(job, board, targets))
            if seed is not None and "seed=" not in url:
                camera.options = replace(camera.options, seed=int(seed) % 2**32)
        image = np.asarray(camera.grab())
        twin = twin_intrinsics(camera, url) if simulated else None
        if truth is not None and simulated:
            truth.extend(camera.truth())
    finally:
        camera.close()
    size = (int(image.shape[1]), int(image.shape[0]))
    if intrinsics is not None or twin is None or name is not None and calibrate.camera_file(name).exists():
        return image, calibrate.intrinsics_for(size, intrinsics=intrinsics, name=name or "camera-side")
    return image, twin


@station_errors
def is_side_url(url: str) -> bool | None:
    """Whether a camera URL is a simulated side camera (``sim://camera?view=side``); None for a real camera (its
    frame tells: :func:`view_of_frame`)."""
    if not str(url).strip().lower().startswith("sim://camera"):
        return None
    return parse_camera_options(url)["view"] == "side"


@station_errors
def plane_name(name: str) -> str:
    """Where the side camera ``name`` keeps its last plane (the board's): apart from any table plane."""
    return f"{name}-board"


@station_errors
def side_overlay(side: SideView) -> np.ndarray:
    """The side camera's frame with its check drawn on it (RGB): each jig plate where the guide wants it (green) and
    where the camera found it (orange, carried by its tag), each tag it did not read where it should be (red), the
    lines about them and the instructions written above. Drawn through the board's plane found in the frame (the
    frame as it is when none was found)."""
    out = np.array(side.image, dtype=np.uint8, copy=True)
    if out.ndim == 2:
        out = np.repeat(out[:, :, None], 3, axis=2)
    plane = side.measurement.plane
    missing = side.measurement.missing_reference_ids
    lines = _board_lines(missing, side.hidden, plane is None)
    lines += [c.instruction for c in side.checks] or ["the side camera reads no tag"]
    if plane is not None:
        matrix = np.asarray(side.intrinsics.camera_matrix, float)
        dist = np.asarray(side.intrinsics.dist_coeffs, float)

        def pixels(points, depth) -> np.ndarray:
            points = np.column_stack([np.asarray(points, float).reshape(-1, 2), np.full(len(points), float(depth))])
            found, _ = cv2.projectPoints(points, np.asarray(plane.rvec, float), np.asarray(plane.tvec, float), matrix,
                                         dist)
            return np.round(found.reshape(-1, 2) * 16).astype(np.int32)

        checks = {c.name: c for c in side.checks}
        for target in side.targets:
            if not target.plate_mm:
                continue
            cv2.polylines(out, [pixels(target.plate_mm, target.tag_depth_mm)], True, (40, 200, 60), 2, cv2.LINE_AA,
                          4)
            check = checks.get(target.part)
            if check is not None and check.found:
                turn = math.radians(check.measured_heading_deg - target.heading_deg)
                c, s = math.cos(turn), math.sin(turn)
                offset = np.asarray(target.plate_mm, float) - target.center_mm
                moved = np.asarray(check.measured_center_mm) + offset @ np.array([[c, s], [-s, c]])
                cv2.polylines(out, [pixels(moved, target.tag_depth_mm)], True, (255, 140, 0), 3, cv2.LINE_AA, 4)
        unread = [(t.center_mm, t.size_mm, 0.0, 0.0) for t in side.board.reference_tags if t.id in missing]
        unread += [(t.tag_center_mm, t.tag_size_mm, t.tag_heading_deg, t.tag_depth_mm) for t in side.targets
                   if t.part in checks and not checks[t.part].found]
        for centre, size, heading, depth in unread:  # where a tag should show, with its border
            turn, half = math.radians(heading), 0.625 * size
            square = [(float(centre[0]) + a * math.cos(turn) - b * math.sin(turn),
                       float(centre[1]) + a * math.sin(turn) + b * math.cos(turn))
                      for a, b in ((-half, -half), (half, -half), (half, half), (-half, half))]
            cv2.polylines(out, [pixels(square, depth)], True, (230, 30, 30), 3, cv2.LINE_AA, 4)
    scale = max(out.shape[1] / 1920.0, 0.4)
    lines = [part for line in lines for part in textwrap.wrap(line, 110)]
    for i, line in enumerate(lines[:10]):
        y = int((40 + 34 * i) * scale)
        cv2.putText(out, line, (int(20 * scale), y), cv2.FONT_HERSHEY_SIMPLEX, 0.75 * scale, (0, 0, 0), 4, cv2.LINE_AA)
        cv2.putText(out, line, (int(20 * scale), y), cv2.FONT_HERSHEY_SIMPLEX, 0.75 * scale, (255, 255, 255), 1,
                    cv2.LINE_AA)
    return out


@station_errors
def plane_json(plane) -> dict | None:
    """A plane fix as CHECK.json gives it: ``{"residual_mm", "reference_ids", "moved_mm"}`` (None: no plane)."""
    if plane is None:
        return None
    return {"residual_mm": round(float(plane.residual_mm), 3), "reference_ids": [int(i) for i in plane.reference_ids],
            "moved_mm": None if plane.moved_mm is None else round(float(plane.moved_mm), 3)}


@station_errors
def side_lines(report) -> list[str]:
    """The side camera's part of the check in words: its plane, each part's height and tilt and what to do, the
    parameters it measured (none without a side camera)."""
    side = next((v for v in getattr(report, "views", ()) if v.get("view") == "side"), None)
    if side is None:
        return []
    plane = side.get("plane")
    hidden = {int(k): tuple(v) for k, v in (side.get("hidden_tags") or {}).items()}
    problems = _board_lines(side.get("missing_reference_tags", ()), hidden, plane is None)
    if plane is None:
        return problems + [f"  {part.name} (tag {part.tag_id}): {part.instruction}" for part in report.side_parts]
    lines = [f"side view (heights and tilts): plane from board tags {', '.join(map(str, plane['reference_ids']))} "
             f"(residual {plane['residual_mm']:.2f} mm)", *problems]
    for part in report.side_parts:
        via = f", on jig {part.via}" if part.via else ""
        if part.error is None:
            lines.append(f"  {part.name} (tag {part.tag_id}{via}): {part.instruction}")
        else:
            lines.append(f"  {part.name} (tag {part.tag_id}{via}): up {part.error[1]:+.1f} mm, turn "
                         f"{part.error[3]:+.1f} deg: {part.instruction}")
    measured = report.measured_by_side
    if measured:
        lines.append(f"measured by the side camera: {', '.join(measured)}")
    return lines
