"""Laser material test cards as a service: make a card, burn it on the twin and photograph it, read a photo of a
burned card and write the material's measured settings into the profile.

Used by ``station lasertest`` and ``station calibrate material``. The card's geometry is
:mod:`design.fabrication.lasercard`, the laser job :func:`cam.laser.plan_operations`, the twin's burn and
photo :mod:`drivers.sim.laser_burn`, the reading :mod:`calibration.lasercard`.
"""

from __future__ import annotations

import io
import json
import math
import re
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from PIL import Image, ImageDraw, ImageFont

from calibration.lasercard import MIN_FRAME_PX_PER_MM, SOFT_EDGE_MM, CardReading, read_card
from cam.laser import check_work_area, material_settings, plan_operations, travel_moves, write_laser_gcode
from common.datafiles import load_json
from design.fabrication.lasercard import (
    Card,
    CardError,
    CardManifest,
    CardSpec,
    card_geometry,
    card_manifest,
    geometric_steps,
    linear_steps,
    read_manifest,
)
from drivers.profiles import BUILTIN_PROFILES, MachineProfile, profile_from_toml
from drivers.sim.laser_burn import burn_gcode, line_kerf, photograph, sim_material
from station.errors import ServiceError, station_errors
from station.services.calibrate import grab_frame
from station.services.images import check_frame_size, check_image_file
from station.services.profiles import load_station_profile, replace_material_table, station_copy_path
from vision.tags import tag_cells

__all__ = [
    "DEFAULT_DARKNESS",
    "CardOutput",
    "Choice",
    "MaterialMeasurement",
    "ProfileUpdate",
    "TwinPhoto",
    "choose_settings",
    "make_card",
    "measure_material",
    "parse_steps",
    "photograph_card",
    "png_bytes",
    "read_card_manifest",
    "update_profile",
    "write_card",
]

#: The engraving darkness chosen by default: a clear dark brown on plywood (0 bare wood, 1 char).
DEFAULT_DARKNESS = 0.6
#: Cells whose darkness is this close to the target count as hitting it (the fastest of them is chosen).
DARKNESS_TOLERANCE = 0.08
#: The report's scale, pixels per card millimetre.
REPORT_PX_PER_MM = 12.0
#: Where the card lies on the bed: this far in from the work area's front-left corner (mm).
CARD_OFFSET = 5.0
GCODE_FILE, MANIFEST_FILE, PREVIEW_FILE = "card.gcode", "card.json", "card.png"


@station_errors
def parse_steps(text: str, field: str, low: float, high: float, unit: str) -> tuple[float, float, int]:
    """``"a:b:n"`` → ``(a, b, n)``: ``n`` values from ``a`` to ``b`` (``"a"`` alone is one value); a
    :class:`ServiceError` naming ``field`` otherwise."""
    parts = str(text).split(":")
    example = "0.2:1:5" if unit == "" else "200:3000:5"
    unreadable = ServiceError(f"{field} {text!r}: expected FIRST:LAST:COUNT, e.g. {example}", field=field, value=text)
    if len(parts) not in (1, 3):
        raise unreadable
    try:
        first, last, count = (float(parts[0]), float(parts[0]), 1) if len(parts) == 1 else (
            float(parts[0]), float(parts[1]), int(parts[2]))
    except ValueError:
        raise unreadable from None
    if not (math.isfinite(first) and math.isfinite(last) and low <= min(first, last) and max(first, last) <= high
            and first > 0):
        raise ServiceError(f"{field} {text!r}: expected values from {low:g} to {high:g}{unit}, e.g. {example}",
                           field=field, value=text)
    if not 1 <= count <= 12 or (count > 1 and first == last):
        raise ServiceError(f"{field} {text!r}: expected a COUNT from 1 to 12 (and FIRST != LAST for more than one)",
                           field=field, value=text)
    return first, last, count


@dataclass
class CardOutput:
    """A card made for a profile and material: its geometry, laser job, G-code, manifest and preview PNG."""

    card: Card
    job: Any
    gcode: str
    manifest: dict[str, Any]
    png: bytes
    profile: MachineProfile


