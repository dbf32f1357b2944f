"""Hand-built guides (no scenario, no simulation): for the outputs' tests, the docs' pictures and demos.

:func:`sample_guide` is a small ball run on a backboard (side view) with what the outputs must cope with: static
parts, a U-shaped cup (concave), a run of dominoes (a MultiPolygon), a ball without a tag, parts with tags and with
tolerances of every care level, and the four reference tags near the corners. :func:`tiny_guide` is one square part.
"""

from __future__ import annotations

import numpy as np
from shapely import affinity
from shapely.geometry import MultiPolygon, Point, Polygon, box

from projector.guide import (
    REFERENCE_TAG_IDS,
    Guide,
    GuidePlane,
    ParameterTolerance,
    PartDrawing,
    PartKind,
    ReferenceTag,
)

__all__ = ["side_plane", "top_plane", "reference_tags_around", "sample_guide", "tiny_guide", "extent_of"]


def top_plane() -> GuidePlane:
    """The table seen from above: (u, v) = (x, y)."""
    return GuidePlane("top", np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), np.array([0, 0, 1.0]))


def side_plane() -> GuidePlane:
    """A backboard facing +y seen from the front: (u, v) = (-x, z)."""
    return GuidePlane("side", np.zeros(3), np.array([-1.0, 0, 0]), np.array([0, 0, 1.0]), np.array([0, 1.0, 0]))


def reference_tags_around(bounds, size_mm: float = 40.0, gap_mm: float = 15.0) -> tuple[ReferenceTag, ...]:
    """The four reference tags just outside ``bounds`` (u0, v0, u1, v1): lower-left, lower-right, upper-right,
    upper-left, ids 583 to 586."""
    u0, v0, u1, v1 = bounds
    d = gap_mm + size_mm * 0.625
    centres = [(u0 - d, v0 - d), (u1 + d, v0 - d), (u1 + d, v1 + d), (u0 - d, v1 + d)]
    return tuple(ReferenceTag(i, c, size_mm) for i, c in zip(REFERENCE_TAG_IDS, centres))


def extent_of(parts, tags) -> tuple[float, float, float, float]:
    """``(u_min, v_min, u_max, v_max)`` of the parts' outlines and the tags' black squares."""
    boxes = [p.outline.bounds for p in parts if not p.outline.is_empty]
    boxes += [(t.center_mm[0] - t.size_mm / 2, t.center_mm[1] - t.size_mm / 2, t.center_mm[0] + t.size_mm / 2,
               t.center_mm[1] + t.size_mm / 2) for t in tags]
    b = np.array(boxes)
    return (float(b[:, 0].min()), float(b[:, 1].min()), float(b[:, 2].max()), float(b[:, 3].max()))


def _tol(parameter: str, delta: float | None, unit: str, predicted: float | None = 0.9,
         measured: float | None = None, source: str = "model") -> ParameterTolerance:
    return ParameterTolerance(parameter, delta, unit, predicted, measured, source)


def sample_guide() -> Guide:
    """A small ball run on a backboard (side view), about 390 x 260 mm with its reference tags."""
    plank = box(-20, 0, 330, 12)
    post = box(290, 12, 302, 200)
    track = affinity.rotate(box(0, -4, 200, 4), -8, origin=(0, 0))
    track = affinity.translate(track, 70, 170)
    cup_outer, cup_inner = box(-20, -15, 20, 15), box(-15, -10, 15, 16)
    cup = affinity.translate(cup_outer.difference(cup_inner), 40, 120)  # a U open at the top
    dominoes = MultiPolygon([box(130 + 28 * k, 12, 138 + 28 * k, 60) for k in range(5)])
    ball = Point(265, 205).buffer(12, quad_segs=16)
    lever = affinity.translate(affinity.rotate(box(-45, -3, 45, 3), 12, origin=(0, 0)), 60, 40)
    parts = [
        PartDrawing("floor_plank", PartKind.STATIC, 1, plank, (155.0, 6.0), 0.0),
        PartDrawing("support_post", PartKind.STATIC, 2, post, (296.0, 106.0), 90.0),
        PartDrawing("top_track", PartKind.PLACED, 3, track, (70.0, 170.0), -8.0, tag_id=0,
                    tag_center_mm=(150.0, 158.8), tag_size_mm=20.0,
                    parameters=("top_track.x", "top_track.z", "top_track.roll"),
                    tolerances=(_tol("top_track.x", 2.1, "mm", 0.9, 0.86), _tol("top_track.z", 1.5, "mm", 0.9, 0.88),
                                _tol("top_track.roll", 1.5, "deg", 0.9, 0.91)), care="tight"),
        PartDrawing("catch_cup", PartKind.PLACED, 4, cup, (40.0, 120.0), 0.0, tag_id=1,
                    tag_center_mm=(40.0, 112.0), tag_size_mm=16.0,
                    parameters=("catch_cup.x", "catch_cup.z"),
                    tolerances=(_tol("catch_cup.x", 6.0, "mm"), _tol("catch_cup.z", 4.5, "mm")), care="normal"),
        PartDrawing("lever & <arm>", PartKind.PLACED, 5, lever, (60.0, 40.0), 12.0, tag_id=2,
                    tag_center_mm=(80.0, 44.3), tag_size_mm=16.0,
                    parameters=("lever.roll", "lever.y"),
                    tolerances=(_tol("lever.roll", 6.0, "deg"), _tol("lever.y", 10.0, "mm")), care="normal"),
        PartDrawing("domino_run", PartKind.PLACED, 6, dominoes, (130.0, 12.0), 0.0,
                    parameters=("domino_run.x",), tolerances=(_tol("domino_run.x", 14.0, "mm"),), care="loose"),
        PartDrawing("ball", PartKind.PLACED, 7, ball, (265.0, 205.0), 0.0),
    ]
    core = extent_of(parts, ())
    tags = reference_tags_around(core)
    return Guide("sample_ballrun", "0" * 16, side_plane(), tuple(parts), tags, extent_of(parts, tags), "model")


def tiny_guide(*, tag: bool = True, tolerance: bool = True, reference_tags: bool = False) -> Guide:
    """One 20 mm square part (centre (30, 30) mm, top view), optionally with a tag, an x tolerance of ±2 mm (tight)
    and the four reference tags."""
    square = Polygon([(20, 20), (40, 20), (40, 40), (20, 40)])
    tolerances = (ParameterTolerance("square.x", 2.0, "mm", 0.9),) if tolerance else ()
    part = PartDrawing("square", PartKind.PLACED, 1, square, (30.0, 30.0), 0.0, tag_id=7 if tag else None,
                       tag_center_mm=(30.0, 30.0) if tag else None, tag_size_mm=10.0,
                       parameters=("square.x",) if tolerance else (), tolerances=tolerances,
                       care="tight" if tolerance else None)
    tags = reference_tags_around(square.bounds, 20.0, 5.0) if reference_tags else ()
    return Guide("tiny", "0" * 16, top_plane(), (part,), tags, extent_of([part], tags),
                 "model" if tolerance else "none")
