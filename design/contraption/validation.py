"""Reading a scenario file: parsing TOML or JSON, then every table and field against the schema.

:func:`load_scenario` and :func:`scenario_from_data` are the only ways in (:func:`with_physics` reads a scenario's
content again with other material values). The fields are read in file order with
:class:`~design.contraption.fields.Checker`, so the first bad value stops the load with one line naming the file,
the field's path and what was expected (``t.toml: objects[3].transform.heading: expected a number, got text
('north')``); what needs the whole file (references, parents, the causal graph) is checked by
:mod:`design.contraption.graph` once every object and event is read. This is hand-written rather than a pydantic
model: most rules relate several fields (a range holds its transform's value, a DominoRun takes poses or a path,
body references and the graph), and pydantic's messages need rewriting into this form (see docs/architecture.md).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from design.contraption.design_space import DesignSpace
from design.contraption.errors import LayoutError, ScenarioFormatError
from design.contraption.fields import Checker
from design.contraption.graph import check_event_graph, check_references, resolve_body_ref
from design.contraption.materials import MaterialValue, data_with_physics, parse_materials
from design.contraption.model import (
    EventSpec,
    ObjectSpec,
    Physics,
    Scenario,
    Settings,
    Tag,
    Transform,
    content_hash,
    domino_count,
)
from design.contraption.schema import (
    EVENT_COMMON,
    EVENTS,
    HEADER_KEYS,
    NAME,
    OBJECT_KEYS,
    PHYSICS_KEYS,
    PLANE_PHYSICS_KEYS,
    PRIMITIVES,
    SETTINGS_KEYS,
    TAG_KEYS,
    TOP_KEYS,
    TRANSFORM_KEYS,
    UNPLACED,
    Kind,
)
from design.datafiles import parse_json, parse_toml

#: What a scenario file should be, the end of the message for one that is not TOML or JSON.
SCENARIO_FILE = "a scenario: [scenario], [[objects]] and [[events]] tables (TOML or JSON)"

#: The most parts a scenario may have: its objects, a domino run counting each domino. Each is a body every
#: simulation builds and steps, and building grows faster than their number: 2000 dominoes take about 2 s of CPU a
#: simulation, 10 000 about 50 s, a million would take weeks; optimize runs hundreds of simulations and robustness
#: thousands. The thesis's largest scenario has about 70.
MAX_PARTS = 2000
_WHY_PARTS = "each is a body every simulation builds; optimize and robustness run hundreds to thousands of them"
#: The most wall panels of a Goblet (each a collision shape of its body; 12 by default).
MAX_GOBLET_SIDES = 64


def load_scenario(path: str | Path) -> Scenario:
    """Load and validate a scenario file (``.toml`` or ``.json``).

    Raises
    ------
    ScenarioFormatError
        For any problem with the file's syntax or content; the message names the file, field and expectation.
    FileNotFoundError
        When the file does not exist.
    """
    path = Path(path)
    file = str(path)
    suffix = path.suffix.lower()
    if suffix not in (".toml", ".json"):
        raise ScenarioFormatError(file, "", f"expected a .toml or .json scenario file, got {suffix or 'no suffix'!r}")
    raw = path.read_bytes()
    data = parse_text(raw, file, suffix)
    return scenario_from_data(data, file=file)


def with_physics(scenario: Scenario, values: Mapping[str, float]) -> Scenario:
    """The same scenario with other material values (``{"wood.friction": 0.42}``), read and validated again.

    Uncertain values keep their range and must lie in it. The result's :attr:`~Scenario.content_hash` is that of the
    new values (its simulations are other simulations); an empty ``values`` returns ``scenario``. The values set are
    kept in :attr:`~Scenario.physics_overrides` (added to any set before), so a worker process that loads the file
    again can apply them again.

    Raises
    ------
    ScenarioFormatError
        Naming ``physics."NAME"``: an unknown material or parameter, or a value outside its range.
    LayoutError
        A scenario built without its content (:attr:`~Scenario.data` None).
    """
    if not values:
        return scenario
    if scenario.data is None:
        raise LayoutError(f"{scenario.source}: this scenario was built without its content; load it from its file")
    data = data_with_physics(scenario.data, values, scenario.source)
    result = scenario_from_data(data, file=scenario.source)
    overrides = {**scenario.physics_overrides, **{k: float(v) for k, v in values.items()}}
    object.__setattr__(result, "physics_overrides", overrides)
    return result


def design_space_of(objects: Iterable[ObjectSpec]) -> DesignSpace:
    """The design space of validated objects: each ranged component, its bounds and the transform's value."""
    names, lower, upper, default = [], [], [], []
    for obj in objects:
        for key in TRANSFORM_KEYS:
            if key in obj.ranges:
                lo, hi = obj.ranges[key]
                names.append(f"{obj.name}.{key}")
                lower.append(lo)
                upper.append(hi)
                default.append(getattr(obj.transform, key))
    return DesignSpace(names, lower, upper, default)


