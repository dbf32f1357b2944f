"""Drawing-machine models of the thesis (chapter 3.6, Table 3.2, Appendix A).

>>> from design.machines import get_machine
>>> m = get_machine("spirograph")
>>> points = m.sample({"r_f": 5, "r_r": 3, "d": 2.0}, n=1024, spacing="arclength")  # (1024, 2), closed

Machines: ``spirograph``, ``elliptic_spirograph``, ``cycloid_drawing_machine``, ``hoot_nanny``; others can be
added with :func:`register_machine` or the ``chaos_station.machines`` entry-point group (see
:mod:`design.machines.registry`). The API every machine has is :class:`~design.machines.base.DrawingMachine`.
"""

from design.machines.base import (
    CATEGORIES,
    MAX_GEAR_RADIUS,
    Circle,
    Constraint,
    DrawingMachine,
    Ellipse,
    Parameter,
    Point,
    Segment,
    Shape,
    Violation,
    shapes_to_jsonable,
)
from design.machines.registry import (
    ENTRY_POINT_GROUP,
    MachineRegistryError,
    all_machines,
    declared_machine_names,
    get_machine,
    machine_names,
    register_machine,
    unregister_machine,
)

__all__ = [
    "CATEGORIES",
    "ENTRY_POINT_GROUP",
    "MAX_GEAR_RADIUS",
    "Circle",
    "Constraint",
    "DrawingMachine",
    "Ellipse",
    "MachineRegistryError",
    "Parameter",
    "Point",
    "Segment",
    "Shape",
    "Violation",
    "all_machines",
    "declared_machine_names",
    "get_machine",
    "machine_names",
    "register_machine",
    "shapes_to_jsonable",
    "unregister_machine",
]
