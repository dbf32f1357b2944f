"""The simulated camera of the as-built check: what ``sim://camera`` is shown, where it is aimed and the lens
it knows of itself (simulation only).

A real camera sees the real parts. The simulated one (``sim://camera``) is handed a plain description of the plane
(:mod:`drivers.sim.camera_scene`): the guide's reference tags, every part tag at its part's designed pose and face
height (a part resting on a jig stand: the stand's tag, carried with it), and a picture of the guide sheet under
them; ``--sim-offset PART=DU,DV[,DEG]`` moves a part and
``--sim-cover TAG`` puts a hand over a tag, for demos and tests.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace

import cv2
import numpy as np

from calibration.intrinsics import CameraIntrinsics
from drivers.sim.camera_scene import ImageItem, Occluder, PlaneScene, TagItem
from station.errors import ServiceError, station_errors

__all__ = ["aim_camera", "parse_offset", "sim_scene", "twin_intrinsics"]


#: The largest simulated offset: a metre moves a part off any table the camera sees (and 1e308 mm overflows the
#: camera's projection), a turn is every heading.
MAX_OFFSET_MM = 1000.0
MAX_OFFSET_DEG = 360.0


@station_errors
def parse_offset(text: str) -> tuple[str, tuple[float, float, float]]:
    """``PART=DU,DV[,DEG]`` (mm, mm, degrees) as ``(part, (du, dv, deg))``; a ServiceError naming ``sim_offset``."""
    name, _, values = str(text).partition("=")
    try:
        numbers = [float(v) for v in values.split(",")]
    except ValueError:
        numbers = []
    if not name or len(numbers) not in (2, 3) or not all(math.isfinite(n) for n in numbers):
        raise ServiceError(f"sim_offset must be PART=DU,DV[,DEG] (mm, mm, degrees), got {text!r}",
                           field="sim_offset", value=text)
    du, dv, deg = numbers[0], numbers[1], numbers[2] if len(numbers) == 3 else 0.0
    if max(abs(du), abs(dv)) > MAX_OFFSET_MM or abs(deg) > MAX_OFFSET_DEG:
        raise ServiceError(f"sim_offset must move a part at most {MAX_OFFSET_MM:g} mm and turn it at most "
                           f"{MAX_OFFSET_DEG:g} degrees each way, got {text!r}", field="sim_offset", value=text)
    return name, (du, dv, deg)


@station_errors
def sim_scene(guide, offsets: Mapping[str, Sequence[float]] | None = None, *, occluded: Sequence[int] = (),
              sheet: bool = True):
    """What a simulated camera sees: the guide's reference tags on the plane and every part tag at its part's
    designed pose and face height, a part moved by ``offsets[name] = (du, dv, deg)`` (rigidly: its tag turns about
    the part's origin), the tags ``occluded`` covered by a hand. With ``sheet``, a picture on the plane under them:
    the guide's outlines (thin) and every part's outline where it stands (filled, its footprint seen from the
    camera's side, drawn flat on the plane: context for the eye, never over a tag). Simulation only: a real camera
    sees the real parts.

    Raises
    ------
    ServiceError
        An offset of a part the guide has no tag on (``sim_offset``).
    """
    from calibration.check import jig_views  # heavy: scipy, shapely

    offsets = dict(offsets or {})
    tagged = {p.name: p for p in guide.parts if p.tag_views() or jig_views(guide, p)}
    unknown = sorted(set(offsets) - set(tagged))
    if unknown:
        raise ServiceError(f"sim_offset: no tagged part {unknown[0]!r}; tagged parts: {', '.join(tagged) or 'none'}",
                           field="sim_offset", value=unknown[0])
    tags = [TagItem(t.id, tuple(t.center_mm), t.size_mm) for t in guide.reference_tags]
    occluders = []
    for name, part in tagged.items():
        du, dv, turn = offsets.get(name, (0.0, 0.0, 0.0))
        c, s = math.cos(math.radians(turn)), math.sin(math.radians(turn))
        # the part's own tag, or its bodies', or the stand's it rests on: all move with the part
        for view in part.tag_views() or tuple(view for _, view in jig_views(guide, part)):
            offset = np.subtract(view.tag_center_mm, part.center_mm)
            centre = np.asarray(part.center_mm) + [du, dv] + [c * offset[0] - s * offset[1],
                                                              s * offset[0] + c * offset[1]]
            tags.append(TagItem(view.tag_id, (float(centre[0]), float(centre[1])), view.tag_size_mm,
                                view.tag_heading_deg + turn, view.tag_height_mm))
            if view.tag_id in occluded:  # a hand over the tag, just above it
                half = 0.8 * view.tag_size_mm
                square = np.array([[-half, -half], [half, -half], [half, half], [-half, half]]) + centre
                occluders.append(Occluder(square, view.tag_height_mm + 5.0))
    images = (ImageItem(*_sheet_picture(guide, offsets)),) if sheet else ()
    return PlaneScene(tags=tuple(tags), images=images, occluders=tuple(occluders))


def _moved_outline(part, offset):
    from shapely import affinity  # heavy: shapely

    du, dv, turn = offset
    return affinity.translate(affinity.rotate(part.outline, turn, origin=tuple(part.center_mm)), du, dv)


def _sheet_picture(guide, offsets, px_per_mm: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """The picture under the parts (see :func:`sim_scene`) and its corners on the plane (top-left first)."""
    u0, v0, u1, v1 = guide.extent_mm
    width, height = int(np.ceil((u1 - u0) * px_per_mm)), int(np.ceil((v1 - v0) * px_per_mm))
    picture = np.full((height, width, 3), 245, dtype=np.uint8)

    def pixels(ring) -> np.ndarray:  # row 0 is the picture's top (largest v); fixed point, 4 fractional bits
        ring = np.asarray(ring)[:, :2]
        return np.round(16 * np.column_stack([(ring[:, 0] - u0) * px_per_mm,
                                              (v1 - ring[:, 1]) * px_per_mm])).astype(np.int32)

    for part in guide.parts:
        body = _moved_outline(part, offsets.get(part.name, (0.0, 0.0, 0.0)))
        for polygon in getattr(body, "geoms", [body]):
            if not polygon.is_empty:
                cv2.fillPoly(picture, [pixels(polygon.exterior.coords)], (196, 164, 120), cv2.LINE_AA, 4)
        for polygon in getattr(part.outline, "geoms", [part.outline]):
            if not polygon.is_empty:
                cv2.polylines(picture, [pixels(polygon.exterior.coords)], True, (110, 110, 110), 1, cv2.LINE_AA, 4)
    corners = np.array([[u0, v1], [u1, v1], [u1, v0], [u0, v0]], dtype=float)
    return picture, corners


@station_errors
def aim_camera(camera, guide) -> None:
    """Move a simulated camera told no ``target`` in the plane so that its optical axis meets the guide's middle
    (as a maker sets the camera up over the sheets): the camera translated by d, ``t' = t - R d``."""
    model = camera.camera_model
    u0, v0, u1, v1 = guide.extent_mm
    rotation = cv2.Rodrigues(np.asarray(model.rvec, dtype=float))[0]
    axis = rotation.T @ np.array([0.0, 0.0, 1.0])  # the optical axis in plane coordinates
    centre = np.asarray(model.centre_mm, dtype=float)
    if abs(axis[2]) < 1e-9:
        return
    hit = centre - centre[2] / axis[2] * axis  # where the optical axis meets the plane now
    shift = np.array([(u0 + u1) / 2 - hit[0], (v0 + v1) / 2 - hit[1], 0.0])
    camera.place(replace(model, tvec=np.asarray(model.tvec, dtype=float) - rotation @ shift))


@station_errors
def twin_intrinsics(camera, url: str) -> CameraIntrinsics:
    """A simulated camera's own lens, as a calibration would give it."""
    model = camera.camera_model
    return CameraIntrinsics(np.asarray(model.camera_matrix, float), np.asarray(model.dist_coeffs, float),
                            tuple(int(v) for v in model.image_size), name=f"{url} (the simulated camera's own)")
