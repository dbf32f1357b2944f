"""Gear profiles for laser cutting: involute circular gears, internal ring gears and elliptic gears.

Thesis 3.6.3: gear profiles are generated procedurally, the way a gear shop makes them, so that a laser cutter gets
an exact outline. We simulate the generating process itself with polygon Booleans (shapely/GEOS):

- **external gears** (circular or elliptic) are cut by a *rack cutter* that rolls without slipping along the gear's
  pitch curve (Bair's method for non-circular gears): the gear is its addendum blank minus the union of every
  rack position. The flanks come out as involutes of the base circle, the rack's rounded tip leaves a trochoidal root
  fillet, and small tooth counts get their genuine undercut;
- **internal (ring) gears** are cut by a *shaper cutter*, itself an involute pinion, rolling inside the ring blank.

The pitch curve is the model's primitive: a circle of radius ``r × scale``, or the elliptic Spirograph's ellipse
whose perimeter is ``2π r_eq × scale``. Tooth counts follow from the radius and the module: every gear of a machine
has ``z = k·r`` teeth for one integer ``k`` (teeth per unit of radius), so gears of integer radii always share one
module ``m = 2·scale/k`` and mesh at the model's centre distances. The tooth system (:class:`GearSettings`, the
module, the teeth per unit) is in :mod:`design.fabrication.tooth_system`, re-exported here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import shapely
import shapely.affinity
import shapely.errors
from scipy.special import ellipe, ellipeinc
from shapely.geometry import LineString, MultiPolygon, Polygon

from design.errors import ParameterError, parameter_error
from design.fabrication.tooth_system import (
    GearSettings,
    min_teeth_without_undercut,
    rack_flank_depth,
    rack_half_tip,
    rack_tip_radius,
    teeth_per_unit,
    undercut_limit,
)

#: The tooth system of a gear made without settings of its own.
DEFAULT_SETTINGS = GearSettings()

__all__ = [
    "GearSettings",
    "Gear",
    "EllipticPitch",
    "CircularPitch",
    "teeth_per_unit",
    "external_gear",
    "elliptic_gear",
    "ring_gear",
    "min_teeth_without_undercut",
    "undercut_limit",
    "rack_flank_depth",
    "ellipse_axes",
]


# ---------------------------------------------------------------------------------------------------------------
# Pitch curves: positions, unit tangents and outward normals by arc length (counter-clockwise).


@dataclass(frozen=True)
class CircularPitch:
    """A circular pitch curve of radius ``radius`` (mm), arc length measured from the +x axis."""

    radius: float

    @property
    def perimeter(self) -> float:
        return 2.0 * math.pi * self.radius

    def frame(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Points, unit tangents and outward unit normals at arc lengths ``s``, each ``(len(s), 2)``."""
        theta = np.asarray(s, dtype=float) / self.radius
        normal = np.stack([np.cos(theta), np.sin(theta)], axis=-1)
        tangent = np.stack([-np.sin(theta), np.cos(theta)], axis=-1)
        return self.radius * normal, tangent, normal

    def polyline(self, n: int = 720) -> np.ndarray:
        return self.frame(np.linspace(0.0, self.perimeter, n, endpoint=False))[0]


