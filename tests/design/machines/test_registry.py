"""Adding a machine without editing the core: register_machine and the entry-point group."""

from __future__ import annotations

from importlib.metadata import entry_points

import numpy as np
import pytest

from design.errors import ParameterError
from design.machines import (
    ENTRY_POINT_GROUP,
    Circle,
    Constraint,
    DrawingMachine,
    MachineRegistryError,
    Parameter,
    Point,
    get_machine,
    machine_names,
    register_machine,
    unregister_machine,
)
from design.machines.base import gear_period
from design.machines.registry import BUILTIN_MACHINES


class Rose(DrawingMachine):
    """A toy plug-in machine: a pen on a gear of radius k driven by a unit crank (a rose-like epicycle)."""

    name = "test_rose"
    title = "Rose (test plug-in)"
    parameters = (
        Parameter("k", "discrete", 3, 1, 9, "gear radius"),
        Parameter("a", "continuous", 0.5, 0.0, 1.0, "pen offset"),
    )

    def constraints(self):
        yield Constraint("a_positive", "symmetry reduction", "", lambda P: P["a"], lambda p: f"a > 0, got {p['a']}")

    def _period(self, P):
        return gear_period(np.ones_like(P["k"]), P["k"])

    def _positions(self, P, t):
        return np.exp(1j * t) + P["a"] * np.exp(-1j * t / P["k"])

    def mechanism(self, params, t, frame="drawing"):
        z = self.curve(params, [t])[0]
        return [Circle("crank", (0.0, 0.0), 1.0), Point("pen", (z[0], z[1]))]


def test_register_machine_adds_a_machine_without_editing_the_core():
    try:
        registered = register_machine(Rose)
        assert "test_rose" in machine_names()
        machine = get_machine("test_rose")
        assert machine is registered
        assert machine.period({"k": 4}) == pytest.approx(8 * np.pi)
        points = machine.sample({"k": 4, "a": 0.3}, 200, "arclength")
        assert np.array_equal(points[0], points[-1])
        assert machine.feasible_interval({"k": 4, "a": 0.3}, "a")[1] == 1.0
        with pytest.raises(MachineRegistryError, match="already registered"):
            register_machine(type("Other", (Rose,), {}))
    finally:
        unregister_machine("test_rose")
    assert "test_rose" not in machine_names()


def test_register_rejects_non_machines():
    with pytest.raises(MachineRegistryError, match="DrawingMachine"):
        register_machine(object())


def test_builtins_are_declared_as_entry_points():
    declared = {point.name: point.value for point in entry_points(group=ENTRY_POINT_GROUP)}
    assert declared == BUILTIN_MACHINES


def test_unknown_machine_is_a_parameter_error_listing_the_known_ones():
    with pytest.raises(ParameterError, match="must be one of spirograph"):
        get_machine("harmonograph")