@station_errors
def make_card(profile_name: str, material: str, *, power: str | None = None, feed: str | None = None,
              passes: int | None = None) -> CardOutput:
    """The test card for ``material`` of the profile ``profile_name`` (a built-in name, the station's copy of it, or a
    file): powers ``a:b:n`` (fractions of max power, spaced evenly; default 0.2:1:5), feeds ``a:b:n`` (mm/min, in
    equal ratios; default from two thirds of the material's cut feed to its engrave feed, 5), the cut lines'
    passes (default the material's cut passes). Raises ServiceError, ProfileError, CardError, JobRefused."""
    profile = load_station_profile(profile_name)
    engrave, cut, material = material_settings(profile, material)
    thickness = profile.material(material).thickness
    powers = linear_steps(*parse_steps(power, "power", 0.001, 1.0, "")) if power else linear_steps(0.2, 1.0, 5)
    if feed:
        feeds = geometric_steps(*parse_steps(feed, "feed", 1.0, profile.max_feed, " mm/min"))
    else:
        low = max(1.0, round(cut.feed * 2.0 / 3.0))
        feeds = geometric_steps(low, max(engrave.feed, low * 2), 5)
    if passes is not None and (isinstance(passes, bool) or not 1 <= int(passes) <= 20):
        raise ServiceError(f"passes {passes!r}: expected a whole number from 1 to 20", field="passes", value=passes)
    spec = CardSpec(material, thickness, powers, feeds, int(passes) if passes is not None else int(cut.passes),
                    (engrave.power, engrave.feed, engrave.passes), (cut.power, cut.feed, cut.passes))
    card = card_geometry(spec, tag_cells)
    xmin, ymin, _, _ = profile.work_bounds()
    offset = (xmin + CARD_OFFSET, ymin + CARD_OFFSET)
    name = profile_name if profile_name in BUILTIN_PROFILES and not Path(profile_name).exists() \
        else str(Path(profile_name).resolve())
    job = plan_operations(card.operations, profile.laser.max_power, profile.plot.travel_feed, offset=offset,
                          start=(xmin, ymin), metadata={"test card": f"{material} on {profile.name}",
                                                        "card": f"{card.width:g}x{card.height:g} mm at "
                                                                f"X{offset[0]:g} Y{offset[1]:g}"},
                          machine_settings=profile.grbl_settings)
    check_work_area(job, profile.work_bounds(), profile.name)
    stream = io.StringIO()
    write_laser_gcode(job, stream, profile.work_bounds(), profile.laser.laser_mode, profile.name)
    manifest = card_manifest(card, profile=name, offset=offset,
                             files={"gcode": GCODE_FILE, "preview": PREVIEW_FILE})
    manifest["estimate_seconds"] = round(job.estimate_seconds()["total"], 1)
    return CardOutput(card, job, stream.getvalue(), manifest, _preview(card, job, offset), profile)


