"""The scenario code split by topic: old import paths keep working, modules stay small, the schema is typed."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

import design.contraption as contraption
from design.contraption.fields import Checker
from design.contraption.schema import EVENTS, PRIMITIVES, REQUIRED, Kind, Param

PACKAGE = Path(contraption.__file__).parent

#: Every public name ``design.contraption.scenario`` had when it held the whole format in one module.
SCENARIO_NAMES = (
    "ANGLE_KEYS", "DesignSpace", "EVENTS", "EVENT_COMMON", "EventSpec", "LayoutError", "ObjectSpec",
    "PHYSICS_DEFAULTS", "PHYSICS_KEYS", "PRIMITIVES", "Physics", "REQUIRED", "Scenario", "ScenarioFormatError",
    "Settings", "TRANSFORM_KEYS", "Tag", "Transform", "UNPLACED", "Y_AXIS", "domino_count", "load_scenario",
    "parse_text", "resolve_body_ref", "scenario_from_data",
)


@pytest.mark.parametrize("name", SCENARIO_NAMES)
def test_scenario_module_still_exports(name):
    scenario = importlib.import_module("design.contraption.scenario")
    assert hasattr(scenario, name)


def test_package_names_resolve():
    for name in contraption.__all__:
        assert getattr(contraption, name) is not None, name


def test_modules_stay_small_or_say_why():
    for path in sorted(PACKAGE.glob("*.py")):
        text = path.read_text()
        lines = text.count("\n")
        docstring = ast.get_docstring(ast.parse(text)) or ""
        assert lines <= 600 or "lines" in docstring, f"{path.name}: {lines} lines and no reason in its docstring"


def _as_file_value(value):
    # Defaults are stored as tuples; a file gives arrays (lists).
    return [_as_file_value(v) for v in value] if isinstance(value, tuple) else value


def _fields():
    for kind, primitive in PRIMITIVES.items():
        for key, param in primitive.params.items():
            yield f"{kind}.{key}", param
    for kind, params in EVENTS.items():
        for key, param in params.items():
            yield f"{kind}.{key}", param


@pytest.mark.parametrize(("where", "param"), list(_fields()), ids=lambda v: v if isinstance(v, str) else "")
def test_schema_fields_are_typed_and_their_defaults_valid(where, param):
    assert isinstance(param, Param)
    assert isinstance(param.kind, Kind)
    assert param.kind.expected
    if param.default is not REQUIRED and param.default is not None:
        # The default must be a value the validator itself would accept for that field.
        parsed = Checker("<schema>").param(param.kind, _as_file_value(param.default), where)
        assert parsed == param.default
