"""Fabrication benchmark: parts generation time per machine, sheet usage, laser travel before/after ordering.

Run with ``.venv/bin/python -m bench fabrication``. Each machine at its default design and at 8 mm per unit, kerf
0.15 mm, gap 3 mm, on the built-in laser's 400×400 mm work area; then a mixed sheet of all four machines' parts
(at 5 mm per unit), and gear generation timings by tooth count.
"""

from __future__ import annotations

import time

from cam.laser import material_settings, plan_laser_job
from design.fabrication import (
    GearSettings,
    elliptic_gear,
    external_gear,
    machine_parts,
    nest_parts,
    ring_gear,
    sheet_paths,
)
from drivers.profiles import builtin_profile

MACHINES = ("spirograph", "elliptic_spirograph", "cycloid_drawing_machine", "hoot_nanny")


def _job(sheet, profile):
    engrave, cut, _ = material_settings(profile, None)
    paths = sheet_paths(sheet)
    return plan_laser_job(
        paths["engrave"], paths["cut"], engrave, cut, profile.laser.max_power, profile.plot.travel_feed,
        machine_settings=profile.grbl_settings,
    )


def main() -> None:
    profile = builtin_profile("laser")
    print(
        f"{'machine':26s} {'parts':>5s} {'generate s':>10s} {'nest s':>7s} {'sheet use':>9s} {'envelope':>8s} "
        f"{'travel before mm':>16s} {'after mm':>9s} {'ratio':>6s} {'order s':>7s} {'job min':>7s}"
    )
    for machine in MACHINES:
        started = time.perf_counter()
        parts = machine_parts(machine, {}, 8.0)
        generated = time.perf_counter() - started
        started = time.perf_counter()
        sheet = nest_parts(parts, profile.width, profile.height, gap=3.0, kerf=0.15)
        nested = time.perf_counter() - started
        started = time.perf_counter()
        job = _job(sheet, profile)
        ordered = time.perf_counter() - started
        print(
            f"{machine:26s} {len(parts):5d} {generated:10.2f} {nested:7.2f} {100 * sheet.usage:8.1f}% "
            f"{100 * sheet.envelope_usage:7.1f}% {job.travel_unordered:16.0f} {job.travel:9.0f} "
            f"{job.travel / job.travel_unordered:6.2f} {ordered:7.2f} {job.estimate_seconds()['total'] / 60:7.1f}"
        )

    # Every machine's parts on one sheet: a denser nesting problem and a longer tour.
    parts = []
    for machine in MACHINES:
        for part in machine_parts(machine, {}, 5.0):
            parts.append(type(part)(f"{machine}: {part.name}", part.shape, part.engrave, part.info, part.notes))
    started = time.perf_counter()
    sheet = nest_parts(parts, profile.width, profile.height, gap=3.0, kerf=0.15)
    nested = time.perf_counter() - started
    job = _job(sheet, profile)
    plain = sum(len(p.engrave) for p in sheet.parts)
    print(
        f"\nall four machines at 5 mm/unit: {len(parts)} parts nested in {nested:.2f} s, sheet usage "
        f"{100 * sheet.usage:.1f}%, envelope {sheet.used_width:.0f}x{sheet.used_height:.0f} mm filled "
        f"{100 * sheet.envelope_usage:.1f}%; {plain} label strokes; travel {job.travel_unordered:.0f} -> "
        f"{job.travel:.0f} mm (ratio {job.travel / job.travel_unordered:.2f})"
    )

    print("\ngear generation (module 1.5, 20 deg):")
    settings = GearSettings()
    for teeth in (12, 24, 48, 96):
        started = time.perf_counter()
        external_gear(teeth, 1.5, settings)
        t_ext = time.perf_counter() - started
        started = time.perf_counter()
        elliptic_gear(teeth, 1.5, 0.6, settings)
        t_ell = time.perf_counter() - started
        started = time.perf_counter()
        ring_gear(teeth * 2, 1.5, 8.0, settings, cutter_teeth=teeth)
        t_ring = time.perf_counter() - started
        print(
            f"  z={teeth:3d}: external {t_ext:.3f} s, elliptic (e=0.6) {t_ell:.3f} s, ring z={2 * teeth} {t_ring:.3f} s"
        )
