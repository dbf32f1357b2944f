"""A hand-built guide like BALLRUN's (a backboard, side view) for the projected-frame tests and the README's figures:
static rail and post first, then three tracks, a goblet (concave), a domino run (a MultiPolygon), the ball last."""

from __future__ import annotations

from shapely import affinity
from shapely.geometry import MultiPolygon, Point, Polygon, box

from projector.guide import REFERENCE_TAG_IDS, Guide, ParameterTolerance, PartDrawing, PartKind, ReferenceTag
from projector.samples import side_plane

#: The backboard of BALLRUN: facing +y, so u = -x and v = z.
SIDE = side_plane()


def tolerances(name: str, **deltas: float) -> tuple[ParameterTolerance, ...]:
    return tuple(ParameterTolerance(f"{name}.{key}", delta, "deg" if key in ("heading", "pitch", "roll") else "mm",
                                    0.9) for key, delta in deltas.items())


def part(name, kind, step, outline, center, heading=0.0, tag=None, care=None, **deltas) -> PartDrawing:
    return PartDrawing(name, kind, step, outline, center, heading, tag, None if tag is None else center, 20.0, 5.0,
                       tuple(f"{name}.{k}" for k in deltas), tolerances(name, **deltas), care)


def track(center, length, heading):
    return affinity.rotate(affinity.translate(box(-length / 2, -7, length / 2, 7), *center), heading, origin=center)


def goblet(center):
    u, v = center
    cup = Polygon([(-32, 70), (-24, 30), (-6, 18), (-6, 4), (-22, 0), (22, 0), (6, 4), (6, 18), (24, 30), (32, 70),
                   (26, 70), (19, 34), (0, 24), (-19, 34), (-26, 70)])
    return affinity.translate(cup, u, v)


def sample_guide() -> Guide:
    parts = [
        part("rail", PartKind.STATIC, 1, box(-40, 0, 640, 12), (300.0, 6.0)),
        part("post", PartKind.STATIC, 2, box(20, 12, 40, 300), (30.0, 156.0)),
        part("top_track", PartKind.PLACED, 3, track((190.0, 330.0), 260, -12.0), (190.0, 330.0), -12.0, 3, "tight",
             x=2.1, z=3.4, roll=1.5),
        part("bottom_track", PartKind.PLACED, 4, track((420.0, 210.0), 240, 10.0), (420.0, 210.0), 10.0, 4,
             "normal", x=4.0, z=6.0, roll=3.0),
        part("goblet", PartKind.PLACED, 5, goblet((560.0, 12.0)), (560.0, 12.0), 0.0, 5, "loose", x=8.0, z=5.0),
        part("dominoes", PartKind.PLACED, 6, MultiPolygon([box(250 + 28 * i, 12, 258 + 28 * i, 60) for i in range(5)]),
             (314.0, 36.0), 0.0, None, "normal", x=3.0),
        part("ball", PartKind.PLACED, 7, Point(80, 372).buffer(12, 32), (80.0, 372.0), 0.0, None, "tight", x=1.0,
             z=1.2),
    ]
    u0, v0, u1, v1 = -90.0, -60.0, 690.0, 450.0
    centres = [(u0 + 30, v0 + 30), (u1 - 30, v0 + 30), (u1 - 30, v1 - 30), (u0 + 30, v1 - 30)]
    tags = tuple(ReferenceTag(tag_id, center, 40.0) for tag_id, center in zip(REFERENCE_TAG_IDS, centres))
    return Guide("BALLRUN-like", "0" * 16, SIDE, tuple(parts), tags, (u0, v0, u1, v1), "model")
