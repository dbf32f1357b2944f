"""The as-built check: how far each part stands from where the guide wants it, and what to do about it (pure).

From a camera :class:`~calibration.measure.Measurement` (the tags found, in guide-plane millimetres) and the
:class:`~projector.guide.Guide`, per tagged part:

- its **measured pose**: the tag's measured centre and heading carried back through the tag's offset in the part's
  frame (a rigid move in the plane: the part turned by the tag's heading error about the tag), so the part's origin
  is measured even where the tag sits off it;
- its **error**, measured minus designed: ``du``, ``dv``, the distance (mm) and the heading (deg);
- **within tolerance** or not: each error against the part's tolerance along that axis of the plane
  (:func:`projector.drawing.placement_deltas`, the zone the sheets and the projector draw); None when no tolerance
  is known along any measured axis;
- an **instruction** in the sheets' words: ``u`` is the maker's right, ``v`` away from the maker on the table (top)
  or up on the board (side), headings counter-clockwise as the maker sees the plane.

A tag not found is *missing* (its part is not measured), a tag seen twice is a *duplicate* (never guessed between), a
decoded id that is neither a reference nor a part tag is *unknown*. Parts without a tag (a ball, a run of dominoes,
a track seen edge-on) are checked *by eye* against the sheet.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from projector.drawing import UNTOLERATED_DEG, UNTOLERATED_MM, must_move, placement_deltas
from projector.guide import Guide, PartDrawing

__all__ = ["CHECK_FORMAT", "LAYOUT_DECIMALS", "CheckReport", "PartCheck", "check_parts", "instruction", "jig_views",
           "part_tags", "reference_tags", "residual_error", "same_layout_value"]

CHECK_FORMAT = "chaos-station check"
CHECK_VERSION = 1
#: Below these, an error is not worth an instruction: about what the camera resolves (a 15 mm tag from 1 m reads to
#: 0.1-0.3 mm and 0.1-0.3 deg), and finer than any tolerance the guides draw.
NEGLIGIBLE_MM, NEGLIGIBLE_DEG = 0.5, 0.5


@dataclass(frozen=True)
class PartCheck:
    """One tagged part, checked.

    Attributes
    ----------
    name : str
    tag_id : int
    found : bool
        Its tag was measured (seen once).
    measured_center_mm, measured_heading_deg :
        The part's origin and heading on the plane, as measured (None when not found).
    error : tuple of float or None
        ``(du_mm, dv_mm, distance_mm, heading_deg)``, measured minus designed.
    tolerance : tuple
        ``(du, dv, dheading)``: its tolerance along u, v and in heading (None where unknown).
    within_tolerance : bool or None
    instruction : str
    cost : float or None
        How much the layout's predicted success falls with this part's error alone (None without a model).
    part : str
        The part the checked tag is on ("" : ``name`` itself); a run's domino is checked as ``"run[0]"``.
    body : int or None
        The body of ``part`` the tag is on (a domino's index), None for the part's own tag.
    """

    name: str
    tag_id: int
    found: bool
    measured_center_mm: tuple[float, float] | None
    measured_heading_deg: float | None
    error: tuple[float, float, float, float] | None
    tolerance: tuple[float | None, float | None, float | None]
    within_tolerance: bool | None
    instruction: str
    cost: float | None = None
    part: str = ""
    body: int | None = None
    #: The view that measured it (``"top"``, ``"side"``; empty: the guide's own) and the jig whose tag it was
    #: measured through (empty: the part's own tag).
    view: str = ""
    via: str = ""

    @property
    def owner(self) -> str:
        """The part this check belongs to."""
        return self.part or self.name

    def to_json(self) -> dict:
        measured = None if self.measured_center_mm is None else {
            "center_mm": [_r(c) for c in self.measured_center_mm], "heading_deg": _r(self.measured_heading_deg)}
        error = None if self.error is None else dict(zip(("du_mm", "dv_mm", "distance_mm", "heading_deg"),
                                                         (_r(e) for e in self.error)))
        return {"name": self.name, "tag_id": self.tag_id, "found": self.found, "measured": measured, "error": error,
                "within_tolerance": self.within_tolerance, "instruction": self.instruction,
                "cost": None if self.cost is None else round(float(self.cost), 4),
                "view": self.view or None, "via_jig": self.via or None}


@dataclass(frozen=True)
class CheckReport:
    """A whole check: CHECK.json's content (:meth:`to_json`, the public contract the trial log stores)."""

    scenario: str
    content_hash: str
    layout: dict[str, float]
    view: str
    plane: object | None
    parts: tuple[PartCheck, ...]
    missing_tags: tuple[int, ...]
    unknown_tags: tuple[int, ...]
    duplicate_tags: tuple[int, ...]
    by_eye: tuple[str, ...]
    as_built: dict[str, float]
    not_measured: tuple[str, ...]
    residual_error: dict[str, float]
    predicted_success_as_built: float | None = None
    predicted_success_as_designed: float | None = None
    prediction_note: str | None = None
    simulated_success_as_built: float | None = None
    missing_reference_tags: tuple[int, ...] = field(default=())
    #: the measured parameters as measured: ``as_built`` keeps each in its design range, these may leave it
    as_measured: dict[str, float] = field(default_factory=dict)
    #: misplaced parts no design parameter places: the predictions simulate them where the guide puts them
    not_simulated: tuple[str, ...] = field(default=())
    #: every camera's view: ``{"view", "camera", "plane": {...} or None}`` (the first the top's)
    views: tuple[dict, ...] = field(default=())
    #: the side camera's checks (heights and tilts on the board's plane)
    side_parts: tuple[PartCheck, ...] = field(default=())
    #: per measured design parameter, the view that measured it
    measured_by: dict[str, str] = field(default_factory=dict)

    @property
    def measured_by_side(self) -> tuple[str, ...]:
        """The design parameters the side camera measured."""
        return tuple(name for name, view in self.measured_by.items() if view == "side")

    def to_json(self) -> dict:
        plane = None if self.plane is None else {
            "residual_mm": _r(self.plane.residual_mm), "reference_ids": [int(i) for i in self.plane.reference_ids],
            "moved_mm": None if self.plane.moved_mm is None else _r(self.plane.moved_mm)}
        return {
            "format": CHECK_FORMAT, "version": CHECK_VERSION, "scenario": self.scenario,
            "content_hash": self.content_hash, "layout": _values(self.layout), "view": self.view, "plane": plane,
            "parts": [p.to_json() for p in self.parts],
            "missing_tags": list(self.missing_tags), "unknown_tags": list(self.unknown_tags),
            "duplicate_tags": list(self.duplicate_tags), "by_eye": list(self.by_eye),
            "missing_reference_tags": list(self.missing_reference_tags),
            "as_built": _values(self.as_built), "as_measured": _values(self.as_measured),
            "not_measured": list(self.not_measured),
            "residual_error": {k: _r(v) for k, v in self.residual_error.items()},
            "predicted_success_as_built": _p(self.predicted_success_as_built),
            "predicted_success_as_designed": _p(self.predicted_success_as_designed),
            "prediction_note": self.prediction_note,
            "simulated_success_as_built": _p(self.simulated_success_as_built),
            "not_simulated": list(self.not_simulated),
            "views": [dict(v) for v in self.views],
            "side_parts": [p.to_json() for p in self.side_parts],
            "measured_by": dict(self.measured_by),
        }


def _r(value) -> float:
    return round(float(value), 3) + 0.0


def _p(value) -> float | None:
    return None if value is None else round(float(value), 4)


def as_built_values(check: Mapping, fail: Callable[[str], Exception]) -> dict[str, float]:
    """The as-built layout of a CHECK.json's content: its ``as_built``, each measured parameter as measured
    (``as_measured``, which may leave the design range; checks written before it existed have none).

    ``fail(message)`` makes the error raised for a malformed table (``as_built.NAME: expected a number...``).
    """
    values: dict[str, float] = {}
    for table in ("as_built", "as_measured"):
        given = check.get(table, {} if table == "as_measured" else None)
        if not isinstance(given, Mapping):
            raise fail(f"{table}: expected {{parameter: value}}, got {given!r:.40}")
        for name, value in given.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise fail(f"{table}.{name}: expected a number, got {value!r}")
            values[str(name)] = float(value)
    return values


def not_measured_names(check: Mapping | None, names: Sequence[str],
                       fail: Callable[[str], Exception]) -> tuple[str, ...]:
    """A CHECK.json content's ``not_measured``: the design parameters (of ``names``) the check did not measure (none
    when there is no check or it does not say).

    ``fail(message)`` makes the error raised for a malformed list (``not_measured: ...``).
    """
    listed = check.get("not_measured", []) if isinstance(check, Mapping) else []
    if not isinstance(listed, list) or not all(isinstance(n, str) for n in listed):
        raise fail(f"not_measured: expected a list of design parameter names, got {listed!r}")
    unknown = [n for n in listed if n not in names]
    if unknown:
        raise fail(f"not_measured: {unknown[0]!r} is not a design parameter (expected one of {', '.join(names)})")
    return tuple(listed)


#: CHECK.json writes layout values to this many decimals (metres and degrees: a micrometre, a millionth of a degree).
LAYOUT_DECIMALS = 6


def _values(values: dict[str, float]) -> dict[str, float]:
    return {k: round(float(v), LAYOUT_DECIMALS) + 0.0 for k, v in values.items()}


def same_layout_value(checked: float, value: float) -> bool:
    """Whether ``checked`` (a CHECK.json's ``layout`` value, written to :data:`LAYOUT_DECIMALS`) is ``value`` (a
    layout's, at full precision) as the check wrote it: equal after the same rounding, give or take the float's own
    last digit."""
    rounded = round(float(value), LAYOUT_DECIMALS)
    return abs(float(checked) - rounded) <= 1e-12 * max(1.0, abs(rounded))


def reference_tags(guide: Guide) -> list[tuple[int, tuple[float, float], float]]:
    """The guide's reference tags as :func:`calibration.measure.measure` takes them: ``(id, centre mm, size mm)``."""
    return [(t.id, tuple(t.center_mm), float(t.size_mm)) for t in guide.reference_tags]


def part_tags(guide: Guide) -> dict[int, tuple[float, float]]:
    """The part tags as :func:`calibration.measure.measure` takes them: ``id -> (size mm, height mm)``, the jigs'
    tags among them (a jig's tag measures the part it carries)."""
    tags = {t.tag_id: (float(t.tag_size_mm), float(t.tag_height_mm)) for p in guide.parts for t in p.tag_views()}
    tags.update({j.tag_id: (float(j.tag_size_mm), float(j.tag_height_mm)) for j in guide.jigs
                 if j.tag_id is not None and j.tag_center_mm is not None})
    return tags


def jig_views(guide: Guide, part: PartDrawing) -> list[tuple[str, PartDrawing]]:
    """A part without a tag of its own, as the tag of the stand it rests on shows it: ``(jig id, the part with the
    jig's tag)``. A stand carries its part rigidly on the plane (the part rests on its plate, against its stop); a
    template is lifted off once the part is in its pocket, so it measures nothing at check time."""
    if part.tag_views():
        return []
    return [(j.id, replace(part, tag_id=j.tag_id, tag_center_mm=tuple(j.tag_center_mm), tag_size_mm=j.tag_size_mm,
                           tag_height_mm=j.tag_height_mm, tag_heading_deg=j.tag_heading_deg))
            for j in guide.jigs if j.part == part.name and j.kind == "stand" and j.tag_id is not None
            and j.tag_center_mm is not None][:1]


def _wrap(angle: float) -> float:
    angle = (float(angle) + 180.0) % 360.0 - 180.0
    return 180.0 if angle == -180.0 else angle


def check_parts(guide: Guide, measurement) -> tuple[list[PartCheck], list[str]]:
    """Every tagged part of ``guide`` against ``measurement``; and the parts to check by eye (no tag).

    A part whose tags are on its bodies (a run's first and last dominoes) is checked body by body: each as
    ``"name[i]"``, its error that body's.

    Parameters
    ----------
    guide : Guide
    measurement : calibration.measure.Measurement
        Its ``tags`` (one :class:`~calibration.measure.TagPose` per part tag seen once) and ``duplicate_ids``.
    """
    checks, by_eye = [], []
    for part in guide.parts:
        views = [(None, part)] if part.tag_id is not None and part.tag_center_mm is not None else []
        views += [(b.body, replace(part, name=f"{part.name}[{b.body}]", center_mm=b.center_mm,
                                   heading_deg=b.heading_deg, tag_id=b.tag_id, tag_center_mm=b.tag_center_mm,
                                   tag_heading_deg=b.tag_heading_deg)) for b in part.body_tags]
        carried = jig_views(guide, part)
        if not views and not carried:
            by_eye.append(part.name)
        for body, view in views:
            checks.append(replace(_check_one(view, measurement, guide), part=part.name if body is not None else "",
                                  body=body))
        for jig, view in carried:
            check = _check_one(view, measurement, guide)
            words = check.instruction.replace(f"`{part.name}`", f"jig {jig} (with `{part.name}` on it)", 1)
            checks.append(replace(check, via=jig, instruction=words))
    return checks, by_eye


def _check_one(part: PartDrawing, measurement, guide: Guide) -> PartCheck:
    """One tag's part (or body) against the measurement."""
    seen = {int(t.tag_id): t for t in measurement.tags}
    duplicates = {int(i) for i in measurement.duplicate_ids}
    deltas = placement_deltas(part, guide.plane)
    tag = seen.get(part.tag_id) if part.tag_id not in duplicates else None
    if tag is None:
        if measurement.plane is None:
            why = "not measured: the camera sees too few reference tags to find the plane"
        elif part.tag_id in duplicates:
            why = "seen more than once: not measured (cover or remove the extra copy)"
        else:
            why = "not seen: is the part placed, its tag uncovered and facing the camera?"
        return PartCheck(part.name, part.tag_id, False, None, None, None, deltas, None,
                         f"`{part.name}`: tag {part.tag_id} {why}")
    center, heading = measured_pose(part, tag.center_mm, tag.heading_deg)
    du, dv = center[0] - part.center_mm[0], center[1] - part.center_mm[1]
    dheading = _wrap(heading - part.heading_deg)
    error = (du, dv, math.hypot(du, dv), dheading)
    within = _within(error, deltas)
    return PartCheck(part.name, part.tag_id, True, center, heading, error, deltas, within,
                     instruction(part.name, error, guide.view, within, deltas))


def measured_pose(part: PartDrawing, tag_center_mm, tag_heading_deg: float) -> tuple[tuple[float, float], float]:
    """The part's origin and heading from its tag's measured centre and heading: the designed offset from the tag to
    the part's origin, turned by the tag's heading error (the part is rigid, and moves in the plane)."""
    turn = _wrap(float(tag_heading_deg) - part.tag_heading_deg)
    c, s = math.cos(math.radians(turn)), math.sin(math.radians(turn))
    offset = np.asarray(part.center_mm, dtype=float) - np.asarray(part.tag_center_mm, dtype=float)
    rotated = np.array([c * offset[0] - s * offset[1], s * offset[0] + c * offset[1]])
    center = np.asarray(tag_center_mm, dtype=float) + rotated
    return (float(center[0]), float(center[1])), _wrap(part.heading_deg + turn)


def _within(error, deltas) -> bool | None:
    du, dv, _, dheading = error
    pairs = [(abs(e), d) for e, d in zip((du, dv, dheading), deltas) if d is not None]
    if not pairs:
        return None
    return all(e <= d for e, d in pairs)


def instruction(name: str, error: Sequence[float], view: str, within: bool | None = None,
                deltas: Sequence[float | None] = (None, None, None)) -> str:
    """What to do to put the part where the guide wants it, in the sheets' words, e.g.
    ``"move `bottom_track` 3.2 mm right and 1.0 mm down, turn it 1.5 deg clockwise"``.

    ``error`` is ``(du, dv, distance, dheading)``, measured minus designed: the part moves by minus that. Along u
    the words are right/left; along v away from you / towards you (top view) or up/down (side view); a heading error
    is undone clockwise when positive (the sheets' headings are counter-clockwise). Errors under 0.5 mm / 0.5 deg
    (about the measurement's resolution) are left out; a part within its tolerance says so first.
    """
    du, dv, _, dheading = error
    moves = []
    if abs(du) >= NEGLIGIBLE_MM:
        moves.append(f"{abs(du):.1f} mm {'left' if du > 0 else 'right'}")
    if abs(dv) >= NEGLIGIBLE_MM:
        if view == "top":
            moves.append(f"{abs(dv):.1f} mm {'towards you' if dv > 0 else 'away from you'}")
        else:
            moves.append(f"{abs(dv):.1f} mm {'down' if dv > 0 else 'up'}")
    words = []
    if moves:
        words.append(f"move `{name}` " + " and ".join(moves))
    if abs(dheading) >= NEGLIGIBLE_DEG:
        turn = f"{abs(dheading):.1f} deg {'clockwise' if dheading > 0 else 'counter-clockwise'}"
        words.append(f"turn it {turn}" if words else f"turn `{name}` {turn}")
    if not words:
        return f"`{name}` is in place"
    text = ", ".join(words)
    if within:
        return f"`{name}` is within its tolerance (to centre it: {text})"
    if not must_move(error, within):
        return (f"`{name}` is in place: off by less than {UNTOLERATED_MM:g} mm / {UNTOLERATED_DEG:g} deg, what a part "
                f"with no tolerance on the sheet may be (to centre it: {text})")
    return text


def residual_error(measurement, tag_sizes_mm: Sequence[float] = ()) -> dict[str, float]:
    """The measurement's own error, for simulating the as-built layout: ``position_mm``, the RMS of the plane's
    residual at the reference tags and of the part tags' fit residuals; ``heading_deg``, what that position error at
    one corner of the smallest part tag (``tag_sizes_mm``; 20 mm without one) turns it by:
    ``atan(e / (s / sqrt(2)))``, the corner's distance from the tag's centre being ``s / sqrt(2)``."""
    plane = measurement.plane
    values = [float(plane.residual_mm)] if plane is not None else []
    values += [float(t.fit_residual_mm) for t in measurement.tags]
    position = float(np.sqrt(np.mean(np.square(values)))) if values else 0.0
    size = min([float(s) for s in tag_sizes_mm if s > 0], default=20.0)
    heading = math.degrees(math.atan(position / (size / math.sqrt(2.0))))
    return {"position_mm": position, "heading_deg": heading}
