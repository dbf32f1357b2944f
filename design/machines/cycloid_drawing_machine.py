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

from design.machines.base import (
    MAX_GEAR_RADIUS,
    Circle,
    Constraint,
    DrawingMachine,
    Parameter,
    Point,
    Segment,
    Shape,
    _xy,
    coprime_constraint,
    gear_period,
)

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


class CycloidDrawingMachine(DrawingMachine):
    """Cycloid Drawing Machine: 2 discrete + 4 continuous parameters (Table 3.2)."""

    name = "cycloid_drawing_machine"
    title = "Cycloid Drawing Machine"
    description = (
        "A turntable drives an external gear whose slider swings a rod about a fixed fulcrum; the pen on the rod "
        "draws on the turning paper."
    )
    symmetry_gear = "r_t"
    parameters = (
        Parameter(
            "r_t", "discrete", 7, 1, MAX_GEAR_RADIUS - 1, "radius of the turntable gear",
            category="finite pattern", equation="A.41",
        ),
        Parameter(
            "r_e", "discrete", 4, 1, MAX_GEAR_RADIUS - 1, "radius of the external gear",
            category="finite pattern", equation="A.41",
        ),
        Parameter(
            "d_tf", "continuous", 9.0, 0.0, MAX_FULCRUM_DISTANCE,
            "distance from the turntable's center to the fulcrum", equation="A.51",
        ),
        Parameter(
            "theta_te", "continuous", 2.4, 0.0, float(np.pi), "polar angle of the external gear's center",
            unit="rad", category="symmetry reduction", equation="A.46",
        ),
        Parameter(
            "r_s", "continuous", 3.5, 0.0, MAX_GEAR_RADIUS - 1,
            "distance from the external gear's center to the slider", category="valid layout", equation="A.44",
        ),
        Parameter(
            "d_fh", "continuous", 10.5, 0.0, 2.0 * MAX_FULCRUM_DISTANCE,
            "distance from the fulcrum to the pen holder, along the rod", category="valid layout", equation="A.43",
        ),
    )  # fmt: skip

    def constraints(self) -> Iterable[Constraint]:
        def gear_clearance(P):
            return np.abs(fulcrum_to_gear(P)) - P["r_e"]

        yield Constraint(
            "fulcrum_outside_turntable",
            "valid layout",
            "A.42",
            lambda P: P["d_tf"] - P["r_t"],
            lambda p: f"d_tf must exceed r_t = {p['r_t']:g} (the fulcrum is off the turntable), got {p['d_tf']:g}",
            depends=("d_tf", "r_t"),
        )
        yield Constraint(
            "pen_offset_positive",
            "valid layout",
            "A.43",
            lambda P: P["d_fh"],
            lambda p: f"d_fh must be greater than 0, got {p['d_fh']:g}",
            depends=("d_fh",),
        )
        yield Constraint(
            "pen_before_gear",
            "valid layout",
            "A.43",
            lambda P: gear_clearance(P) - P["d_fh"],
            lambda p: (
                f"d_fh must be smaller than d_fe - r_e = {float(gear_clearance(_arrays(p))):.6g} (the pen holder "
                f"sits between the fulcrum and the external gear, whose center is "
                f"d_fe = {float(np.abs(fulcrum_to_gear(_arrays(p)))):.6g} from the fulcrum), got {p['d_fh']:g}"
            ),
            depends=("r_t", "r_e", "d_tf", "theta_te", "d_fh"),
        )
        yield Constraint(
            "slider_inside_gear",
            "valid layout",
            "A.44",
            lambda P: P["r_e"] - P["r_s"],
            lambda p: f"r_s must be smaller than r_e = {p['r_e']:g}, got {p['r_s']:g}",
            depends=("r_e", "r_s"),
        )
        yield coprime_constraint("A.45", "r_t", "r_e")
        yield Constraint(
            "pen_on_turntable",
            "drawing bounds",
            "A.47",
            lambda P: P["r_t"] - farthest_pen_distance(P),
            lambda p: (
                f"the pen must stay on the turntable: its farthest distance from the turntable's center must be "
                f"below r_t = {p['r_t']:g}, got {float(farthest_pen_distance(_arrays(p))):.6g}"
            ),
            depends=("r_t", "r_e", "d_tf", "theta_te", "r_s", "d_fh"),
        )

    def _period(self, P: Mapping[str, np.ndarray]) -> np.ndarray:
        return gear_period(P["r_t"], P["r_e"])

    @staticmethod
    def _fixed_frame(P: Mapping[str, np.ndarray], t: np.ndarray):
        """Gear center, slider and pen in the machine's fixed frame at times t."""
        gear = (P["r_t"] + P["r_e"]) * np.exp(1j * P["theta_te"])
        theta_es = -(P["r_t"] / P["r_e"]) * t  # law of gearing, integrated (A.54)
        slider = gear + P["r_s"] * np.exp(1j * theta_es)
        rod = slider - P["d_tf"]
        pen = P["d_tf"] + P["d_fh"] * rod / np.abs(rod)
        return gear, slider, pen

    def _positions(self, P: Mapping[str, np.ndarray], t: np.ndarray) -> np.ndarray:
        _, _, pen = self._fixed_frame(P, t)
        return pen * np.exp(-1j * t)  # into the turntable's frame (A.52)

    def mechanism(self, params: Mapping[str, float], t: float, frame: str = "drawing") -> list[Shape]:
        self._check_frame(frame)
        p = self.validate(params)
        P = {k: np.float64(v) for k, v in p.items()}
        gear, slider, pen = self._fixed_frame(P, np.float64(t))
        fulcrum = complex(p["d_tf"], 0.0)
        turn = np.exp(-1j * t) if frame == "drawing" else 1.0
        gear, slider, pen, fulcrum = (z * turn for z in (gear, slider, pen, fulcrum))
        # A mark on the turntable shows its rotation (fixed on the paper in the drawing frame).
        mark = p["r_t"] * (1.0 if frame == "drawing" else np.exp(1j * t))
        return [
            Circle("turntable", (0.0, 0.0), float(p["r_t"])),
            Segment("turntable mark", (0.0, 0.0), _xy(mark)),
            Circle("external gear", _xy(gear), float(p["r_e"])),
            Segment("slider crank", _xy(gear), _xy(slider)),
            Segment("rod", _xy(fulcrum), _xy(slider)),
            Point("fulcrum", _xy(fulcrum)),
            Point("slider", _xy(slider)),
            Point("pen", _xy(pen)),
        ]


def _arrays(p: Mapping[str, float]) -> dict[str, np.ndarray]:
    return {k: np.float64(v) for k, v in p.items()}
