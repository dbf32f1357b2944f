"""Fabrication as a service: a drawing-machine design → parts, nesting, sheets' SVG, PNG and laser jobs.

Used by ``station fabricate`` and the Fabrication screen; see :func:`fabricate`.
"""

from __future__ import annotations

import io
import json
import re
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cam.laser import check_work_area, material_settings, plan_laser_job, travel_moves, write_laser_gcode
from common.progress import Reporter
from design.fabrication import FABRICABLE_MACHINES, GearSettings, Hardware
from design.machines import get_machine
from drivers.profiles import MachineProfile
from station.errors import ServiceError, station_errors
from station.jsonable import to_jsonable
from station.services.profiles import load_station_profile

DEFAULT_KERF = 0.15
#: Where the kerf came from, in words (``kerf_source`` in parts.json).
KERF_SOURCES = {"material": "from the material table", "default": "by default", "given": "as given"}
DEFAULT_GAP = 3.0
#: The progress stages of :func:`fabricate` besides the gears' (:data:`design.fabrication.parts.GEARS_STAGE`, in
#: teeth): the parts' sizes checked against the sheet (one report, before the gears), the nesting (one step), then
#: the sheets' laser jobs and files (counted in sheets).
SIZES_STAGE, NESTING_STAGE, SHEETS_STAGE = "sizes", "nesting", "sheets"


@station_errors
@dataclass
class SheetOutput:
    """One nested sheet with its files' contents: the laser job, SVG, G-code and preview."""

    index: int
    sheet: Any
    job: Any
    svg: str
    gcode: str
    png: bytes

    @property
    def suffix(self) -> str:
        """File-name suffix: none for the first sheet, ``-2``, ``-3``... for the next ones."""
        return "" if self.index == 1 else f"-{self.index}"


@station_errors
@dataclass
class FabricationResult:
    """Everything one fabrication run produced (kept in memory for the TUI, written to files by the CLI).

    ``sheet``, ``job``, ``svg``, ``gcode`` and ``png`` are the first sheet's; ``sheets`` has them all.
    """

    machine: str
    params: dict[str, Any]
    scale: float
    sheets: list[SheetOutput]
    summary: dict[str, Any]

    @property
    def sheet(self) -> Any:
        return self.sheets[0].sheet

    @property
    def job(self) -> Any:
        return self.sheets[0].job

    @property
    def svg(self) -> str:
        return self.sheets[0].svg

    @property
    def gcode(self) -> str:
        return self.sheets[0].gcode

    @property
    def png(self) -> bytes:
        return self.sheets[0].png


@station_errors
def parse_sheet(text: str) -> tuple[float, float]:
    """``"300x200"`` → ``(300.0, 200.0)`` mm; a :class:`ServiceError` (``field="sheet"``) otherwise."""
    match = re.fullmatch(r"\s*(\d+(?:\.\d*)?)\s*[xX×]\s*(\d+(?:\.\d*)?)\s*(?:mm)?\s*", text or "")
    if not match or float(match.group(1)) <= 0 or float(match.group(2)) <= 0:
        raise ServiceError(f"sheet {text!r}: expected WIDTHxHEIGHT in mm, e.g. 300x200", field="sheet", value=text)
    return float(match.group(1)), float(match.group(2))


@dataclass(frozen=True)
class FabricationRequest:
    """What :func:`fabricate` makes: a drawing-machine design's parts at a scale, nested on a laser's sheets.

    Parameters
    ----------
    machine : str
        A drawing machine's name (:data:`FABRICABLE_MACHINES` have parts).
    params : mapping
        The design (missing parameters take the machine's defaults).
    scale : float
        Millimetres per model unit.
    kerf : float, optional
        The laser's kerf (mm); None: the material's in the profile, else :data:`DEFAULT_KERF`.
    sheet_size : (float, float), optional
        The sheet (mm); None: the profile's bed.
    gap : float
        Between two parts on a sheet (mm).
    profile : MachineProfile or str
        The laser's profile, or what names one (a TOML file or a built-in profile's name, which means the station's
        copy of it once a test card's measurement wrote one: :func:`~station.services.profiles.load_station_profile`).
    material : str, optional
        A material of the profile; None: its first.
    gear_settings : GearSettings, optional
        The gears' module, pressure angle and backlash (None: the defaults).
    hardware : Hardware, optional
        The pen, axle and pin holes (None: the defaults).
    max_sheets : int
        The most sheets the parts may take.
    """

    machine: str
    params: Mapping[str, float]
    scale: float
    kerf: float | None = None
    sheet_size: tuple[float, float] | None = None
    gap: float = DEFAULT_GAP
    profile: MachineProfile | str = "laser"
    material: str | None = None
    gear_settings: GearSettings | None = None
    hardware: Hardware | None = None
    max_sheets: int = 4


