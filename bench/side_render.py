"""An independent renderer of the side camera's frame, for checking the side view against code it shares nothing with.

The camera twin (:mod:`drivers.sim.camera_render`) casts rays through OpenCV's lens model onto planes parallel to the
board, and :mod:`station.services.check_side` puts the tags on those planes. This module does neither: it builds the
camera from a look-at in the scene (metres, the scenario's world frame), carries each jig's face tag in three
dimensions with its part (the part's world pose at the moved layout times the inverse of its designed pose, applied
to the tag's cells on the jig's face), projects every tag cell through a plain pinhole written out here (no OpenCV),
and fills the cells as polygons with Pillow on an 8x supersampled patch per tag (Pillow's own rasteriser),
averaged down, blurred with Pillow's Gaussian.

What stands between the camera and the board is ray cast, in the world (metres), against the scene graph's
collision shapes as they are (not their hulls): a box by its slabs in its own frame, a sphere by the quadratic, a
cylinder by its side and its two caps, a capsule by its cylinder and two end spheres; a jig stand's plate (its
outline, as thick as its sheet, carried with its part as the tag is) and its base (its footprint on the table) by
the segment a ray runs between the prism's two faces, tested against the outline (inside at either face, or
crossing an edge). A sample sees the nearest hit in front of the board's plane; a tag's sample is hidden when a hit
is nearer the camera than the tag. Solids are drawn flat grey (2x2 samples a pixel; 8x8 inside a tag's patch).
Its only shared inputs are the scenario's scene graph, the jig's face frame and outline, and the tags' bit patterns.
"""

from __future__ import annotations

import numpy as np
from PIL import Image, ImageDraw, ImageFilter

from calibration.intrinsics import CameraIntrinsics
from design.contraption.geometry import world_poses
from design.contraption.primitives import body_specs
from vision.tags import tag_cells

__all__ = ["independent_side_frame"]

#: The grey of a solid in the frame (parts and jigs alike) and of everything else that is not a tag.
SOLID_GREY = 96.0
BACKGROUND_GREY = 170.0

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


