"""The flat parts of each drawing machine, as 2D outlines with holes (mm), derived from a design's parameters.

A model's lengths are in gear-radius units (Appendix A); ``scale`` is millimetres per unit. Every gear's pitch
curve is its primitive × scale, so the cut machine draws the modelled pattern (scaled). Connectors (axles, pins,
spacers, pen holders) are bought or 3D-printed, as in the thesis (3.6.3): the flat parts carry holes for them.

Parts per machine:

- Spirograph: fixed ring gear (internal, with mounting holes), rolling gear (with the pen hole at ``d``);
- elliptic Spirograph: fixed ring gear, elliptic rolling gear (pen hole on the major axis at ``d``);
- Cycloid Drawing Machine: turntable gear, external gear (axle + slider pin at ``r_S``), the pen arm (pivot hole at
  the fulcrum, a slot where the slider pin slides, the pen hole at ``d_FH``), base plate (axles of both gears and the
  fulcrum at their model positions);
- Hoot-Nanny: turntable gear, two external gears (axle + pivot pin at ``r_Pi``), two arms (pivot hole, pen hole at
  ``l_i``), base plate (axles of the three gears).

A pin so near a gear's rim that its hole would cut the teeth goes on a crank disc bolted (or glued) on the gear.
Holes that do not fit their part are refused with a :class:`~design.errors.ConstraintViolation` naming the part,
the hole and the material left. Every part carries an engraved label (a short code on small parts); base plates
are marked next to each axle.

The hardware and what the parts share with their sizes are in :mod:`design.fabrication.layout`, the sizes computed
before building in :mod:`design.fabrication.sizes` (both re-exported here).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np
import shapely.affinity as affinity
from shapely.geometry import LineString, MultiPoint, Point, Polygon, box

from common.progress import Reporter
from design.errors import ConstraintViolation
from design.fabrication.catalog import FABRICABLE_MACHINES
from design.fabrication.gears import (
    Gear,
    GearSettings,
    ellipse_axes,
    elliptic_gear,
    external_gear,
    ring_gear,
    teeth_per_unit,
)
from design.fabrication.labels import place_label
from design.fabrication.layout import (
    Hardware,
    checked_design,
    crank_radius,
    cycloid_positions,
    hoot_nanny_positions,
    pin_mount,
)
from design.fabrication.sizes import PartSize, part_sizes

__all__ = ["Hardware", "Part", "PartSize", "machine_parts", "part_sizes", "FABRICABLE_MACHINES"]



@dataclass(frozen=True)
class Part:
    """One flat part to cut.

    Attributes
    ----------
    name : str
        Unique within a machine, e.g. ``"rolling gear"``.
    shape : shapely Polygon
        Material (mm) with its holes, as designed (before kerf compensation).
    engrave : tuple of (n, 2) arrays
        Label strokes to engrave, in the part's coordinates.
    info : mapping
        Facts for the parts list (teeth, module, pitch radius, hole positions, ...).
    notes : tuple of str
        Warnings for the maker.
    """

    name: str
    shape: Polygon
    engrave: tuple[np.ndarray, ...] = ()
    info: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))
    notes: tuple[str, ...] = ()

    def transformed(self, angle_deg: float, dx: float, dy: float) -> Part:
        """The part rotated by ``angle_deg`` about the origin, then translated."""
        shape = affinity.translate(affinity.rotate(self.shape, angle_deg, origin=(0, 0)), dx, dy)
        c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
        rotation = np.array([[c, s], [-s, c]])
        engrave = tuple(stroke @ rotation + np.array([dx, dy]) for stroke in self.engrave)
        return Part(self.name, shape, engrave, self.info, self.notes)


def _disc(centre: tuple[float, float], diameter: float) -> Polygon:
    return Point(centre).buffer(diameter / 2.0, quad_segs=16)


def _with_holes(part_name: str, shape: Polygon, holes: list[tuple[str, tuple[float, float], float]],
                wall: float) -> Polygon:
    """``shape`` minus round holes; every hole keeps ``wall`` of material to the edge and to the other holes."""
    boundary = shape.exterior
    discs = []
    for hole_name, centre, diameter in holes:
        disc = _disc(centre, diameter)
        margin = boundary.distance(disc) if shape.contains(disc) else -1.0
        if margin < wall:
            raise ConstraintViolation(
                f"{part_name}: the {hole_name} ({diameter:g} mm at {centre[0]:.1f}, {centre[1]:.1f} mm) leaves "
                f"{max(margin, 0.0):.2f} mm of material to the edge, expected at least {wall:g} mm; use a larger "
                "scale or a smaller hole",
                constraint=f"{part_name} {hole_name}", margin=float(margin - wall))
        for other_name, other in discs:
            gap = disc.distance(other)
            if gap < wall:
                raise ConstraintViolation(
                    f"{part_name}: the {hole_name} and the {other_name} are {gap:.2f} mm apart, expected at least "
                    f"{wall:g} mm; use a larger scale or smaller holes",
                    constraint=f"{part_name} {hole_name}", margin=float(gap - wall))
        discs.append((hole_name, disc))
    for _, disc in discs:
        shape = shape.difference(disc)
    return shape


def _short_code(text: str) -> str:
    """A fallback label for small parts: initials and numbers, e.g. ``"GEAR 1 CRANK"`` → ``"G1C"``."""
    words = [w for w in text.split() if not (w.startswith("Z") and w[1:].isdigit())]
    return "".join(w if w.isdigit() else w[0] for w in words)


def _label(shape: Polygon, text: str, hardware: Hardware, near=(0.0, 0.0)) -> tuple[np.ndarray, ...]:
    """The label's strokes, or a short code when the full text finds no room in the part."""
    strokes = place_label(shape, text, hardware.label_height, near=near)
    if not strokes and _short_code(text) != text:
        strokes = place_label(shape, _short_code(text), hardware.label_height, near=near, min_height=1.5)
    return tuple(strokes)


