"""Fabrication: gear profiles, the flat parts of each drawing machine, kerf, nesting, SVG and previews.

Thesis 3.6.3: laser-cut the precision-critical flat parts (gears, arms, plates), buy or print the connectors.
"""

from design.lazy import lazy_exports

# Imported on first use: the CLI's parser needs FABRICABLE_MACHINES, not shapely and scipy.
_SOURCES = {
    "catalog": ("FABRICABLE_MACHINES",),
    "export": ("render_png", "sheet_paths", "write_svg"),
    "gears": ("Gear", "elliptic_gear", "external_gear", "ring_gear"),
    "tooth_system": ("GearSettings", "min_teeth_without_undercut", "teeth_per_unit"),
    "layout": ("Hardware",),
    "nesting": (
        "Placement", "Sheet", "check_sizes_fit", "kerf_compensate", "largest_fitting_scale", "nest_parts",
        "nest_sheets",
    ),
    "parts": ("GEARS_STAGE", "Part", "machine_parts"),
    "sizes": ("PartSize", "part_sizes"),
}
__getattr__, __dir__, _MODULE_OF = lazy_exports(__name__, _SOURCES)

__all__ = [
    "FABRICABLE_MACHINES",
    "GEARS_STAGE",
    "Gear",
    "GearSettings",
    "Hardware",
    "Part",
    "PartSize",
    "Placement",
    "Sheet",
    "check_sizes_fit",
    "elliptic_gear",
    "external_gear",
    "kerf_compensate",
    "largest_fitting_scale",
    "machine_parts",
    "min_teeth_without_undercut",
    "nest_parts",
    "nest_sheets",
    "part_sizes",
    "render_png",
    "ring_gear",
    "sheet_paths",
    "teeth_per_unit",
    "write_svg",
]
