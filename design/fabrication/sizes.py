"""Sizes before building: the outer size of each part a machine's design makes, without generating its gears.

Generating gears takes seconds to minutes at large scales, their outer sizes do not: :func:`part_sizes` lets a part
too large for the sheet be refused, and the largest scale that fits be found, before any work.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from design.fabrication import layout
from design.fabrication.gears import ellipse_axes
from design.fabrication.layout import Hardware
from design.fabrication.tooth_system import GearSettings, teeth_per_unit


@dataclass(frozen=True)
class PartSize:
    """The outer size of one part, known from the design and the scale before the part is built.

    Attributes
    ----------
    name : str
        As in :func:`machine_parts`.
    width, height : float
        The bounding box of the designed outline, upright as :func:`machine_parts` makes it (mm); never smaller
        than the built part's.
    tolerance : float
        How much smaller the built part's box can be on each axis (mm): a gear's teeth do not reach every side of
        its tip circle.
    teeth : int
        Teeth to generate (0 for arms, plates and crank discs): the part's share of the building time.
    """

    name: str
    width: float
    height: float
    tolerance: float = 0.0
    teeth: int = 0


def part_sizes(machine: str, params: Mapping[str, float], scale: float,
               settings: GearSettings | None = None, hardware: Hardware | None = None) -> list[PartSize]:
    """The parts :func:`machine_parts` would make, with their outer sizes, in the same order, without building them.

    Milliseconds instead of the seconds or minutes gear generation takes at large scales: a part too large for the
    sheet is refused, and the largest scale that fits found, before any work.

    Raises
    ------
    ParameterError, ConstraintViolation
        As :func:`machine_parts` for the machine, the design and the scale (not for the holes, which are checked
        only when the parts are built).
    """
    validated, settings, hardware = layout.checked_design(machine, params, scale, settings, hardware)
    return _SIZERS[machine](validated, float(scale), settings, hardware)


def _gear_size(name: str, teeth: int, radius: float, module: float) -> PartSize:
    """An external gear of pitch radius ``radius`` (mm): its tip circle, less at most about a module on an axis
    where no tooth points (the nearest one is half a pitch away)."""
    return PartSize(name, 2.0 * radius, 2.0 * radius, tolerance=module + 1e-3 * radius, teeth=teeth)


def _disc_size(name: str, radius: float) -> PartSize:
    return PartSize(name, 2.0 * radius, 2.0 * radius, tolerance=1e-3 * radius + 0.05)


def _ring_size(teeth: int, radius: float, module: float, settings: GearSettings, hw: Hardware) -> PartSize:
    # The ring's outer edge is a plain circle (the dedendum and the rim outside the pitch circle), a polygon of
    # ring_gear's vertex count, turned by half a pitch: its box falls short of the circle's by the polygon's sagitta.
    outer = radius + settings.dedendum * module + hw.rim
    vertices = teeth * max(12, -(-256 // teeth))
    sagitta = outer * (1.0 - math.cos(2.0 * math.pi / vertices))
    return PartSize("fixed ring", 2.0 * outer, 2.0 * outer, tolerance=sagitta + 0.01, teeth=teeth)


def _axle_gear_sizes(name: str, radius: int, k: int, module: float, scale: float, settings: GearSettings,
                     hw: Hardware, pin: float | None = None) -> list[PartSize]:
    """As :func:`_axle_gear`: the gear, and its crank disc when the pin would cut the teeth."""
    tip = radius * scale + settings.addendum * module
    sizes = [_gear_size(name, k * radius, tip, module)]
    if pin is not None:
        root = radius * scale - settings.dedendum * module
        if layout.pin_mount(pin * scale, root, module, hw) == "crank":
            sizes.append(_disc_size(f"{name} crank", layout.crank_radius(pin * scale, hw)))
    return sizes


def _bar_size(name: str, length: float, hw: Hardware) -> PartSize:
    """An arm of ``length`` mm between its end holes' centres, ``arm_width`` wide with round ends."""
    return PartSize(name, length + hw.arm_width, hw.arm_width, tolerance=0.05)