def _plate_labels(shape: Polygon, main: tuple[str, tuple[float, float]],
                  marks: list[tuple[str, tuple[float, float]]], hardware: Hardware) -> tuple[np.ndarray, ...]:
    """The plate's name plus a small mark next to each axle (which part goes where); labels never overlap."""
    strokes: list[np.ndarray] = []
    room = shape
    for index, (text, near) in enumerate([main, *marks]):
        height = hardware.label_height if index == 0 else 0.75 * hardware.label_height
        placed = place_label(room, text, height, near=near, min_height=1.5)
        if placed:
            points = np.concatenate(placed)
            lo, hi = points.min(axis=0), points.max(axis=0)
            room = room.difference(box(*lo, *hi).buffer(1.0))
            strokes.extend(placed)
    return tuple(strokes)


def _root_radius(gear: Gear) -> float:
    return gear.pitch_radius - gear.settings.dedendum * gear.module


def _gear_info(gear: Gear, model_radius: float, scale: float) -> dict[str, Any]:
    info: dict[str, Any] = {
        "kind": gear.kind,
        "teeth": gear.teeth,
        "module_mm": round(gear.module, 5),
        "pressure_angle_deg": gear.settings.pressure_angle,
        "pitch_radius_mm": round(gear.pitch_radius, 5),
        "model_radius": model_radius,
        "model_radius_times_scale_mm": round(model_radius * scale, 5),
    }
    if gear.kind != "elliptic":
        info["base_radius_mm"] = round(gear.base_radius, 5)
    if gear.kind == "elliptic":
        info["semi_axes_mm"] = [round(gear.pitch.a, 5), round(gear.pitch.b, 5)]
        info["perimeter_mm"] = round(gear.pitch.perimeter, 5)
    return info