@station_errors
def fabricate(request: FabricationRequest, *, report: Reporter | None = None) -> FabricationResult:
    """Parts → kerf → nesting → SVG, PNG, laser job, as ``request`` says. Bad input raises a station error.

    ``report``, optional: given a :class:`common.progress.Progress` at each step: the parts' sizes checked (stage
    ``"sizes"``), each gear and the end of the gears (``"gears"``, in teeth), the nesting (``"nesting"``), each
    sheet (``"sheets"``), and a last ``"sheets"`` report with ``done == total`` when the work is done. Its stop
    check is asked after each report (:class:`common.progress.Cancelled` stops the work between two steps).

    Parts that do not fit one sheet go on further sheets (at most ``max_sheets``), each with its own job.

    A part too large for the sheet is refused before any gear is generated (which takes minutes at large scales),
    with the largest scale that fits.
    """
    # the parts' geometry (shapely, scipy, OpenCV) loads when parts are made: `station fabricate --help` imports this
    from design.fabrication import check_sizes_fit, machine_parts, nest_sheets, part_sizes

    machine, params, scale, gap, kerf = request.machine, dict(request.params), request.scale, request.gap, request.kerf
    gear_settings, hardware = request.gear_settings, request.hardware
    report = Reporter.of(report)
    if machine in FABRICABLE_MACHINES:
        # The summary records the complete design (defaults filled in), as the parts were made from it.
        params = dict(get_machine(machine).validate(params))
    profile = load_station_profile(request.profile) if isinstance(request.profile, str) else request.profile
    engrave_ops, cut_ops, material_name = material_settings(profile, request.material)
    if kerf is None:
        material_kerf = profile.material(material_name).kerf
        kerf, kerf_source = (DEFAULT_KERF, "default") if material_kerf is None else (material_kerf, "material")
    else:
        kerf_source = "given"
    width, height = request.sheet_size if request.sheet_size is not None else (profile.width, profile.height)
    # Sizes first (milliseconds): a part too large for the sheet is refused before the gears are generated.
    sizes = part_sizes(machine, params, scale, gear_settings, hardware)
    check_sizes_fit(sizes, width, height, gap, kerf, scale=scale,
                    sizes_at=lambda s: part_sizes(machine, params, s, gear_settings, hardware))
    total_teeth = sum(size.teeth for size in sizes)

    started = time.perf_counter()
    report(SIZES_STAGE, len(sizes), len(sizes), f"the {len(sizes)} parts of {machine} at {scale:g} mm per unit fit "
           f"{width:g}x{height:g} mm sheets; generating their {total_teeth} teeth")
    parts = machine_parts(machine, params, scale, gear_settings, hardware, report=report)
    generated = time.perf_counter() - started
    report(NESTING_STAGE, 0, None,
           f"nesting {len(parts)} parts on {width:g}x{height:g} mm sheets (kerf {kerf:g} mm, gap {gap:g} mm)")
    sheets = nest_sheets(parts, width, height, gap=gap, kerf=kerf, max_sheets=request.max_sheets)
    outputs = laser_sheets(sheets, profile, engrave_ops, cut_ops,
                           {"machine": machine, "scale": f"{scale:g} mm per unit", "material": material_name,
                            "profile": profile.name},
                           f"{machine} parts at {scale:g} mm per unit", report)
    parts_area = sum(o.sheet.parts_area for o in outputs)
    estimates = [o.job.estimate_seconds() for o in outputs]
    summary = {
        "machine": machine,
        "params": dict(params),
        "scale_mm_per_unit": scale,
        "kerf_mm": kerf,
        "kerf_source": kerf_source,
        "gap_mm": gap,
        "sheet_mm": [width, height],
        "sheet_count": len(outputs),
        "sheet_usage": round(parts_area / (len(outputs) * width * height), 4),
        "generation_seconds": round(generated, 3),
        "parts": [_part_summary(part, cut, placement, o.index)
                  for o in outputs
                  for part, cut, placement in zip(o.sheet.parts, o.sheet.cut_shapes, o.sheet.placements)],
        "sheets": [{
            "index": o.index,
            "files": {"svg": f"parts{o.suffix}.svg", "gcode": f"laser{o.suffix}.gcode", "png": f"sheet{o.suffix}.png"},
            "parts": [part.name for part in o.sheet.parts],
            "usage": round(o.sheet.usage, 4),
            "envelope_usage": round(o.sheet.envelope_usage, 4),
            "used_mm": [round(o.sheet.used_width, 2), round(o.sheet.used_height, 2)],
            "job": _job_summary(o.job),
        } for o in outputs],
        "job": {
            "profile": profile.name,
            "material": material_name,
            "engrave": {"power": engrave_ops.power, "feed_mm_min": engrave_ops.feed, "passes": engrave_ops.passes},
            "cut": {"power": cut_ops.power, "feed_mm_min": cut_ops.feed, "passes": cut_ops.passes},
            "paths": sum(len(o.job.paths) for o in outputs),
            "travel_mm_unordered": round(sum(o.job.travel_unordered for o in outputs), 1),
            "travel_mm": round(sum(o.job.travel for o in outputs), 1),
            "estimate_seconds": {k: round(sum(e[k] for e in estimates), 1) for k in estimates[0]},
        },
    }
    report(SHEETS_STAGE, len(outputs), len(outputs),
           f"{len(parts)} parts on {len(outputs)} sheet{'' if len(outputs) == 1 else 's'}")
    return FabricationResult(machine, dict(params), scale, outputs, summary)


