"""The laser twin's mark on the stock: a G-code job burned into a sheet of a simulated material, as a picture.

What the job leaves is worked out from the energy it puts into the sheet, line by line of the G-code (its ``S`` and
``F`` words, passes included, since every pass is a line of its own):

* every burning move delivers ``P * S / $30 / v`` joules per millimetre (``P`` the laser's optical power in watts,
  ``v`` the feed in mm/s), spread across the move by a Gaussian beam;
* the **ablation** dose (beam sigma :attr:`BurnMaterial.beam_sigma_mm`) removes material: where it reaches
  :attr:`BurnMaterial.through_dose` (J/mm^2, the thickness's worth) the sheet is cut through and the camera sees what
  lies under it; a straight cut line of ``e`` J/mm (passes summed) opens
  ``2 sigma sqrt(2 ln(e / (sqrt(2 pi) sigma D)))`` wide: the material's true kerf (:func:`line_kerf`);
* the **heat** dose (a wider Gaussian, :attr:`BurnMaterial.heat_sigma_mm`: what conducts sideways) darkens the
  surface: darkness ``1 - exp(-dose / dark_dose)`` blends the wood towards char.

The picture carries the sheet's own grain (seeded low-frequency shading) and is anti-aliased at the through edges
(a pixel's share of the opening is taken from the dose's slope), so that a measurement of the kerf can be checked
against :func:`line_kerf` to a small fraction of a pixel. Plain data in and out: no import of ``design``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.special import erf

from drivers.errors import SimConfigError
from drivers.gcode import interpret
from drivers.sim.camera_render import render
from drivers.sim.camera_scene import CameraModel, ImageItem, PlaneScene, RenderOptions

__all__ = ["SIM_MATERIALS", "BurnMaterial", "BurnedSheet", "burn_gcode", "line_energy", "line_goes_through",
           "line_kerf", "photograph", "sim_material"]


@dataclass(frozen=True)
class BurnMaterial:
    """How a material answers the simulated laser (the twin's truth; a real sheet is measured, not described)."""

    name: str
    laser_watts: float = 10.0        # the twin's optical power at S = $30
    beam_sigma_mm: float = 0.07      # the beam's Gaussian sigma (ablation)
    heat_sigma_mm: float = 0.12      # the darkening's sigma (heat spreads sideways)
    through_dose: float = 9.0        # J/mm^2 that cut through the sheet
    dark_dose: float = 0.8           # J/mm^2 that darken the surface to 1 - 1/e of char
    wood_rgb: tuple[int, int, int] = (214, 178, 128)
    char_rgb: tuple[int, int, int] = (38, 26, 20)
    grain: float = 0.04              # relative amplitude of the sheet's shading


#: The twin's materials, by the built-in laser profile's names; their truth differs from the profile's guesses (a
#: profile's kerf is what a measurement corrects).
SIM_MATERIALS = {
    "plywood_3mm": BurnMaterial("plywood_3mm"),
    "mdf_3mm": BurnMaterial("mdf_3mm", beam_sigma_mm=0.075, through_dose=11.0, dark_dose=0.8,
                            wood_rgb=(160, 120, 80), char_rgb=(30, 22, 18), grain=0.015),
    "cardboard_2mm": BurnMaterial("cardboard_2mm", beam_sigma_mm=0.08, through_dose=2.5, dark_dose=0.9,
                                  wood_rgb=(190, 160, 120), grain=0.02),
    "acrylic_3mm_black": BurnMaterial("acrylic_3mm_black", beam_sigma_mm=0.06, through_dose=12.0, dark_dose=4.0,
                                      wood_rgb=(30, 30, 32), char_rgb=(120, 120, 120), grain=0.0),
}


def sim_material(name: str) -> BurnMaterial:
    """The twin's material ``name``; unknown names burn like plywood (the twin has one truth per name it knows)."""
    return SIM_MATERIALS.get(name, BurnMaterial(name))


def line_energy(material: BurnMaterial, power: float, feed: float, passes: int = 1) -> float:
    """Joules per mm a straight line receives at ``power`` (fraction of max), ``feed`` (mm/min), ``passes``."""
    return material.laser_watts * float(power) / (float(feed) / 60.0) * int(passes)


def line_kerf(material: BurnMaterial, power: float, feed: float, passes: int = 1) -> float:
    """The true width (mm) a straight cut line opens through the sheet; 0 when it does not go through."""
    sigma = material.beam_sigma_mm
    peak = line_energy(material, power, feed, passes) / (math.sqrt(2 * math.pi) * sigma)
    if peak <= material.through_dose:
        return 0.0
    return 2.0 * sigma * math.sqrt(2.0 * math.log(peak / material.through_dose))


def line_goes_through(material: BurnMaterial, power: float, feed: float, passes: int = 1) -> bool:
    """Whether a straight cut line at these settings cuts through the sheet."""
    return line_kerf(material, power, feed, passes) > 0.0


@dataclass(frozen=True)
class BurnedSheet:
    """The burned sheet as seen from above: ``rgb`` (float32 surface colour, row 0 at the top = the highest y),
    ``through`` (float 0..1: the share of each pixel cut through), ``darkness`` (0..1), and where it lies:
    ``origin_mm`` the work coordinates of the picture's lower-left corner, ``px_per_mm``."""

    rgb: np.ndarray
    through: np.ndarray
    darkness: np.ndarray
    origin_mm: tuple[float, float]
    px_per_mm: float

    def picture(self, under_rgb: Sequence[float]) -> np.ndarray:
        """The sheet as a camera sees it lying on a surface of colour ``under_rgb``: what is cut through shows it."""
        under = np.asarray(under_rgb, dtype=np.float32)[None, None, :]
        share = self.through[..., None].astype(np.float32)
        return np.clip(self.rgb * (1.0 - share) + under * share + 0.5, 0, 255).astype(np.uint8)

    @property
    def size_mm(self) -> tuple[float, float]:
        return self.rgb.shape[1] / self.px_per_mm, self.rgb.shape[0] / self.px_per_mm

    def corners_mm(self) -> np.ndarray:
        """Top-left, top-right, bottom-right, bottom-left corners (work mm): an image item's ``corners_mm``."""
        x0, y0 = self.origin_mm
        w, h = self.size_mm
        return np.array([[x0, y0 + h], [x0 + w, y0 + h], [x0 + w, y0], [x0, y0]], dtype=float)


def _segment_dose(doses: Sequence[np.ndarray], sigmas: Sequence[float], a: np.ndarray, b: np.ndarray,
                  energy: float, origin: np.ndarray, px: float) -> None:
    """Add a segment's dose (``energy`` J/mm along it, a Gaussian of each of ``sigmas`` across, the ends' erf
    tails) to each of ``doses`` (rows: y down from the top; pixel centres at ``origin + (i + 0.5) / px``)."""
    height, width = doses[0].shape
    reach = 4.0 * max(sigmas)
    lo = np.minimum(a, b) - reach
    hi = np.maximum(a, b) + reach
    c0 = max(0, int(math.floor((lo[0] - origin[0]) * px)))
    c1 = min(width, int(math.ceil((hi[0] - origin[0]) * px)) + 1)
    top = origin[1] + height / px
    r0 = max(0, int(math.floor((top - hi[1]) * px)))
    r1 = min(height, int(math.ceil((top - lo[1]) * px)) + 1)
    direction = b - a
    length = float(np.hypot(*direction))
    if c0 >= c1 or r0 >= r1 or length < 1e-9:
        return
    xs = origin[0] + (np.arange(c0, c1) + 0.5) / px
    ys = top - (np.arange(r0, r1) + 0.5) / px
    unit = direction / length
    dx = xs[None, :] - a[0]
    dy = ys[:, None] - a[1]
    along = dx * unit[0] + dy * unit[1]
    across2 = (dx * unit[1] - dy * unit[0]) ** 2
    for dose, sigma in zip(doses, sigmas):
        root2s = math.sqrt(2.0) * sigma
        share = 0.5 * (erf((length - along) / root2s) + erf(along / root2s))
        dose[r0:r1, c0:c1] += (energy / (math.sqrt(2 * math.pi) * sigma)) * np.exp(-across2 / (2 * sigma ** 2)) \
            * share


def burn_gcode(lines: Sequence[str], material: BurnMaterial, region: Sequence[float], *, max_power: float = 1000.0,
               px_per_mm: float = 20.0, seed: int = 0) -> BurnedSheet:
    """Burn a laser job into a sheet covering ``region`` ``(xmin, ymin, xmax, ymax)`` (work mm).

    Raises
    ------
    SimConfigError
        A bad region or resolution, or a picture too large to hold.
    drivers.gcode.GcodeError
        A line the G-code parser cannot read.
    """
    xmin, ymin, xmax, ymax = (float(v) for v in region)
    if not (all(math.isfinite(v) for v in (xmin, ymin, xmax, ymax)) and xmax > xmin and ymax > ymin):
        raise SimConfigError(f"burn: region: expected xmin < xmax and ymin < ymax in mm, got {list(region)}")
    if not (math.isfinite(px_per_mm) and 1.0 <= px_per_mm <= 100.0):
        raise SimConfigError(f"burn: px_per_mm: expected 1 to 100, got {px_per_mm!r}")
    width = int(math.ceil((xmax - xmin) * px_per_mm))
    height = int(math.ceil((ymax - ymin) * px_per_mm))
    if width * height > 40_000_000:
        raise SimConfigError(f"burn: a {width}x{height} picture is too large; burn a smaller region or fewer px/mm")
    toolpath = interpret(list(lines))
    origin = np.array([xmin, ymin])
    ablation = np.zeros((height, width), dtype=np.float64)
    heat = np.zeros((height, width), dtype=np.float64)
    for k in np.flatnonzero(~toolpath.rapid & (toolpath.power > 0) & np.isfinite(toolpath.feed)):
        power = float(toolpath.power[k]) / float(max_power)
        energy = material.laser_watts * min(power, 1.0) / (float(toolpath.feed[k]) / 60.0)
        a, b = toolpath.start[k, :2], toolpath.end[k, :2]
        _segment_dose((ablation, heat), (material.beam_sigma_mm, material.heat_sigma_mm), a, b, energy, origin,
                      px_per_mm)
    # The through share of a pixel: the dose's excess over the threshold across one pixel of its slope.
    gy, gx = np.gradient(ablation)
    slope = np.hypot(gx, gy) + 1e-12
    through = np.clip((ablation - material.through_dose) / slope + 0.5, 0.0, 1.0)
    through[ablation < material.through_dose - slope] = 0.0
    # What a closed through-cut encloses falls out (a slot's slug, a tab, a square burned through): every part of the
    # sheet cut off from its largest piece shows what lies under the sheet.
    count, labels = cv2.connectedComponents((through < 0.5).astype(np.uint8), connectivity=4)
    if count > 2:
        sizes = np.bincount(labels.ravel(), minlength=count)
        sizes[0] = 0  # the through-cut pixels themselves
        loose = np.ones(count, dtype=bool)
        loose[[0, int(np.argmax(sizes))]] = False
        through[loose[labels]] = 1.0
    darkness = 1.0 - np.exp(-heat / material.dark_dose)
    rng = np.random.default_rng(seed)
    coarse = rng.standard_normal((max(2, height // 40), max(2, width // 40)))
    grain = cv2.resize(coarse.astype(np.float32), (width, height), interpolation=cv2.INTER_CUBIC)
    wood = np.asarray(material.wood_rgb, dtype=np.float64)[None, None, :] * (1.0 + material.grain * grain[..., None])
    char = np.asarray(material.char_rgb, dtype=np.float64)[None, None, :]
    surface = wood * (1.0 - darkness[..., None]) + char * darkness[..., None]
    return BurnedSheet(np.clip(surface, 0, 255).astype(np.float32), through, darkness, (xmin, ymin),
                       float(px_per_mm))


def photograph(sheet: BurnedSheet, *, under_rgb: Sequence[int] = (240, 240, 235), angle_deg: float = 7.0,
               shift_mm: Sequence[float] = (3.0, -2.0), px_per_mm: float = 20.0, height_mm: float = 250.0,
               noise: float = 2.0, blur_px: float = 0.7, supersample: int = 2, seed: int = 0,
               ) -> tuple[np.ndarray, CameraModel]:
    """A photo of the burned sheet taken from above (a phone held over the card, or the station's camera): the
    sheet lies turned by ``angle_deg`` on a surface of ``under_rgb`` (a light box, white paper: what shows through
    the cuts), the camera ``height_mm`` above it sees ``px_per_mm`` at the centre; the frame is just large enough
    for the sheet. Returns the RGB frame and the camera (its truth)."""
    for name, value, low, high in (("angle_deg", angle_deg, -360.0, 360.0), ("px_per_mm", px_per_mm, 2.0, 60.0),
                                   ("height_mm", height_mm, 50.0, 5000.0), ("noise", noise, 0.0, 50.0),
                                   ("blur_px", blur_px, 0.0, 10.0)):
        if not (math.isfinite(value) and low <= value <= high):
            raise SimConfigError(f"photograph: {name}: expected {low:g} to {high:g}, got {value!r}")
    width, height = sheet.size_mm
    theta = math.radians(angle_deg)
    rotation = np.array([[math.cos(theta), -math.sin(theta)], [math.sin(theta), math.cos(theta)]])
    corners = sheet.corners_mm() - (np.asarray(sheet.origin_mm) + [width / 2.0, height / 2.0])
    corners = corners @ rotation.T + np.asarray(shift_mm, dtype=float)
    extent = np.abs(corners).max(axis=0) + 8.0  # mm of surface around the sheet on each side
    image_size = tuple(int(math.ceil(2 * e * px_per_mm / 2.0) * 2) for e in extent)
    camera = CameraModel.looking_down((0.0, 0.0), height_mm, image_size, px_per_mm * height_mm)
    scene = PlaneScene(images=(ImageItem(sheet.picture(under_rgb), corners),), background=tuple(under_rgb))
    frame, _ = render(scene, camera, RenderOptions(blur_px=blur_px, noise=noise, seed=seed,
                                                           supersample=supersample))
    return frame, camera