@station_errors
def write_card(output: CardOutput, folder: Path) -> dict[str, Path]:
    """card.gcode, card.json and card.png into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    files = {"gcode": folder / GCODE_FILE, "json": folder / MANIFEST_FILE, "png": folder / PREVIEW_FILE}
    files["gcode"].write_text(output.gcode, encoding="utf-8")
    files["json"].write_text(json.dumps(output.manifest, indent=2) + "\n", encoding="utf-8")
    files["png"].write_bytes(output.png)
    return files


def _font(size: int):
    try:
        return ImageFont.truetype("DejaVuSans.ttf", size)
    except OSError:
        return ImageFont.load_default(size)


def _preview(card: Card, job, offset, px: float = 8.0) -> bytes:
    """The job drawn on the card at ``px`` per mm: engravings grey by their energy, cuts red, travel light grey."""
    margin = 4.0
    size = (int((card.width + 2 * margin) * px), int((card.height + 2 * margin) * px))
    image = Image.new("RGB", size, (250, 248, 242))
    draw = ImageDraw.Draw(image)

    def point(p) -> tuple[float, float]:
        return ((p[0] - offset[0] + margin) * px, (card.height + margin - (p[1] - offset[1])) * px)

    for move in travel_moves(job):
        draw.line([point(p) for p in move], fill=(215, 215, 215), width=1)
    energies = {name: ops.power / ops.feed for name, ops in job.operations.items()}
    top = max(energies.values())
    for path in job.paths:
        if path.operation.startswith("cut") or path.operation in ("comb", "outline"):
            colour, width = (200, 30, 30), 2
        else:
            level = int(200 * (1.0 - min(1.0, (energies[path.operation] / top) ** 0.35)))
            colour, width = (level, level, level), 1
        draw.line([point(p) for p in path.points], fill=colour, width=width)
    buffer = io.BytesIO()
    image.save(buffer, format="PNG")
    return buffer.getvalue()


# ---------------------------------------------------------------------------------------------------------------
# The twin: burn the card's G-code into the simulated material and photograph it.


@dataclass
class TwinPhoto:
    """A photo of a card burned on the twin, with the twin's truth (the kerf of each cut, which lines went
    through)."""

    frame: np.ndarray
    truth: dict[str, Any]


@station_errors
def read_card_manifest(path: str | Path) -> CardManifest:
    """``card.json`` read and checked (one-line errors naming the file and the field)."""
    path = Path(path)
    try:
        data = load_json(path, "a test card's manifest (station lasertest card writes card.json)",
                         error=lambda detail: CardError(f"{path}: {detail}"))
    except OSError as error:
        problem = "no such file" if isinstance(error, FileNotFoundError) else f"cannot read it ({error.strerror})"
        raise ServiceError(f"card {str(path)!r}: {problem}; expected the card.json station lasertest card wrote",
                           field="card", value=str(path)) from None
    return read_manifest(data, str(path))


@station_errors
def photograph_card(card_json: str | Path, *, gcode: str | Path | None = None, seed: int = 0,
                    noise: float = 2.0, angle_deg: float = 7.0, px_per_mm: float = 20.0) -> TwinPhoto:
    """Burn the card's G-code (``gcode``, default the file card.json names beside it) into the twin's material of
    the card and photograph it lying on a light surface. Raises CardError, SimConfigError, GcodeError,
    ServiceError."""
    card_json = Path(card_json)
    manifest = read_card_manifest(card_json)
    gcode_path = Path(gcode) if gcode is not None else card_json.parent / str(manifest.data.get("files", {}).get(
        "gcode", GCODE_FILE))
    try:
        lines = gcode_path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as error:
        raise ServiceError(f"gcode {str(gcode_path)!r}: cannot read the card's G-code ({error.__class__.__name__})",
                           field="gcode", value=str(gcode_path)) from None
    offset = manifest.data.get("offset_mm", [0.0, 0.0])
    width, height = manifest.card_mm
    profile = load_station_profile(manifest.profile)
    material = sim_material(manifest.material)
    sheet = burn_gcode(lines, material, (offset[0], offset[1], offset[0] + width, offset[1] + height),
                       max_power=profile.laser.max_power, px_per_mm=16.0, seed=seed)
    frame, camera = photograph(sheet, angle_deg=angle_deg, px_per_mm=px_per_mm, noise=noise, seed=seed)
    power, feed, passes = manifest.comb
    truth = {
        "material": manifest.material,
        "kerf_mm": round(line_kerf(material, power, feed, passes), 4),
        "kerf_settings": {"power": power, "feed_mm_min": feed, "passes": passes},
        "cells": [{"name": c.name, "power": c.power, "feed_mm_min": c.feed,
                   "cut_kerf_mm": round(line_kerf(material, c.power, c.feed, manifest.cut_passes), 4),
                   "through": line_kerf(material, c.power, c.feed, manifest.cut_passes) > 0} for c in manifest.cells],
        "camera": {"px_per_mm": px_per_mm, "angle_deg": angle_deg, "image_size": list(camera.image_size),
                   "noise": noise, "seed": seed},
    }
    return TwinPhoto(frame, truth)


# ---------------------------------------------------------------------------------------------------------------
# Reading a photo and choosing the settings.


@dataclass(frozen=True)
class Choice:
    """The settings chosen from a card: ``cut`` and ``engrave`` as ``(power, feed, passes)`` (None: nothing on the
    card qualifies, the profile's are kept) with the cell they came from and why."""

    cut: tuple[float, float, int] | None
    cut_cell: str | None
    cut_why: str
    engrave: tuple[float, float, int] | None
    engrave_cell: str | None
    engrave_why: str
    darkness: float | None = None


@station_errors
def choose_settings(reading: CardReading, manifest: CardManifest, darkness: float = DEFAULT_DARKNESS) -> Choice:
    """Cut: the fastest feed whose line went through, one power step above the lowest power that did (the lowest
    when it is the only one; the card's passes). Engrave:
    among the squares that did not burn through, those within :data:`DARKNESS_TOLERANCE` of ``darkness``, the
    fastest (then the nearest); else the nearest."""
    through = [c for c in reading.cells if c.through]
    if through:
        fastest = max(c.feed for c in through)
        at_feed = sorted((c for c in through if c.feed == fastest), key=lambda c: c.power)
        # One power step above the weakest line that went through: a margin for the sheet's variation.
        best = at_feed[1] if len(at_feed) > 1 else at_feed[0]
        cut = (best.power, best.feed, manifest.cut_passes)
        cut_cell = best.name
        cut_why = (f"the fastest feed that cut through ({len(through)} of {len(reading.cells)} lines went through), "
                   + ("one power step above its weakest line that did" if len(at_feed) > 1
                      else "at the only power that did"))
    else:
        cut, cut_cell = None, None
        cut_why = f"no cut line went through (of {len(reading.cells)}): the profile's cut is kept"
    marked = [c for c in reading.cells if c.darkness is not None]
    if marked:
        near = [c for c in marked if abs(c.darkness - darkness) <= DARKNESS_TOLERANCE]
        if near:
            best = min(near, key=lambda c: (-c.feed, abs(c.darkness - darkness)))
            why = f"the fastest square within {DARKNESS_TOLERANCE:g} of darkness {darkness:g}"
        else:
            best = min(marked, key=lambda c: (abs(c.darkness - darkness), -c.feed))
            why = f"the square nearest to darkness {darkness:g} (none within {DARKNESS_TOLERANCE:g})"
        return Choice(cut, cut_cell, cut_why, (best.power, best.feed, 1), best.name, why, best.darkness)
    return Choice(cut, cut_cell, cut_why, None, None, "every square burned through: the profile's engrave is kept")


@station_errors
@dataclass
class MaterialMeasurement:
    """A card read from a frame: the reading, the chosen settings, the report PNG, and where they came from."""

    manifest: CardManifest
    reading: CardReading
    choice: Choice
    report_png: bytes
    frame_source: str
    darkness_target: float

    def warnings(self) -> list[str]:
        """What makes this reading less sure than usual, in words."""
        notes = []
        if self.reading.frame_px_per_mm < MIN_FRAME_PX_PER_MM:
            notes.append(f"the card is {self.reading.frame_px_per_mm:.1f} px per mm in the frame: below "
                         f"{MIN_FRAME_PX_PER_MM:g} the kerf may read up to 0.02 mm wide; photograph it closer")
        edges = [s.edge_mm for s in self.reading.slots if s.edge_mm is not None]
        if edges and float(np.median(edges)) > SOFT_EDGE_MM:
            notes.append(f"the comb's edges look soft ({float(np.median(edges)):.2f} mm from light to dark): the kerf "
                         "may read 0.02-0.05 mm wide; photograph it sharper or closer")
        if len(self.reading.tags_found) < 4:
            notes.append(f"{len(self.reading.tags_found)} of the 4 reference tags found: the card's plane is less "
                         "sure")
        return notes

    def to_dict(self) -> dict[str, Any]:
        r, c = self.reading, self.choice

        def settings(value):
            return None if value is None else {"power": value[0], "feed_mm_min": value[1], "passes": value[2]}

        return {
            "card": self.manifest.source, "frame": self.frame_source, "material": self.manifest.material,
            "profile": self.manifest.profile,
            "tags_found": list(r.tags_found), "tag_fit_mm": r.residual_mm, "frame_px_per_mm": r.frame_px_per_mm,
            "edge_px": r.edge_px,
            "warnings": self.warnings(),
            "levels": {"under_card": r.light_level, "wood": r.wood_level},
            "kerf_mm": r.kerf_mm, "kerf_uncertainty_mm": r.kerf_uncertainty_mm,
            "kerf_settings": settings(self.manifest.comb),
            "slots": [{"nominal_width_mm": s.nominal_mm, "opening_mm": s.opening_mm, "kerf_mm": s.kerf_mm,
                       "edge_mm": s.edge_mm} for s in r.slots],
            "cells": [{"name": x.name, "power": x.power, "feed_mm_min": x.feed, "darkness": x.darkness,
                       "darkness_spread": x.darkness_spread, "square_through": x.square_through,
                       "cut_through": x.through, "cut_through_share": x.through_share,
                       "mark_width_mm": x.mark_width_mm} for x in r.cells],
            "chosen": {"cut": settings(c.cut), "cut_cell": c.cut_cell, "cut_why": c.cut_why,
                       "engrave": settings(c.engrave), "engrave_cell": c.engrave_cell, "engrave_why": c.engrave_why,
                       "darkness_target": self.darkness_target},
        }


@station_errors
def measure_material(card_json: str | Path, *, image: str | Path | np.ndarray | None = None,
                     camera: str | None = None, darkness: float = DEFAULT_DARKNESS) -> MaterialMeasurement:
    """Read a burned card from a frame (an image file, an array, or grabbed from ``camera``) and choose the
    settings. Raises CardError, CalibrationError, ServiceError, DriverError."""
    if not (math.isfinite(darkness) and 0.0 < darkness < 1.0):
        raise ServiceError(f"darkness {darkness!r}: expected a number between 0 and 1 (0 bare wood, 1 char)",
                           field="darkness", value=darkness)
    manifest = read_card_manifest(card_json)
    if isinstance(image, np.ndarray):
        frame, source = image, "a frame in memory"
    elif image is not None:
        frame, source = _read_frame(Path(image)), str(Path(image).resolve())
    elif camera is not None:
        frame, source = grab_frame(camera), f"camera {camera}"
    else:
        raise ServiceError("give a frame: an image file or a camera", field="image")
    reading = read_card(frame, manifest)
    choice = choose_settings(reading, manifest, darkness)
    return MaterialMeasurement(manifest, reading, choice, _report(reading, manifest, choice), source, darkness)


def _read_frame(path: Path) -> np.ndarray:
    """An image file as RGB, refused in one line when it is missing, not an image, or too large."""
    if not path.is_file():
        raise ServiceError(f"image: no such file: {path}", field="image", value=str(path))
    check_image_file(path, "image")  # from the header: a huge image is refused before it is decoded
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise ServiceError(f"image: {path} is not an image OpenCV can read (png, jpg, ...)", field="image",
                           value=str(path))
    check_frame_size(path, (image.shape[1], image.shape[0]), "image")
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


def _report(reading: CardReading, manifest: CardManifest, choice: Choice) -> bytes:
    """The rectified card with the measured values written on it."""
    px, margin = REPORT_PX_PER_MM, reading.margin_mm
    image = Image.fromarray(reading.rectified).convert("RGB")
    image = image.resize((round(image.width * px / reading.px_per_mm), round(image.height * px / reading.px_per_mm)),
                         Image.Resampling.BOX)
    draw = ImageDraw.Draw(image)
    height = manifest.card_mm[1]

    def at(x: float, y: float) -> tuple[float, float]:
        return ((x + margin) * px, (height + margin - y) * px)

    tiny, small, large = _font(int(1.4 * px)), _font(int(1.8 * px)), _font(int(2.8 * px))
    ink, box = (0, 90, 200), (255, 255, 255)
    for cell, read in zip(manifest.cells, reading.cells):
        x0, y0, x1, y1 = cell.square
        text = "through" if read.square_through else f"d {read.darkness:.2f}"
        position = at((x0 + x1) / 2.0, (y0 + y1) / 2.0)
        draw.text(position, text, fill=ink, font=small, anchor="mm", stroke_width=3, stroke_fill=box)
        (lx0, ly), (lx1, _) = cell.cut_line
        mark = "cut" if read.through else ("part" if read.through_share > 0.2 else "no")
        colour = (0, 140, 60) if read.through else (200, 40, 40)
        draw.text(at(lx1 + 0.3, ly), mark, fill=colour, font=small, anchor="lm", stroke_width=3, stroke_fill=box)
        for chosen, outline in ((choice.engrave_cell, (0, 90, 200)), (choice.cut_cell, (0, 160, 60))):
            if chosen == cell.name:
                draw.rectangle([at(x0 - 2.5, y1 + 4.0), at(x1 + 2.5, ly - 1.5)], outline=outline, width=4)
    for slot, read in zip(manifest.slots, reading.slots):
        x0, y0, x1, y1 = slot.rect
        text = f"{slot.nominal_width:g}" if read.kerf_mm is None else f"+{read.kerf_mm:.3f}"
        draw.text(at((x0 + x1) / 2.0, y1 + 1.6), text, fill=ink, font=tiny, anchor="mm", stroke_width=3,
                  stroke_fill=box)
    kerf = "not measured" if reading.kerf_mm is None else \
        f"{reading.kerf_mm:.3f} ± {reading.kerf_uncertainty_mm:.3f} mm"
    lines = [f"kerf {kerf}", f"tags {len(reading.tags_found)}/4, fit {reading.residual_mm:.3f} mm"]
    if choice.cut is not None:
        lines.append(f"cut {100 * choice.cut[0]:.0f}% {choice.cut[1]:.0f} mm/min x{choice.cut[2]}")
    if choice.engrave is not None:
        lines.append(f"engrave {100 * choice.engrave[0]:.0f}% {choice.engrave[1]:.0f} mm/min")
    banner = Image.new("RGB", (image.width, int(len(lines) * 3.4 * px + px)), (255, 255, 255))
    banner_draw = ImageDraw.Draw(banner)
    for index, line in enumerate(lines):
        banner_draw.text((px, px * (0.6 + 3.4 * index)), line, fill=(20, 20, 20), font=large)
    result = Image.new("RGB", (image.width, image.height + banner.height), (255, 255, 255))
    result.paste(banner, (0, 0))
    result.paste(image, (0, banner.height))
    return png_bytes(np.asarray(result))


@station_errors
def png_bytes(rgb: np.ndarray) -> bytes:
    """An RGB picture as PNG (OpenCV's encoder: several times faster than Pillow's on a camera frame)."""
    ok, data = cv2.imencode(".png", cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2BGR),
                            [cv2.IMWRITE_PNG_COMPRESSION, 3])
    if not ok:
        raise ServiceError("could not encode the picture as PNG")
    return data.tobytes()