def parse_text(raw: bytes, file: str, suffix: str) -> Any:
    """Parse the bytes of a TOML or JSON file into plain data, raising :class:`ScenarioFormatError` with
    :mod:`design.datafiles`'s one message (``FILE: not valid TOML (... at line L column C); expected ...``)."""
    fail = lambda detail: ScenarioFormatError(file, "", detail)  # noqa: E731 - the one line it takes
    if suffix == ".json":
        return parse_json(raw, file, SCENARIO_FILE, error=fail)
    return parse_toml(raw, file, SCENARIO_FILE, error=fail)


def scenario_from_data(data: Any, *, file: str = "<data>") -> Scenario:
    """Validate parsed scenario data (the content of a TOML/JSON file) and build the :class:`Scenario`."""
    check = Checker(file)
    top = check.table(data, "")
    check.only(top, "", TOP_KEYS)

    header = check.table(top.get("scenario", {}), "scenario")
    check.only(header, "scenario", HEADER_KEYS)
    name = check.string(header["name"], "scenario.name") if "name" in header else Path(file).stem
    description = check.string(header.get("description", ""), "scenario.description")

    settings = _settings(check, top.get("settings", {}))
    materials = parse_materials(check, top.get("materials", {}))
    objects = _objects(check, top, materials)
    parts = sum(domino_count(o.shape) if o.type == "DominoRun" else 1 for o in objects)
    if parts > MAX_PARTS:
        raise check.fail("objects", f"expected at most {MAX_PARTS} parts (objects, a domino run counting each "
                         f"domino), got {parts} ({_WHY_PARTS})")
    by_name = {o.name: o for o in objects}
    for i, (a, b) in enumerate(settings.ignore_overlap):
        for j, ref in enumerate((a, b)):
            if ref not in by_name:
                raise check.fail(f"settings.ignore_overlap[{i}][{j}]", f"unknown object {ref!r}")
    check_references(check, objects, by_name)
    events = _events(check, top, settings, by_name)
    space = design_space_of(objects)
    layouts = _layouts(check, top.get("layouts", {}), space)

    return Scenario(
        name=name,
        description=description,
        settings=settings,
        objects=tuple(objects),
        event_specs=tuple(events),
        design_space=space,
        layouts=layouts,
        content_hash=content_hash(top),
        source=file,
        materials=materials,
        data=top,
    )


def _settings(check: Checker, value: Any) -> Settings:
    table = check.table(value, "settings")
    check.only(table, "settings", SETTINGS_KEYS)
    kwargs: dict[str, Any] = {}
    for key in ("time_step", "event_timeout", "max_duration"):
        if key in table:
            kwargs[key] = check.number(table[key], f"settings.{key}", minimum=0.0, strict=True)
    if "gravity" in table:
        kwargs["gravity"] = check.number(table["gravity"], "settings.gravity")
    if "solver_iterations" in table:
        kwargs["solver_iterations"] = check.integer(table["solver_iterations"], "settings.solver_iterations")
    if "overlap_tolerance" in table:
        kwargs["overlap_tolerance"] = check.number(table["overlap_tolerance"], "settings.overlap_tolerance", minimum=0)
    if "ignore_overlap" in table:
        pairs = check.array(table["ignore_overlap"], "settings.ignore_overlap")
        kwargs["ignore_overlap"] = tuple(
            tuple(
                check.string(v, f"settings.ignore_overlap[{i}][{j}]", pattern=NAME, what="an object name")
                for j, v in enumerate(check.array(pair, f"settings.ignore_overlap[{i}]", min_len=2, max_len=2))
            )
            for i, pair in enumerate(pairs)
        )
    settings = Settings(**kwargs)
    if settings.time_step > 0.05:
        raise check.fail("settings.time_step", f"expected at most 0.05 s, got {settings.time_step:g}")
    if settings.max_duration / settings.time_step > 1e6:
        raise check.fail("settings.max_duration", "expected at most a million time steps (max_duration / time_step)")
    return settings


