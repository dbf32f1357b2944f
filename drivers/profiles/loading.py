"""Machine profiles from TOML: validation, unit conversion, and the built-in profiles shipped as package data.

The built-in profiles are the TOML files in ``drivers/profiles/builtin/`` (``plotter.toml``, ``laser.toml``), read
with :mod:`importlib.resources`, so an installed wheel has them. They describe the station's default simulated
machines, ``[grbl]`` table included: :func:`builtin_grbl_settings` is the one source of the simulated GRBL's EEPROM.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from types import MappingProxyType
from typing import Any

from common.datafiles import parse_toml
from drivers.gcode import GcodeError, clean_line, tokenize
from drivers.profiles.firmware import check_grbl_settings, parse_grbl_table
from drivers.profiles.model import (
    LaserOperation,
    LaserSettings,
    MachineProfile,
    Material,
    PaperSettings,
    PenSettings,
    PlotSettings,
    ProfileError,
)
from drivers.profiles.units import parse_duration, parse_feed, parse_length

__all__ = [
    "BUILTIN_PROFILES",
    "MAX_KERF",
    "builtin_grbl_settings",
    "builtin_profile",
    "builtin_profile_names",
    "load_profile",
    "profile_from_dict",
    "profile_from_toml",
]

#: A kerf wider than this is surely a typo (a diode or CO2 laser burns 0.05-0.5 mm).
MAX_KERF = 2.0


def _kerf(value, where: str) -> float:
    kerf = parse_length(value, where)
    if not 0.0 <= kerf <= MAX_KERF:
        raise ProfileError(f"{where}: expected a kerf between 0 and {MAX_KERF:g} mm, got {kerf:g} mm")
    return kerf


_KINDS = ("plotter", "laser")
_ORIGINS = ("front-left", "center")
_PEN_MODES = ("servo", "z")


def _table(data: Mapping[str, Any], key: str, where: str, required: bool = False) -> dict[str, Any]:
    value = data.get(key)
    if value is None:
        if required:
            raise ProfileError(f"{where}: missing table [{key}]")
        return {}
    if not isinstance(value, Mapping):
        raise ProfileError(f"{where}: [{key}] must be a table, got {type(value).__name__}")
    return dict(value)


def _check_keys(table: Mapping[str, Any], allowed: set[str], where: str) -> None:
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise ProfileError(f"{where}: unknown field(s) {unknown}; expected some of {sorted(allowed)}")


def _positive(value: float, where: str, allow_zero: bool = False) -> float:
    if not (value > 0 or (allow_zero and value == 0)):
        raise ProfileError(f"{where}: expected a {'non-negative' if allow_zero else 'positive'} value, got {value}")
    return value


def _fraction(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 <= float(value) <= 1.0:
        raise ProfileError(f"{where}: expected a fraction of max power between 0 and 1, got {value!r}")
    return float(value)


def _operation(data: Any, where: str) -> LaserOperation:
    if not isinstance(data, Mapping):
        raise ProfileError(f"{where}: expected a table with power, feed, passes")
    _check_keys(data, {"power", "feed", "passes"}, where)
    for key in ("power", "feed"):
        if key not in data:
            raise ProfileError(f"{where}: missing field {key!r}")
    passes = data.get("passes", 1)
    if isinstance(passes, bool) or not isinstance(passes, int) or passes < 1:
        raise ProfileError(f"{where}.passes: expected an integer >= 1, got {passes!r}")
    return LaserOperation(
        power=_fraction(data["power"], f"{where}.power"),
        feed=_positive(parse_feed(data["feed"], f"{where}.feed"), f"{where}.feed"),
        passes=passes,
    )


def profile_from_dict(data: Mapping[str, Any], source: str = "<dict>") -> MachineProfile:
    """Build a profile from parsed TOML, converting units and validating every field.

    Raises
    ------
    ProfileError
        Naming ``source``, the field and what was expected.
    """
    _check_keys(data, {"machine", "work_area", "laser", "pen", "paper", "plot", "materials", "grbl"}, source)
    machine = _table(data, "machine", source, required=True)
    _check_keys(machine, {"name", "kind", "port", "baud"}, f"{source} [machine]")
    kind = machine.get("kind")
    if kind not in _KINDS:
        raise ProfileError(f"{source} [machine].kind: expected one of {list(_KINDS)}, got {kind!r}")
    name = machine.get("name", kind)
    port = machine.get("port", f"sim://grbl?profile={kind}")
    baud = machine.get("baud", 115200)
    if not isinstance(name, str) or not isinstance(port, str):
        raise ProfileError(f"{source} [machine]: name and port must be strings")
    if isinstance(baud, bool) or not isinstance(baud, int) or baud <= 0:
        raise ProfileError(f"{source} [machine].baud: expected a positive integer, got {baud!r}")

    area = _table(data, "work_area", source, required=True)
    where = f"{source} [work_area]"
    _check_keys(area, {"width", "height", "origin", "max_feed"}, where)
    for key in ("width", "height"):
        if key not in area:
            raise ProfileError(f"{where}: missing field {key!r}")
    width = _positive(parse_length(area["width"], f"{where}.width"), f"{where}.width")
    height = _positive(parse_length(area["height"], f"{where}.height"), f"{where}.height")
    origin = area.get("origin", "front-left")
    if origin not in _ORIGINS:
        raise ProfileError(f"{where}.origin: expected one of {list(_ORIGINS)}, got {origin!r}")
    max_feed = _positive(parse_feed(area.get("max_feed", 6000), f"{where}.max_feed"), f"{where}.max_feed")

    plot_table = _table(data, "plot", source)
    where = f"{source} [plot]"
    _check_keys(plot_table, {"draw_feed", "travel_feed", "tolerance"}, where)
    plot = PlotSettings(
        draw_feed=_positive(parse_feed(plot_table.get("draw_feed", min(3000.0, max_feed)), f"{where}.draw_feed"),
                            f"{where}.draw_feed"),
        travel_feed=_positive(parse_feed(plot_table.get("travel_feed", max_feed), f"{where}.travel_feed"),
                              f"{where}.travel_feed"),
        tolerance=_positive(parse_length(plot_table.get("tolerance", 0.05), f"{where}.tolerance"),
                            f"{where}.tolerance", allow_zero=True),
    )
    for key in ("draw_feed", "travel_feed"):
        if getattr(plot, key) > max_feed:
            raise ProfileError(f"{where}.{key}: {getattr(plot, key)} mm/min exceeds work_area.max_feed {max_feed}")

    laser = pen = paper = None
    materials: dict[str, Material] = {}
    if kind == "laser":
        if "pen" in data or "paper" in data:
            raise ProfileError(f"{source}: [pen] and [paper] are only for kind = 'plotter'")
        table = _table(data, "laser", source, required=True)
        where = f"{source} [laser]"
        _check_keys(table, {"max_power", "laser_mode", "frame_power"}, where)
        max_power = table.get("max_power", 1000)
        if isinstance(max_power, bool) or not isinstance(max_power, (int, float)) or max_power <= 0:
            raise ProfileError(f"{where}.max_power: expected a positive number ($30), got {max_power!r}")
        laser_mode = table.get("laser_mode", True)
        if not isinstance(laser_mode, bool):
            raise ProfileError(f"{where}.laser_mode: expected true or false ($32), got {laser_mode!r}")
        laser = LaserSettings(
            max_power=float(max_power),
            laser_mode=laser_mode,
            frame_power=_fraction(table.get("frame_power", 0.01), f"{where}.frame_power"),
        )
        for mat_name, mat in _table(data, "materials", source).items():
            where = f"{source} [materials.{mat_name}]"
            if not isinstance(mat, Mapping):
                raise ProfileError(f"{where}: must be a table")
            _check_keys(mat, {"thickness", "cut", "engrave", "kerf", "measured"}, where)
            for key in ("cut", "engrave"):
                if key not in mat:
                    raise ProfileError(f"{where}: missing table {key!r}")
            materials[mat_name] = Material(
                name=mat_name,
                thickness=_positive(parse_length(mat.get("thickness", 0), f"{where}.thickness"), f"{where}.thickness",
                                    allow_zero=True),
                cut=_operation(mat["cut"], f"{where}.cut"),
                engrave=_operation(mat["engrave"], f"{where}.engrave"),
                kerf=_kerf(mat["kerf"], f"{where}.kerf") if "kerf" in mat else None,
                measured=_measured(mat.get("measured", {}), f"{where}.measured"),
            )
        for mat in materials.values():
            for op_name in ("cut", "engrave"):
                op = mat.operation(op_name)
                if op.feed > max_feed:
                    raise ProfileError(f"{source} [materials.{mat.name}].{op_name}.feed: {op.feed} mm/min exceeds "
                                       f"work_area.max_feed {max_feed}")
    else:
        if "laser" in data or "materials" in data:
            raise ProfileError(f"{source}: [laser] and [materials] are only for kind = 'laser'")
        table = _table(data, "pen", source)
        where = f"{source} [pen]"
        _check_keys(table, {"mode", "up", "down", "up_delay", "down_delay", "z_feed", "change"}, where)
        mode = table.get("mode", "servo")
        if mode not in _PEN_MODES:
            raise ProfileError(f"{where}.mode: expected one of {list(_PEN_MODES)}, got {mode!r}")
        if mode == "servo":
            up = _number(table.get("up", 50), f"{where}.up")
            down = _number(table.get("down", 30), f"{where}.down")
        else:
            up = parse_length(table.get("up", 2.0), f"{where}.up")
            down = parse_length(table.get("down", 0.0), f"{where}.down")
        pen = PenSettings(
            mode=mode,
            up=up,
            down=down,
            up_delay=_positive(parse_duration(table.get("up_delay", 0.15), f"{where}.up_delay"),
                               f"{where}.up_delay", allow_zero=True),
            down_delay=_positive(parse_duration(table.get("down_delay", 0.15), f"{where}.down_delay"),
                                 f"{where}.down_delay", allow_zero=True),
            z_feed=_positive(parse_feed(table.get("z_feed", 1000), f"{where}.z_feed"), f"{where}.z_feed"),
            change=_gcode_lines(table.get("change", ["M0"]), f"{where}.change"),
        )
        table = _table(data, "paper", source)
        where = f"{source} [paper]"
        _check_keys(table, {"width", "height", "margin"}, where)
        paper = PaperSettings(
            width=_positive(parse_length(table.get("width", 210), f"{where}.width"), f"{where}.width"),
            height=_positive(parse_length(table.get("height", 297), f"{where}.height"), f"{where}.height"),
            margin=_positive(parse_length(table.get("margin", 10), f"{where}.margin"), f"{where}.margin",
                             allow_zero=True),
        )
        if paper.width > width or paper.height > height:
            raise ProfileError(f"{where}: paper {paper.width}x{paper.height} mm does not fit the work area "
                               f"{width}x{height} mm")
        if 2 * paper.margin >= min(paper.width, paper.height):
            raise ProfileError(f"{where}.margin: {paper.margin} mm leaves no drawable area")

    where = f"{source} [grbl]"
    grbl = parse_grbl_table(_table(data, "grbl", source), where)
    check_grbl_settings(grbl, kind=kind, width=width, height=height, laser=laser, where=where)
    return MachineProfile(
        name=name, kind=kind, port=port, baud=baud, width=width, height=height, origin=origin, max_feed=max_feed,
        laser=laser, pen=pen, paper=paper, plot=plot, materials=MappingProxyType(materials), source=source,
        grbl=MappingProxyType(grbl),
    )


def _gcode_lines(value: Any, where: str) -> tuple[str, ...]:
    """A list of G-code lines (a pen-change macro): each one a block GRBL can read, none ending the program."""
    if not isinstance(value, list) or not all(isinstance(line, str) for line in value):
        raise ProfileError(f'{where}: expected a list of G-code lines such as ["G0 X0 Y0", "M0"], got {value!r:.60}')
    for line in value:
        try:
            words = tokenize(clean_line(line))
        except GcodeError:
            raise ProfileError(f"{where}: {line!r} is not a G-code line (a letter and a number per word)") from None
        if ("M", 2.0) in words or ("M", 30.0) in words:
            raise ProfileError(f"{where}: {line!r} ends the program; expected a pause such as M0")
    return tuple(value)


def _measured(value: Any, where: str) -> Mapping[str, Any]:
    """A material's ``measured`` table: where its settings came from (``station calibrate material`` writes it),
    plain values only (text, numbers, true/false)."""
    if not isinstance(value, Mapping):
        raise ProfileError(f"{where}: expected a table of measured values, got {value!r:.60}")
    for key, item in value.items():
        if not isinstance(item, (str, int, float, bool)):
            raise ProfileError(f"{where}.{key}: expected text, a number or true/false, got {item!r:.60}")
    return MappingProxyType(dict(value))


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ProfileError(f"{where}: expected a number, got {value!r}")
    return float(value)


def profile_from_toml(text: str | bytes, source: str = "<toml>") -> MachineProfile:
    """Parse TOML text (or a file's bytes) into a profile; a bad file is reported as every data file is
    (:mod:`common.datafiles`): ``FILE: not valid TOML (... at line L column C); expected a machine profile ...``."""
    raw = text.encode("utf-8") if isinstance(text, str) else text
    data = parse_toml(raw, source, "a machine profile (see drivers/profiles)",
                      error=lambda detail: ProfileError(f"{source}: {detail}"))
    return profile_from_dict(data, source)


def load_profile(path: str | Path) -> MachineProfile:
    """Load a profile from a TOML file, or a built-in one by name (``"plotter"``, ``"laser"``): what ``--profile``
    takes. A file of that name in the working directory wins over the built-in profile."""
    if str(path) in BUILTIN_PROFILES and not Path(path).exists():
        return builtin_profile(str(path))
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise ProfileError(f"profile {str(path)!r}: no such file (built-in profiles: "
                           f"{', '.join(builtin_profile_names())})") from None
    except (IsADirectoryError, PermissionError) as error:
        raise ProfileError(f"profile {str(path)!r}: cannot read: {error}") from None
    return profile_from_toml(raw, str(path))


def _read_builtins() -> Mapping[str, str]:
    folder = resources.files("drivers.profiles").joinpath("builtin")
    texts = {entry.name[: -len(".toml")]: entry.read_text(encoding="utf-8")
             for entry in folder.iterdir() if entry.name.endswith(".toml")}
    return MappingProxyType(dict(sorted(texts.items())))


#: The TOML text of each built-in profile by name: the machines behind the station's default simulated devices.
BUILTIN_PROFILES: Mapping[str, str] = _read_builtins()


def builtin_profile_names() -> list[str]:
    """The names of the built-in profiles (``--profile NAME``), sorted."""
    return sorted(BUILTIN_PROFILES)


@functools.cache
def builtin_profile(name: str) -> MachineProfile:
    """A built-in profile by name (``"plotter"`` or ``"laser"``); parsed once (a profile is frozen)."""
    try:
        text = BUILTIN_PROFILES[name]
    except KeyError:
        raise ProfileError(f"no built-in profile {name!r}; known: {', '.join(builtin_profile_names())}") from None
    return profile_from_toml(text, f"builtin:{name}")


def builtin_grbl_settings(name: str) -> dict[int, float]:
    """The GRBL settings (``$N``: value) the built-in machine ``name`` ships with, e.g. the EEPROM of the simulated
    GRBL behind ``sim://grbl?profile=NAME``: the profile's ``[grbl]`` table with ``$130``/``$131`` from its work area
    and ``$30``/``$32`` from its ``[laser]`` table."""
    return dict(builtin_profile(name).grbl_settings)
