"""Random feasible designs of every machine: parts are valid and nest, or the refusal names the part (slow)."""

from __future__ import annotations

import itertools

import pytest

from design.errors import DesignError
from design.fabrication import FABRICABLE_MACHINES, machine_parts, nest_parts

from .conftest import random_feasible_designs


@pytest.mark.slow
@pytest.mark.parametrize("machine", FABRICABLE_MACHINES)
def test_random_designs_make_valid_parts_or_a_named_refusal(machine):
    designs = random_feasible_designs(machine, 6, seed=11)
    assert designs
    made = 0
    for params, scale in zip(designs, itertools.cycle([4.0, 6.0, 10.0])):
        try:
            parts = machine_parts(machine, params, scale)
        except DesignError as error:
            assert ":" in str(error)  # "part name: what is wrong"
            continue
        made += 1
        sheet = nest_parts(parts, 1200, 1200, gap=3, kerf=0.15)
        for part in parts:
            assert part.shape.is_valid and not part.shape.is_empty
        for a, b in itertools.combinations(sheet.cut_shapes, 2):
            assert a.distance(b) >= 3 - 1e-6
    assert made >= 1
