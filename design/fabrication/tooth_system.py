"""The tooth system of every gear the station cuts: :class:`GearSettings` and what follows from it.

Module, pressure angle, addendum, dedendum, root fillet and backlash describe the rack cutter that generates external
gears (:mod:`design.fabrication.gears`); from them follow the depth of the rack's straight flank, the smallest tooth
count cut without undercut, and the teeth per unit of model radius at a given scale.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from design.errors import ParameterError, parameter_error


@dataclass(frozen=True)
class GearSettings:
    """Tooth system of every gear of a machine (ISO 53 basic rack by default).

    Parameters
    ----------
    module : float
        Nominal module (mm). The module actually used is ``2·scale/k`` for the integer ``k`` closest to
        ``2·scale/module`` (at least 1), so that every integer radius gets an integer tooth count.
    pressure_angle : float
        Pressure angle (degrees).
    addendum : float
        Addendum, in modules (tooth height above the pitch curve).
    dedendum : float
        Dedendum, in modules (depth below the pitch curve; ``dedendum - addendum`` is the tip clearance).
    root_fillet : float
        Radius of the rack cutter's tip rounding, in modules; it leaves a trochoidal fillet at the tooth root.
    backlash : float
        Circumferential backlash of a mesh (mm, at the pitch curve); each gear's teeth are thinned by half of it.
    steps_per_pitch : int
        Rack/cutter positions per circular pitch in the simulated generation (finer = smoother flanks).
    """

    module: float = 1.5
    pressure_angle: float = 20.0
    addendum: float = 1.0
    dedendum: float = 1.25
    root_fillet: float = 0.38
    backlash: float = 0.15
    steps_per_pitch: int = 32

    def __post_init__(self) -> None:
        checks = [
            ("module", self.module > 0, "a positive length (mm)"),
            ("pressure_angle", 10.0 <= self.pressure_angle <= 30.0, "an angle in [10, 30] degrees"),
            ("addendum", 0.3 <= self.addendum <= 1.5, "a number of modules in [0.3, 1.5]"),
            ("dedendum", self.addendum < self.dedendum <= 2.0, "more than the addendum and at most 2 modules"),
            ("root_fillet", 0.0 <= self.root_fillet <= 0.6, "a number of modules in [0, 0.6]"),
            ("backlash", self.backlash >= 0.0, "a non-negative length (mm)"),
            ("steps_per_pitch", 4 <= int(self.steps_per_pitch) <= 400, "an integer in [4, 400]"),
        ]
        for name, ok, expected in checks:
            if not ok:
                raise parameter_error("gear settings", name, expected, getattr(self, name))

    @property
    def alpha(self) -> float:
        """Pressure angle in radians."""
        return math.radians(self.pressure_angle)


def rack_flank_depth(settings: GearSettings, module: float | None = None) -> float:
    """How deep (in modules) the straight flank of the rack cutter of external gears reaches below its pitch line.

    The rack's tip lies a dedendum below the pitch line, and its corners are rounded with the radius ``ρ`` that
    :func:`_rack_tooth` uses: the root fillet, or less where the tip is too narrow for it (a large fillet, a steep
    pressure angle or a deep dedendum; the tip's width depends on the backlash in mm, hence on the module). The
    rounding is tangent to the flank where its outward normal is ``(cos α, -sin α)``: its centre lies ``ρ`` above
    the tip line and the tangent point ``ρ·sin α`` below the centre, so the straight flank ends
    ``dedendum - ρ·(1 - sin α)`` below the pitch line (1.0 modules for the ISO 53 rack at 20°).

    Parameters
    ----------
    settings : GearSettings
    module : float, optional
        Module actually used (mm); default ``settings.module``.
    """
    module = settings.module if module is None else float(module)
    # The rack tooth is the gear's tooth space: half a pitch wide on the pitch line, widened by half the backlash
    # (how external_gear and elliptic_gear thin the teeth).
    space = math.pi * module / 2.0 + settings.backlash / 2.0
    depth = settings.dedendum * module
    rho = rack_tip_radius(settings, module, rack_half_tip(settings, module, space, depth))
    return (depth - rho * (1.0 - math.sin(settings.alpha))) / module


def undercut_limit(settings: GearSettings, module: float | None = None) -> float:
    """Tooth count below which the rack cutter undercuts a circular external gear: ``2·h/sin²α``.

    The rack's flank touches the gear on the line of action, which meets the base circle at the interference
    point ``r·sin α`` from the pitch point, i.e. ``r·sin²α`` below the pitch line. The involute starts there; a
    straight flank reaching deeper (``h`` = :func:`rack_flank_depth`, in modules) cuts in behind it. Hence
    undercut when ``h·m > r·sin²α``, i.e. ``z = 2r/m < 2h/sin²α``. The tip rounding below the flank's end only
    leaves the trochoidal fillet. An elliptic gear is compared by the equivalent tooth count of its most curved
    place. Internal gears have no such limit (see :attr:`Gear.undercut`).

    Parameters
    ----------
    settings : GearSettings
    module : float, optional
        Module actually used (mm); default ``settings.module``. It matters only when the rack's tip is too narrow
        for the root fillet, through the backlash (mm) that widens it.
    """
    return 2.0 * rack_flank_depth(settings, module) / math.sin(settings.alpha) ** 2


def min_teeth_without_undercut(settings: GearSettings, module: float | None = None) -> int:
    """Smallest tooth count of a circular external gear that the rack cuts without undercut.

    The whole number at or above :func:`undercut_limit` (18 for the default settings at 20°, 22 for a rack
    without tip rounding).
    """
    return int(math.ceil(undercut_limit(settings, module) - 1e-9))


def teeth_per_unit(scale: float, settings: GearSettings) -> int:
    """Teeth per unit of model radius ``k``: the module used is ``2·scale/k``."""
    if not scale > 0:
        raise parameter_error("fabrication", "scale", "a positive number of mm per model unit", scale)
    return max(1, int(round(2.0 * scale / settings.module)))


def rack_half_tip(settings: GearSettings, module: float, space_width: float, depth: float) -> float:
    """Half the width (mm) of the rack tooth's tip line, before rounding (the rack tooth is drawn in
    :mod:`design.fabrication.gears`)."""
    half_tip = space_width / 2.0 - depth * math.tan(settings.alpha)
    if half_tip <= 0:
        raise ParameterError(f"gear settings: a dedendum of {depth / module:.2f} modules leaves no tip on the rack "
                             f"cutter at a pressure angle of {settings.pressure_angle} degrees")
    return half_tip


def rack_tip_radius(settings: GearSettings, module: float, half_tip: float) -> float:
    """Radius (mm) of the rack tooth's corner rounding: the root fillet, or less if the tip is too narrow for it."""
    # The corner between the tip line and the flank has an interior angle of 90° + α; a rounding of radius ρ
    # starts ρ/tan(half that angle) from the corner, which must stay on the tip (2 % of it left straight).
    half_corner = (math.pi / 2 + settings.alpha) / 2.0
    return min(settings.root_fillet * module, 0.98 * half_tip * math.tan(half_corner))