# ---------------------------------------------------------------------------------------------------------------
# Writing the profile.


@dataclass
class ProfileUpdate:
    """What was (or would be) written: the material's new TOML table, the file, whether it was written, and
    whether it is the station's copy of a built-in profile."""

    path: Path
    block: str
    written: bool
    station_copy: bool
    profile: MachineProfile | None = field(default=None, repr=False)


def _fmt(value: float) -> str:
    return f"{value:.4f}".rstrip("0").rstrip(".")


def _toml_string(text: str) -> str:
    return json.dumps(str(text), ensure_ascii=False)


@station_errors
def material_block(measurement: MaterialMeasurement, profile: MachineProfile, when: datetime | None = None) -> str:
    """The ``[materials.NAME]`` table with the chosen settings and its ``measured`` record."""
    name = measurement.manifest.material
    current = profile.material(name)
    choice, reading = measurement.choice, measurement.reading
    cut = choice.cut or (current.cut.power, current.cut.feed, current.cut.passes)
    engrave = choice.engrave or (current.engrave.power, current.engrave.feed, current.engrave.passes)
    kerf = reading.kerf_mm if reading.kerf_mm is not None else current.kerf
    when = when or datetime.now(timezone.utc)
    power, feed, passes = measurement.manifest.comb
    record = {
        "by": "station calibrate material",
        "at": when.strftime("%Y-%m-%dT%H:%M:%SZ"),
        "card": str(Path(measurement.manifest.source).resolve()),
        "frame": measurement.frame_source,
        "tag_fit_mm": reading.residual_mm,
        "frame_px_per_mm": reading.frame_px_per_mm,
    }
    if reading.kerf_mm is not None:
        record.update(kerf_mm=reading.kerf_mm, kerf_uncertainty_mm=reading.kerf_uncertainty_mm,
                      kerf_from=f"comb: {sum(s.kerf_mm is not None for s in reading.slots)} slots cut at power "
                                f"{power:g}, {feed:g} mm/min, {passes} passes")
    else:
        record.update(kerf_from="not measured (no comb slot opened): the profile's kerf is kept")
    record.update(cut_from=(f"cell {choice.cut_cell}: " if choice.cut_cell else "") + choice.cut_why)
    record.update(engrave_from=(f"cell {choice.engrave_cell}: " if choice.engrave_cell else "") + choice.engrave_why)
    if choice.darkness is not None:
        spread = next(c.darkness_spread for c in reading.cells if c.name == choice.engrave_cell)
        record.update(engrave_darkness=choice.darkness, engrave_darkness_spread=spread,
                      engrave_darkness_target=measurement.darkness_target)
    lines = [f"[materials.{name}]",
             f"# settings read from a test card by station calibrate material ({record['at']})",
             f'thickness = "{_fmt(current.thickness)}mm"']
    if kerf is not None:
        lines.append(f'kerf = "{_fmt(kerf)}mm"')
    lines.append(f'cut = {{ power = {_fmt(cut[0])}, feed = "{_fmt(cut[1])}mm/min", passes = {int(cut[2])} }}')
    lines.append(f'engrave = {{ power = {_fmt(engrave[0])}, feed = "{_fmt(engrave[1])}mm/min", '
                 f'passes = {int(engrave[2])} }}')
    lines.append("")
    lines.append(f"[materials.{name}.measured]")
    for key, value in record.items():
        rendered = _toml_string(value) if isinstance(value, str) else _fmt(float(value))
        lines.append(f"{key} = {rendered}")
    return "\n".join(lines) + "\n"


