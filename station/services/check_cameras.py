"""A table check with two cameras: the top camera reads the table's plane, the side camera the board stood at its
edge (:mod:`station.services.check_side`); the parameters each view measured combine in one as-built layout, and
CHECK.json says which view measured what. Used by ``station check --camera TOP --camera SIDE`` and by an attempt's
checks (:class:`station.services.assemble.Assembly`: ``station assemble``, the Assemble screen, ``station loop``),
where a simulated world's parts are seen by both cameras where its maker set them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

from common.progress import Reporter
from projector.board import side_board
from station.config import configured_devices
from station.errors import ServiceError, station_errors
from station.services import calibrate
from station.services.check import CheckRequest, FrameSource, camera_frame, check_frame, grab_frame, remember_plane
from station.services.check_side import (
    is_side_url,
    measure_side,
    plane_name,
    side_frame,
    side_targets,
    view_of_frame,
)
from station.services.images import load_image

__all__ = ["SIDE_CAMERA", "camera_names", "check_views", "configured_cameras", "reads_side"]

#: The side camera a simulated world serves when no side camera is named: the twin 700 mm in front of the board,
#: where the side camera's figures were measured (docs/results/2026-12-05-side-camera.md), raised to look down 20
#: degrees so that it sees every board tag over the parts of the examples (docs/guide/side-camera.md).
SIDE_CAMERA = "sim://camera?view=side&height=700&tilt=-20"


@station_errors
def camera_names(urls: Sequence[str]) -> list[tuple[str, str]]:
    """The cameras given by URL, ``(name, url)``: the first named as the station's camera, the others ``camera-2``,
    ``camera-3``... (their saved calibrations and planes are kept under those names)."""
    return [(calibrate.DEFAULT_CAMERA if i == 0 else f"{calibrate.DEFAULT_CAMERA}-{i + 1}", url)
            for i, url in enumerate(urls)]


@station_errors
def configured_cameras() -> list[tuple[str, str]]:
    """Every camera station.toml names, ``(name, url)``, in its order."""
    return [(d.name, d.url) for d in configured_devices() if d.kind == "camera"]


@station_errors
def reads_side(job) -> bool:
    """Whether a side camera has something to read in ``job``: a table guide (it has a board) with jig stands whose
    face tag looks at the board's camera."""
    board = side_board(job.guide)
    return board is not None and bool(side_targets(job, board))


@station_errors
def check_views(job, cameras: Sequence[tuple[str, str]], request: CheckRequest | None = None, *, image=None,
                intrinsics=None, offsets=None, side_offsets=None, occluded: Sequence[int] = (), side_image=None,
                side_intrinsics=None, scene=None, side_layout=None, seed: int | None = None,
                station_cameras: bool = True, report: Reporter | None = None):
    """The check of ``job`` with every camera in ``cameras`` (``(name, url)``): the top camera's frame (or the file
    ``image``) measures the table's plane, a side camera's the heights and tilts on the board's plane; the
    parameters combine in the as-built layout and CHECK.json says which view measured what. ``request`` and
    ``report`` go to :func:`station.services.check.check_frame` (the top camera's name added).
    The planes are remembered per camera (the next check says how far each moved). ``side_image`` is the side
    camera's frame from a file (a photo), read with ``side_intrinsics`` (a file; else the side camera's saved
    calibration, else guessed and said).

    A simulated world's parts as placed: ``scene`` is what a simulated top camera sees
    (:func:`station.services.world.world_scene`), ``side_layout`` the design parameters a simulated side camera shows
    the parts at (:func:`station.services.world.as_placed_layout`); ``seed`` seeds the simulated cameras' noise in
    these frames. ``station_cameras`` False: simulated cameras read through their own lenses and nothing kept (no
    saved calibration or plane read, none saved: ``station loop``'s unattended attempts).

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
            frames[url] = camera_frame(job.guide, FrameSource(camera=url, name=name, scene=scene))
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
            picture, lens = side_frame(job, board, targets, url, offsets=side_offsets, occluded=occluded,
                                       layout=side_layout, seed=None if seed is None else seed + 1,
                                       name=name if station_cameras else None)
        previous = calibrate.load_plane(plane_name(name)) if station_cameras else None
        side_view = measure_side(job, board, targets, picture, lens, previous, camera=name)
    elif side_offsets:
        raise ServiceError("sim_side_offset: no side camera to show it (add --camera 'sim://camera?view=side')",
                           field="sim_side_offset")
    top_name, top_url = top_cameras[0] if top_cameras else (calibrate.DEFAULT_CAMERA, None)
    if top_url in frames:
        frame, lens, _, previous = frames[top_url]
    elif not station_cameras and image is None:
        frame, lens = grab_frame(top_url, job.guide, offsets=offsets, occluded=tuple(occluded), scene=scene,
                                 seed=seed)
        previous = None
    else:
        frame, lens, _, previous = camera_frame(job.guide, FrameSource(image, top_url, intrinsics, offsets,
                                                                       tuple(occluded), scene, name=top_name))
    result = check_frame(job, frame, lens, replace(request or CheckRequest(), camera=top_name), previous=previous,
                         side=side_view, report=report)
    if not station_cameras:
        return result
    remember_plane(top_name, result)
    if side_view is not None and side_view.measurement.plane is not None:
        try:
            calibrate.save_plane(plane_name(side_view.camera), side_view.measurement.plane)
        except OSError:
            pass  # the check stands without it; only the next "moved" report is lost
    return result
