"""The Cycloid Drawing Machine (thesis A.2.3, Figure A.3; Joe Freedman's machine, single gear, fixed fulcrum).

The paper is on a turntable gear (radius ``r_t``, center G_T at the origin) which drives an external gear
(radius ``r_e``, center G_E at polar angle ``theta_te``, distance ``r_t + r_e``). A slider S on the external gear,
``r_s`` from its center, pulls a rod that pivots on a fixed fulcrum F at ``(d_tf, 0)``; the pen holder H is on the
rod, ``d_fh`` from F. The drawing is the pen's path in the turntable's (rotating) frame (A.52-A.53)::

    H(t) = F + d_fh (S - F) / |S - F|,   S = G_E + r_s (cos theta_es, sin theta_es),   theta_es = -(r_t / r_e) t
    gamma(t) = R_{-t} H(t)

Time ``t`` is the turntable's angle (A.55). Period (lcm rule): ``T = 2 pi lcm(r_t, r_e) / r_t``.

The drawing-bounds condition A.47 is evaluated exactly: H moves on the arc of radius ``d_fh`` around F whose
directions span ``theta_fe -+ alpha`` with ``alpha = arcsin(r_s / d_fe)`` (the rod's widest swing, where it is
tangent to the slider's circle; the thesis writes arctan, a slight under-estimate), and its farthest point from G_T
is the arc point closest in direction to the x axis. The distance ``d_fe`` is the law of cosines in the triangle
G_T F G_E (the thesis's formula after A.44 has ``d_fh`` where ``d_tf`` is meant).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

from design.machines.base import TurntableMachine
from design.machines.constraints import Constraint, coprime_constraint, ordered, positive
from design.machines.parameters import MAX_GEAR_RADIUS, angle, gear_period, gear_radius, length, scalar_arrays
from design.machines.shapes import Circle, Point, Segment, Shape, xy

#: Arbitrary bound B_d of A.51 on the fulcrum's distance (gear-radius units).
MAX_FULCRUM_DISTANCE = 2.0 * MAX_GEAR_RADIUS


def fulcrum_to_gear(P: Mapping[str, np.ndarray]) -> np.ndarray:
    """Complex vector from the fulcrum F to the external gear's center G_E."""
    return (P["r_t"] + P["r_e"]) * np.exp(1j * P["theta_te"]) - P["d_tf"]


def farthest_pen_distance(P: Mapping[str, np.ndarray]) -> np.ndarray:
    """Exact maximum over time of the pen's distance to the turntable's center (A.47-A.50, see module doc)."""
    v = fulcrum_to_gear(P)
    d_fe = np.abs(v)
    alpha = np.arcsin(np.clip(P["r_s"] / d_fe, 0.0, 1.0))
    off_axis = np.abs(np.angle(v))  # angular distance of the rod's mean direction from the +x axis, in [0, pi]
    closest = np.maximum(off_axis - alpha, 0.0)
    d_tf, d_fh = P["d_tf"], P["d_fh"]
    return np.sqrt(np.maximum(d_tf * d_tf + d_fh * d_fh + 2.0 * d_tf * d_fh * np.cos(closest), 0.0))


class CycloidDrawingMachine(TurntableMachine):
    """Cycloid Drawing Machine: 2 discrete + 4 continuous parameters (Table 3.2)."""

    name = "cycloid_drawing_machine"
    title = "Cycloid Drawing Machine"
    description = (
        "A turntable drives an external gear whose slider swings a rod about a fixed fulcrum; the pen on the rod "
        "draws on the turning paper."
    )
    parameters = (
        gear_radius("r_t", 7, "radius of the turntable gear", "A.41"),
        gear_radius("r_e", 4, "radius of the external gear", "A.41"),
        length(
            "d_tf", 9.0, MAX_FULCRUM_DISTANCE, "distance from the turntable's center to the fulcrum", "A.51",
            category="practical dimensions",
        ),
        angle("theta_te", 2.4, "polar angle of the external gear's center", "A.46"),
        length("r_s", 3.5, MAX_GEAR_RADIUS - 1, "distance from the external gear's center to the slider", "A.44"),
        length(
            "d_fh", 10.5, 2.0 * MAX_FULCRUM_DISTANCE, "distance from the fulcrum to the pen holder, along the rod",
            "A.43",
        ),
    )  # fmt: skip

    def constraints(self) -> Iterable[Constraint]:
        def gear_clearance(P):
            return np.abs(fulcrum_to_gear(P)) - P["r_e"]

        yield ordered("fulcrum_outside_turntable", "d_tf", ">", "r_t", "A.42", "the fulcrum is off the turntable")
        yield positive("pen_offset_positive", "d_fh", "A.43", "valid layout")
        yield Constraint(
            "pen_before_gear",
            "valid layout",
            "A.43",
            lambda P: gear_clearance(P) - P["d_fh"],
            lambda p: (
                f"d_fh must be smaller than d_fe - r_e = {float(gear_clearance(scalar_arrays(p))):.6g} (the pen holder "
                f"sits between the fulcrum and the external gear, whose center is "
                f"d_fe = {float(np.abs(fulcrum_to_gear(scalar_arrays(p)))):.6g} from the fulcrum), got {p['d_fh']:g}"
            ),
            depends=("r_t", "r_e", "d_tf", "theta_te", "d_fh"),
        )
        yield ordered("slider_inside_gear", "r_s", "<", "r_e", "A.44")
        yield coprime_constraint("A.45", "r_t", "r_e")
        yield self._pen_on_turntable(
            "A.47", farthest_pen_distance, "its farthest distance from the turntable's center must be below"
        )

    def sampling_box(self, radii: Mapping[str, np.ndarray]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """The slider inside its gear (A.44) and the fulcrum off the turntable (A.42)."""
        box = super().sampling_box(radii)
        r_e = np.asarray(radii["r_e"], dtype=float)
        box["r_s"] = (np.zeros_like(r_e), np.minimum(r_e, box["r_s"][1]))
        box["d_tf"] = (np.asarray(radii["r_t"], dtype=float), box["d_tf"][1])
        return box

    def _period(self, P: Mapping[str, np.ndarray]) -> np.ndarray:
        return gear_period(P["r_t"], P["r_e"])

    def _fixed_frame(self, P: Mapping[str, np.ndarray], t: np.ndarray) -> tuple[np.ndarray, ...]:
        """Fulcrum, gear center, slider and pen in the machine's fixed frame at times t."""
        gear = (P["r_t"] + P["r_e"]) * np.exp(1j * P["theta_te"])
        theta_es = -(P["r_t"] / P["r_e"]) * t  # law of gearing, integrated (A.54)
        slider = gear + P["r_s"] * np.exp(1j * theta_es)
        rod = slider - P["d_tf"]
        pen = P["d_tf"] + P["d_fh"] * rod / np.abs(rod)
        return P["d_tf"] + 0j, gear, slider, pen

    def mechanism(self, params: Mapping[str, float], t: float, frame: str = "drawing") -> list[Shape]:
        p, (fulcrum, gear, slider, pen), turntable = self._turntable_preview(params, t, frame)
        return turntable + [
            Circle("external gear", xy(gear), float(p["r_e"])),
            Segment("slider crank", xy(gear), xy(slider)),
            Segment("rod", xy(fulcrum), xy(slider)),
            Point("fulcrum", xy(fulcrum)),
            Point("slider", xy(slider)),
            Point("pen", xy(pen)),
        ]