@station_errors
def update_profile(measurement: MaterialMeasurement, profile_name: str | None = None, *, yes: bool = False,
                   when: datetime | None = None) -> ProfileUpdate:
    """Write the chosen settings into the profile the card was made for (or ``profile_name``): the station's copy of
    a built-in profile (made from it when missing), or the user's file only when ``yes``; otherwise the update is
    returned unwritten. A profile that is not a laser is a ServiceError."""
    name = profile_name or measurement.manifest.profile
    builtin = name in BUILTIN_PROFILES and not Path(name).exists()
    profile = load_station_profile(name)
    if not profile.is_laser:
        raise ServiceError(f"profile {name!r} is a {profile.kind}, not a laser")
    profile.material(measurement.manifest.material)  # the material must be in it
    block = material_block(measurement, profile, when)
    path = station_copy_path(name, create=True) if builtin else Path(name)
    text = path.read_text(encoding="utf-8") if path.is_file() else BUILTIN_PROFILES[name]
    if builtin and not path.is_file():
        text = re.sub(r"^# Built-in profile[^\n]*\n", f"# The station's copy of the built-in profile '{name}', with "
                      "measured materials (delete it to go back to the built-in).\n", text, count=1)
    updated = replace_material_table(text, measurement.manifest.material, block, str(path))
    if not builtin and not yes:
        return ProfileUpdate(path, block, False, False)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(updated, encoding="utf-8")
    return ProfileUpdate(path, block, True, builtin, profile_from_toml(updated, str(path)))
