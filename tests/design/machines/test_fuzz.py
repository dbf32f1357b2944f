"""Any numbers in, never a crash: violations() and feasible_mask() agree, feasible designs sample finite curves."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from design.machines import get_machine

MACHINES = ["spirograph", "elliptic_spirograph", "cycloid_drawing_machine", "hoot_nanny"]
numbers = st.one_of(
    st.floats(-100, 100, allow_nan=False), st.integers(-5, 40), st.sampled_from([0.0, 1.0, 1e-300, 1e6, -0.0])
)


@st.composite
def designs(draw):
    machine = get_machine(draw(st.sampled_from(MACHINES)))
    names = draw(st.lists(st.sampled_from(machine.parameter_names), unique=True))
    return machine, {name: draw(numbers) for name in names}


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(designs())
def test_violations_never_crash_and_agree_with_the_mask(case):
    machine, params = case
    found = machine.violations(params)
    for violation in found:
        assert violation.message and violation.margin <= 0
    assert machine.feasible_mask([params])[0] == (not found)
    if not found:
        points = machine.sample(params, 64)
        assert np.isfinite(points).all()