def _gear_part(name: str, code: str, gear: Gear, model_radius: float, scale: float, hardware: Hardware,
               holes: list[tuple[str, tuple[float, float], float]], label_near=(0.0, 0.0),
               extra_info: Mapping[str, Any] | None = None) -> Part:
    shape = _with_holes(name, gear.outline, holes, hardware.wall)
    info = _gear_info(gear, model_radius, scale)
    info["holes"] = [{"name": n, "at_mm": [round(c[0], 3), round(c[1], 3)], "diameter_mm": d} for n, c, d in holes]
    if extra_info:
        info.update(extra_info)
    text = f"{code} Z{gear.teeth}"
    return Part(name, shape, _label(shape, text, hardware, label_near), MappingProxyType(info), tuple(gear.notes()))


def _bar(length_points: list[float], width: float) -> Polygon:
    """A straight arm along +x covering ``[min, max]`` of ``length_points``, with round ends."""
    lo, hi = min(length_points), max(length_points)
    return LineString([(lo, 0.0), (hi, 0.0)]).buffer(width / 2.0, quad_segs=16)


def _plate(points: list[tuple[float, float]], border: float) -> Polygon:
    """A base plate: the convex hull of discs of radius ``border`` around every axle."""
    return MultiPoint(points).convex_hull.buffer(border, quad_segs=16)


# ---------------------------------------------------------------------------------------------------------------
# The four machines.


#: The progress stage of :func:`machine_parts`: generating the gears, counted in teeth.
GEARS_STAGE = "gears"


def _no_step(part_name: str, teeth: int) -> None:
    """The default of a builder's ``step``: called before each gear is generated (the slow part)."""


def _spirograph(p: Mapping[str, float], scale: float, settings: GearSettings, hw: Hardware,
                step=_no_step) -> list[Part]:
    k = teeth_per_unit(scale, settings)
    module = 2.0 * scale / k
    r_f, r_r, d = int(p["r_f"]), int(p["r_r"]), float(p["d"])
    step("rolling gear", k * r_r)
    rolling = external_gear(k * r_r, module, settings)
    step("fixed ring", k * r_f)
    ring = ring_gear(k * r_f, module, hw.rim, settings, cutter_teeth=min(k * r_r, k * r_f - 2))
    return [_ring_part(ring, r_f, scale, hw),
            _gear_part("rolling gear", "ROLL", rolling, r_r, scale, hw,
                       [("pen hole", (d * scale, 0.0), hw.pen_hole)], label_near=(-0.5 * rolling.pitch_radius, 0),
                       extra_info={"pen_distance_mm": round(d * scale, 4)})]


def _ring_part(ring: Gear, model_radius: float, scale: float, hw: Hardware) -> Part:
    mount = ring.pitch_radius + ring.settings.dedendum * ring.module + hw.rim / 2.0
    holes = [(f"mounting hole {i + 1}", (mount * math.cos(a), mount * math.sin(a)), hw.axle_hole)
             for i, a in enumerate(np.radians([90.0, 210.0, 330.0]))]
    return _gear_part("fixed ring", "RING", ring, model_radius, scale, hw, holes, label_near=(0.0, -mount),
                      extra_info={"outer_radius_mm": round(mount + hw.rim / 2.0, 4)})


def _elliptic_spirograph(p: Mapping[str, float], scale: float, settings: GearSettings, hw: Hardware,
                         step=_no_step) -> list[Part]:
    k = teeth_per_unit(scale, settings)
    module = 2.0 * scale / k
    r_f, r_r, e, d = int(p["r_f"]), int(p["r_r"]), float(p["e"]), float(p["d"])
    step("elliptic gear", k * r_r)
    rolling = elliptic_gear(k * r_r, module, e, settings)
    # Cut the ring with the largest circular cutter the ellipse resembles (its flattest arc, radius a²/b), so that
    # the ring's tips clear the ellipse everywhere along its roll.
    a, b = ellipse_axes(k * r_r * module / 2.0, e)
    cutter = int(math.floor(2.0 * (a * a / b) / module))
    step("fixed ring", k * r_f)
    ring = ring_gear(k * r_f, module, hw.rim, settings, cutter_teeth=max(6, min(cutter, k * r_f - 2)))
    return [_ring_part(ring, r_f, scale, hw),
            _gear_part("elliptic gear", "ELLIPSE", rolling, r_r, scale, hw,
                       [("pen hole", (d * scale, 0.0), hw.pen_hole)], label_near=(-0.4 * a, 0.0),
                       extra_info={"pen_distance_mm": round(d * scale, 4), "eccentricity": e})]


