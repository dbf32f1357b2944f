"""The side view of a table check: heights and tilts read by a camera facing the reference board (pure).

The top camera measures each part on the table's plane: along u, along v, its turn. What leaves that plane (a
track's height, its tilt) it cannot see. A second camera in front of the table faces an upright board behind the
parts (:mod:`projector.board`); on the board's plane (u along the table's u, v the height above the table) a tag
facing that camera is measured exactly as a top tag is (:func:`calibration.measure.measure`, at its depth in front of
the board), and its pose on the board's plane carries the part's: the part's origin and turn on that plane, hence its
height and its tilt.

A part too thin for a tag of its own (a track, a plank) is measured through what carries it: the jig it rests on
stands on edge with a tag engraved on its face, square to the side camera. The part rests on the jig's support, so
the jig's pose on the board's plane is the part's (what the part does on its support, it does unseen).

A :class:`SideTarget` is one such tag and the part it measures, as designed; :func:`side_guide` makes them a
:class:`~projector.guide.Guide` on the board's plane, so the top check's own machinery
(:func:`calibration.check.check_parts`, :func:`calibration.asbuilt.as_built_layout`) measures them; and
:func:`side_instruction` says what to do in a maker's words: "raise `track`'s lower end 3.0 mm, tilt it 1.5 deg
steeper".
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from shapely.geometry import Polygon

from calibration.check import NEGLIGIBLE_DEG, NEGLIGIBLE_MM, PartCheck, measured_pose
from projector.guide import Guide, PartDrawing, PartKind

__all__ = ["SideTarget", "lower_end_error", "side_guide", "side_instruction", "side_view_checks"]

#: A tag is read square enough by the side camera when its face turns at most this far from the board's normal.
FACING_DEG = 20.0


@dataclass(frozen=True)
class SideTarget:
    """One tag the side camera reads and the part it measures, as designed, on the board's plane (mm, degrees).

    Attributes
    ----------
    part : str
        The part measured.
    via : str
        The jig whose face carries the tag (``"J1"``); empty for a tag on the part itself.
    tag_id, tag_size_mm : int, float
    tag_center_mm : tuple of float
        The tag's centre on the board's plane (u, height above the table).
    tag_depth_mm : float
        How far in front of the board the tag's face stands.
    tag_heading_deg : float
        Its printed "up" on the board's plane, counter-clockwise as the camera sees it, 0 = up.
    center_mm, heading_deg :
        The part's origin and turn on the board's plane.
    lower_end_mm : tuple of float
        The named point whose height the instruction gives: the lower end of the support the part rests on.
    tilt_deg : float
        The support's slope on the board's plane as designed (counter-clockwise from +u; 0 level).
    """

    part: str
    via: str
    tag_id: int
    tag_size_mm: float
    tag_center_mm: tuple[float, float]
    tag_depth_mm: float
    tag_heading_deg: float
    center_mm: tuple[float, float]
    heading_deg: float
    lower_end_mm: tuple[float, float]
    tilt_deg: float
    #: The jig's plate and the part resting on it, as the side camera sees them on the board's plane (rings of
    #: (u, v) mm; pictures only: the measurement reads the tag alone).
    plate_mm: tuple[tuple[float, float], ...] = ()
    silhouette_mm: tuple[tuple[tuple[float, float], ...], ...] = ()


def side_guide(guide: Guide, board, targets: Sequence[SideTarget]) -> Guide:
    """The side view as a guide on the board's plane: the board's reference tags, one part per target (its tag, its
    pose on that plane, the part's own tolerances, which :func:`projector.drawing.placement_deltas` reads on the
    board's axes: a height along v, a tilt as a turn)."""
    parts = {p.name: p for p in guide.parts}
    drawings = []
    for step, target in enumerate(targets, start=1):
        source = parts.get(target.part)
        drawings.append(PartDrawing(
            name=target.part, kind=PartKind.PLACED, step=step, outline=Polygon(), center_mm=target.center_mm,
            heading_deg=target.heading_deg, tag_id=target.tag_id, tag_center_mm=target.tag_center_mm,
            tag_size_mm=target.tag_size_mm, tag_height_mm=target.tag_depth_mm, tag_heading_deg=target.tag_heading_deg,
            parameters=source.parameters if source is not None else (),
            tolerances=source.tolerances if source is not None else ()))
    u0, v0, u1, v1 = board.extent_mm
    for target in targets:  # what the side camera is aimed over: the sheet and every tag it reads
        u, v, half = *target.tag_center_mm, target.tag_size_mm
        u0, v0, u1, v1 = min(u0, u - half), min(v0, v - half), max(u1, u + half), max(v1, v + half)
    return Guide(guide.scenario, guide.content_hash, board.plane, tuple(drawings), tuple(board.reference_tags),
                 (u0, v0, u1, v1), tolerance_source=guide.tolerance_source)


def lower_end_error(target: SideTarget, check: PartCheck) -> tuple[float, float]:
    """How far the measured lower end stands from the designed one: ``(along u, up)`` mm (the rigid move the tag
    shows, applied to the lower end)."""
    drawn = PartDrawing(target.part, PartKind.PLACED, 1, Polygon(), target.lower_end_mm, 0.0,
                        tag_center_mm=target.tag_center_mm, tag_heading_deg=target.tag_heading_deg)
    moved, _ = measured_pose(drawn, _tag_centre(target, check), _tag_heading(target, check))
    return moved[0] - target.lower_end_mm[0], moved[1] - target.lower_end_mm[1]


def _tag_centre(target: SideTarget, check: PartCheck) -> tuple[float, float]:
    """The tag's measured centre, back from the part's measured pose (the inverse of :func:`measured_pose`)."""
    turn = math.radians(check.measured_heading_deg - target.heading_deg)
    offset = np.subtract(target.tag_center_mm, target.center_mm)
    rotated = np.array([math.cos(turn) * offset[0] - math.sin(turn) * offset[1],
                        math.sin(turn) * offset[0] + math.cos(turn) * offset[1]])
    centre = np.asarray(check.measured_center_mm, dtype=float) + rotated
    return float(centre[0]), float(centre[1])


def _tag_heading(target: SideTarget, check: PartCheck) -> float:
    return target.tag_heading_deg + (check.measured_heading_deg - target.heading_deg)


def side_instruction(name: str, lower_end: tuple[float, float], turn_deg: float, tilt_deg: float, *,
                     via: str = "", within: bool | None = None) -> str:
    """What to do about a part's height and tilt, in the maker's words, e.g. ``"raise `track`'s lower end 3.0 mm,
    tilt it 1.5 deg steeper"``.

    ``lower_end`` is the measured minus designed ``(along, up)`` of its lower end (only the height is said: where
    the part stands along the table is the top camera's), ``turn_deg`` its measured minus designed turn on the
    board's plane, ``tilt_deg`` its designed slope there. A tilted part is tilted steeper or flatter; a level one is
    levelled by lowering or raising one end (as the side camera sees it). Errors under 0.5 mm / 0.5 deg are left out.
    Through a jig (``via``), the jig is what to look at: is it down in its slot, its base flat?
    """
    height = lower_end[1]
    words = []
    if abs(height) >= NEGLIGIBLE_MM:
        words.append(f"{'lower' if height > 0 else 'raise'} `{name}`'s lower end {abs(height):.1f} mm")
    if abs(turn_deg) >= NEGLIGIBLE_DEG:
        amount = f"{abs(turn_deg):.1f} deg"
        if abs(tilt_deg) >= NEGLIGIBLE_DEG:
            steeper = (tilt_deg + turn_deg) * math.copysign(1.0, tilt_deg) < abs(tilt_deg)
            tilt = f"{amount} {'steeper' if steeper else 'flatter'}"
        else:  # level by design: the end that rose comes down
            tilt = f"{amount} back to level: lower its {'right' if turn_deg > 0 else 'left'} end as the side " \
                   "camera sees it"
        words.append(f"tilt it {tilt}" if words else f"tilt `{name}` {tilt}")
    if not words:
        return f"`{name}` is at its height and tilt"
    text = ", ".join(words)
    if via:
        text += f" (through jig {via}: is its plate down in the base's slot and its base flat on the table?)"
    if within:
        return f"`{name}` is within its tolerance in height and tilt (to centre it: {text})"
    return text


def side_view_checks(checks: Sequence[PartCheck], targets: Sequence[SideTarget]) -> list[PartCheck]:
    """The side view's checks with their instructions in the side camera's words (:func:`side_instruction`)."""
    by_part = {t.part: t for t in targets}
    result = []
    for check in checks:
        target = by_part.get(check.name)
        if target is None or not check.found:
            result.append(check)
            continue
        lower = lower_end_error(target, check)
        result.append(replace(check, instruction=side_instruction(
            target.part, lower, check.error[3], target.tilt_deg, via=target.via, within=check.within_tolerance)))
    return result
