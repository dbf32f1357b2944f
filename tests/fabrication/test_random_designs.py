"""Random feasible designs of every machine: parts are valid and nest, or the refusal names the part (slow)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from design.errors import DesignError
from design.fabrication import FABRICABLE_MACHINES, machine_parts, nest_parts
from design.machines import get_machine


def random_feasible_designs(name, count, seed):
    """Designs near the defaults (the feasible regions of the turntable machines are small)."""
    model = get_machine(name)
    defaults = model.defaults()
    rng = np.random.default_rng(seed)
    designs = []
    for _ in range(20000):
        params = dict(defaults)
        for p in model.parameters:
            if p.kind == "discrete":
                params[p.name] = int(np.clip(defaults[p.name] + rng.integers(-3, 4), p.lower, p.upper))
            else:
                params[p.name] = float(defaults[p.name] * rng.uniform(0.6, 1.4))
        if model.is_feasible(params):
            designs.append(params)
        if len(designs) == count:
            break
    return designs


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