def _axle_gear(name: str, code: str, radius: int, k: int, module: float, scale: float, settings: GearSettings,
               hw: Hardware, pin: tuple[str, float] | None = None, step=_no_step) -> list[Part]:
    """A gear on an axle, with a pin at a model distance from its centre.

    A pin near the rim (the models allow it anywhere inside the pitch circle) would cut the teeth: it then goes on
    a *crank disc* bolted on top of the gear (two fixing holes on both, or glued when the gear is too small for
    them), which carries the pin at the same radius.
    """
    step(name, k * radius)
    gear = external_gear(k * radius, module, settings)
    holes = [("axle hole", (0.0, 0.0), hw.axle_hole)]
    notes: list[str] = []
    extra: list[Part] = []
    if pin is not None:
        pin_name, distance = pin
        at = distance * scale
        mount = pin_mount(at, _root_radius(gear), module, hw)
        if mount == "axle":
            notes.append(f"{name}: the {pin_name} at {at:.2f} mm is on the axle; no separate hole cut")
        elif mount == "hole":
            holes.append((pin_name, (at, 0.0), hw.pin_hole))
        else:
            fix_radius = max(0.5 * (hw.axle_hole / 2.0 + _root_radius(gear)),
                             (hw.axle_hole + hw.pin_hole) / 2.0 + hw.wall + 0.01)
            fixing = [(f"fixing hole {i + 1}", (0.0, sign * fix_radius), hw.pin_hole) for i, sign in enumerate((1, -1))]
            if fix_radius + hw.pin_hole / 2.0 + hw.wall <= _root_radius(gear):
                holes.extend(fixing)
                fastening = f"bolted on top of the gear (fixing holes {fix_radius:.1f} mm from the axle)"
            else:
                fixing = []
                fastening = "glued on top of the gear, centred on the axle (no room for fixing holes)"
            crank_size = crank_radius(at, hw)
            crank_name = f"{name} crank"
            crank_shape = _with_holes(crank_name, Point(0.0, 0.0).buffer(crank_size, quad_segs=32),
                                      [("axle hole", (0.0, 0.0), hw.axle_hole), *fixing,
                                       (pin_name, (at, 0.0), hw.pin_hole)], hw.wall)
            extra.append(Part(crank_name, crank_shape,
                              _label(crank_shape, f"{code} CRANK", hw, near=(-0.5 * crank_size, 0.0)),
                              MappingProxyType({"radius_mm": round(crank_size, 3), "pin_at_mm": round(at, 4)}),
                              (f"the {pin_name} at {at:.1f} mm would cut the teeth of the {name}: it is on a crank "
                               f"disc {fastening}; raise it on spacers so that it clears the neighbouring gear",)))
    part = _gear_part(name, code, gear, radius, scale, hw, holes, label_near=(-0.5 * gear.pitch_radius, 0.0))
    if notes:
        part = Part(part.name, part.shape, part.engrave, part.info, part.notes + tuple(notes))
    return [part, *extra]


