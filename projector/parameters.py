"""Every design parameter of a part in the maker's words (pure computation on the posed scenario).

A layout parameter (``track.z``, ``track_joint.roll``) means nothing at the table; a maker acts on "the track's
underside 58.2 mm above the table at its middle", "tilted 30.0 deg, lower end towards the dominoes". This module
turns each design parameter that moves a part into a :class:`~projector.guide.PartParameter` (its value, what it
does on the guide plane, the maker's words, its tolerance and how the guide tells the maker to set it), and a part
that a parameter moves off the plane into an :class:`~projector.guide.Elevation` (the part alone seen from the
side, with its named points), which the sheets draw dimensioned.

**What a parameter does** is measured, not read from its name: the layout is moved a hair along that parameter and
the part's frame followed through the scene graph (an Empty frame it hangs from included). A position that moves the
part mostly along the plane's normal is a ``height`` (above the table; in front of the board on a side view), else a
place along ``u`` or ``v``; an angle that turns the part about an axis within 45 deg of the normal is a ``turn``,
else a ``tilt``.

**The part seen from the side** (the elevation): looked at along the tilt's axis, so the tilt shows at its true
angle (without a tilt, along the outline's shorter side), the guide-plane direction drawn to the right being the
one nearer +u (else +v). The part's **length** is the axis of its own frame, across the line of sight, that it
reaches furthest along; its two **ends** are the faces across its length, and at each end the named point is the
one nearest the plane ("the underside at the lower end"); the **middle** is the underside halfway between them.
A part whose length is its own up axis (local z: a goblet, a post) is **standing**: its lower end is its foot, its
upper end's named point its top (the highest), and its tilt how far it leans from upright, towards its top.
The **tilt** is the angle between the length and the plane; the **lower end** the end nearer it, and **which way
it falls** names the nearest other part (not one that rides on it) in a strip from the lower end outwards, and the
direction as the maker sees it ("towards `dominoes` (to your right)").

**How each is set** (``set_with``, :data:`~projector.guide.SET_WITH`): a place or turn on the plane of a part with a
tag: ``check`` (laid on its outline, then measured by the camera check); of a part without one: ``sheet``; a height
or a tilt: ``ruler`` (a ruler, the two end heights giving the tilt); a caller's mapping overrides any of these per
parameter (a laser-cut jig's parameters: ``jig``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace

import numpy as np
import shapely
from shapely.geometry import LineString, Point

from design.contraption.geometry import world_poses
from design.contraption.model import Scenario
from projector.errors import ProjectorError
from projector.guide import (
    IN_PLANE_ROLES,
    SET_WITH,
    Elevation,
    GuidePlane,
    ParameterTolerance,
    PartDrawing,
    PartParameter,
    where_point,
    where_word,
)
from projector.outline import part_outline

__all__ = ["ROTATION_KEYS", "check_set_with", "describe_parts", "how_text", "layout_from_manifest",
           "off_plane_text", "tolerance_words"]

#: The transform keys that are angles (degrees); the others (x, y, z) are positions (metres, the guide's mm).
ROTATION_KEYS = ("heading", "pitch", "roll")
#: The hair a parameter is moved by to see what it does (m, deg): far below any printed digit.
_STEP = {"mm": 1e-4, "deg": 1e-2}
#: How far the strip that looks for the part the lower end points at reaches (mm).
_REACH_MM = 1500.0
#: The words of each view: how far off the plane, the face nearest it, its two ends, the plane's directions.
_WORDS = {
    "top": {"off": "above the table", "under": "underside", "lower": "lower end", "upper": "upper end",
            "height": "height above the table", "u": "left-right on the sheet", "v": "front-back on the sheet",
            "plus_u": "to your right", "minus_u": "to your left", "plus_v": "away from you",
            "minus_v": "towards you", "facing": "seen from above"},
    "side": {"off": "in front of the board", "under": "back", "lower": "end nearer the board",
             "upper": "end further out", "height": "depth in front of the board", "u": "left-right on the sheet",
             "v": "up-down on the sheet", "plus_u": "to your right", "minus_u": "to your left", "plus_v": "up",
             "minus_v": "down", "facing": "facing the board"},
}
#: How the steps say a parameter is set.
_HOW = {"sheet": "on its outline on the sheet", "ruler": "with a ruler", "jig": "with its jig",
        "check": "on its outline, then the camera check"}


def check_set_with(set_with: Mapping[str, str] | None, names) -> dict[str, str]:
    """A caller's ``set_with`` overrides, checked: known parameters, each set with one of :data:`SET_WITH`.

    Raises
    ------
    ProjectorError
        An unknown parameter or way of setting it (one line naming it and what was expected).
    """
    overrides = dict(set_with or {})
    for name, how in overrides.items():
        if name not in names:
            raise ProjectorError(f"set_with: unknown layout parameter {name!r}; expected one of "
                                 f"{', '.join(names) or '(none: the scenario has no ranges)'}")
        if how not in SET_WITH:
            raise ProjectorError(f"set_with[{name!r}]: expected one of {', '.join(SET_WITH)}, got {how!r}")
    return overrides


def describe_parts(scenario: Scenario, x, frames, bodies, plane: GuidePlane, drawings: list[PartDrawing],
                   set_with: Mapping[str, str] | None = None) -> list[PartDrawing]:
    """``drawings`` with every parameter's :attr:`~projector.guide.PartDrawing.settings` and, for a part moved off
    the plane, its :attr:`~projector.guide.PartDrawing.elevation` (module notes).

    Parameters
    ----------
    scenario : Scenario
    x : array_like or None
        The layout (real units, design-space order); None for the scenario's default.
    frames : dict of str to Pose
        The objects' world frames at ``x``.
    bodies : dict of str to list of PlacedBody
        Each part's bodies at ``x``.
    plane : GuidePlane
    drawings : list of PartDrawing
        The parts, tagged (the tags decide ``check`` or ``sheet``).
    set_with : mapping of str to str, optional
        Per layout parameter, how the guide tells the maker to set it (overrides the module notes' defaults).
    """
    names = tuple(scenario.design_space.names)
    overrides = check_set_with(set_with, names)
    x = np.asarray(scenario.default_layout() if x is None else x, dtype=float)
    moved = {}  # per parameter, the world frames with it moved a hair (computed once, for every part it moves)
    spans = None  # each part's reach off the plane (mm), once one part needs it
    result = []
    for part in drawings:
        if not part.parameters:
            result.append(part)
            continue
        roles = {}
        for name in part.parameters:
            if name not in moved:
                moved[name] = _moved_frames(scenario, x, names.index(name))
            roles[name] = _role(name, frames[part.name], moved[name][part.name], plane)
        elevation = None
        if any(role in ("height", "tilt") for role, _ in roles.values()):
            if spans is None:
                spans = _spans(bodies, plane)
            elevation = _elevation(scenario, part, frames[part.name], bodies[part.name], plane, drawings, spans,
                                   next((axis for role, axis in roles.values() if role == "tilt"), None))
        known = {t.parameter: t for t in part.tolerances}
        tagged = bool(part.tag_views())
        settings = []
        for name in part.parameters:
            role, _ = roles[name]
            unit = "deg" if name.rsplit(".", 1)[-1] in ROTATION_KEYS else "mm"
            value = float(x[names.index(name)]) * (1.0 if unit == "deg" else 1000.0)
            default = ("check" if tagged else "sheet") if role in IN_PLANE_ROLES else "ruler"
            how = overrides.get(name, default)
            tolerance = known.get(name)
            settings.append(PartParameter(name=name, value=value, unit=unit, role=role,
                                          meaning=_meaning(part, role, unit, tolerance, elevation, plane.view),
                                          set_with=how, tolerance=tolerance))
        result.append(replace(part, settings=tuple(settings), elevation=elevation))
    return result


def tolerance_words(tolerance: ParameterTolerance | None, unit: str) -> str:
    """``"+-2.1 mm"``, ``"at least +-0.5 deg, the range's end"`` (a delta bound only by the design space), or
    ``"tolerance unknown"``."""
    if tolerance is None or tolerance.delta is None or not math.isfinite(tolerance.delta):
        return "tolerance unknown"
    words = f"+-{abs(tolerance.delta):.1f} {unit}"
    return f"at least {words}, the range's end" if tolerance.bound_limited else words


def how_text(set_with: str) -> str:
    """How the steps say a parameter is set (``"with a ruler"``)."""
    return _HOW.get(set_with, set_with)


def off_plane_text(part: PartDrawing, view: str, symbols: bool = False) -> str:
    """A short line of what the sheet cannot show (the projected frames; with ``symbols`` the sheets' labels, in ±
    and °), e.g. ``"height 58.7 mm +-5.3, tilt 30.0 deg +-10.6, lower end towards `dominoes` (to your right)"``:
    the height of the underside at the middle, the tilt and which way it falls; empty for a part on the plane."""
    elevation = part.elevation
    if elevation is None:
        return ""
    words = _WORDS.get(view, _WORDS["top"])
    plus, mm, deg = ("±", " mm", "°") if symbols else ("+-", " mm", " deg")

    def tolerance(setting: PartParameter, unit: str) -> str:
        t = setting.tolerance
        if t is None or t.delta is None or not math.isfinite(t.delta):
            return ""
        return f" {'>=' if t.bound_limited and symbols else ''}{plus}{abs(t.delta):.1f}{unit}" \
            + (" (range end)" if t.bound_limited and not symbols else "")

    phrases = []
    toward = elevation.toward.replace("`", "") if symbols else elevation.toward
    for setting in part.settings:
        if setting.role == "height":
            what, at = ("foot", elevation.ends[0][1]) if elevation.standing else \
                ("height" if view == "top" else "depth", elevation.middle[1])
            phrases.append(f"{what} {at:.1f}{mm}{tolerance(setting, mm)}")
        elif setting.role == "tilt":
            if elevation.level:
                phrases.append(f"{'upright' if elevation.standing else 'level'}{tolerance(setting, deg)}")
            elif elevation.standing:
                phrases.append(f"leans {elevation.lean_deg:.1f}{deg}{tolerance(setting, deg)}")
                phrases.append(f"top {toward}")
            else:
                phrases.append(f"tilt {elevation.tilt_deg:.1f}{deg}{tolerance(setting, deg)}")
                phrases.append(f"{words['lower']} {toward}")
    return ", ".join(phrases)


def layout_from_manifest(manifest: Mapping) -> dict[str, float]:
    """Every design parameter a guide's manifest states, in the layout's own units (m, degrees), to the rounding
    the guide prints (0.1 mm, 0.1 deg): what a program that has only the manifest knows of the layout.

    A parameter that moves several parts (an Empty frame's) is stated by each; they must agree.

    Raises
    ------
    ProjectorError
        A part's ``parameters`` missing or malformed, or two parts that disagree (one line naming the field).
    """
    parts = manifest.get("parts") if isinstance(manifest, Mapping) else None
    if not isinstance(parts, list):
        raise ProjectorError(f"guide manifest: field 'parts': expected a list of parts, got {parts!r:.60}")
    values: dict[str, float] = {}
    for k, part in enumerate(parts):
        entries = part.get("parameters", []) if isinstance(part, Mapping) else None
        if not isinstance(entries, list):
            raise ProjectorError(f"guide manifest: field 'parts[{k}].parameters': expected a list, got "
                                 f"{entries!r:.60}")
        for j, entry in enumerate(entries):
            where = f"parts[{k}].parameters[{j}]"
            if not isinstance(entry, Mapping) or not isinstance(entry.get("name"), str) \
                    or entry.get("unit") not in ("mm", "deg") or isinstance(entry.get("value"), bool) \
                    or not isinstance(entry.get("value"), (int, float)) or not math.isfinite(entry["value"]):
                raise ProjectorError(f"guide manifest: field {where!r}: expected {{\"name\": text, \"value\": a "
                                     f"finite number, \"unit\": \"mm\" or \"deg\", ...}}, got {entry!r:.80}")
            printed = round(float(entry["value"]), 1)
            value = printed / 1000.0 if entry["unit"] == "mm" else printed
            name = entry["name"]
            if name in values and abs(values[name] - value) > (1e-4 if entry["unit"] == "mm" else 0.1) + 1e-9:
                raise ProjectorError(f"guide manifest: field '{where}.value': {name} is {entry['value']} "
                                     f"{entry['unit']} here and differs on another part")
            values.setdefault(name, value)
    return values


# -- what a parameter does --------------------------------------------------------------------------------------

def _moved_frames(scenario: Scenario, x: np.ndarray, index: int):
    name = scenario.design_space.names[index]
    moved = x.copy()
    moved[index] += _STEP["deg" if name.rsplit(".", 1)[-1] in ROTATION_KEYS else "mm"]
    return world_poses(scenario.objects, scenario.transforms(moved, checked=False))


def _role(name: str, before, after, plane: GuidePlane) -> tuple[str, np.ndarray | None]:
    """What moving ``name`` a hair does to a part whose frame goes from ``before`` to ``after``: its role, and for a
    turn or tilt the world axis it turns about."""
    if name.rsplit(".", 1)[-1] in ROTATION_KEYS:
        turn = (after.rotation * before.rotation.inv()).as_rotvec()
        size = float(np.linalg.norm(turn))
        if size < 1e-12:  # a rotation that leaves the part's attitude alone: it only swings it round a point
            return "turn", None
        axis = turn / size
        return ("turn" if abs(float(axis @ plane.normal)) >= math.sqrt(0.5) else "tilt"), axis
    shift = np.asarray(after.position) - np.asarray(before.position)
    along = {"u": abs(float(shift @ plane.u_axis)), "v": abs(float(shift @ plane.v_axis)),
             "height": abs(float(shift @ plane.normal))}
    return max(along, key=along.get), None


# -- the part seen from the side ----------------------------------------------------------------------------------

def _spans(bodies, plane: GuidePlane) -> dict[str, tuple[float, float]]:
    """Each part's lowest and highest point off the plane (mm)."""
    spans = {}
    for name, group in bodies.items():
        points = np.concatenate([b.world_points() for b in group])
        heights = 1000.0 * (points - plane.origin) @ plane.normal
        spans[name] = (float(heights.min()), float(heights.max())) if len(heights) else (0.0, 0.0)
    return spans


def _elevation(scenario, part: PartDrawing, frame, group, plane: GuidePlane, drawings, spans,
               tilt_axis) -> Elevation:
    normal = np.asarray(plane.normal, dtype=float)
    if tilt_axis is not None:
        direction = np.cross(tilt_axis, normal)
    else:
        direction = _long_side(part, plane)
    direction = direction - (direction @ normal) * normal
    if np.linalg.norm(direction) < 1e-9:
        direction = np.asarray(plane.u_axis, dtype=float)
    direction /= np.linalg.norm(direction)
    du, dv = float(direction @ plane.u_axis), float(direction @ plane.v_axis)
    if (du < -1e-9) if abs(du) >= abs(dv) - 1e-9 else (dv < 0):
        direction, du, dv = -direction, -du, -dv
    side = GuidePlane("elevation", plane.origin, direction, normal, np.cross(direction, normal))
    profile = part_outline(group, side)

    # the part's length: of its frame's axes across the line of sight, the one it reaches furthest along
    points = np.concatenate([b.world_points() for b in group])
    sight = np.cross(direction, normal)
    axes = [(k, axis) for k, axis in enumerate(frame.rotation.as_matrix().T)
            if abs(float(axis @ sight)) < math.sqrt(0.5)]
    along, length = max(axes, key=lambda item: (float(np.ptp(points @ item[1])), abs(float(item[1] @ direction))))
    length = length if length @ direction >= 0 else -length
    tilt = abs(math.degrees(math.atan2(float(length @ normal), float(length @ direction))))
    tilt = min(tilt, 180.0 - tilt)

    s = 1000.0 * (points - plane.origin) @ direction
    h = 1000.0 * (points - plane.origin) @ normal
    t = 1000.0 * (points - frame.position) @ length
    band = 0.5 + 0.002 * float(t.max() - t.min())
    faces = [np.flatnonzero(np.abs(t - extreme) <= band) for extreme in (t.min(), t.max())]
    # the lower end first (level: the left one); at each end its point nearest the plane
    faces.sort(key=lambda face: (round(float(h[face].min()), 6), float(s[face[np.argmin(h[face])]])))
    low, high = (int(face[np.argmin(h[face])]) for face in faces)
    standing = along == 2  # its length is its own up (a goblet, a post): it stands, however far it leans
    if standing:  # a standing part's top is the highest point of its upper end
        high = int(faces[1][np.argmax(h[faces[1]])])
    middle_s = 0.5 * float(s[low] + s[high])
    middle_h = _underside(profile, middle_s, 0.5 * float(h[low] + h[high]))
    toward = ""
    if (90.0 - tilt if standing else tilt) >= 0.05:
        # which way it falls: from the lower end outwards; a standing part's top, the way it leans
        end = high if standing else low
        foot, top = (float(s[face].mean()) for face in faces)  # the ends' middles: which way the length runs
        out = 1.0 if (top >= foot if standing else foot >= top) else -1.0
        toward = _toward(scenario, part, drawings, spans, plane.to_plane(points[end])[0], float(h[end]),
                         out * np.array([du, dv]), plane.view)
    return Elevation(direction_uv=(du, dv), seen_from=_seen_from(direction, normal, plane), profile=profile,
                     ends=((float(s[low]), float(h[low])), (float(s[high]), float(h[high]))),
                     middle=(middle_s, middle_h), tilt_deg=tilt, toward=toward, standing=standing,
                     axis=tuple((float(s[face].mean()), float(h[face].mean())) for face in faces))


def _long_side(part: PartDrawing, plane: GuidePlane) -> np.ndarray:
    """The world direction of the part's outline's longer side (the side view of a part that only rises)."""
    outline = part.outline
    if outline.is_empty:
        return np.asarray(plane.u_axis, dtype=float)
    ring = np.asarray(outline.minimum_rotated_rectangle.exterior.coords) \
        if outline.minimum_rotated_rectangle.geom_type == "Polygon" else np.array([[0, 0], [1, 0]])
    edges = np.diff(ring, axis=0)
    edge = edges[int(np.argmax(np.linalg.norm(edges, axis=1)))]
    return edge[0] * np.asarray(plane.u_axis) + edge[1] * np.asarray(plane.v_axis)


def _underside(profile, s: float, fallback: float) -> float:
    """The lowest point of ``profile`` straight above ``s`` (the underside there)."""
    cut = profile.intersection(LineString([(s, -1e5), (s, 1e5)]))
    return fallback if cut.is_empty else float(cut.bounds[1])


def _seen_from(direction: np.ndarray, normal: np.ndarray, plane: GuidePlane) -> str:
    """Where the maker stands to see the elevation as drawn (``direction`` to the right, the normal up)."""
    stand = np.cross(direction, normal)  # towards the viewer: right x up
    su, sv = float(stand @ plane.u_axis), float(stand @ plane.v_axis)
    if plane.view == "top":
        if abs(sv) >= abs(su):
            return "seen from the front (your side of the table)" if sv < 0 else "seen from the far side"
        return "seen from your right" if su > 0 else "seen from your left"
    if abs(sv) >= abs(su):
        return "seen from above" if sv > 0 else "seen from below"
    return "seen from your right" if su > 0 else "seen from your left"


def _direction_words(uv, view: str) -> str:
    words = _WORDS.get(view, _WORDS["top"])
    u, v = float(uv[0]), float(uv[1])
    said = sorted([(abs(u), words["plus_u" if u > 0 else "minus_u"]), (abs(v), words["plus_v" if v > 0 else
                                                                                        "minus_v"])], reverse=True)
    return " and ".join(text for size, text in said if size >= 0.38) or said[0][1]


def _toward(scenario, part: PartDrawing, drawings, spans, start, height: float, out, view: str) -> str:
    """``"towards `dominoes` (to your right)"``: the nearest other part in a strip from ``start`` (the lower end, at
    ``height`` off the plane) along ``out`` (none riding on this part), nearest counting how far above or below
    that height the part lies (a part far under the lower end is not what it points at), and the direction in the
    maker's words."""
    out = np.asarray(out, dtype=float) / max(float(np.linalg.norm(out)), 1e-12)
    riders = _riders(scenario, part.name)
    across = np.array([-out[1], out[0]])
    coords = np.asarray(part.outline.exterior.coords if part.outline.geom_type == "Polygon"
                        else shapely.convex_hull(part.outline).exterior.coords)
    width = float(np.ptp(coords @ across)) if len(coords) else 0.0
    strip = LineString([start, start + _REACH_MM * out]).buffer(max(10.0, width / 2.0), cap_style="flat")
    origin = Point(start)
    best, best_distance = None, math.inf
    for other in drawings:
        if other.name == part.name or other.name in riders or other.outline.is_empty:
            continue
        seen = other.outline.intersection(strip)
        if seen.is_empty:
            continue
        low, high = spans.get(other.name, (height, height))
        distance = math.hypot(origin.distance(seen), max(low - height, height - high, 0.0))
        if distance < best_distance:
            best, best_distance = other.name, distance
    where = _direction_words(out, view)
    return f"towards `{best}` ({where})" if best is not None else where


def _riders(scenario, name: str) -> set[str]:
    """The objects that hang from ``name`` in the scene graph (a ball on a track): not what its tilt points at."""
    children: dict[str, list[str]] = {}
    for obj in scenario.objects:
        if obj.parent is not None:
            children.setdefault(obj.parent, []).append(obj.name)
    found, todo = set(), [name]
    while todo:
        for child in children.get(todo.pop(), []):
            if child not in found:
                found.add(child)
                todo.append(child)
    return found


# -- words -----------------------------------------------------------------------------------------------------------

def _meaning(part: PartDrawing, role: str, unit: str, tolerance, elevation: Elevation | None, view: str) -> str:
    words = _WORDS.get(view, _WORDS["top"])
    tol = tolerance_words(tolerance, unit)
    if role in ("u", "v"):
        u, v = (round(c, 1) + 0.0 for c in where_point(part))
        at = "centre at" if where_word(part) == "centre" else "around"
        return f"{words[role]}: {at} {role} = {u if role == 'u' else v:.1f} mm ({tol})"
    if role == "turn":
        heading = round(part.heading_deg, 1) + 0.0
        way = "counter-clockwise" if heading >= 0 else "clockwise"
        return f"turn on the sheet: {abs(heading):.1f} deg {way}, {words['facing']} ({tol})"
    assert elevation is not None
    (_, low), (_, high) = elevation.ends
    if elevation.standing:
        if role == "height":
            return f"{words['height']}: its foot {low:.1f} mm ({tol})"
        if elevation.level:
            return f"tilt: upright (0.0 deg from upright, {tol}), its foot {low:.1f} mm {words['off']}"
        return (f"tilt: leans {elevation.lean_deg:.1f} deg from upright ({tol}), its top {elevation.toward}: its "
                f"foot {low:.1f} mm {words['off']}, its top {high:.1f} mm")
    if role == "height":
        at = "" if elevation.level else " at the middle"
        return f"{words['height']}: its {words['under']}{at} {elevation.middle[1]:.1f} mm ({tol})"
    if elevation.level:
        return (f"tilt: level (0.0 deg, {tol}), its {words['under']} {low:.1f} mm {words['off']} at both "
                f"ends")
    return (f"tilt: {elevation.tilt_deg:.1f} deg ({tol}), {words['lower']} {elevation.toward}: its {words['under']} "
            f"{low:.1f} mm {words['off']} at the {words['lower']}, {high:.1f} mm at the {words['upper']}")
