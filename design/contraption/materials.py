"""Materials of a scenario: ``[materials.NAME]`` tables, their uncertain values, and physics overrides.

A material says how a kind of part behaves at its surfaces and in motion (``friction``, ``rolling_friction``,
``spinning_friction``, ``restitution``, ``linear_damping``, ``angular_damping``; not its mass, which is the part's).
Each value is a number, or an uncertain value ``{ value = 0.6, range = [0.3, 0.9] }``: ``value`` is what is
simulated, ``range`` is where simulator calibration (:mod:`calibration.sim_fit`) may look for the real one. An
object takes a material with ``material = "NAME"``; the keys of its own ``physics`` table override the material's.

Parameters are named ``"MATERIAL.PARAM"`` (``"wood.friction"``) in physics profiles, on the command line and in JSON.

The content hash (:func:`effective_content`) is of what is simulated: every object's material is resolved into its
``physics`` table and the ``materials`` tables (with their ranges) are left out. So rewriting a file with materials
that give every object the same values keeps its hash (and every cached result and saved layout stays valid),
while :meth:`~design.contraption.model.Scenario.with_physics` with other values gives another hash.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from design.contraption.errors import ScenarioFormatError
from design.contraption.fields import Checker, describe
from design.contraption.schema import MATERIAL_KEYS, NAME

#: What a material's value must be, the end of its error messages.
_EXPECTED_VALUE = "a number >= 0 or { value = V, range = [MIN, MAX] }"


@dataclass(frozen=True)
class MaterialValue:
    """One value of a material: what is simulated, and the range calibration may search (None: taken as known)."""

    value: float
    range: tuple[float, float] | None = None

    @property
    def uncertain(self) -> bool:
        return self.range is not None


def parse_materials(check: Checker, value: Any) -> dict[str, dict[str, MaterialValue]]:
    """The ``[materials.NAME]`` tables of a scenario, validated (one error naming file and field).

    Returns
    -------
    dict
        Material name -> {parameter -> :class:`MaterialValue`}, in file order.
    """
    table = check.table(value, "materials")
    materials: dict[str, dict[str, MaterialValue]] = {}
    for name, entry in table.items():
        path = f"materials.{name}"
        if not NAME.match(name):
            raise check.fail(path, f"expected a material name of letters, digits, _ or -, got {name!r}")
        fields = check.table(entry, path)
        check.only(fields, path, MATERIAL_KEYS)
        materials[name] = {key: _material_value(check, fields[key], f"{path}.{key}") for key in fields}
    return materials


def _material_value(check: Checker, value: Any, path: str) -> MaterialValue:
    if isinstance(value, dict):
        check.only(value, path, ("value", "range"))
        if "value" not in value:
            raise check.fail(f"{path}.value", "missing; expected a number >= 0")
        number = check.number(value["value"], f"{path}.value", minimum=0.0)
        if "range" not in value:
            raise check.fail(f"{path}.range", "missing; expected [min, max] (the values calibration may fit)")
        lo, hi = check.vector(value["range"], f"{path}.range", 2)
        if not 0.0 <= lo < hi:
            raise check.fail(f"{path}.range", f"expected [min, max] with 0 <= min < max, got [{lo:g}, {hi:g}]")
        if not lo <= number <= hi:
            raise check.fail(f"{path}.value", f"expected a value inside its range [{lo:g}, {hi:g}], got {number:g}")
        return MaterialValue(number, (lo, hi))
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise check.fail(path, f"expected {_EXPECTED_VALUE}, got {describe(value)}")
    return MaterialValue(check.number(value, path, minimum=0.0))


def raw_value(value: Any) -> Any:
    """The simulated value of a material entry as written (the number, or the ``value`` of an uncertain one)."""
    return value["value"] if isinstance(value, dict) else value


def effective_content(top: Mapping[str, Any]) -> dict[str, Any]:
    """A validated scenario's content as simulated: materials resolved into each object's ``physics``.

    The ``materials`` table goes; an object's ``material`` becomes the material's values (as written) under its own
    ``physics`` keys. A file without materials is returned as it is (same keys, same values), so its hash does not
    change.
    """
    materials = top.get("materials")
    if not materials:
        return {k: v for k, v in top.items() if k != "materials"}
    result = {k: v for k, v in top.items() if k != "materials"}
    objects = []
    for obj in top.get("objects", []):
        if isinstance(obj, dict) and "material" in obj:
            obj = dict(obj)
            material = materials[obj.pop("material")]
            physics = {key: raw_value(v) for key, v in material.items()}
            physics.update(obj.get("physics", {}))
            obj["physics"] = physics
        objects.append(obj)
    result["objects"] = objects
    return result


def split_name(name: str) -> tuple[str, str]:
    """``"wood.friction"`` -> ``("wood", "friction")``; raises ValueError when it is not MATERIAL.PARAM."""
    material, dot, param = name.partition(".")
    if not dot or not NAME.match(material) or param not in MATERIAL_KEYS:
        raise ValueError(name)
    return material, param


def data_with_physics(top: Mapping[str, Any], values: Mapping[str, float], file: str) -> dict[str, Any]:
    """A copy of a validated scenario's data whose material values are ``values`` (``{"wood.friction": 0.42}``).

    An uncertain value keeps its range (and must lie in it: the range is what calibration searched, a value
    outside it is a mistake of the profile or of the scenario); a plain number is replaced.

    Raises
    ------
    ScenarioFormatError
        Naming ``physics.NAME``: a name that is not MATERIAL.PARAM, a material or parameter the scenario does not
        have, or a value that is not a number >= 0 or lies outside the parameter's range.
    """
    data = copy.deepcopy(dict(top))
    materials = data.get("materials", {})
    for name, value in values.items():
        path = f'physics."{name}"'
        try:
            material, param = split_name(name)
        except ValueError:
            raise ScenarioFormatError(
                file, path, f"expected MATERIAL.PARAM with PARAM one of {', '.join(MATERIAL_KEYS)}") from None
        if material not in materials:
            have = ", ".join(materials) or "none"
            raise ScenarioFormatError(file, path, f"no material {material!r} in the scenario; it has: {have}")
        entry = materials[material]
        if param not in entry:
            have = ", ".join(entry) or "none"
            raise ScenarioFormatError(file, path, f"material {material!r} does not set {param}; it sets: {have}")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not float(value) >= 0.0:
            raise ScenarioFormatError(file, path, f"expected a number >= 0, got {value!r}")
        old = entry[param]
        if isinstance(old, dict):
            lo, hi = old["range"]
            if not lo - 1e-12 <= float(value) <= hi + 1e-12:
                raise ScenarioFormatError(
                    file, path, f"expected a value inside the scenario's range [{lo:g}, {hi:g}], got {value:g}")
            entry[param] = {**old, "value": float(min(max(float(value), lo), hi))}
        else:
            entry[param] = float(value)
    return data


#: How far a material value given as a plain number may be off when the station treats it as unknown after all
#: (``station loop``, ``station calibrate sim --all-materials``): frictions by a factor of 0.5 to 1.5, restitution by
#: +- 0.3 (within 0 and 0.99), damping by a factor of 0.25 to 4. Wider than what a material table is usually off by:
#: the fit and the prediction then search and draw across all of it.
DEFAULT_FACTOR_RANGES = {"friction": (0.5, 1.5), "rolling_friction": (0.5, 1.5), "spinning_friction": (0.5, 1.5),
                         "linear_damping": (0.25, 4.0), "angular_damping": (0.25, 4.0)}
DEFAULT_RESTITUTION_SHIFT = 0.3


def default_range(name: str, value: float) -> tuple[float, float]:
    """The range of ``MATERIAL.PARAM`` = ``value`` when its scenario gives it without one (see
    :data:`DEFAULT_FACTOR_RANGES`); a zero friction or damping gets ``(0, 0.05)``."""
    _, param = split_name(name)
    value = float(value)
    if param == "restitution":
        return max(0.0, value - DEFAULT_RESTITUTION_SHIFT), min(0.99, value + DEFAULT_RESTITUTION_SHIFT)
    low, high = DEFAULT_FACTOR_RANGES.get(param, (0.5, 1.5))
    if value <= 0.0:
        return 0.0, 0.05
    return low * value, high * value