class _Shapes:
    """The scene's solids for ray casting (world mm): ``distance(item, origin, directions)`` is each ray's distance
    to the solid ``item`` (inf: it misses), the rays unit vectors from ``origin``."""

    def __init__(self) -> None:
        self.items = []  # (kind, its shape's data, points whose hull holds it)

    def add_part(self, kind: str, dims, pose) -> None:
        rotation = pose.rotation.as_matrix()
        dims = np.asarray(dims, float) * 1000.0
        signs = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)], float)
        centre = pose.position * 1000.0
        if kind == "box":  # bounds only: points the shape lies within the hull of
            corners = centre + (signs * dims) @ rotation.T
        elif kind == "sphere":
            corners = centre + signs * dims[0]
        else:  # a cylinder's or capsule's two ends, a cube round each as wide as it (and a capsule's cap)
            ends = centre + np.outer([-dims[1] / 2.0, dims[1] / 2.0], rotation[:, 2])
            corners = np.vstack([end + signs * dims[0] for end in ends])
        self.items.append((kind, (dims, rotation, pose.position * 1000.0), corners))

    def add_prism(self, outline: np.ndarray, face_origin, x_axis, y_axis, back) -> None:
        """A flat outline (n, 2) mm on the plane through ``face_origin`` spanned by ``x_axis``, ``y_axis``, extruded
        by the vector ``back`` (mm)."""
        outline, face_origin, x_axis, y_axis, back = (np.asarray(v, float) for v in
                                                       (outline, face_origin, x_axis, y_axis, back))
        face = face_origin + outline[:, :1] * x_axis + outline[:, 1:2] * y_axis
        self.items.append(("prism", (outline, face_origin, x_axis, y_axis, back), np.vstack([face, face + back])))

    def distance(self, item, origin: np.ndarray, rays: np.ndarray) -> np.ndarray:
        kind, data, _ = item
        return getattr(self, f"_{kind}")(origin, rays, *data)

    @staticmethod
    def _local(origin, rays, rotation, position):
        return (origin - position) @ rotation, rays @ rotation  # into the part's frame (rows: R^T x)

    def _box(self, origin, rays, dims, rotation, position):
        o, d = self._local(origin, rays, rotation, position)
        with np.errstate(divide="ignore", invalid="ignore"):
            t1, t2 = (-dims - o) / d, (dims - o) / d
        near = np.nanmax(np.where(np.isnan(t1), -np.inf, np.minimum(t1, t2)), axis=1)
        far = np.nanmin(np.where(np.isnan(t2), np.inf, np.maximum(t1, t2)), axis=1)
        inside_slab = np.all((np.abs(d) > 1e-12) | (np.abs(o) <= dims), axis=1)
        hit = inside_slab & (near <= far) & (far > 0)
        return np.where(hit, np.maximum(near, 0.0), np.inf)

    def _sphere(self, origin, rays, dims, rotation, position, centre_offset=0.0):
        centre = position + centre_offset * rotation[:, 2]
        oc = origin - centre
        b = rays @ oc
        c = float(oc @ oc) - dims[0] ** 2
        disc = b * b - c
        t = -b - np.sqrt(np.maximum(disc, 0.0))
        return np.where((disc >= 0) & (t > 0), t, np.inf)

    def _cylinder(self, origin, rays, dims, rotation, position):
        radius, half = dims[0], dims[1] / 2.0
        o, d = self._local(origin, rays, rotation, position)
        a = d[:, 0] ** 2 + d[:, 1] ** 2
        b = o[0] * d[:, 0] + o[1] * d[:, 1]
        c = o[0] ** 2 + o[1] ** 2 - radius ** 2
        disc = b * b - a * c
        with np.errstate(divide="ignore", invalid="ignore"):
            side = (-b - np.sqrt(np.maximum(disc, 0.0))) / a
        z = o[2] + side * d[:, 2]
        best = np.where((disc >= 0) & (a > 1e-12) & (side > 0) & (np.abs(z) <= half), side, np.inf)
        for cap in (-half, half):
            with np.errstate(divide="ignore", invalid="ignore"):
                t = (cap - o[2]) / d[:, 2]
            x, y = o[0] + t * d[:, 0], o[1] + t * d[:, 1]
            best = np.minimum(best, np.where((t > 0) & (x * x + y * y <= radius ** 2), t, np.inf))
        return best

    def _capsule(self, origin, rays, dims, rotation, position):
        best = self._cylinder(origin, rays, dims, rotation, position)
        for end in (-dims[1] / 2.0, dims[1] / 2.0):
            best = np.minimum(best, self._sphere(origin, rays, dims, rotation, position, end))
        return best

    def _prism(self, origin, rays, outline, face, x_axis, y_axis, back):
        normal = np.cross(x_axis, y_axis)
        depth = float(back @ normal)
        with np.errstate(divide="ignore", invalid="ignore"):
            t0 = ((face - origin) @ normal) / (rays @ normal)
            t1 = ((face + back - origin) @ normal) / (rays @ normal)
        enter, leave = np.minimum(t0, t1), np.maximum(t0, t1)
        ok = np.isfinite(enter) & (leave > 0) & (abs(depth) > 0)

        def planar(t):  # the ray's point at t, in the outline's (x, y) mm (on the face's plane)
            point = origin + t[:, None] * rays - face
            point = point - ((point @ normal) / (normal @ normal))[:, None] * normal
            return np.column_stack([point @ x_axis, point @ y_axis])

        a, b = planar(np.where(ok, enter, 0.0)), planar(np.where(ok, leave, 0.0))
        inside = _inside(a, outline) | _inside(b, outline) | _crosses(a, b, outline)
        return np.where(ok & inside, np.maximum(enter, 0.0), np.inf)


