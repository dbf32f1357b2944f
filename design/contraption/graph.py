"""Checks that need the whole file: references between objects, the tree of parents, and the causal graph.

Each field has been read on its own first (:mod:`design.contraption.validation`); here the names it gives are
resolved against the other objects and events: a body reference names an object that has bodies (one domino of a
run by its index), parents form a tree, and the events form a DAG with a single root (thesis 4.3).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from design.contraption.fields import Checker
from design.contraption.model import EventSpec, ObjectSpec, domino_count
from design.contraption.schema import BODY_REF, PRIMITIVES, Kind


def resolve_body_ref(check: Checker, path: str, ref: str, by_name: Mapping[str, ObjectSpec]) -> tuple[str, int | None]:
    """Split ``"run[3]"`` into ``("run", 3)`` and check the object exists and has bodies."""
    match = BODY_REF.match(ref)
    if match is None:  # pragma: no cover - checked by body_ref already
        raise check.fail(path, f"expected an object name, got {ref!r}")
    name, index = match.group(1), match.group(2)
    if name not in by_name:
        raise check.fail(path, f"unknown object {name!r}; expected one of {', '.join(sorted(by_name))}")
    obj = by_name[name]
    if not obj.has_body:
        raise check.fail(path, f"expected an object with a body, {name!r} is a {obj.type}")
    if obj.type == "DominoRun":
        if index is None:
            raise check.fail(path, f"expected one domino of the run, e.g. '{name}[0]' or '{name}[-1]'")
        count = domino_count(obj.shape)
        if not -count <= int(index) < count:
            raise check.fail(path, f"expected a domino index in [{-count}, {count - 1}], got {index}")
        return name, int(index) % count
    if index is not None:
        raise check.fail(path, f"{name!r} is a single body ({obj.type}); expected no index")
    return name, None


def check_references(check: Checker, objects: Sequence[ObjectSpec], by_name: Mapping[str, ObjectSpec]) -> None:
    """Parents and the bodies named in shapes exist (a RopePulley's pulleys are Pulleys); parents form a tree."""
    for obj in objects:
        path = f"objects[{obj.index}]"
        if obj.parent is not None:
            if obj.parent not in by_name:
                raise check.fail(f"{path}.parent", f"unknown object {obj.parent!r}")
            if obj.parent == obj.name:
                raise check.fail(f"{path}.parent", "an object cannot be its own parent")
        for key, (kind, _default) in PRIMITIVES[obj.type].params.items():
            if key not in obj.shape or not kind.refers_to_bodies:
                continue
            value = obj.shape[key]
            if kind is Kind.BODY:
                refs = [(f"{path}.shape.{key}", value)]
            else:
                refs = [(f"{path}.shape.{key}[{i}]", r) for i, r in enumerate(value)]
            for rpath, ref in refs:
                target = resolve_body_ref(check, rpath, ref, by_name)
                if key == "pulleys" and by_name[target[0]].type != "Pulley":
                    raise check.fail(rpath, f"expected a Pulley object, {ref!r} is a {by_name[target[0]].type}")
    _check_parent_tree(check, objects, by_name)


def _check_parent_tree(check: Checker, objects: Sequence[ObjectSpec], by_name: Mapping[str, ObjectSpec]) -> None:
    # Parent chains must end (no cycles): the scene graph is walked from the root down.
    for obj in objects:
        seen = [obj.name]
        current = obj
        while current.parent is not None:
            if current.parent in seen:
                raise check.fail(
                    f"objects[{obj.index}].parent", f"expected a tree of parents, found a cycle {' -> '.join(seen)}"
                )
            seen.append(current.parent)
            current = by_name[current.parent]


def check_event_graph(check: Checker, events: Sequence[EventSpec]) -> None:
    """Every parent event exists and is not the event itself, exactly one event has none, and there is no cycle."""
    names = {e.name for e in events}
    for event in events:
        for j, parent in enumerate(event.after):
            if parent not in names:
                raise check.fail(f"events[{event.index}].after[{j}]", f"unknown event {parent!r}")
            if parent == event.name:
                raise check.fail(f"events[{event.index}].after[{j}]", "an event cannot follow itself")
    roots = [e for e in events if not e.after]
    if len(roots) != 1:
        found = ", ".join(e.name for e in roots) or "none"
        raise check.fail("events", f"expected exactly one root event (an event without 'after'), found {found}")
    _check_acyclic(check, events)


def _check_acyclic(check: Checker, events: Sequence[EventSpec]) -> None:
    parents = {e.name: e.after for e in events}
    state: dict[str, int] = {}

    def visit(name: str, trail: list[str]) -> None:
        # Iterative depth would be nicer, but graphs are small; recursion depth is bounded by the event count.
        if state.get(name) == 2:
            return
        if state.get(name) == 1:
            cycle = trail[trail.index(name):] + [name]
            index = next(e.index for e in events if e.name == name)
            raise check.fail(f"events[{index}].after", f"expected a DAG, found a cycle {' <- '.join(cycle)}")
        state[name] = 1
        for parent in parents[name]:
            visit(parent, trail + [name])
        state[name] = 2

    for event in events:
        visit(event.name, [])