def _tables(check: Checker, top: dict, section: str, what: str) -> Iterator[tuple[int, str, dict]]:
    """The tables of the required, non-empty array ``section`` (``[[objects]]``, ``[[events]]``), one at a time.

    Each is checked to be a table only when it is reached, so a file's first error is the one reported.

    Yields
    ------
    tuple of (int, str, dict)
        The table's index, its path in the file (e.g. ``objects[2]``) and the table.
    """
    if section not in top:
        raise check.fail(section, f"missing; expected an array of {what} tables ([[{section}]])")
    items = check.array(top[section], section, min_len=1)
    if section == "objects" and len(items) > MAX_PARTS:
        raise check.fail(section, f"expected at most {MAX_PARTS} objects, got {len(items)} ({_WHY_PARTS})")
    for i, item in enumerate(items):
        path = f"{section}[{i}]"
        yield i, path, check.table(item, path)


def _unique_name(check: Checker, table: dict, path: str, seen: set[str], missing: str) -> str:
    """The required ``name`` of an object or event table, new among ``seen`` (and added to it).

    Parameters
    ----------
    check : Checker
        Reports a bad value as one line naming the field.
    table : dict
        The object or event table.
    path : str
        Where the table is in the file, e.g. ``objects[2]``.
    seen : set of str
        Names of the tables before this one (of the same section).
    missing : str
        What the message of a missing name says is expected, e.g. ``"an object name"``.

    Returns
    -------
    str
        The name.
    """
    if "name" not in table:
        raise check.fail(f"{path}.name", f"missing; expected {missing}")
    name = check.string(table["name"], f"{path}.name", pattern=NAME, what="a name of letters, digits, _ or -")
    if name in seen:
        raise check.fail(f"{path}.name", f"expected a unique name, {name!r} is used twice")
    seen.add(name)
    return name


def _type_of(check: Checker, table: dict, path: str, types: Mapping[str, Any]) -> str:
    """The required ``type`` of an object or event table, one of the keys of ``types`` (listed in their order)."""
    if "type" not in table:
        raise check.fail(f"{path}.type", f"missing; expected one of {', '.join(types)}")
    kind = check.string(table["type"], f"{path}.type")
    if kind not in types:
        raise check.fail(f"{path}.type", f"expected one of {', '.join(types)}, got {kind!r}")
    return kind


def _objects(check: Checker, top: dict, materials: dict[str, dict[str, MaterialValue]]) -> list[ObjectSpec]:
    objects: list[ObjectSpec] = []
    seen: set[str] = set()
    for i, path, table in _tables(check, top, "objects", "object"):
        check.only(table, path, OBJECT_KEYS)
        sleeping = check.boolean(table["sleeping"], f"{path}.sleeping") if "sleeping" in table else None
        name = _unique_name(check, table, path, seen, "an object name")
        kind = _type_of(check, table, path, PRIMITIVES)
        parent = None
        if "parent" in table:
            parent = check.string(table["parent"], f"{path}.parent", pattern=NAME, what="an object name")
        transform_table = check.table(table.get("transform", {}), f"{path}.transform")
        check.only(transform_table, f"{path}.transform", TRANSFORM_KEYS)
        transform = Transform(
            **{k: check.number(v, f"{path}.transform.{k}") for k, v in transform_table.items()}
        )
        ranges_table = check.table(table.get("ranges", {}), f"{path}.ranges")
        check.only(ranges_table, f"{path}.ranges", TRANSFORM_KEYS)
        if ranges_table and kind in UNPLACED:
            raise check.fail(f"{path}.ranges", f"a {kind} has no placement of its own; expected no ranges")
        ranges: dict[str, tuple[float, float]] = {}
        for key in TRANSFORM_KEYS:  # stable order, whatever the file's order
            if key not in ranges_table:
                continue
            rpath = f"{path}.ranges.{key}"
            lo, hi = check.vector(ranges_table[key], rpath, 2)
            if not lo < hi:
                raise check.fail(rpath, f"expected [min, max] with min < max, got [{lo:g}, {hi:g}]")
            value = getattr(transform, key)
            if not lo <= value <= hi:
                raise check.fail(
                    f"{path}.transform.{key}",
                    f"expected a value inside its range [{lo:g}, {hi:g}] (the default layout), got {value:g}",
                )
            ranges[key] = (lo, hi)
        schema = PRIMITIVES[kind].params
        shape_table = check.table(table.get("shape", {}), f"{path}.shape")
        check.only(shape_table, f"{path}.shape", tuple(schema))
        shape = check.params(schema, shape_table, f"{path}.shape")
        _check_shape(check, kind, shape, f"{path}.shape")
        physics_table = check.table(table.get("physics", {}), f"{path}.physics")
        if kind == "Plane":
            allowed = PLANE_PHYSICS_KEYS
        else:
            allowed = PHYSICS_KEYS if PRIMITIVES[kind].body else ()
        check.only(physics_table, f"{path}.physics", allowed)
        material = None
        values: dict[str, float] = {}
        if "material" in table:
            material = check.string(table["material"], f"{path}.material", pattern=NAME, what="a material name")
            if not PRIMITIVES[kind].body:
                raise check.fail(f"{path}.material", f"a {kind} makes no body; expected no material")
            if material not in materials:
                known = ", ".join(materials) or "none (add a [materials.NAME] table)"
                raise check.fail(f"{path}.material", f"unknown material {material!r}; expected one of: {known}")
            values = {k: v.value for k, v in materials[material].items()}
        for k, v in physics_table.items():
            if isinstance(v, dict):
                raise check.fail(f"{path}.physics.{k}", "expected a number >= 0 (uncertain values with a range go "
                                 "in a [materials.NAME] table)")
            values[k] = check.number(v, f"{path}.physics.{k}", minimum=0.0)
        physics = Physics(**values)
        tag, body_tags = _tags(check, table, kind, shape, path)
        objects.append(
            ObjectSpec(
                name=name,
                type=kind,
                transform=transform,
                parent=parent,
                ranges=ranges,
                shape=shape,
                physics=physics,
                tag=tag,
                index=i,
                sleeping=sleeping,
                body_tags=body_tags,
                material=material,
            )
        )
    return objects


