"""The assembly order of a contraption's parts: what the maker places first, and what last.

Rules, in order of precedence:

1. **Hard constraints** (never broken): a part comes after its parent part (it moves with it; an Empty parent is
   no part) and after every part it rests on. "B rests on A" is read from gravity (world -z) at the layout: their
   footprints seen from above overlap, B's lowest point is more than 1 mm above A's, and B's lowest point is at most
   3 mm above A's highest (B sits on or in A: a ball on a track, a cage over a ball, a plank on a lever). A static
   part rests on nothing (it is fixed: a pin a gate leans on comes with the other fixed parts). Since the lowest
   point strictly rises along these edges, they cannot form a cycle.
2. **The trigger** (the actor of the scenario's first event: its ``body``, or ``a`` for a contact) comes at the very
   end, followed only by what must come after it (its children, what rests on it: a lever's weight box, the weight
   in it). A static actor starts nothing by being placed, and is ordered like any static part.
3. Among the parts free to go next: **static** parts (mass 0, or fastened alone to the world) first, then the
   placed parts that stay where they are put, then those that would **topple** (domino runs, boxes standing on end,
   anything riding on a lever), then those that would **roll** away (balls, capsules, cylinders lying on their
   side), each group in the scenario file's order.
"""

from __future__ import annotations

import heapq
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from shapely.geometry.base import BaseGeometry

from design.contraption.model import ObjectSpec, Scenario
from projector.guide import PartKind

__all__ = ["PartFacts", "assembly_order", "part_kind", "rests_on", "rolls", "topples", "trigger_object"]

#: Rank of each group of rule 3.
STATIC, STABLE, TOPPLES, ROLLS = 0, 1, 2, 3
#: A box stands on end when its vertical edge is this many times its shortest horizontal edge.
_ON_END = 1.5
#: rests-on thresholds (m): B's bottom above A's bottom by more than ``_ABOVE``, above A's top by at most ``_GAP``.
_ABOVE = 0.001
_GAP = 0.003


@dataclass(frozen=True)
class PartFacts:
    """What the order needs to know of one part at the layout.

    Attributes
    ----------
    obj : ObjectSpec
    kind : PartKind
    parent : str or None
        The nearest ancestor that is a part (Empty frames skipped).
    footprint : shapely geometry
        Its outline seen from above (x, y in mm), whatever the guide's view.
    z_min, z_max : float
        Its lowest and highest world points (m).
    axes_up : ndarray, shape (3,)
        For each of the object's local axes, its |component| along world z (which axis stands up).
    """

    obj: ObjectSpec
    kind: PartKind
    parent: str | None
    footprint: BaseGeometry
    z_min: float
    z_max: float
    axes_up: np.ndarray


def part_kind(scenario: Scenario, obj: ObjectSpec) -> PartKind:
    """STATIC for a part of mass 0 (static physics) or fastened alone to the world; PLACED otherwise."""
    if obj.physics.static:
        return PartKind.STATIC
    for other in scenario.objects:
        if other.type == "Fastener":
            bodies = [ref.split("[", 1)[0] for ref in other.shape["bodies"]]
            if len(bodies) == 1 and bodies[0] == obj.name:
                return PartKind.STATIC
    return PartKind.PLACED


def trigger_object(scenario: Scenario) -> str | None:
    """The object whose part the first (root) event is about: its ``body``, or ``a`` for a (No)Contact."""
    event = scenario.event(scenario.root)
    ref = event.params.get("body", event.params.get("a"))
    return None if ref is None else str(ref).split("[", 1)[0]


def rolls(facts: PartFacts) -> bool:
    """Whether the part would roll away if nudged: a ball, a capsule, a cylinder whose axis lies flat."""
    kind = facts.obj.type
    return kind in ("Ball", "Capsule") or (kind == "Cylinder" and facts.axes_up[2] < 0.5)


def topples(facts: PartFacts, parts: Mapping[str, PartFacts]) -> bool:
    """Whether the part would topple if nudged: a domino run, a box on end, a part riding on a lever."""
    obj = facts.obj
    if obj.type == "DominoRun":
        return True
    if obj.type == "Box":
        size = np.asarray(obj.shape["size"], dtype=float)
        up = int(np.argmax(facts.axes_up))
        others = np.delete(size, up)
        if size[up] > _ON_END * float(others.min()):
            return True
    parent = parts.get(facts.parent) if facts.parent else None
    return parent is not None and parent.obj.type == "Lever" and parent.kind is PartKind.PLACED


def rests_on(upper: PartFacts, lower: PartFacts) -> bool:
    """Whether ``upper`` sits on or in ``lower`` (see the module notes, rule 1)."""
    if upper.kind is PartKind.STATIC or not upper.z_min > lower.z_min + _ABOVE or upper.z_min > lower.z_max + _GAP:
        return False
    return upper.footprint.intersection(lower.footprint).area > 1.0  # mm², not a touch along an edge


def assembly_order(scenario: Scenario, parts: Mapping[str, PartFacts]) -> list[str]:
    """The parts' names in assembly order (see the module notes)."""
    names = list(parts)
    index = {name: i for i, name in enumerate(names)}
    after: dict[str, set[str]] = {name: set() for name in names}  # after[a]: parts that must come after a
    for name, facts in parts.items():
        if facts.parent is not None:
            after[facts.parent].add(name)
    for upper in names:
        for lower in names:
            # A parent resting on its child would be a cycle: the parent edge wins.
            if lower != upper and upper not in _ancestors(lower, parts) and lower not in after[upper] \
                    and rests_on(parts[upper], parts[lower]):
                after[lower].add(upper)

    trigger = trigger_object(scenario)
    group: set[str] = set()
    if trigger in parts and parts[trigger].kind is PartKind.PLACED:
        stack = [trigger]
        while stack:
            name = stack.pop()
            if name not in group:
                group.add(name)
                stack.extend(after[name])

    def rank(name: str) -> tuple[int, int, int]:
        facts = parts[name]
        if name in group:
            # The trigger before what must follow it; the group after everything else.
            return (ROLLS + 1, 0 if name == trigger else 1, index[name])
        if facts.kind is PartKind.STATIC:
            level = STATIC
        else:
            level = ROLLS if rolls(facts) else TOPPLES if topples(facts, parts) else STABLE
        return (level, 0, index[name])

    return _topological(names, after, rank)


def _ancestors(name: str, parts: Mapping[str, PartFacts]) -> set[str]:
    seen = set()
    parent = parts[name].parent
    while parent is not None and parent not in seen:
        seen.add(parent)
        parent = parts[parent].parent
    return seen


def _topological(names: Sequence[str], after: Mapping[str, set[str]], rank) -> list[str]:
    """Kahn's algorithm, taking the lowest ``rank`` among the parts free to go next."""
    waiting = {name: 0 for name in names}
    for name in names:
        for successor in after[name]:
            waiting[successor] += 1
    ready = [(rank(name), name) for name in names if waiting[name] == 0]
    heapq.heapify(ready)
    order = []
    while ready:
        _, name = heapq.heappop(ready)
        order.append(name)
        for successor in after[name]:
            waiting[successor] -= 1
            if waiting[successor] == 0:
                heapq.heappush(ready, (rank(successor), successor))
    if len(order) != len(names):  # pragma: no cover - the edges are acyclic by construction (module notes)
        order.extend(name for name in names if name not in order)
    return order