@station_errors
def laser_sheets(sheets, profile, engrave_ops, cut_ops, metadata: dict[str, str], title: str,
                 report: Reporter | None = None) -> list[SheetOutput]:
    """Each nested sheet's laser job (engraving, then each part's holes before its outline; dark travels), checked
    against the profile's work area, with its G-code, SVG and PNG preview (the travel drawn grey). ``metadata`` goes
    in the G-code's header (the sheet's number is added); ``title`` names the SVG (", sheet i of n" is added)."""
    from design.fabrication import render_png, sheet_paths, write_svg  # shapely and OpenCV, as in fabricate()

    report = report if report is not None else Reporter.of(None)
    xmin, ymin, _, _ = profile.work_bounds()
    outputs: list[SheetOutput] = []
    for index, sheet in enumerate(sheets, start=1):
        report(SHEETS_STAGE, index - 1, len(sheets), f"ordering the laser job of sheet {index} of {len(sheets)}")
        paths = sheet_paths(sheet)
        job = plan_laser_job(paths["engrave"], paths["cut"], engrave_ops, cut_ops, profile.laser.max_power,
                             profile.plot.travel_feed, offset=(xmin, ymin), start=(xmin, ymin),
                             metadata={**metadata, "sheet": f"{index} of {len(sheets)}"},
                             machine_settings=profile.grbl_settings)
        check_work_area(job, profile.work_bounds(), profile.name)
        gcode = io.StringIO()
        write_laser_gcode(job, gcode, profile.work_bounds(), profile.laser.laser_mode, profile.name)
        svg = io.StringIO()
        write_svg(sheet, svg, title=f"{title}, sheet {index} of {len(sheets)}")
        # The preview shows travel in sheet coordinates.
        moves = [m - [xmin, ymin] for m in travel_moves(job)]
        outputs.append(SheetOutput(index, sheet, job, svg.getvalue(), gcode.getvalue(),
                                   render_png(sheet, travel=moves)))
    return outputs


def _job_summary(job) -> dict[str, Any]:
    lo, hi = job.extent()
    return {
        "paths": len(job.paths),
        "travel_mm_unordered": round(job.travel_unordered, 1),
        "travel_mm": round(job.travel, 1),
        "estimate_seconds": {k: round(v, 1) for k, v in job.estimate_seconds().items()},
        "extent_mm": [[float(v) for v in lo], [float(v) for v in hi]],
    }


def _part_summary(part, cut_shape, placement, sheet_index: int) -> dict[str, Any]:
    minx, miny, maxx, maxy = part.shape.bounds
    return {
        "name": part.name,
        "sheet": sheet_index,
        "size_mm": [round(maxx - minx, 2), round(maxy - miny, 2)],
        "bbox_on_sheet_mm": [round(v, 3) for v in cut_shape.bounds],
        "area_mm2": round(part.shape.area, 1),
        "holes": len(part.shape.interiors),
        "placement": {"angle_deg": placement.angle, "dx_mm": round(placement.dx, 3), "dy_mm": round(placement.dy, 3)},
        "info": to_jsonable(dict(part.info)),
        "notes": list(part.notes),
    }


@station_errors
def write_outputs(result: FabricationResult, out: Path) -> dict[str, Path]:
    """Write parts.svg, laser.gcode, sheet.png (``-2``, ``-3``... for further sheets) and parts.json into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    files: dict[str, Path] = {}
    for o in result.sheets:
        key = "" if o.index == 1 else f" {o.index}"
        files[f"svg{key}"] = out / f"parts{o.suffix}.svg"
        files[f"gcode{key}"] = out / f"laser{o.suffix}.gcode"
        files[f"png{key}"] = out / f"sheet{o.suffix}.png"
        files[f"svg{key}"].write_text(o.svg, encoding="utf-8")
        files[f"gcode{key}"].write_text(o.gcode, encoding="utf-8")
        files[f"png{key}"].write_bytes(o.png)
    files["json"] = out / "parts.json"
    files["json"].write_text(json.dumps(to_jsonable(result.summary), indent=2, allow_nan=False) + "\n",
                             encoding="utf-8")
    return files
