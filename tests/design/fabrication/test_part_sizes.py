"""Part sizes known before building: they match the built parts, and a part too large for the sheet is refused
before any gear is generated, with the largest scale that fits."""

from __future__ import annotations

import re

import pytest

from common.progress import Cancelled, Reporter
from design.errors import ConstraintViolation, DesignError
from design.fabrication import (
    FABRICABLE_MACHINES,
    GEARS_STAGE,
    check_sizes_fit,
    largest_fitting_scale,
    machine_parts,
    nest_parts,
    part_sizes,
)

from .conftest import random_feasible_designs


def _box(part) -> tuple[float, float]:
    minx, miny, maxx, maxy = part.shape.bounds
    return maxx - minx, maxy - miny


@pytest.mark.parametrize("machine", FABRICABLE_MACHINES)
def test_sizes_bound_the_built_parts(machine):
    # The defaults and a random design, at scales where the module rounding differs (k = 2·scale/1.5 rounded).
    designs = [{}, *random_feasible_designs(machine, 1, seed=3)]
    checked = 0
    for params in designs:
        for scale in (3.0, 5.3):
            try:
                parts = machine_parts(machine, params, scale)
            except DesignError:
                continue  # a hole that does not fit at this scale: sizes do not claim to know
            sizes = part_sizes(machine, params, scale)
            assert [s.name for s in sizes] == [p.name for p in parts]
            for part, size in zip(parts, sizes):
                width, height = _box(part)
                assert size.width - size.tolerance - 1e-6 <= width <= size.width + 1e-6, part.name
                assert size.height - size.tolerance - 1e-6 <= height <= size.height + 1e-6, part.name
                assert (size.teeth > 0) == ("teeth" in part.info), part.name
                if size.teeth:
                    assert size.teeth == part.info["teeth"]
            checked += 1
    assert checked >= 2


def test_machine_parts_reports_each_gear_before_generating_it():
    steps = []
    parts = machine_parts("hoot_nanny", {}, 4.0, report=Reporter(steps.append))
    gears = {p.name: p.info["teeth"] for p in parts if "teeth" in p.info}
    *before_each, last = steps
    reported = [re.fullmatch(r"generating (.+) \((\d+) teeth\)", step.message) for step in before_each]
    assert all(reported) and len(reported) == len(gears) == 3
    assert {m.group(1): int(m.group(2)) for m in reported} == gears
    total = sum(s.teeth for s in part_sizes("hoot_nanny", {}, 4.0))
    assert total == sum(gears.values())
    # Teeth done so far before each gear, out of every tooth to generate; the last report ends the stage.
    done = 0
    for step, match in zip(before_each, reported):
        assert (step.stage, step.done, step.total) == (GEARS_STAGE, done, total)
        done += int(match.group(2))
    assert (last.stage, last.done, last.total) == (GEARS_STAGE, total, total) and last.fraction == 1.0


def test_machine_parts_stops_between_gears_when_asked():
    steps = []
    with pytest.raises(Cancelled):
        machine_parts("hoot_nanny", {}, 4.0, report=Reporter(steps.append, stop=lambda: len(steps) >= 2))
    assert len(steps) == 2  # the second gear was announced, then the work stopped before generating it


@pytest.mark.parametrize(("machine", "scale"), [("spirograph", 500.0), ("hoot_nanny", 1000.0)])
def test_a_part_too_large_for_the_sheet_is_refused_from_its_size(machine, scale):
    # What took 31 s (spirograph) and over 2 minutes (hoot_nanny) before the refusal: now sizes only.
    sizes = part_sizes(machine, {}, scale)
    with pytest.raises(ConstraintViolation) as refused:
        check_sizes_fit(sizes, 400, 400, gap=3, kerf=0.15, scale=scale,
                        sizes_at=lambda s: part_sizes(machine, {}, s))
    message = str(refused.value)
    assert "sheet 400x400 mm: no room for part" in message and f"at {scale:g} mm per unit" in message
    largest = largest_fitting_scale(lambda s: part_sizes(machine, {}, s), scale, 400, 400, gap=3, kerf=0.15)
    assert largest is not None and 1 < largest < scale
    assert f"--scale {largest:g}" in message and "--sheet WxH" in message
    # Largest: at the suggested scale every part fits the sheet, a little above it one does not.
    check_sizes_fit(part_sizes(machine, {}, largest), 400, 400, gap=3, kerf=0.15)
    with pytest.raises(ConstraintViolation):
        check_sizes_fit(part_sizes(machine, {}, largest * 1.1), 400, 400, gap=3, kerf=0.15)


def test_the_suggested_scale_really_nests():
    # A small sheet keeps the build cheap: the refusal's scale is built and nested without a complaint.
    refused_at = 20.0
    largest = largest_fitting_scale(lambda s: part_sizes("spirograph", {}, s), refused_at, 100, 100, gap=3,
                                    kerf=0.15)
    assert largest is not None and largest < refused_at
    parts = machine_parts("spirograph", {}, largest)
    for part in parts:
        nest_parts([part], 100, 100, gap=3, kerf=0.15)


def test_parts_that_fit_pass_and_no_scale_is_said_when_none_fits():
    check_sizes_fit(part_sizes("spirograph", {}, 6.0), 400, 400, gap=3, kerf=0.15)
    sizes = part_sizes("hoot_nanny", {}, 5.0)
    with pytest.raises(ConstraintViolation, match="no scale fits this sheet; use a larger sheet"):
        check_sizes_fit(sizes, 20, 20, gap=3, kerf=0.15, scale=5.0, sizes_at=lambda s: part_sizes("hoot_nanny", {}, s))


def test_sizes_refuse_what_machine_parts_refuses():
    with pytest.raises(DesignError):
        part_sizes("spirograph", {"r_r": 7}, 6.0)  # r_r >= r_f: not feasible
    with pytest.raises(DesignError):
        part_sizes("spirograph", {}, -1.0)
