"""What a machine's parts and their sizes share: the hardware, the model positions of the axles, where a pin goes,
and the check of a design before anything is built or measured (:mod:`design.fabrication.parts`,
:mod:`design.fabrication.sizes`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np

from design.errors import ConstraintViolation, parameter_error
from design.fabrication.catalog import FABRICABLE_MACHINES
from design.fabrication.tooth_system import GearSettings

#: The largest scale, in mm per model unit: at 1000 a gear of model radius 1 is 2 m across, beyond any laser's bed,
#: with over 1300 teeth at the default module (and a scale of 1e308 overflows the tooth count).
MAX_SCALE = 1000.0

@dataclass(frozen=True)
class Hardware:
    """Physical sizes of what the flat parts hold (mm).

    Parameters
    ----------
    pen_hole : float
        Diameter of the pen hole (a ballpoint refill tip by default).
    axle_hole : float
        Diameter of gear axles (an M4 bolt by default).
    pin_hole : float
        Diameter of pivot and slider pins (M3).
    arm_width : float
        Width of arms and of the base plate's border around each axle.
    rim : float
        Width of a ring gear's plain rim outside its tooth roots.
    wall : float
        Least material left between a hole and an edge.
    label_height : float
        Height of engraved capitals.
    """

    pen_hole: float = 3.0
    axle_hole: float = 4.2
    pin_hole: float = 3.2
    arm_width: float = 12.0
    rim: float = 10.0
    wall: float = 1.5
    label_height: float = 4.0

    def __post_init__(self) -> None:
        for size in fields(self):  # every field is a length
            name, value = size.name, getattr(self, size.name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise parameter_error("hardware", name, "a positive length (mm)", value)


def pin_mount(at: float, root_radius: float, module: float, hw: Hardware) -> str:
    """Where a pin ``at`` mm from a gear's axle goes: ``"axle"`` (too near it for a hole of its own), ``"hole"``
    (in the gear) or ``"crank"`` (so near the rim that its hole would cut the teeth: on a crank disc)."""
    if at < (hw.axle_hole + hw.pin_hole) / 2.0 + hw.wall:
        return "axle"
    if at <= root_radius - hw.wall - hw.pin_hole / 2.0 - 0.5 * module:
        return "hole"
    return "crank"


def crank_radius(at: float, hw: Hardware) -> float:
    """Radius of the crank disc that carries a pin ``at`` mm from the axle."""
    return at + max(hw.pin_hole / 2.0 + 2.0 * hw.wall, hw.arm_width / 2.0)


def cycloid_positions(p: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray, float]:
    """Model positions (Appendix A.2.3): the external gear's centre G_E, the fulcrum F, and the distance F-G_E.

    G_T is at the origin, F on +x, G_E at angle theta_TE.
    """
    r_t, r_e, d_tf, theta_te = int(p["r_t"]), int(p["r_e"]), float(p["d_tf"]), float(p["theta_te"])
    g_e = (r_t + r_e) * np.array([math.cos(theta_te), math.sin(theta_te)])
    fulcrum = np.array([d_tf, 0.0])
    return g_e, fulcrum, float(np.linalg.norm(g_e - fulcrum))


def hoot_nanny_positions(p: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """Model positions of gear 1 (on +x) and gear 2 (at angle theta_12), the turntable at the origin."""
    r_t, r_g1, r_g2, theta_12 = int(p["r_t"]), int(p["r_g1"]), int(p["r_g2"]), float(p["theta_12"])
    return (np.array([r_t + r_g1, 0.0]),
            (r_t + r_g2) * np.array([math.cos(theta_12), math.sin(theta_12)]))


def checked_design(machine: str, params: Mapping[str, float], scale: float, settings: GearSettings | None,
             hardware: Hardware | None) -> tuple[Mapping[str, float], GearSettings, Hardware]:
    """The validated design and the settings (defaults filled in), or the error that refuses them."""
    from design.machines import get_machine

    settings = settings if settings is not None else GearSettings()
    hardware = hardware if hardware is not None else Hardware()
    if machine not in FABRICABLE_MACHINES:
        raise parameter_error("fabrication", "machine", f"one of {list(FABRICABLE_MACHINES)}", machine)
    if not (isinstance(scale, (int, float)) and math.isfinite(scale) and 0 < scale <= MAX_SCALE):
        raise parameter_error("fabrication", "scale", f"a positive number of mm per model unit, at most "
                              f"{MAX_SCALE:g} (a metre per unit is beyond any laser's bed)", scale)
    model = get_machine(machine)
    validated = model.validate(params)
    violations = model.violations(validated)
    if violations:
        first = violations[0]
        raise ConstraintViolation(f"{machine}: the design is not feasible: {first.message}",
                                  constraint=first.constraint, margin=first.margin)
    return validated, settings, hardware