def _check_shape(check: Checker, kind: str, shape: dict, path: str) -> None:
    if kind == "Goblet":
        if shape["thickness"] >= min(shape["radius_top"], shape["radius_bottom"]):
            raise check.fail(f"{path}.thickness", "expected a wall thinner than the smaller radius")
        if not 3 <= shape["sides"] <= MAX_GOBLET_SIDES:
            raise check.fail(f"{path}.sides", f"expected an integer in [3, {MAX_GOBLET_SIDES}] (wall panels), got "
                             f"{shape['sides']}")
    elif kind == "Track":
        if 2 * shape["wall_thickness"] >= shape["width"] or shape["wall_thickness"] >= shape["height"] + 1e-12:
            raise check.fail(f"{path}.wall_thickness", "expected walls thinner than half the width and the height")
    elif kind == "OpenBox":
        size = shape["size"]
        if 2 * shape["thickness"] >= min(size[0], size[1]) or shape["thickness"] >= size[2]:
            raise check.fail(f"{path}.thickness", "expected walls thinner than half the size")
    elif kind == "DominoRun":
        has_poses = "poses" in shape
        has_path = "path" in shape
        if has_poses == has_path:
            raise check.fail(path, "expected exactly one of 'poses' or 'path' (with 'spacing' or 'count')")
        if has_path and ("spacing" in shape) == ("count" in shape):
            raise check.fail(f"{path}.spacing", "expected exactly one of 'spacing' or 'count' with a 'path'")
        if has_poses and ("spacing" in shape or "count" in shape):
            raise check.fail(path, "'spacing' and 'count' only go with a 'path'")
        if has_path and shape.get("count", 2) < 2:
            raise check.fail(f"{path}.count", "expected at least 2 dominoes along a path")
        if has_path:
            points = np.asarray(shape["path"], dtype=float)
            lengths = np.linalg.norm(np.diff(points, axis=0), axis=1)
            if np.any(lengths <= 1e-9):
                i = int(np.argmax(lengths <= 1e-9))
                raise check.fail(f"{path}.path[{i + 1}]", "expected a point distinct from the previous one")
        count = domino_count(shape)
        if count > MAX_PARTS:
            field = "poses" if has_poses else "count" if "count" in shape else "spacing"
            raise check.fail(f"{path}.{field}", f"expected at most {MAX_PARTS} dominoes in a run, got {count} "
                             f"({_WHY_PARTS})")
    elif kind == "Pivot":
        if "other" in shape and shape["other"] == shape["body"]:
            raise check.fail(f"{path}.other", "expected a body other than 'body' (or none: the world)")
    elif kind == "Fastener":
        if len(shape["bodies"]) == 2 and shape["bodies"][0] == shape["bodies"][1]:
            raise check.fail(f"{path}.bodies", "expected two different bodies (or one: fastened to the world)")
    elif kind in ("TensionRope", "RopePulley"):
        if shape["ends"][0] == shape["ends"][1]:
            raise check.fail(f"{path}.ends", "expected two different bodies")