def _inside(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd rule, each point (n, 2) against the polygon (m, 2)."""
    x, y = points[:, :1], points[:, 1:]
    x0, y0 = polygon[None, :, 0], polygon[None, :, 1]
    x1, y1 = np.roll(polygon[:, 0], -1)[None, :], np.roll(polygon[:, 1], -1)[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        crossing = ((y0 > y) != (y1 > y)) & (x < x0 + (y - y0) * (x1 - x0) / (y1 - y0))
    return (np.count_nonzero(crossing, axis=1) % 2) == 1


def _crosses(a: np.ndarray, b: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Whether each segment a-b (n, 2 each) crosses an edge of the polygon."""
    p, q = polygon[None, :, :], np.roll(polygon, -1, axis=0)[None, :, :]
    a, b = a[:, None, :], b[:, None, :]

    def side(u, v, w):
        return (v[..., 0] - u[..., 0]) * (w[..., 1] - u[..., 1]) - (v[..., 1] - u[..., 1]) * (w[..., 0] - u[..., 0])

    return np.any((side(a, b, p) * side(a, b, q) < 0) & (side(p, q, a) * side(p, q, b) < 0), axis=1)


def _shapes(job, board, x_moved) -> _Shapes:
    """The parts' collision shapes at ``x_moved`` and every jig stand's plate and base carried with its part."""
    scenario = job.scenario
    designed = world_poses(scenario.objects, scenario.transforms(np.asarray(job.layout.x, float), checked=False))
    moved = world_poses(scenario.objects, scenario.transforms(np.asarray(x_moved, float), checked=False))
    shapes = _Shapes()
    for obj in scenario.objects:
        if obj.type == "Plane":
            continue
        for spec in body_specs(obj):
            for part in spec.parts:
                if part.kind != "plane":
                    shapes.add_part(part.kind, part.dims, moved[obj.name] * spec.pose * part.pose)
    top = job.guide.plane
    up = np.asarray(top.normal, float)
    for jig in job.jigs.plan.jigs:
        if jig.kind != "stand" or jig.face_frame is None:
            continue
        carry = moved[jig.part] * designed[jig.part].inverse()
        rotation = carry.rotation.as_matrix()
        face_origin, x_axis, y_axis, facing = (np.asarray(v, float) for v in jig.face_frame)
        shapes.add_prism(np.asarray(jig.outline.exterior.coords)[:-1], carry.apply(face_origin) * 1000.0,
                         rotation @ x_axis, rotation @ y_axis, -rotation @ facing * jig.thickness_mm)
        # the base stays on the table where it is drawn: the plate moves in its slot
        shapes.add_prism(np.asarray(jig.footprint.exterior.coords)[:-1], np.asarray(top.origin, float) * 1000.0,
                         np.asarray(top.u_axis, float), np.asarray(top.v_axis, float), up * jig.thickness_mm)
    return shapes


def independent_side_frame(job, board, x_moved, *, distance_mm: float = 700.0, aim_mm=None, noise: float = 2.0,
                           blur: float = 0.8, seed: int = 0, rise_mm: float = 0.0, occlusion: bool = True,
                           visibility: dict | None = None):
    """The side camera's frame of ``job``'s board and jig face tags with the parts at layout ``x_moved``, and the
    camera's intrinsics (pinhole, no distortion).

    The camera stands ``distance_mm`` in front of the board's point ``aim_mm`` (board (u, v) mm; default the sheet's
    middle) and ``rise_mm`` above it, looking at it; ``blur`` (Pillow's Gaussian radius, px) and ``noise`` (grey
    levels) degrade it. With ``occlusion`` the parts and jig stands hide what they stand in front of (module notes);
    ``visibility``, a dict, is filled with each tag id: whether all of it (with its border) is in the frame and
    unhidden.
    """
    plane = board.plane
    metres = 1000.0
    u_axis, v_axis, normal = (np.asarray(a, float) for a in (plane.u_axis, plane.v_axis, plane.normal))
    origin = np.asarray(plane.origin, float) * metres
    u0, v0, u1, v1 = board.extent_mm
    aim = np.array(aim_mm if aim_mm is not None else ((u0 + u1) / 2.0, (v0 + v1) / 2.0), float)
    target = origin + aim[0] * u_axis + aim[1] * v_axis
    centre = target + distance_mm * normal + rise_mm * v_axis
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
    shapes = _shapes(job, board, x_moved) if occlusion else _Shapes()

    def rays(x0, y0, x1, y1, scale):
        """Unit rays (world) through the sub-pixel centres of pixels [x0, x1) x [y0, y1), ``scale`` a side."""
        xs = x0 + (np.arange((x1 - x0) * scale) + 0.5) / scale - 0.5
        ys = y0 + (np.arange((y1 - y0) * scale) + 0.5) / scale - 0.5
        gx, gy = np.meshgrid(xs, ys)
        local = np.column_stack([(gx.ravel() - cx) / FOCAL_PX, (gy.ravel() - cy) / FOCAL_PX, np.ones(gx.size)])
        world = local @ rotation
        return world / np.linalg.norm(world, axis=1, keepdims=True)

    def to_plane(directions, point, plane_normal):
        with np.errstate(divide="ignore"):
            return ((point - centre) @ plane_normal) / (directions @ plane_normal)

    def depths(x0, y0, x1, y1, scale):
        """Each sample's distance to the nearest solid in front of the board over pixels [x0, x1) x [y0, y1)
        (``scale`` samples a side; inf: none): each solid cast only over the pixels its bounds cover."""
        nearest = np.full(((y1 - y0) * scale, (x1 - x0) * scale), np.inf)
        for item in shapes.items:
            if np.any((item[2] - centre) @ rotation[2] <= 1.0):
                a0, b0, a1, b1 = x0, y0, x1, y1  # reaching behind the camera: anywhere
            else:
                px = pixels(item[2])
                a0, b0 = max(int(np.floor(px[:, 0].min())) - 1, x0), max(int(np.floor(px[:, 1].min())) - 1, y0)
                a1, b1 = min(int(np.ceil(px[:, 0].max())) + 2, x1), min(int(np.ceil(px[:, 1].max())) + 2, y1)
            if a1 <= a0 or b1 <= b0:
                continue
            window = (slice((b0 - y0) * scale, (b1 - y0) * scale), slice((a0 - x0) * scale, (a1 - x0) * scale))
            directions = rays(a0, b0, a1, b1, scale)
            found = shapes.distance(item, centre, directions)
            found[found >= to_plane(directions, origin, normal)] = np.inf  # behind the board: hidden by it
            nearest[window] = np.minimum(nearest[window], found.reshape(nearest[window].shape))
        return nearest

    grey = np.full((height, width), BACKGROUND_GREY, dtype=np.float32)
    if shapes.items:  # the solids in front of the board, 2x2 samples a pixel
        cover = np.isfinite(depths(0, 0, width, height, 2)).reshape(height, 2, width, 2).mean(axis=(1, 3))
        grey = grey * (1.0 - cover) + SOLID_GREY * cover
    scale = SUPERSAMPLE
    ids = [tag.id for tag in board.reference_tags] + [jig.face_tag_id for jig in job.jigs.plan.jigs
                                                     if jig.face_tag_id is not None and jig.face_frame is not None]
    for tag_id, quads in zip(ids, tags, strict=True):  # each tag on its own supersampled patch
        projected = [(pixels(quad), white) for quad, white in quads]
        every = np.concatenate([p for p, _ in projected])
        inside = bool(np.all((every >= -0.5) & (every <= [width - 0.5, height - 0.5])))
        x0, y0 = (int(np.floor(v)) - 2 for v in every.min(axis=0))
        x1, y1 = (int(np.ceil(v)) + 3 for v in every.max(axis=0))
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, width), min(y1, height)
        if x1 <= x0 or y1 <= y0:
            if visibility is not None:
                visibility[int(tag_id)] = False
            continue
        patch = Image.new("L", ((x1 - x0) * scale, (y1 - y0) * scale), 170)
        mask = Image.new("L", patch.size, 0)
        draw, outline = ImageDraw.Draw(patch), ImageDraw.Draw(mask)
        for points, white in projected:
            # Pillow fills the sub-pixels whose centres (its integers) the polygon covers
            corners = (points - [x0, y0] + 0.5) * scale - 0.5
            draw.polygon([tuple(p) for p in corners], fill=236 if white else 26)
            outline.polygon([tuple(p) for p in corners], fill=255)
        samples = np.asarray(patch, dtype=np.float32)
        printed = np.asarray(mask) > 0
        solid, directions = depths(x0, y0, x1, y1, scale), rays(x0, y0, x1, y1, scale)
        quad = quads[0][0]
        tag_normal = np.cross(quad[1] - quad[0], quad[3] - quad[0])
        tag_at = to_plane(directions, quad[0], tag_normal).reshape(samples.shape)
        hidden = printed & (solid < tag_at - 0.05)
        samples = np.where(printed & ~hidden, samples, np.where(np.isfinite(solid), SOLID_GREY, BACKGROUND_GREY))
        if visibility is not None:
            visibility[int(tag_id)] = inside and not hidden.any()
        block = samples.reshape(y1 - y0, scale, x1 - x0, scale).mean(axis=(1, 3))
        grey[y0:y1, x0:x1] = block
    picture = Image.fromarray(np.clip(np.round(grey), 0, 255).astype(np.uint8))
    if blur > 0:
        picture = picture.filter(ImageFilter.GaussianBlur(blur))  # Pillow's own, not OpenCV's
    grey = np.asarray(picture, dtype=np.float32) + np.random.default_rng(seed).normal(0.0, noise, grey.shape)
    image = np.repeat(np.clip(np.round(grey), 0, 255).astype(np.uint8)[:, :, None], 3, axis=2)
    matrix = np.array([[FOCAL_PX, 0.0, cx], [0.0, FOCAL_PX, cy], [0.0, 0.0, 1.0]])
    return image, CameraIntrinsics(matrix, np.zeros(5), SIZE, name="independent pinhole")
