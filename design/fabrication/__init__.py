"""Fabrication: gear profiles, the flat parts of each drawing machine, kerf, nesting, SVG and previews.

Thesis 3.6.3: laser-cut the precision-critical flat parts (gears, arms, plates), buy or print the connectors.
"""

from design.fabrication.export import render_png, sheet_paths, write_svg
from design.fabrication.gears import (
    Gear,
    GearSettings,
    elliptic_gear,
    external_gear,
    min_teeth_without_undercut,
    ring_gear,
    teeth_per_unit,
)
from design.fabrication.nesting import Placement, Sheet, kerf_compensate, nest_parts, nest_sheets
from design.fabrication.parts import FABRICABLE_MACHINES, Hardware, Part, machine_parts

__all__ = [
    "FABRICABLE_MACHINES",
    "Gear",
    "GearSettings",
    "Hardware",
    "Part",
    "Placement",
    "Sheet",
    "elliptic_gear",
    "external_gear",
    "kerf_compensate",
    "machine_parts",
    "min_teeth_without_undercut",
    "nest_parts",
    "nest_sheets",
    "render_png",
    "ring_gear",
    "sheet_paths",
    "teeth_per_unit",
    "write_svg",
]