def _plate_size(points: list[np.ndarray], hw: Hardware) -> PartSize:
    """A base plate: the axles' bounding box grown by ``arm_width`` on every side."""
    xy = np.asarray(points, dtype=float)
    span = xy.max(axis=0) - xy.min(axis=0) + 2.0 * hw.arm_width
    return PartSize("base plate", float(span[0]), float(span[1]), tolerance=0.05)


def _spirograph_sizes(p: Mapping[str, float], scale: float, settings: GearSettings, hw: Hardware) -> list[PartSize]:
    k = teeth_per_unit(scale, settings)
    module = 2.0 * scale / k
    r_f, r_r = int(p["r_f"]), int(p["r_r"])
    return [_ring_size(k * r_f, r_f * scale, module, settings, hw),
            _gear_size("rolling gear", k * r_r, r_r * scale + settings.addendum * module, module)]


def _elliptic_spirograph_sizes(p: Mapping[str, float], scale: float, settings: GearSettings,
                               hw: Hardware) -> list[PartSize]:
    k = teeth_per_unit(scale, settings)
    module = 2.0 * scale / k
    r_f, r_r, e = int(p["r_f"]), int(p["r_r"]), float(p["e"])
    # The blank is the pitch ellipse grown by the addendum; the tips reach it on the axes less about a module.
    a, b = ellipse_axes(k * r_r * module / 2.0, e)
    ha = settings.addendum * module
    gear = PartSize("elliptic gear", 2.0 * (a + ha), 2.0 * (b + ha), tolerance=module + 1e-3 * a, teeth=k * r_r)
    return [_ring_size(k * r_f, r_f * scale, module, settings, hw), gear]


def _cycloid_sizes(p: Mapping[str, float], scale: float, settings: GearSettings, hw: Hardware) -> list[PartSize]:
    k = teeth_per_unit(scale, settings)
    module = 2.0 * scale / k
    r_t, r_e, r_s = int(p["r_t"]), int(p["r_e"]), float(p["r_s"])
    g_e, fulcrum, d_fe = layout.cycloid_positions(p)
    # The pen arm runs from half an arm's width behind the pivot to half a width beyond the slot's far end.
    slot_hi = (d_fe + r_s) * scale
    arm = PartSize("pen arm", slot_hi + 2.0 * hw.arm_width, hw.arm_width, tolerance=0.05)
    return [*_axle_gear_sizes("turntable gear", r_t, k, module, scale, settings, hw),
            *_axle_gear_sizes("external gear", r_e, k, module, scale, settings, hw, pin=r_s),
            arm, _plate_size([np.zeros(2), g_e * scale, fulcrum * scale], hw)]


def _hoot_nanny_sizes(p: Mapping[str, float], scale: float, settings: GearSettings, hw: Hardware) -> list[PartSize]:
    k = teeth_per_unit(scale, settings)
    module = 2.0 * scale / k
    g1, g2 = layout.hoot_nanny_positions(p)
    return [*_axle_gear_sizes("turntable gear", int(p["r_t"]), k, module, scale, settings, hw),
            *_axle_gear_sizes("gear 1", int(p["r_g1"]), k, module, scale, settings, hw, pin=float(p["r_p1"])),
            *_axle_gear_sizes("gear 2", int(p["r_g2"]), k, module, scale, settings, hw, pin=float(p["r_p2"])),
            _bar_size("arm 1", float(p["l1"]) * scale, hw), _bar_size("arm 2", float(p["l2"]) * scale, hw),
            _plate_size([np.zeros(2), g1 * scale, g2 * scale], hw)]


_SIZERS = {
    "spirograph": _spirograph_sizes,
    "elliptic_spirograph": _elliptic_spirograph_sizes,
    "cycloid_drawing_machine": _cycloid_sizes,
    "hoot_nanny": _hoot_nanny_sizes,
}
