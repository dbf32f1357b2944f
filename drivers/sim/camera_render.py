"""Render what a simulated camera sees of the guide plane, exactly, and the ground truth of every tag.

Geometry
--------
Every output pixel is cut into ``supersample x supersample`` samples. A sample's ray goes through the lens model
backwards: its pixel position is undistorted (``cv2.undistortPointsIter``, iterated to 1e-9 px, cached per camera
and interpolated between pixel centres) into a ray direction, which is intersected with the plane of each item at the
item's height. The item's picture (a tag's cells, an image, an occluder's outline) is sampled there (``cv2.remap``),
the items drawn from the lowest up (at one height: pictures, then occluders, then tags, which are printed on
them; else in the scene's order).

A solid (:class:`~drivers.sim.camera_scene.Solid`: a part's body, a jig's plate) is drawn as flat occluders: each
convex piece is cut into slabs at the heights of the flat items inside it (so none of them lies inside a slab), and
each slab is drawn at its middle height as its silhouette seen from the camera's centre, which is the slab's points
projected along the rays through that centre onto that height. Every ray that meets the slab crosses that polygon
and no other ray does, so what the slab hides and what hides it are exact in perspective; between two solids'
slabs the nearer middle is drawn last (exact for convex pieces that do not interpenetrate along the ray).
The samples are averaged into the pixel (``cv2.resize`` INTER_AREA), then exposure, vignetting, blur, noise and JPEG
are applied in that order.

Textures are sampled bilinearly at about one texel per sample, so an edge between two cells is a symmetric ramp
centred exactly on the edge: the averaged pixel keeps the edge's position to a small fraction of a pixel (a point
sample would quantize it to a third of a pixel).

Tags come from OpenCV's ``cv2.aruco.DICT_APRILTAG_36h11`` bitmaps turned 180 degrees, which is the upstream
tag36h11 as printed (written here again on purpose: the renderer shares no code with the station's tag drawing or its
detector), with their white border (one cell wide).

Truth and the detector's pixels
-------------------------------
:class:`~drivers.sim.camera_scene.TagTruth` corners are OpenCV pixel centres (``cv2.projectPoints`` of the black
square's corners). pupil-apriltags puts pixel edges at integers, so its corners are half a pixel larger: OpenCV =
pupil - 0.5 (tests/drivers/test_camera_render.py checks the sign; the other one is a pixel off). On sharp renders the
detector's corners then agree on average to 0.01 px, 90% within 0.15 px; on tag edges parallel to the image axes it
has a bias of its own of about 0.1 px towards -x, -y, where the picture is exact (its darkness centroid is where the
geometry puts it, to 0.03 px).

Light
-----
The projector's light (:meth:`drivers.sim.projector.SimulatedProjector.light`) lands on whatever surface a sample
sees: the surface's (u, v) is taken through ``plane_from_pixel`` (the projector's mapping at h = 0; its parallax on a
raised surface is not modelled) and the surface's colour is multiplied by ``1 + LIGHT_GAIN * light / 255``. The
table's light goes through fixed-point remap tables cached per camera and placement (1/32 projector pixel; about
110 MB for a 1080p camera at supersample 3; :func:`forget_caches` frees them).
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from dataclasses import dataclass, replace

import cv2
import numpy as np

from common.opencv import undistort_points
from drivers.errors import SimConfigError
from drivers.sim.camera_scene import (
    CameraModel,
    ImageItem,
    Occluder,
    PlaneScene,
    RenderOptions,
    Solid,
    TagItem,
    TagTruth,
    tag_corners_mm,
)

__all__ = ["DEFAULT_OPTIONS", "LIGHT_GAIN", "forget_caches", "TAG_BLACK", "TAG_WHITE", "render", "tag_cells_upstream"]

#: How bright the projector's full white makes a surface, relative to the room's light on it.
LIGHT_GAIN = 0.6
#: Printed black and paper white of a tag (RGB).
TAG_BLACK = (28.0, 28.0, 30.0)
TAG_WHITE = (238.0, 238.0, 232.0)
#: Output rows rendered at a time (bounds the memory of the supersampled buffer).
BAND_ROWS = 64
#: Largest texture side (cv2.remap takes sources below 32767 pixels).
MAX_TEXTURE = 4096

#: The options :func:`render` uses when given none.
DEFAULT_OPTIONS = RenderOptions()

_GRIDS: OrderedDict[bytes, np.ndarray] = OrderedDict()
_LIGHT_TABLES: dict = {}
_GRIDS_LOCK = threading.Lock()


@dataclass(frozen=True)
class _Layer:
    height: float
    texture: np.ndarray        # float32 (h, w, 4), premultiplied RGB + alpha, a transparent texel all round
    tex_from_plane: np.ndarray  # 3x3: plane (u, v, 1) mm -> texture pixel (x, y, 1)
    outline_mm: np.ndarray     # (n, 2) polygon covering what it hides
    bbox: tuple[int, int, int, int] | None  # x0, y0, x1, y1 pixels (None: not in view)
    kind: int = 0              # 0 picture, 1 occluder, 2 tag
    index: int = 0             # its place in the scene's tuple of its kind


def tag_cells_upstream(tag_id: int) -> np.ndarray:
    """The 10 x 10 cells (True = white) of tag36h11 ``tag_id`` with its border, row 0 the top as printed (upstream
    orientation: OpenCV's bitmap turned 180 degrees)."""
    if isinstance(tag_id, bool) or not isinstance(tag_id, (int, np.integer)) or not 0 <= int(tag_id) < 587:
        raise SimConfigError(f"tag id: expected an integer from 0 to 586 (tag36h11), got {tag_id!r}")
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    cells = np.ones((10, 10), dtype=bool)
    cells[1:-1, 1:-1] = np.rot90(dictionary.generateImageMarker(int(tag_id), 8) > 0, 2)
    return cells


def render(scene: PlaneScene, camera: CameraModel,
           options: RenderOptions = DEFAULT_OPTIONS) -> tuple[np.ndarray, tuple[TagTruth, ...]]:
    """The camera's RGB uint8 image ``(h, w, 3)`` of ``scene`` and the truth of every tag (in the scene's order).

    Raises
    ------
    SimConfigError
        A bad option or scene item, naming it.
    """
    _check_options(options)
    samples = int(options.supersample)
    width, height = camera.image_size
    layers = _layers(scene, camera, samples)
    grid = _normalized_grid(camera)
    rotation, centre = camera.rotation.astype(np.float32), camera.centre_mm
    light = _light_source(scene.light)
    tables = _table_maps(camera, light[1], grid, samples) if light is not None else None
    background = np.asarray(scene.background, dtype=np.float32).reshape(3)
    image = np.empty((height, width, 3), dtype=np.float32)
    for y0 in range(0, height, BAND_ROWS):
        y1 = min(height, y0 + BAND_ROWS)
        band = np.empty(((y1 - y0) * samples, width * samples, 3), dtype=np.float32)
        band[:] = background
        seen = np.zeros(band.shape[:2], dtype=np.float32)  # the height of the surface each sample sees
        for layer in layers:
            if layer.bbox is None or layer.bbox[3] <= y0 or layer.bbox[1] >= y1:
                continue
            x0, x1 = layer.bbox[0], layer.bbox[2]
            r0, r1 = max(layer.bbox[1], y0), min(layer.bbox[3], y1)
            a, b, down = _rays(grid, rotation, x0, x1, r0, r1, samples)
            k = layer.height - centre[2]
            to_plane = np.array([[k, 0.0, centre[0]], [0.0, k, centre[1]], [0.0, 0.0, 1.0]])
            tx, ty = _apply(layer.tex_from_plane @ to_plane, a, b)
            hit = down if k < 0 else ~down  # the item's plane is in front of the camera
            tx[~hit] = -10.0
            texel = cv2.remap(layer.texture, tx, ty, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                              borderValue=(0, 0, 0, 0))
            alpha = texel[..., 3:4]
            rows = slice((r0 - y0) * samples, (r1 - y0) * samples)
            cols = slice(x0 * samples, x1 * samples)
            band[rows, cols] = band[rows, cols] * (1.0 - alpha) + texel[..., :3]
            seen[rows, cols] = np.where(alpha[..., 0] > 0.5, np.float32(layer.height), seen[rows, cols])
        if light is not None:
            raised = [(layer.bbox[0], max(layer.bbox[1], y0), layer.bbox[2], min(layer.bbox[3], y1))
                      for layer in layers if layer.height != 0 and layer.bbox is not None
                      and layer.bbox[1] < y1 and layer.bbox[3] > y0]
            _add_light(band, seen, light, tables[y0 // BAND_ROWS], raised, grid, rotation, centre, y0, samples)
        image[y0:y1] = cv2.resize(band, (width, y1 - y0), interpolation=cv2.INTER_AREA)
    return _finish(image, options), _truth(scene, camera, layers)


# -- the lens -----------------------------------------------------------------------------------------------------


def forget_caches() -> None:
    """Free the cached lens grids and light tables (they are made again when needed)."""
    with _GRIDS_LOCK:
        _GRIDS.clear()
        _LIGHT_TABLES.clear()


def _normalized_grid(camera: CameraModel) -> np.ndarray:
    """Normalized image coordinates (x/z, y/z) of every pixel centre, with one pixel more all round, float32
    ``(h + 2, w + 2, 2)``; cached per intrinsics (undistorting two million points takes most of a second)."""
    key = b"".join(np.ascontiguousarray(v, dtype=float).tobytes() for v in
                   (camera.camera_matrix, camera.dist_coeffs, np.array(camera.image_size, dtype=float)))
    with _GRIDS_LOCK:
        if key in _GRIDS:
            _GRIDS.move_to_end(key)
            return _GRIDS[key]
    width, height = camera.image_size
    xs, ys = np.meshgrid(np.arange(-1, width + 1, dtype=float), np.arange(-1, height + 1, dtype=float))
    pixels = np.stack([xs, ys], axis=-1).reshape(-1, 1, 2)
    if np.any(camera.dist_coeffs):
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-9)
        normal = undistort_points(pixels, camera.camera_matrix, camera.dist_coeffs, np.eye(3), np.eye(3),
                                  criteria)
    else:
        matrix = camera.camera_matrix
        y = (pixels[..., 1] - matrix[1, 2]) / matrix[1, 1]
        normal = np.stack([(pixels[..., 0] - matrix[0, 2] - matrix[0, 1] * y) / matrix[0, 0], y], axis=-1)
    grid = normal.reshape(height + 2, width + 2, 2).astype(np.float32)
    grid.flags.writeable = False
    with _GRIDS_LOCK:
        _GRIDS[key] = grid
        while len(_GRIDS) > 4:
            _GRIDS.popitem(last=False)
    return grid


def _rays(grid: np.ndarray, rotation: np.ndarray, x0: int, x1: int, y0: int, y1: int,
          samples: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For the samples of pixels [x0, x1) x [y0, y1): the ray direction's du/dh and dv/dh, and whether it goes
    down (towards -h). Sample i of pixel x sits at x - 0.5 + (i + 0.5) / samples, which is where cv2.resize's
    INTER_LINEAR puts it when the grid (with its margin of one pixel) is scaled up by ``samples``."""
    patch = grid[y0:y1 + 2, x0:x1 + 2]
    if samples > 1:
        patch = cv2.resize(patch, None, fx=samples, fy=samples, interpolation=cv2.INTER_LINEAR)
        patch = patch[samples:-samples, samples:-samples]
    else:
        patch = patch[1:-1, 1:-1]
    xn, yn = patch[..., 0], patch[..., 1]
    # plane direction D = R^T (xn, yn, 1)
    du = rotation[0, 0] * xn + rotation[1, 0] * yn + rotation[2, 0]
    dv = rotation[0, 1] * xn + rotation[1, 1] * yn + rotation[2, 1]
    dh = rotation[0, 2] * xn + rotation[1, 2] * yn + rotation[2, 2]
    down = dh < 0
    dh = np.where(np.abs(dh) < 1e-9, np.float32(1e-9), dh)
    return du / dh, dv / dh, down


def _apply(matrix: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``matrix`` (3x3) applied to the points (a, b, 1), as float32 maps for cv2.remap."""
    m = [[float(v) for v in row] for row in matrix]  # Python floats keep the arithmetic in float32
    w = m[2][0] * a + m[2][1] * b + m[2][2]
    x = (m[0][0] * a + m[0][1] * b + m[0][2]) / w
    y = (m[1][0] * a + m[1][1] * b + m[1][2]) / w
    return x.astype(np.float32), y.astype(np.float32)


# -- what lies on the plane -------------------------------------------------------------------------------------


def _layers(scene: PlaneScene, camera: CameraModel, samples: int) -> list[_Layer]:
    """The scene's items as textured layers, in drawing order."""
    # at one height: pictures, then occluders (a part's top face), then tags (printed on those faces)
    items = [(float(item.height_mm), 0, n, item) for n, item in enumerate(scene.images)]
    items += [(float(item.height_mm), 1, n, item) for n, item in enumerate(scene.occluders)]
    items += [(float(item.height_mm), 2, n, item) for n, item in enumerate(scene.tags)]
    flat = sorted({height for height, *_ in items})
    slabs = [slab for solid in scene.solids for slab in _solid_slabs(solid, flat, camera)]
    items += [(float(item.height_mm), 1, len(scene.occluders) + n, item) for n, item in enumerate(slabs)]
    layers = []
    for _, kind, index, item in sorted(items, key=lambda entry: entry[:3]):
        maker = (_image_layer, _occluder_layer, _tag_layer)[kind]
        layers.append(replace(maker(item, camera, samples), kind=kind, index=index))
    return layers


def _solid_slabs(solid: Solid, flat: list[float], camera: CameraModel) -> list[Occluder]:
    """A solid's convex pieces as flat occluders (module notes): each piece cut at the heights ``flat`` inside it,
    at 0 (what lies behind the plane is hidden by it) and 1 mm short of the camera's centre, each slab its silhouette
    from the camera's centre at its middle height."""
    centre = camera.centre_mm
    nearest = float(centre[2]) - 1.0
    if not isinstance(solid, Solid):
        raise SimConfigError(f"scene solids: expected Solid items, got {type(solid).__name__}")
    occluders = []
    for number, piece in enumerate(solid.pieces):
        points = np.asarray(piece, dtype=float)
        if points.ndim != 2 or points.shape[1] != 3 or len(points) < 3 or not np.isfinite(points).all():
            raise SimConfigError(f"solid piece {number}: expected (n, 3) finite (u, v, h) points with n >= 3, got "
                                 f"{points.shape}")
        low, high = max(0.0, float(points[:, 2].min())), min(nearest, float(points[:, 2].max()))
        if not high > low:
            continue  # behind the plane, or reaching the camera (it would fill the view)
        cuts = [low, *(h for h in flat if low < h < high), high]
        for a, b in zip(cuts[:-1], cuts[1:]):
            slab = _clip_slab(points, a, b)
            if len(slab) < 3:
                continue
            middle = 0.5 * (a + b)
            scale = (middle - centre[2]) / (slab[:, 2] - centre[2])
            seen = centre[:2] + scale[:, None] * (slab[:, :2] - centre[:2])
            hull = cv2.convexHull(seen.astype(np.float32), returnPoints=False).ravel()
            polygon = seen[hull]
            if len(polygon) >= 3 and abs(_area(polygon)) > 1e-6:
                occluders.append(Occluder(polygon, middle, solid.color))
    return occluders


def _clip_slab(points: np.ndarray, low: float, high: float) -> np.ndarray:
    """Points whose hull is the hull of ``points`` cut to ``low <= h <= high``: the points inside, and where every
    segment between two of them crosses either cut (each edge of the hull crossing a cut is one of them)."""
    h = points[:, 2]
    below, above = points[h < low], points[h > high]
    inside = points[(h >= low) & (h <= high)]
    found = [inside]
    for level, near, far in ((low, below, points[h >= low]), (high, above, points[h <= high])):
        if len(near) and len(far):
            t = (level - near[:, 2])[:, None] / (far[None, :, 2] - near[:, None, 2])
            crossing = near[:, None, :] + t[..., None] * (far[None, :, :] - near[:, None, :])
            found.append(crossing.reshape(-1, 3))
    clipped = np.concatenate(found)
    clipped[:, 2] = np.clip(clipped[:, 2], low, high)
    return clipped


def _tag_layer(tag: TagItem, camera: CameraModel, samples: int) -> _Layer:
    if tag.family != "tag36h11":
        raise SimConfigError(f"tag {tag.tag_id}: family: expected 'tag36h11', got {tag.family!r}")
    if not (math.isfinite(tag.size_mm) and tag.size_mm > 0 and math.isfinite(tag.heading_deg)
            and math.isfinite(tag.height_mm)):
        raise SimConfigError(f"tag {tag.tag_id}: expected a size > 0 and finite heading and height, got size "
                             f"{tag.size_mm!r}, heading {tag.heading_deg!r}, height {tag.height_mm!r}")
    cells = tag_cells_upstream(tag.tag_id)
    outline = tag_corners_mm(tag, 10.0 / 8.0)
    quad = camera.project(np.column_stack([tag_corners_mm(tag), np.full(4, tag.height_mm)]))
    cell_samples = math.sqrt(abs(_area(quad))) / 8.0 * samples
    per_cell = int(min(64, max(2, math.ceil(cell_samples))))
    grey = np.kron(cells, np.ones((per_cell, per_cell), dtype=bool))
    rgb = np.where(grey[..., None], np.float32(TAG_WHITE), np.float32(TAG_BLACK)).astype(np.float32)
    theta = math.radians(tag.heading_deg)
    right = np.array([math.cos(theta), math.sin(theta)])
    up = np.array([-math.sin(theta), math.cos(theta)])
    centre = np.asarray(tag.center_mm, dtype=float)
    scale = per_cell / (tag.size_mm / 8.0)  # texels per mm
    # texel x = (5 cells + along "right") * per_cell - 0.5, + 1 for the transparent margin; y runs down the print
    tex = np.array([[scale * right[0], scale * right[1], 5 * per_cell + 0.5 - scale * right.dot(centre)],
                    [-scale * up[0], -scale * up[1], 5 * per_cell + 0.5 + scale * up.dot(centre)],
                    [0.0, 0.0, 1.0]])
    return _Layer(float(tag.height_mm), _premultiplied(rgb), tex, outline, _bbox(outline, tag.height_mm, camera))


def _image_layer(item: ImageItem, camera: CameraModel, samples: int) -> _Layer:
    picture = np.asarray(item.image)
    corners = np.asarray(item.corners_mm, dtype=float)
    if picture.dtype != np.uint8 or picture.ndim not in (2, 3) or (picture.ndim == 3 and picture.shape[2] != 3) \
            or min(picture.shape[:2]) < 1:
        raise SimConfigError(f"image item: image: expected uint8 HxW or HxWx3, got {picture.dtype} {picture.shape}")
    if corners.shape != (4, 2) or not np.isfinite(corners).all() or abs(_area(corners)) < 1e-9:
        raise SimConfigError(f"image item: corners_mm: expected 4 distinct (u, v) corners, got {corners.tolist()}")
    rgb = np.repeat(picture[..., None], 3, axis=2) if picture.ndim == 2 else picture
    quad = camera.project(np.column_stack([corners, np.full(4, item.height_mm)]))
    texels = (rgb.shape[0] + rgb.shape[1]) * 2.0
    seen = _perimeter(quad) * samples
    factor = max(texels / max(seen, 1.0), (max(rgb.shape[:2]) + 2) / MAX_TEXTURE)
    if factor > 1.5:  # minified: average it first, else the samples would alias
        size = (max(2, round(rgb.shape[1] / factor)), max(2, round(rgb.shape[0] / factor)))
        rgb = cv2.resize(rgb, size, interpolation=cv2.INTER_AREA)
    h, w = rgb.shape[:2]
    target = np.array([[0.5, 0.5], [w + 0.5, 0.5], [w + 0.5, h + 0.5], [0.5, h + 0.5]], dtype=np.float32)
    tex = cv2.getPerspectiveTransform(corners.astype(np.float32), target).astype(float)
    return _Layer(float(item.height_mm), _premultiplied(rgb.astype(np.float32)), tex, corners,
                  _bbox(corners, item.height_mm, camera))


def _occluder_layer(item: Occluder, camera: CameraModel, samples: int) -> _Layer:
    polygon = np.asarray(item.polygon_mm, dtype=float)
    if polygon.ndim != 2 or polygon.shape[1] != 2 or len(polygon) < 3 or not np.isfinite(polygon).all():
        raise SimConfigError(f"occluder: polygon_mm: expected (n, 2) plane points with n >= 3, got {polygon.shape}")
    image = camera.project(np.column_stack([polygon, np.full(len(polygon), item.height_mm)]))
    plane_area, image_area = abs(_area(polygon)), abs(_area(image))
    per_mm = samples * math.sqrt(image_area / plane_area) if plane_area > 1e-9 and image_area > 1e-9 else 1.0
    low, high = polygon.min(axis=0), polygon.max(axis=0)
    per_mm = min(per_mm, (MAX_TEXTURE - 8) / max(float(np.max(high - low)), 1e-9))
    size = np.ceil((high - low) * per_mm).astype(int) + 6
    tex = np.array([[per_mm, 0.0, 3.0 - per_mm * low[0]], [0.0, -per_mm, 3.0 + per_mm * high[1]], [0.0, 0.0, 1.0]])
    points = np.column_stack([polygon, np.ones(len(polygon))]) @ tex.T
    mask = np.zeros((size[1], size[0]), dtype=np.uint8)
    cv2.fillPoly(mask, [np.round(points[:, :2] * 16).astype(np.int32)], 255, cv2.LINE_AA, shift=4)
    alpha = mask.astype(np.float32)[..., None] / 255.0
    texture = np.concatenate([alpha * np.asarray(item.color, dtype=np.float32), alpha], axis=2)
    return _Layer(float(item.height_mm), np.ascontiguousarray(texture), tex, polygon,
                  _bbox(polygon, item.height_mm, camera))


def _premultiplied(rgb: np.ndarray) -> np.ndarray:
    """RGBA float32 with alpha 1 and a transparent texel all round (so an item's outer edge is smooth too)."""
    h, w = rgb.shape[:2]
    texture = np.zeros((h + 2, w + 2, 4), dtype=np.float32)
    texture[1:-1, 1:-1, :3] = rgb
    texture[1:-1, 1:-1, 3] = 1.0
    return texture


def _bbox(outline: np.ndarray, height: float, camera: CameraModel) -> tuple[int, int, int, int] | None:
    """The pixels an item may cover: its outline (edges sampled densely, for the lens' curve) projected, padded."""
    closed = np.vstack([outline, outline[:1]])
    t = np.linspace(0.0, 1.0, 17)[:-1, None]
    points = np.vstack([p + t * (q - p) for p, q in zip(closed[:-1], closed[1:], strict=True)])
    points = np.column_stack([points, np.full(len(points), height)])
    width, size_h = camera.image_size
    if np.any(camera.depth(points) <= 1e-6):  # partly behind the camera: its picture may be anywhere
        return 0, 0, width, size_h
    pixels = camera.project(points)
    x0, y0 = np.floor(pixels.min(axis=0)).astype(int) - 2
    x1, y1 = np.ceil(pixels.max(axis=0)).astype(int) + 3
    x0, y0, x1, y1 = max(0, x0), max(0, y0), min(width, x1), min(size_h, y1)
    return (int(x0), int(y0), int(x1), int(y1)) if x1 > x0 and y1 > y0 else None


def _area(polygon: np.ndarray) -> float:
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _perimeter(polygon: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(np.vstack([polygon, polygon[:1]]), axis=0), axis=1).sum())


# -- light, finish, truth -----------------------------------------------------------------------------------------


def _light_source(light: dict | None) -> tuple[np.ndarray, np.ndarray] | None:
    """(light image uint8, pixel_from_plane) or None when nothing lands (no light, blank, no placement)."""
    if light is None or light.get("blank") or light.get("plane_from_pixel") is None:
        return None
    image = np.asarray(light.get("image"))
    matrix = np.asarray(light["plane_from_pixel"], dtype=float)
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8 or matrix.shape != (3, 3):
        raise SimConfigError(f"scene light: expected an (h, w, 3) uint8 image and a 3x3 plane_from_pixel, got "
                             f"{image.dtype} {image.shape} and {matrix.shape}")
    if not image.any():
        return None
    return np.ascontiguousarray(image), np.linalg.inv(matrix)


def _table_maps(camera: CameraModel, pixel_from_plane: np.ndarray, grid: np.ndarray, samples: int) -> list:
    """For each band of rows, the fixed-point remap tables (``cv2.convertMaps``) from the samples to projector
    pixels on the table (h = 0). Cached for the last camera and placement: a projector mapping shows dozens of
    frames through the same geometry, and the tables are most of the light's cost."""
    key = b"".join(np.ascontiguousarray(v, dtype=float).tobytes() for v in
                   (camera.camera_matrix, camera.dist_coeffs, camera.rvec, camera.tvec, pixel_from_plane,
                    np.array([*camera.image_size, samples, BAND_ROWS], dtype=float)))
    with _GRIDS_LOCK:
        if _LIGHT_TABLES.get("key") == key:
            return _LIGHT_TABLES["maps"]
    width, height = camera.image_size
    rotation = camera.rotation.astype(np.float32)
    cu, cv, ch = (float(v) for v in camera.centre_mm)
    maps = []
    for y0 in range(0, height, BAND_ROWS):
        a, b, down = _rays(grid, rotation, 0, width, y0, min(height, y0 + BAND_ROWS), samples)
        px, py = _apply(pixel_from_plane, cu - ch * a, cv - ch * b)
        px[~down] = -10.0
        maps.append(cv2.convertMaps(px, py, cv2.CV_16SC2))
    with _GRIDS_LOCK:
        _LIGHT_TABLES.update(key=key, maps=maps)
    return maps


def _add_light(band: np.ndarray, seen: np.ndarray, light: tuple[np.ndarray, np.ndarray], table: tuple,
               raised: list[tuple[int, int, int, int]], grid: np.ndarray, rotation: np.ndarray, centre: np.ndarray,
               y0: int, samples: int) -> None:
    """Multiply the band's colours by the projector's light on the surface each sample sees: the table's through
    the cached tables (5-bit sub-pixel weights: 1/32 projector pixel), a raised item's exactly, at its height."""
    image, pixel_from_plane = light
    lit = cv2.remap(image, table[0], table[1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                    borderValue=(0, 0, 0))
    for x0, r0, x1, r1 in raised:  # pixels [x0, x1) x [r0, r1) where an item above the table may be seen
        rows, cols = slice((r0 - y0) * samples, (r1 - y0) * samples), slice(x0 * samples, x1 * samples)
        a, b, down = _rays(grid, rotation, x0, x1, r0, r1, samples)
        k = seen[rows, cols] - np.float32(centre[2])
        px, py = _apply(pixel_from_plane, np.float32(centre[0]) + k * a, np.float32(centre[1]) + k * b)
        px[~down] = -10.0
        exact = cv2.remap(image, px, py, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0))
        lit[rows, cols] = np.where((seen[rows, cols] != 0)[..., None], exact, lit[rows, cols])
    band *= 1.0 + lit.astype(np.float32) * np.float32(LIGHT_GAIN / 255.0)


def _finish(image: np.ndarray, options: RenderOptions) -> np.ndarray:
    """Exposure, vignetting, blur, noise, then JPEG, on the float image."""
    height, width = image.shape[:2]
    image *= np.float32(options.exposure)
    if options.vignetting:
        ys, xs = np.ogrid[:height, :width]
        cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
        r2 = ((xs - cx) ** 2 + (ys - cy) ** 2) / (cx * cx + cy * cy)
        image *= (1.0 - options.vignetting * r2).astype(np.float32)[..., None]
    if options.blur_px > 0:
        image = cv2.GaussianBlur(image, (0, 0), options.blur_px)
    if options.noise > 0:
        rng = np.random.default_rng(options.seed)
        image += rng.standard_normal(image.shape, dtype=np.float32) * np.float32(options.noise)
    np.clip(image, 0.0, 255.0, out=image)
    image += np.float32(0.5)  # then truncation rounds
    result = image.astype(np.uint8)
    if options.jpeg_quality is not None:
        ok, data = cv2.imencode(".jpg", cv2.cvtColor(result, cv2.COLOR_RGB2BGR),
                                [cv2.IMWRITE_JPEG_QUALITY, int(options.jpeg_quality)])
        result = cv2.cvtColor(cv2.imdecode(data, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    return result


def _check_options(options: RenderOptions) -> None:
    checks = (("supersample", isinstance(options.supersample, (int, np.integer)) and 1 <= options.supersample <= 8,
               "a whole number from 1 to 8"),
              ("blur_px", math.isfinite(options.blur_px) and options.blur_px >= 0, "a number >= 0"),
              ("noise", math.isfinite(options.noise) and options.noise >= 0, "a number >= 0"),
              ("vignetting", 0.0 <= options.vignetting <= 1.0, "a number from 0 to 1"),
              ("exposure", math.isfinite(options.exposure) and options.exposure > 0, "a number > 0"),
              ("jpeg_quality", options.jpeg_quality is None or (isinstance(options.jpeg_quality, (int, np.integer))
                                                                and 1 <= options.jpeg_quality <= 100),
               "None or a whole number from 1 to 100"))
    for name, ok, expected in checks:
        if not ok:
            raise SimConfigError(f"render option {name}: expected {expected}, got {getattr(options, name)!r}")


def _truth(scene: PlaneScene, camera: CameraModel, layers: list[_Layer]) -> tuple[TagTruth, ...]:
    """Each tag's corners and centre in the image, and whether all of it (with its border) is in view and
    unhidden: a grid of points on it is checked against every item drawn after it, along the ray to the camera."""
    width, height = camera.image_size
    centre = camera.centre_mm
    tag_layers = {layer.index: n for n, layer in enumerate(layers) if layer.kind == 2}
    truths = []
    for index, tag in enumerate(scene.tags):
        mine = tag_layers[index]
        h = float(tag.height_mm)
        corners = camera.project(np.column_stack([tag_corners_mm(tag), np.full(4, h)]))
        centre_px = camera.project(np.array([[*tag.center_mm, h]]))[0]
        border = tag_corners_mm(tag, 10.0 / 8.0)
        s, t = np.meshgrid(np.linspace(0, 1, 11), np.linspace(0, 1, 11))
        s, t = s.ravel()[:, None], t.ravel()[:, None]
        points = (border[0] + s * (border[1] - border[0]) + t * (border[3] - border[0]))
        points3 = np.column_stack([points, np.full(len(points), h)])
        border_px = camera.project(np.column_stack([border, np.full(4, h)]))
        visible = bool(np.all(camera.depth(points3) > 0)
                       and np.all((border_px >= -0.5) & (border_px <= [width - 0.5, height - 0.5]))
                       and _unfolded(camera, np.column_stack([border, np.full(4, h)]), border_px))
        if visible:
            for other in layers[mine + 1:]:
                scale = (other.height - centre[2]) / (h - centre[2]) if h != centre[2] else math.inf
                if not math.isfinite(scale) or scale <= 0:
                    continue
                hit = centre[:2] + scale * (points - centre[:2])
                if np.any(_inside(hit, other.outline_mm)):
                    visible = False
                    break
        truths.append(TagTruth(int(tag.tag_id), (float(tag.center_mm[0]), float(tag.center_mm[1])),
                               float(tag.heading_deg), h, float(tag.size_mm), corners, centre_px, visible))
    return tuple(truths)


def _unfolded(camera: CameraModel, points: np.ndarray, pixels: np.ndarray) -> bool:
    """Whether the lens model maps these points (n, 3) to ``pixels`` one to one. A strong barrel distortion's
    polynomial turns back beyond some radius: a point far outside the view then "projects" inside the image
    (cv2.projectPoints says so), where the camera does not see it; undistorting its pixel gives another ray."""
    if not np.any(camera.dist_coeffs):
        return True
    local = points @ camera.rotation.T + camera.tvec
    ideal = local[:, :2] / local[:, 2:3]
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-9)
    back = undistort_points(pixels.reshape(-1, 1, 2).astype(np.float64), camera.camera_matrix,
                            camera.dist_coeffs, np.eye(3), np.eye(3), criteria).reshape(-1, 2)
    return bool(np.abs(back - ideal).max() < 1e-4)


def _inside(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Whether each point (n, 2) lies inside ``polygon`` (m, 2) (even-odd rule, vectorized)."""
    x, y = points[:, 0:1], points[:, 1:2]
    x0, y0 = polygon[:, 0][None, :], polygon[:, 1][None, :]
    x1, y1 = np.roll(polygon[:, 0], -1)[None, :], np.roll(polygon[:, 1], -1)[None, :]
    crosses = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        at = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    return (np.count_nonzero(crosses & (x < at), axis=1) % 2) == 1