@dataclass(frozen=True)
class EllipticPitch:
    """An elliptic pitch curve ``(a cos t, b sin t)`` (mm, ``a >= b``), arc length measured from ``(a, 0)``.

    Arc length uses the exact incomplete elliptic integral (thesis Eq. A.38); its inverse is tabulated and then
    refined by Newton steps, so ``frame(s)`` is exact to rounding.
    """

    a: float
    b: float
    _table: tuple[np.ndarray, np.ndarray] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not (self.a >= self.b > 0):
            raise parameter_error("elliptic pitch curve", "b", f"a positive length <= a = {self.a}", self.b)
        t = np.linspace(0.0, 2.0 * math.pi, 4097)
        object.__setattr__(self, "_table", (self.arc_length(t), t))

    @property
    def m(self) -> float:
        """Parameter ``m = e²`` of scipy's elliptic integrals."""
        return 1.0 - (self.b / self.a) ** 2

    @property
    def perimeter(self) -> float:
        return 4.0 * self.a * float(ellipe(self.m))

    def arc_length(self, t: np.ndarray) -> np.ndarray:
        """Arc length from ``t = 0`` to ``t`` (any real ``t``)."""
        t = np.asarray(t, dtype=float)
        return self.a * (ellipeinc(t - math.pi / 2, self.m) + float(ellipe(self.m)))

    def parameter(self, s: np.ndarray) -> np.ndarray:
        """The curve parameter ``t`` at arc length ``s`` (inverse of :meth:`arc_length`)."""
        s = np.asarray(s, dtype=float)
        perimeter = self.perimeter
        turns = np.floor(s / perimeter)
        local = s - turns * perimeter
        table_s, table_t = self._table
        t = np.interp(local, table_s, table_t)
        for _ in range(3):
            speed = np.hypot(self.a * np.sin(t), self.b * np.cos(t))
            t = t - (self.arc_length(t) - local) / speed
        return t + 2.0 * math.pi * turns

    def frame(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = self.parameter(s)
        point = np.stack([self.a * np.cos(t), self.b * np.sin(t)], axis=-1)
        tangent = np.stack([-self.a * np.sin(t), self.b * np.cos(t)], axis=-1)
        tangent /= np.linalg.norm(tangent, axis=-1, keepdims=True)
        normal = np.stack([tangent[:, 1], -tangent[:, 0]], axis=-1)
        return point, tangent, normal

    def polyline(self, n: int = 720) -> np.ndarray:
        return self.frame(np.linspace(0.0, self.perimeter, n, endpoint=False))[0]

    @property
    def min_curvature_radius(self) -> float:
        """Radius of curvature at the ends of the major axis, ``b²/a`` (the most curved place)."""
        return self.b**2 / self.a

    @property
    def max_curvature_radius(self) -> float:
        """Radius of curvature at the ends of the minor axis, ``a²/b`` (the flattest place)."""
        return self.a**2 / self.b


def ellipse_axes(equivalent_radius: float, eccentricity: float) -> tuple[float, float]:
    """Semi-axes ``(a, b)`` of the ellipse of eccentricity ``e`` whose perimeter is ``2π·r_eq`` (Eqs. A.16-A.17)."""
    if not 0.0 <= eccentricity < 1.0:
        raise parameter_error("ellipse", "e", "an eccentricity in [0, 1)", eccentricity)
    a = 2.0 * math.pi * equivalent_radius / (4.0 * float(ellipe(eccentricity**2)))
    return a, a * math.sqrt(1.0 - eccentricity**2)


# ---------------------------------------------------------------------------------------------------------------
# The generating tools.


def _rack_tooth(settings: GearSettings, module: float, space_width: float, height: float, depth: float) -> np.ndarray:
    """Outline of one rack-cutter tooth in rack coordinates ``(u, v)``.

    ``u`` runs along the rack's pitch line, ``v`` away from the gear being cut. The tooth is ``space_width`` wide
    on the pitch line, its flanks lean by the pressure angle, its tip lies ``depth`` below the pitch line with
    rounded corners, and it reaches ``height`` above the pitch line (beyond the blank). Counter-clockwise.
    """
    alpha = settings.alpha
    half_tip = rack_half_tip(settings, module, space_width, depth)
    half_corner = (math.pi / 2 + alpha) / 2.0
    rho = rack_tip_radius(settings, module, half_tip)
    points = []
    # Right side: from the top of the flank down to the tip, through the fillet.
    top_half = space_width / 2.0 + height * math.tan(alpha)
    points.append((top_half, height))
    if rho > 0:
        centre_u = half_tip - rho / math.tan(half_corner)
        centre_v = -depth + rho
        # Arc from the flank's tangent point (normal direction (cos α, -sin α)) down to the tip (normal (0, -1)).
        angles = np.linspace(-alpha, -math.pi / 2, 9)
        arc = np.stack([centre_u + rho * np.cos(angles), centre_v + rho * np.sin(angles)], axis=-1)
        right = [tuple(p) for p in arc]
    else:
        right = [(half_tip, -depth)]
    points.extend(right)
    points.extend((-u, v) for u, v in reversed(right))
    points.append((-top_half, height))
    outline = np.array(points[::-1])  # counter-clockwise
    return outline


def _rack_reach(alpha: float, ha: float, hf: float, p: float, radius: float) -> float:
    """How far (arc length) from a tooth space the rack cutter must roll to finish cutting it.

    The envelope is formed along the line of action, within ``(ha + hf)/tan α`` of the pitch point (plus a pitch for
    the tooth's width and the tip fillet). It never needs to go further than where the rack tooth leaves the blank
    of a pitch curve of radius ``radius`` (the flattest place); this also keeps small gears from being swept more
    than half a turn.
    """
    along_action = (ha + hf) / math.tan(alpha) + p
    leaves_blank = math.sqrt((ha + hf) * (2.0 * radius + ha - hf)) + p
    return min(along_action, leaves_blank)


def _place(outline: np.ndarray, origin: np.ndarray, tangent: np.ndarray, normal: np.ndarray, shift: np.ndarray):
    """Rack outline ``(K, 2)`` placed at ``N`` frames: ``origin + (u + shift)·tangent + v·normal`` → ``(N, K, 2)``."""
    u = outline[None, :, 0] + shift[:, None]
    v = outline[None, :, 1]
    return origin[:, None, :] + u[..., None] * tangent[:, None, :] + v[..., None] * normal[:, None, :]


def _rotate(coords: np.ndarray, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return coords @ np.array([[c, s], [-s, c]])


def _largest(geometry) -> Polygon:
    if isinstance(geometry, Polygon):
        return geometry
    if isinstance(geometry, MultiPolygon):
        return max(geometry.geoms, key=lambda g: g.area)
    polygons = [g for g in getattr(geometry, "geoms", []) if isinstance(g, Polygon)]
    if not polygons:
        raise ParameterError("gear generation produced no material: the teeth consume the whole gear")
    return max(polygons, key=lambda g: g.area)


def _tidy(geometry) -> Polygon:
    """The largest piece, with the generation's redundant vertices removed (1 µm tolerance, far below a laser's)."""
    return _largest(_largest(geometry).simplify(1e-3))


def _circle(radius: float, n: int) -> np.ndarray:
    theta = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    return radius * np.stack([np.cos(theta), np.sin(theta)], axis=-1)


# ---------------------------------------------------------------------------------------------------------------
# Gears.


@dataclass(frozen=True)
class Gear:
    """A generated gear outline (mm, centred on its pitch curve's centre, tooth 0 centred on +x).

    Attributes
    ----------
    kind : str
        ``"external"``, ``"internal"`` or ``"elliptic"``.
    teeth : int
    module : float
        Module actually used (mm).
    pitch : CircularPitch or EllipticPitch
        The pitch curve (the model's primitive × scale).
    outline : shapely Polygon
        The gear's material (an internal gear is an annulus with teeth inside, without the centre).
    settings : GearSettings
    undercut : bool
        True when the rack cutter undercuts the teeth: fewer equivalent teeth than :func:`undercut_limit`.
    """

    kind: str
    teeth: int
    module: float
    pitch: CircularPitch | EllipticPitch
    outline: Polygon
    settings: GearSettings

    @property
    def circular_pitch(self) -> float:
        return math.pi * self.module

    @property
    def pitch_radius(self) -> float:
        """Pitch radius (circular gears) or equivalent radius (perimeter / 2π) of the pitch curve."""
        return self.pitch.perimeter / (2.0 * math.pi)

    @property
    def base_radius(self) -> float:
        """Base circle radius ``r·cos α`` (circular gears)."""
        return self.pitch_radius * math.cos(self.settings.alpha)

    @property
    def equivalent_teeth(self) -> float:
        """Teeth of the circular gear as curved as the pitch curve's most curved place (``2·ρ_min/m``)."""
        radius = self.pitch.min_curvature_radius if isinstance(self.pitch, EllipticPitch) else self.pitch.radius
        return 2.0 * radius / self.module

    @property
    def undercut(self) -> bool:
        if self.kind == "internal":
            # A shaper cutter leaves a ring's teeth widening towards their roots: nothing is cut in behind the
            # involute. What it does is trim the ring's tips, on purpose, so that the mating pinions clear them.
            return False
        return self.equivalent_teeth < undercut_limit(self.settings, self.module) - 1e-9

    def notes(self) -> list[str]:
        """Warnings a maker should read before cutting."""
        notes = []
        if self.undercut:
            if isinstance(self.pitch, EllipticPitch):
                why = (f"its most curved part is like a gear of {self.equivalent_teeth:.1f} teeth, fewer than "
                       f"{undercut_limit(self.settings, self.module):.1f}")
            else:
                why = f"fewer than {min_teeth_without_undercut(self.settings, self.module)} teeth"
            notes.append(
                f"{self.teeth}-tooth {self.kind} gear is undercut ({why}): weaker tooth roots; "
                "a larger scale or a smaller module avoids it"
            )
        return notes


def _check_teeth(kind: str, teeth: int) -> None:
    if teeth < 6:
        raise ParameterError(f"{kind} gear: {teeth} teeth is too few to cut (at least 6); use a larger scale or a "
                             "smaller module")


def external_gear(teeth: int, module: float, settings: GearSettings = DEFAULT_SETTINGS) -> Gear:
    """An involute external spur gear generated by a rack cutter.

    Parameters
    ----------
    teeth : int
        Tooth count (at least 6).
    module : float
        Module (mm); the pitch radius is ``teeth·module/2``.
    settings : GearSettings
        Pressure angle, addendum, dedendum, root fillet, backlash.
    """
    _check_teeth("external", teeth)
    return _circular_external(teeth, module, settings, settings.addendum, settings.dedendum, settings.backlash / 2)


def _circular_external(teeth: int, module: float, settings: GearSettings, addendum: float, dedendum: float,
                       thinning: float) -> Gear:
    pitch = CircularPitch(teeth * module / 2.0)
    p = math.pi * module
    ha, hf = addendum * module, dedendum * module
    space = p / 2.0 + thinning
    tooth = _rack_tooth(settings, module, space, height=ha + 0.5 * module, depth=hf)
    # One tooth space (centred on arc length p/2) is cut while the rack rolls across it; every other space is the
    # same cut rotated, because the rolling motion on a circle is equivariant under rotation by one pitch.
    reach = _rack_reach(settings.alpha, ha, hf, p, pitch.radius)
    steps = max(8, int(math.ceil(2 * reach / p * settings.steps_per_pitch)))
    s = p / 2.0 + np.linspace(-reach, reach, steps)
    origin, tangent, normal = pitch.frame(s)
    coords = _place(tooth, origin, tangent, normal, p / 2.0 - s)
    one_space = shapely.union_all(shapely.polygons(coords))
    spaces = _replicate(one_space, teeth)
    blank = Polygon(_circle(pitch.radius + ha, max(256, 24 * teeth)))
    outline = _tidy(blank.difference(spaces))
    return Gear("external", teeth, module, pitch, outline, settings)


def _replicate(shape, copies: int):
    """Union of ``copies`` rotations of ``shape`` by multiples of ``2π/copies``."""
    exterior = np.asarray(_largest(shape).exterior.coords)
    rotated = [Polygon(_rotate(exterior, 2.0 * math.pi * k / copies)) for k in range(copies)]
    return shapely.union_all(rotated)


def elliptic_gear(teeth: int, module: float, eccentricity: float, settings: GearSettings = DEFAULT_SETTINGS) -> Gear:
    """An involute elliptic gear generated by a rack cutter rolling along the elliptic pitch curve (after Bair).

    The pitch curve is the ellipse of eccentricity ``e`` whose perimeter is ``teeth`` circular pitches, i.e. whose
    equivalent radius is ``teeth·module/2`` (thesis Eq. A.16), major axis along x, tooth 0 centred on ``(a, 0)``.
    """
    _check_teeth("elliptic", teeth)
    a, b = ellipse_axes(teeth * module / 2.0, eccentricity)
    pitch = EllipticPitch(a, b)
    p = math.pi * module
    ha, hf = settings.addendum * module, settings.dedendum * module
    space = p / 2.0 + settings.backlash / 2.0
    tooth = _rack_tooth(settings, module, space, height=ha + 0.5 * module, depth=hf)
    reach = _rack_reach(settings.alpha, ha, hf, p, pitch.max_curvature_radius)
    per_space = max(8, int(math.ceil(2 * reach / p * settings.steps_per_pitch)))
    offsets = np.linspace(-reach, reach, per_space)
    centres = (np.arange(teeth) + 0.5) * p
    s = (centres[:, None] + offsets[None, :]).ravel()
    origin, tangent, normal = pitch.frame(s)
    coords = _place(tooth, origin, tangent, normal, np.repeat(centres, per_space) - s)
    cut = shapely.union_all(shapely.polygons(coords))
    # The blank is the addendum curve: the pitch ellipse offset outward by the addendum.
    blank = Polygon(pitch.polyline(max(720, 24 * teeth))).buffer(ha, quad_segs=32)
    outline = _tidy(blank.difference(cut))
    return Gear("elliptic", teeth, module, pitch, outline, settings)


#: Extra clearance of the shaper cutter (modules): covers the cusps left by discrete generation steps.
RING_CLEARANCE = 0.015
#: Largest ring root fillet as a fraction of the tip clearance (a rounded 60° corner reaches ~1.5 radii deep).
RING_FILLET_LIMIT = 0.5


def ring_gear(teeth: int, module: float, rim: float, settings: GearSettings = DEFAULT_SETTINGS,
              cutter_teeth: int | None = None) -> Gear:
    """An internal (ring) gear generated by a shaper cutter, with a plain rim of width ``rim`` (mm) outside.

    Parameters
    ----------
    teeth : int
        Tooth count of the ring.
    module : float
        Module (mm).
    rim : float
        Material outside the tooth roots (mm).
    settings : GearSettings
    cutter_teeth : int, optional
        Teeth of the shaper cutter; cut with the largest pinion that will roll in the ring (its tips are then
        trimmed so that no smaller pinion interferes either). Default ``teeth // 2``.
    """
    _check_teeth("internal", teeth)
    zc = int(cutter_teeth) if cutter_teeth is not None else max(6, teeth // 2)
    if not 6 <= zc <= teeth - 2:
        raise ParameterError(f"ring gear: a shaper cutter of {zc} teeth cannot cut a {teeth}-tooth ring "
                             f"(expected 6 to {teeth - 2} teeth)")
    pitch = CircularPitch(teeth * module / 2.0)
    ha, hf = settings.addendum * module, settings.dedendum * module
    # The cutter is the mating pinion cut by the same rack, so that its roots and fillets are the pinion's (the
    # ring's tips, trimmed by them, then clear the pinion's fillets), thickened by half the backlash, with teeth as
    # long as the ring's spaces are deep (the dedendum) and rounded tips that leave the ring's root fillets.
    cutter = _circular_external(zc, module, settings, addendum=settings.dedendum, dedendum=settings.dedendum,
                                thinning=-settings.backlash / 2).outline
    # The ring's root fillets come from rounding the cutter's tip corners. The rounding must stay within the tip
    # clearance (dedendum - addendum), or the mating pinion's tip corners would graze the fillets.
    fillet = min(settings.root_fillet, RING_FILLET_LIMIT * (settings.dedendum - settings.addendum)) * module
    if fillet > 0:
        cutter = cutter.buffer(-fillet, quad_segs=8).buffer(fillet, quad_segs=8)
    # Discrete cutter positions leave tiny cusps of ring material between them (and the cutter, rack-generated
    # itself, has its own); a clearance of a hundredth of a module all round keeps every cusp out of the mating
    # pinion's path, at a negligible cost in backlash.
    cutter = cutter.buffer(RING_CLEARANCE * module, quad_segs=8)
    cutter_coords = np.asarray(_largest(cutter).exterior.coords)
    rc = zc * module / 2.0
    distance = pitch.radius - rc
    # The cutter's centre goes round at angle phi while it spins so that its pitch circle rolls without slipping
    # inside the ring's: spin = phi·(1 - z/zc). At phi = 0 a cutter tooth points at +x and cuts the ring's space
    # centred on +x. The motion is equivariant under a rotation by one ring pitch, so the cut over phi in [0, pitch)
    # rotated z times is the cut over a whole turn.
    steps = max(8, int(math.ceil(2 * settings.steps_per_pitch)))
    phis = np.linspace(0.0, 2.0 * math.pi / teeth, steps, endpoint=False)
    positions = []
    for phi in phis:
        spin = phi * (1.0 - teeth / zc)
        placed = _rotate(cutter_coords, spin) + distance * np.array([math.cos(phi), math.sin(phi)])
        positions.append(placed)
    cuts = shapely.polygons(np.stack(positions))
    # Vertex counts that are multiples of the tooth count keep the blank periodic, like the cut.
    outer = Polygon(_circle(pitch.radius + hf + rim, teeth * max(12, -(-256 // teeth))))
    inner = Polygon(_circle(pitch.radius - ha, teeth * max(24, -(-256 // teeth))))
    blank = outer.difference(inner)
    # Only what the cutter can reach of the blank matters: the blank within the cutter's tip circle, anywhere
    # along this pitch of its path (with a module of margin). Clipping to it keeps the Booleans small, and every
    # tooth that touches the blank, even far from the contact (tip trimming), is kept.
    reach = rc + hf + RING_CLEARANCE * module + module
    path = LineString([distance * np.array([math.cos(a), math.sin(a)])
                       for a in np.linspace(0.0, 2.0 * math.pi / teeth, 5)])
    window = blank.intersection(path.buffer(reach, quad_segs=32))
    swept = shapely.union_all(shapely.intersection(cuts, window))
    # Build the ring one pitch-wide sector at a time: the sector [0, pitch) is cut by the sweep above rotated by
    # the few whole pitches k that reach it (rotating the sweep by k pitches is the cutter k pitches further on).
    pitch_angle = 2.0 * math.pi / teeth
    sweep_points = np.asarray(shapely.get_coordinates(swept))
    angles = np.arctan2(sweep_points[:, 1], sweep_points[:, 0])
    k_range = range(int(math.floor(-angles.max() / pitch_angle)), int(math.ceil(1.0 - angles.min() / pitch_angle)) + 1)
    far = 2.0 * (pitch.radius + hf + rim)
    sector = Polygon([(0.0, 0.0), (far, 0.0), (far * math.cos(pitch_angle), far * math.sin(pitch_angle))])
    rotated = [shapely.affinity.rotate(swept, k * pitch_angle, origin=(0, 0), use_radians=True) for k in k_range]
    cut_here = shapely.union_all(shapely.intersection(np.array(rotated, dtype=object), sector.buffer(module)))
    piece = blank.intersection(sector).difference(cut_here)
    pieces = [shapely.affinity.rotate(piece, j * pitch_angle, origin=(0, 0), use_radians=True) for j in range(teeth)]
    # Adjacent sectors share their edges up to rounding: snapped to a 1 nm grid they tile the ring exactly, and
    # GEOS's coverage union merges such a tiling fast.
    tiles = shapely.set_precision(np.array(pieces, dtype=object), 1e-6)
    try:
        ring = _largest(shapely.coverage_union_all(tiles))
    except shapely.errors.GEOSException:  # rounding left the tiles unevenly noded: the general union copes
        ring = _largest(shapely.union_all(tiles, grid_size=1e-6))
    # Ring spaces are centred where cutter teeth were, i.e. on +x: rotate by half a pitch so that a ring *tooth* is
    # centred on +x, like the other gears.
    ring = shapely.affinity.rotate(ring, 180.0 / teeth, origin=(0, 0))
    outline = _tidy(ring)
    return Gear("internal", teeth, module, pitch, outline, settings)