def _events(check: Checker, top: dict, settings: Settings, by_name: dict[str, ObjectSpec]) -> list[EventSpec]:
    events: list[EventSpec] = []
    names: set[str] = set()
    for i, path, table in _tables(check, top, "events", "event"):
        name = _unique_name(check, table, path, names, "an event name")
        kind = _type_of(check, table, path, EVENTS)
        schema = EVENTS[kind]
        check.only(table, path, EVENT_COMMON + tuple(schema))
        params = check.params(schema, {k: v for k, v in table.items() if k in schema}, path)
        for key, (kind_, _d) in schema.items():
            if kind_ is Kind.BODY and key in params:
                resolve_body_ref(check, f"{path}.{key}", params[key], by_name)
        after = tuple(
            check.string(v, f"{path}.after[{j}]", pattern=NAME, what="an event name")
            for j, v in enumerate(check.array(table.get("after", []), f"{path}.after"))
        )
        if len(set(after)) != len(after):
            raise check.fail(f"{path}.after", "expected each parent event once")
        join = check.string(table.get("join", "all"), f"{path}.join")
        if join not in ("all", "any"):
            raise check.fail(f"{path}.join", f'expected "all" or "any", got {join!r}')
        timeout = check.number(table.get("timeout", settings.event_timeout), f"{path}.timeout", minimum=0, strict=True)
        duration = check.number(table.get("duration", 0.0), f"{path}.duration", minimum=0.0)
        label = check.string(table.get("label", name.replace("_", " ")), f"{path}.label")
        events.append(EventSpec(name, kind, params, after, join, timeout, duration, label, index=i))
    check_event_graph(check, events)
    return events


def _layouts(check: Checker, value: Any, space: DesignSpace) -> dict[str, np.ndarray]:
    table = check.table(value, "layouts")
    layouts = {}
    for name, entry in table.items():
        path = f"layouts.{name}"
        values = check.table(entry, path)
        numbers = {}
        for key, v in values.items():
            if key not in space.names:
                raise check.fail(
                    f"{path}.{key}", f"unknown design parameter; expected one of {', '.join(space.names) or 'none'}"
                )
            numbers[key] = check.number(v, f'{path}."{key}"')
            i = space.names.index(key)
            if not space.lower[i] <= numbers[key] <= space.upper[i]:
                raise check.fail(
                    f'{path}."{key}"',
                    f"expected a value in [{space.lower[i]:g}, {space.upper[i]:g}], got {numbers[key]:g}",
                )
        layouts[name] = space.vector(numbers)
    return layouts


def _tags(check, table: dict, kind: str, shape, path: str) -> tuple[Tag | None, tuple[Tag, ...]]:
    """An object's ``tag``: one table (on the part), or for a DominoRun tables with ``body`` (on its dominoes, e.g.
    the first and the last: ``tag = [{id = 4, body = 0, ...}, {id = 5, body = -1, ...}]``)."""
    if "tag" not in table:
        return None, ()
    value = table["tag"]
    if isinstance(value, list):
        if kind != "DominoRun" or not 1 <= len(value) <= 2:
            raise check.fail(f"{path}.tag", "expected a table (one tag on the part); only a DominoRun takes an array "
                             "of one or two tables, each with body (the domino it is on)")
        tags = tuple(_tag(check, item, kind, shape, f"{path}.tag[{k}]", body=True) for k, item in enumerate(value))
        return None, tags
    tag = _tag(check, value, kind, shape, f"{path}.tag", body=False)
    return (None, (tag,)) if tag.body is not None else (tag, ())


def _tag(check, value, kind: str, shape, path: str, *, body: bool) -> Tag:
    tag_table = check.table(value, path)
    check.only(tag_table, path, TAG_KEYS)
    if "id" not in tag_table:
        raise check.fail(f"{path}.id", "missing; expected an AprilTag id (integer >= 0)")
    index = None
    if "body" in tag_table or body:
        count = domino_count(shape) if kind == "DominoRun" else 0
        if kind != "DominoRun":
            raise check.fail(f"{path}.body", "only a DominoRun's tag names a body (the domino it is on)")
        raw = tag_table.get("body")
        if isinstance(raw, bool) or not isinstance(raw, int) or not -count <= raw < count:
            raise check.fail(f"{path}.body", f"expected a domino's index from {-count} to {count - 1} (0 the first, "
                             f"-1 the last), got {raw!r}")
        index = raw % count
    return Tag(
        id=check.integer(tag_table["id"], f"{path}.id", minimum=0),
        **{k: check.number(tag_table[k], f"{path}.{k}", minimum=0.0 if k == "size" else None, strict=k == "size")
           for k in ("x", "y", "z", "size", "angle") if k in tag_table},
        body=index,
    )