def _cycloid(p: Mapping[str, float], scale: float, settings: GearSettings, hw: Hardware,
             step=_no_step) -> list[Part]:
    k = teeth_per_unit(scale, settings)
    module = 2.0 * scale / k
    r_t, r_e = int(p["r_t"]), int(p["r_e"])
    r_s, d_fh = float(p["r_s"]), float(p["d_fh"])
    turntable = _axle_gear("turntable gear", "TURNTABLE", r_t, k, module, scale, settings, hw, step=step)
    external = _axle_gear("external gear", "GEAR E", r_e, k, module, scale, settings, hw, pin=("slider pin hole", r_s),
                          step=step)
    g_e, fulcrum, d_fe = cycloid_positions(p)
    # The arm pivots at F and the slider pin slides in its slot between d_FE - r_S and d_FE + r_S from F.
    slot_lo, slot_hi = (d_fe - r_s) * scale, (d_fe + r_s) * scale
    end = hw.arm_width / 2.0
    arm = _bar([-end, slot_hi + end], hw.arm_width)
    slot = LineString([(slot_lo, 0.0), (max(slot_hi, slot_lo + 1e-3), 0.0)]).buffer((hw.pin_hole + 0.2) / 2.0,
                                                                                   quad_segs=16)
    arm_holes = [("pivot hole", (0.0, 0.0), hw.pin_hole), ("pen hole", (d_fh * scale, 0.0), hw.pen_hole)]
    arm_shape = _with_holes("pen arm", arm, arm_holes, hw.wall)
    pen_to_slot = slot.distance(_disc((d_fh * scale, 0.0), hw.pen_hole))
    if pen_to_slot < hw.wall:
        raise ConstraintViolation(f"pen arm: the pen hole is {pen_to_slot:.2f} mm from the slider slot, expected at "
                                  f"least {hw.wall:g} mm", constraint="pen arm slot", margin=pen_to_slot - hw.wall)
    arm_shape = arm_shape.difference(slot)
    arm_part = Part("pen arm", arm_shape, _label(arm_shape, "ARM", hw, near=((d_fh * scale + slot_lo) / 2, 0)),
                    MappingProxyType({"length_mm": round(slot_hi + 2 * end, 3), "pivot_to_pen_mm": d_fh * scale,
                                      "slot_mm": [round(slot_lo, 3), round(slot_hi, 3)]}))
    axles = [("turntable axle", (0.0, 0.0), hw.axle_hole),
             ("external gear axle", tuple(g_e * scale), hw.axle_hole),
             ("fulcrum pivot", tuple(fulcrum * scale), hw.pin_hole)]
    plate = _plate([a[1] for a in axles], hw.arm_width)
    plate_shape = _with_holes("base plate", plate, axles, hw.wall)
    marks = [("T", (0.0, 0.0)), ("E", tuple(g_e * scale)), ("F", tuple(fulcrum * scale))]
    plate_part = Part("base plate", plate_shape,
                      _plate_labels(plate_shape, ("BASE", tuple(g_e * scale / 2)), marks, hw),
                      MappingProxyType({"axles_mm": {n: [round(c[0], 3), round(c[1], 3)] for n, c, _ in axles}}))
    return [*turntable, *external, arm_part, plate_part]


