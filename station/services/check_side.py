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
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import cv2
import numpy as np

from calibration.intrinsics import to_gray
from calibration.measure import measure
from drivers.sim.camera import parse_camera_options
from drivers.sim.camera_scene import ImageItem, Occluder, PlaneScene, TagItem
from station.errors import ServiceError, station_errors
from station.services import calibrate
from station.services.check_scene import aim_camera, twin_intrinsics
from vision.detection import TagDetector

__all__ = ["SideView", "measure_side", "merge_as_built", "plane_json", "side_lines", "side_overlay",
           "side_scene", "side_targets", "view_of_frame"]


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
    covered by a hand. Simulation only.

    Raises
    ------
    ServiceError
        An offset of a part the side camera reads no tag of (``sim_side_offset``).
    """
    from calibration.asbuilt import part_plane_pose  # heavy: scipy, shapely

    offsets = dict(offsets or {})
    known = {t.part for t in targets}
    unknown = sorted(set(offsets) - known)
    if unknown:
        raise ServiceError(f"sim_side_offset: the side camera reads no tag of {unknown[0]!r}; it reads: "
                           f"{', '.join(sorted(known)) or 'none (no jig stand faces it)'}", field="sim_side_offset",
                           value=unknown[0])
    if layout is not None:
        placed = part_plane_pose(job.scenario, np.asarray(layout, float), board.plane, sorted(known))
        for target in targets:
            pose = placed[target.part]
            offsets[target.part] = (pose.center_mm[0] - target.center_mm[0], pose.center_mm[1] - target.center_mm[1],
                                    _wrap(pose.heading_deg - target.heading_deg))
    tags = [TagItem(t.id, tuple(t.center_mm), t.size_mm) for t in board.reference_tags]
    occluders = []
    for target in targets:
        du, dv, turn = offsets.get(target.part, (0.0, 0.0, 0.0))
        c, s = math.cos(math.radians(turn)), math.sin(math.radians(turn))

        def moved(points, c=c, s=s, du=du, dv=dv, target=target) -> np.ndarray:
            offset = np.asarray(points, float).reshape(-1, 2) - target.center_mm
            return np.asarray(target.center_mm) + [du, dv] + offset @ np.array([[c, s], [-s, c]])

        # the plate the tag is engraved on, and the part resting on it just in front (pictures: the tag is clear)
        if target.plate_mm:
            occluders.append(Occluder(moved(target.plate_mm), target.tag_depth_mm, color=(214, 180, 132)))
        occluders.extend(Occluder(moved(ring), target.tag_depth_mm + 1.0, color=(120, 124, 132))
                         for ring in target.silhouette_mm)
        offset = np.subtract(target.tag_center_mm, target.center_mm)
        centre = np.asarray(target.center_mm) + [du, dv] + [c * offset[0] - s * offset[1],
                                                            s * offset[0] + c * offset[1]]
        tags.append(TagItem(target.tag_id, (float(centre[0]), float(centre[1])), target.tag_size_mm,
                            target.tag_heading_deg + turn, target.tag_depth_mm))
        if target.tag_id in occluded:
            half = 0.8 * target.tag_size_mm
            square = np.array([[-half, -half], [half, -half], [half, half], [-half, half]]) + centre
            occluders.append(Occluder(square, target.tag_depth_mm + 5.0))
    u0, v0, u1, v1 = board.extent_mm
    sheet = np.full((8, 8, 3), 246, dtype=np.uint8)  # the white sheet on the board, under its tags
    images = (ImageItem(sheet, np.array([[u0, v1], [u1, v1], [u1, v0], [u0, v0]], float)),)
    return PlaneScene(tags=tuple(tags), images=images, occluders=tuple(occluders), background=(176, 150, 118))


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
    from calibration.check import check_parts, part_tags, reference_tags  # heavy: scipy, shapely
    from calibration.side import side_view_checks  # heavy: scipy, shapely

    if not targets:
        raise ServiceError("camera: the side camera has nothing to read: no jig stand of this layout faces it (use "
                           "the guide's jigs: --jigs)", field="camera", value=camera)
    guide = _side_guide(job, board, targets)
    measurement = measure(np.asarray(image), intrinsics, reference_tags(guide), part_tags(guide), previous)
    checks, _ = check_parts(guide, measurement)
    via = {t.part: t.via for t in targets}
    checks = [replace(c, view="side", via=via.get(c.name, "")) for c in side_view_checks(checks, targets)]
    return SideView(board, tuple(targets), guide, measurement, tuple(checks), camera, np.asarray(image), intrinsics)


@station_errors
def merge_as_built(job, top, side: SideView):
    """The top check's as-built layout (:class:`calibration.asbuilt.AsBuilt`) with what the side view measured:
    each part's parameters the top view did not measure fitted to its pose on the board's plane."""
    from calibration.asbuilt import AsBuilt, PlanePose, as_built_layout  # heavy: scipy, shapely

    scenario = job.scenario
    poses = {c.name: PlanePose(c.measured_center_mm, c.measured_heading_deg) for c in side.checks if c.found}
    if not poses:
        return top, {}
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
               seed: int | None = None, intrinsics=None, name: str | None = "camera-side"):
    """A frame from the side camera at ``url`` and how to read it: ``(image, intrinsics)``. A simulated camera is
    handed :func:`side_scene` first (aimed over the board and the tags it reads unless its URL sets a ``target``);
    the intrinsics: the file ``intrinsics``, else camera ``name``'s saved calibration, else a simulated camera's
    own, else guessed (``name`` None: a simulated camera's own lens, no saved calibration read).

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
    where the camera found it (orange, carried by its tag), the instructions written above. Drawn through the board's
    plane found in the frame (the frame as it is when none was found)."""
    out = np.array(side.image, dtype=np.uint8, copy=True)
    if out.ndim == 2:
        out = np.repeat(out[:, :, None], 3, axis=2)
    plane = side.measurement.plane
    lines = [c.instruction for c in side.checks] or ["the side camera reads no tag"]
    if plane is None:
        lines = ["side view: too few board tags seen: no plane"]
    else:
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
    scale = max(out.shape[1] / 1920.0, 0.4)
    for i, line in enumerate(lines[:6]):
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
    if plane is None:
        missing = ", ".join(map(str, side.get("missing_reference_tags", ())))
        return [f"side view: no plane: too few board tags seen (missing {missing}); no height measured"]
    lines = [f"side view (heights and tilts): plane from board tags {', '.join(map(str, plane['reference_ids']))} "
             f"(residual {plane['residual_mm']:.2f} mm)"]
    for part in report.side_parts:
        via = f", on jig {part.via}" if part.via else ""
        if part.error is None:
            lines.append(f"  {part.name} (tag {part.tag_id}{via}): {part.instruction}")
        else:
            lines.append(f"  {part.name} (tag {part.tag_id}{via}): up {part.error[1]:+.1f} mm, turn "
                         f"{part.error[3]:+.1f} deg: {part.instruction}")
    measured = [name for name, view in report.measured_by.items() if view == "side"]
    if measured:
        lines.append(f"measured by the side camera: {', '.join(measured)}")
    return lines
