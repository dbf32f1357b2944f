"""Helpers shared by the fabrication tests (imported as ``from .conftest import ...``, as tests/drivers does)."""

from __future__ import annotations

import numpy as np

from design.machines import get_machine


def random_feasible_designs(name, count, seed):
    """Up to ``count`` feasible designs near the defaults, seeded (the turntable machines' feasible regions are small).

    Each parameter is moved at random around its default (discrete ones by -3..3 within bounds, continuous ones by a
    factor 0.6..1.4) and the design is kept when the machine calls it feasible; at most 20000 draws are tried.
    """
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
