"""An independent renderer of the side camera's frame, for checking the side view against code it shares nothing with.

The camera twin (:mod:`drivers.sim.camera_render`) casts rays through OpenCV's lens model onto planes parallel to the
board, and :mod:`station.services.check_side` puts the tags on those planes. This module does neither: it builds the
camera from a look-at in the scene (metres, the scenario's world frame), carries each jig's face tag in three
dimensions with its part (the part's world pose at the moved layout times the inverse of its designed pose, applied
to the tag's cells on the jig's face), projects every tag cell through a plain pinhole written out here (no OpenCV),
and fills the cells as polygons with Pillow on an 8x supersampled patch per tag (Pillow's own rasteriser),
averaged down, blurred with Pillow's Gaussian.
Its only shared inputs are the scenario's scene graph, the jig's face frame and the tags' bit patterns.
"""

from __future__ import annotations

import numpy as np
from PIL import Image, ImageDraw, ImageFilter

from calibration.intrinsics import CameraIntrinsics
from design.contraption.geometry import world_poses
from vision.tags import tag_cells

__all__ = ["independent_side_frame"]

SUPERSAMPLE = 8
SIZE = (1920, 1080)
FOCAL_PX = 1400.0


def _look_at(centre: np.ndarray, target: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Rows: the camera's x (image right), y (image down), z (forward) in the world."""
    z = (target - centre) / np.linalg.norm(target - centre)
    y = -up + (up @ z) * z
    y /= np.linalg.norm(y)
    return np.stack([np.cross(y, z), y, z])


def _tag_quads(tag_id: int, centre, right, up, size_mm: float):
    cell = size_mm / 8.0
    bits = tag_cells(tag_id)
    quads = []
    for row in range(10):
        for column in range(10):
            x0, x1 = (column - 5) * cell, (column - 4) * cell
            y0, y1 = (5 - row) * cell, (4 - row) * cell
            corners = [centre + a * right + b * up for a, b in ((x0, y0), (x1, y0), (x1, y1), (x0, y1))]
            quads.append((np.array(corners), bool(bits[row, column])))
    return quads


def independent_side_frame(job, board, x_moved, *, distance_mm: float = 700.0, aim_mm=None, noise: float = 2.0,
                           blur: float = 0.8, seed: int = 0):
    """The side camera's frame of ``job``'s board and jig face tags with the parts at layout ``x_moved``, and the
    camera's intrinsics (pinhole, no distortion).

    The camera stands ``distance_mm`` in front of the board's point ``aim_mm`` (board (u, v) mm; default the sheet's
    middle), looking square at it; ``blur`` (Pillow's Gaussian radius, px) and ``noise`` (grey levels) degrade it.
    """
    plane = board.plane
    metres = 1000.0
    u_axis, v_axis, normal = (np.asarray(a, float) for a in (plane.u_axis, plane.v_axis, plane.normal))
    origin = np.asarray(plane.origin, float) * metres
    u0, v0, u1, v1 = board.extent_mm
    aim = np.array(aim_mm if aim_mm is not None else ((u0 + u1) / 2.0, (v0 + v1) / 2.0), float)
    target = origin + aim[0] * u_axis + aim[1] * v_axis
    centre = target + distance_mm * normal
    rotation = _look_at(centre, target, v_axis)
    width, height = SIZE
    cx, cy = (width - 1) / 2.0, (height - 1) / 2.0

    def pixels(points_mm: np.ndarray) -> np.ndarray:
        camera = (np.asarray(points_mm, float) - centre) @ rotation.T
        return np.column_stack([FOCAL_PX * camera[:, 0] / camera[:, 2] + cx, FOCAL_PX * camera[:, 1] / camera[:, 2]
                                + cy])

    tags = []  # each tag's cells: the board's, then the jigs' (nearer the camera)
    for tag in board.reference_tags:
        tag_centre = origin + tag.center_mm[0] * u_axis + tag.center_mm[1] * v_axis
        tags.append(_tag_quads(tag.id, tag_centre, u_axis, v_axis, tag.size_mm))
    scenario = job.scenario
    designed = world_poses(scenario.objects, scenario.transforms(np.asarray(job.layout.x, float), checked=False))
    moved = world_poses(scenario.objects, scenario.transforms(np.asarray(x_moved, float), checked=False))
    for jig in job.jigs.plan.jigs:
        if jig.face_tag_id is None or jig.face_frame is None:
            continue
        face_origin, x_axis, y_axis, _ = (np.asarray(v, float) for v in jig.face_frame)
        carry = moved[jig.part] * designed[jig.part].inverse()  # the part's move, which the jig it rests on shows
        tag_centre = face_origin * metres + jig.face_tag_center_mm[0] * x_axis + jig.face_tag_center_mm[1] * y_axis
        tags.append([(carry.apply(quad / metres) * metres, white)
                     for quad, white in _tag_quads(jig.face_tag_id, tag_centre, x_axis, y_axis, jig.face_tag_size_mm)])
    grey = np.full((height, width), 170.0, dtype=np.float32)
    scale = SUPERSAMPLE
    for quads in tags:  # each tag on its own supersampled patch (tags never overlap here)
        projected = [(pixels(quad), white) for quad, white in quads]
        every = np.concatenate([p for p, _ in projected])
        x0, y0 = (int(np.floor(v)) - 2 for v in every.min(axis=0))
        x1, y1 = (int(np.ceil(v)) + 3 for v in every.max(axis=0))
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, width), min(y1, height)
        patch = Image.new("L", ((x1 - x0) * scale, (y1 - y0) * scale), 170)
        draw = ImageDraw.Draw(patch)
        for points, white in projected:
            # Pillow fills the sub-pixels whose centres (its integers) the polygon covers
            corners = (points - [x0, y0] + 0.5) * scale - 0.5
            draw.polygon([tuple(p) for p in corners], fill=236 if white else 26)
        block = np.asarray(patch, dtype=np.float32).reshape(y1 - y0, scale, x1 - x0, scale).mean(axis=(1, 3))
        grey[y0:y1, x0:x1] = block
    picture = Image.fromarray(np.clip(np.round(grey), 0, 255).astype(np.uint8))
    if blur > 0:
        picture = picture.filter(ImageFilter.GaussianBlur(blur))  # Pillow's own, not OpenCV's
    grey = np.asarray(picture, dtype=np.float32) + np.random.default_rng(seed).normal(0.0, noise, grey.shape)
    image = np.repeat(np.clip(np.round(grey), 0, 255).astype(np.uint8)[:, :, None], 3, axis=2)
    matrix = np.array([[FOCAL_PX, 0.0, cx], [0.0, FOCAL_PX, cy], [0.0, 0.0, 1.0]])
    return image, CameraIntrinsics(matrix, np.zeros(5), SIZE, name="independent pinhole")
