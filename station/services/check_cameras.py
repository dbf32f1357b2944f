"""A table check with two cameras: the top camera reads the table's plane, the side camera the board stood at its
edge (:mod:`station.services.check_side`); the parameters each view measured combine in one as-built layout, and
CHECK.json says which view measured what. Used by ``station check --camera TOP --camera SIDE``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

from common.progress import Reporter
from projector.board import side_board
from station.errors import ServiceError, station_errors
from station.services import calibrate
from station.services.check import CheckRequest, FrameSource, camera_frame, check_frame, remember_plane
from station.services.check_side import (
    is_side_url,
    measure_side,
    plane_name,
    side_frame,
    side_targets,
    view_of_frame,
)
from station.services.images import load_image

__all__ = ["check_views"]


@station_errors
def check_views(job, cameras: Sequence[tuple[str, str]], request: CheckRequest | None = None, *, image=None,
                intrinsics=None, offsets=None, side_offsets=None, occluded: Sequence[int] = (), side_image=None,
                side_intrinsics=None, report: Reporter | None = None):
    """The check of ``job`` with every camera in ``cameras`` (``(name, url)``): the top camera's frame (or the file
    ``image``) measures the table's plane, a side camera's the heights and tilts on the board's plane; the
    parameters combine in the as-built layout and CHECK.json says which view measured what. ``request`` and
    ``report`` go to :func:`station.services.check.check_frame` (the top camera's name added).
    The planes are remembered per camera (the next check says how far each moved). ``side_image`` is the side
    camera's frame from a file (a photo), read with ``side_intrinsics`` (a file; else the side camera's saved
    calibration, else guessed and said).

    Raises
    ------
    ServiceError
        No top camera, or two cameras of one view (``camera``); a side camera with nothing to read (``camera``).
    """
    board = side_board(job.guide)
    top_cameras, side_cameras, frames = [], [], {}
    for name, url in cameras:
        side = is_side_url(url)
        if side is None:  # a real camera: its frame says which board it faces
            frames[url] = camera_frame(job.guide, FrameSource(camera=url, name=name))
            side = view_of_frame(frames[url][0], board) == "side"
        (side_cameras if side else top_cameras).append((name, url))
    for view, found in (("top", top_cameras), ("side", side_cameras)):
        if len(found) > 1:
            raise ServiceError(f"camera: {len(found)} cameras see the {view} view ({', '.join(u for _, u in found)});"
                               " expected one per view", field="camera", value=found[1][1])
    if side_image is not None:
        side_cameras.append(("camera-side", None))
        if len(side_cameras) > 1:
            raise ServiceError(f"side_image: {side_image} and the camera {side_cameras[0][1]} both see the side view;"
                               " expected one", field="side_image", value=str(side_image))
    if side_cameras and board is None:
        raise ServiceError(f"camera: a side camera checks a table guide; this one is drawn on the {job.guide.view} "
                           "view, its own camera sees the heights already", field="camera", value=side_cameras[0][1])
    if not top_cameras and image is None:
        raise ServiceError("camera: no top camera (the table's plane); give one --camera for the table and one "
                           "with view=side for the board", field="camera")
    side_view = None
    if side_cameras:
        name, url = side_cameras[0]
        targets = side_targets(job, board)
        if url is None:  # a file
            picture = load_image(side_image)
            lens = calibrate.intrinsics_for((picture.shape[1], picture.shape[0]), intrinsics=side_intrinsics,
                                            name=name)
        elif url in frames:
            picture = frames[url][0]
            lens = calibrate.intrinsics_for((picture.shape[1], picture.shape[0]), name=name)
        else:
            picture, lens = side_frame(job, board, targets, url, offsets=side_offsets, occluded=occluded, name=name)
        side_view = measure_side(job, board, targets, picture, lens, calibrate.load_plane(plane_name(name)),
                                 camera=name)
    elif side_offsets:
        raise ServiceError("sim_side_offset: no side camera to show it (add --camera 'sim://camera?view=side')",
                           field="sim_side_offset")
    top_name, top_url = top_cameras[0] if top_cameras else (calibrate.DEFAULT_CAMERA, None)
    if top_url in frames:
        frame, lens, _, previous = frames[top_url]
    else:
        frame, lens, _, previous = camera_frame(job.guide, FrameSource(image, top_url, intrinsics, offsets,
                                                                       tuple(occluded), name=top_name))
    result = check_frame(job, frame, lens, replace(request or CheckRequest(), camera=top_name), previous=previous,
                         side=side_view, report=report)
    remember_plane(top_name, result)
    if side_view is not None and side_view.measurement.plane is not None:
        try:
            calibrate.save_plane(plane_name(side_view.camera), side_view.measurement.plane)
        except OSError:
            pass  # the check stands without it; only the next "moved" report is lost
    return result