def _hoot_nanny(p: Mapping[str, float], scale: float, settings: GearSettings, hw: Hardware,
                step=_no_step) -> list[Part]:
    k = teeth_per_unit(scale, settings)
    module = 2.0 * scale / k
    r_t, r_g1, r_g2 = int(p["r_t"]), int(p["r_g1"]), int(p["r_g2"])
    r_p1, r_p2, l1, l2 = (float(p[n]) for n in ("r_p1", "r_p2", "l1", "l2"))
    parts = [
        *_axle_gear("turntable gear", "TURNTABLE", r_t, k, module, scale, settings, hw, step=step),
        *_axle_gear("gear 1", "GEAR 1", r_g1, k, module, scale, settings, hw, pin=("pivot pin hole", r_p1), step=step),
        *_axle_gear("gear 2", "GEAR 2", r_g2, k, module, scale, settings, hw, pin=("pivot pin hole", r_p2), step=step),
    ]
    for index, length in ((1, l1), (2, l2)):
        name = f"arm {index}"
        end = hw.arm_width / 2.0
        bar = _bar([0.0, length * scale], hw.arm_width)
        shape = _with_holes(name, bar, [("pivot hole", (0.0, 0.0), hw.pin_hole),
                                        ("pen hole", (length * scale, 0.0), hw.pen_hole)], hw.wall)
        parts.append(Part(name, shape, _label(shape, f"ARM {index}", hw, near=(length * scale / 2, 0)),
                          MappingProxyType({"length_mm": round(length * scale + 2 * end, 3),
                                            "pivot_to_pen_mm": round(length * scale, 4)})))
    g1, g2 = (g * scale for g in hoot_nanny_positions(p))
    axles = [("turntable axle", (0.0, 0.0), hw.axle_hole), ("gear 1 axle", tuple(g1), hw.axle_hole),
             ("gear 2 axle", tuple(g2), hw.axle_hole)]
    plate = _plate([a[1] for a in axles], hw.arm_width)
    shape = _with_holes("base plate", plate, axles, hw.wall)
    marks = [("T", (0.0, 0.0)), ("G1", tuple(g1)), ("G2", tuple(g2))]
    parts.append(Part("base plate", shape, _plate_labels(shape, ("BASE", tuple((g1 + g2) / 3)), marks, hw),
                      MappingProxyType({"axles_mm": {n: [round(c[0], 3), round(c[1], 3)] for n, c, _ in axles}})))
    return parts


_BUILDERS = {
    "spirograph": _spirograph,
    "elliptic_spirograph": _elliptic_spirograph,
    "cycloid_drawing_machine": _cycloid,
    "hoot_nanny": _hoot_nanny,
}


def machine_parts(machine: str, params: Mapping[str, float], scale: float,
                  settings: GearSettings | None = None, hardware: Hardware | None = None,
                  report: Reporter | None = None) -> list[Part]:
    """The flat parts of one drawing machine at ``scale`` mm per model unit.

    Parameters
    ----------
    machine : str
        A machine name from :mod:`design.machines` (``"spirograph"``, ``"elliptic_spirograph"``,
        ``"cycloid_drawing_machine"``, ``"hoot_nanny"``).
    params : mapping
        The design's parameters; completed with defaults and validated by the machine's model.
    scale : float
        Millimetres per model unit (e.g. 5: a radius-3 gear gets a 15 mm pitch radius).
    settings : GearSettings, optional
        Tooth system (module, pressure angle, ...).
    hardware : Hardware, optional
        Hole and arm sizes.
    report : Reporter, optional
        Given a :class:`common.progress.Progress` of stage :data:`GEARS_STAGE` before each gear is generated
        (``done`` and ``total`` count teeth, the message is ``"generating <part> (<teeth> teeth)"``), and once
        more when every part is made (``done == total``). Generation takes time in proportion to the teeth
        (seconds for a few hundred), so the teeth over :func:`part_sizes` measure the whole work. A stop asked for
        ends the work with :class:`common.progress.Cancelled` before the next gear.

    Raises
    ------
    ParameterError
        Unknown machine, bad parameter or scale.
    ConstraintViolation
        The design is infeasible, or a hole does not fit in its part at this scale.
    """
    validated, settings, hardware = checked_design(machine, params, scale, settings, hardware)
    report = Reporter.of(report)
    total = sum(size.teeth for size in part_sizes(machine, validated, scale, settings, hardware))
    done = 0

    def gear_started(part_name: str, teeth: int) -> None:
        nonlocal done
        report(GEARS_STAGE, done, total, f"generating {part_name} ({teeth} teeth)")
        done += teeth

    parts = _BUILDERS[machine](validated, float(scale), settings, hardware, step=gear_started)
    report(GEARS_STAGE, done, total, f"generated the {len(parts)} parts ({total} teeth)")
    return parts
