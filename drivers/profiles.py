"""Machine profiles: what the station knows about one GRBL pen plotter or diode laser.

A profile is a TOML file turned into frozen dataclasses (vpype style). Lengths may be written with a unit
(``"297mm"``, ``"30cm"``, ``"11in"``; a bare number is millimetres), feeds with a rate unit (``"3000mm/min"``,
``"50mm/s"``; a bare number is mm/min), durations with a time unit (``"150ms"``, ``"0.2s"``; a bare number is
seconds). Everything is converted at load time, so code only ever sees millimetres, mm/min and seconds.

Example (a GRBL diode laser)::

    [machine]
    name = "GRBL diode laser"
    kind = "laser"                  # "plotter" or "laser"
    port = "sim://grbl?profile=laser"
    baud = 115200

    [work_area]
    width = "400mm"                 # must match $130
    height = "400mm"                # must match $131
    origin = "front-left"           # where work X0 Y0 is: "front-left" or "center"
    max_feed = "6000mm/min"

    [laser]
    max_power = 1000                # $30: the S value of full power
    laser_mode = true               # $32=1 required before any laser job
    frame_power = 0.01              # fraction of max power used to trace the frame

    [materials.plywood_3mm]
    thickness = "3mm"
    cut = { power = 1.0, feed = "300mm/min", passes = 2 }
    engrave = { power = 0.3, feed = "3000mm/min", passes = 1 }

A pen plotter has a ``[pen]`` table (``mode = "servo"`` with ``up``/``down`` S values, or ``mode = "z"`` with
``up``/``down`` heights; ``up_delay`` and ``down_delay``) and a ``[paper]`` table (``width``, ``height``,
``margin``); a ``[plot]`` table holds ``draw_feed``, ``travel_feed`` and ``tolerance``.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

from drivers.errors import DriverError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = [
    "LaserOperation",
    "LaserSettings",
    "MachineProfile",
    "Material",
    "PaperSettings",
    "PenSettings",
    "PlotSettings",
    "ProfileError",
    "builtin_profile",
    "builtin_profile_names",
    "load_profile",
    "parse_duration",
    "parse_feed",
    "parse_length",
    "profile_from_dict",
    "profile_from_toml",
]


class ProfileError(DriverError, ValueError):
    """A machine profile is malformed; the message names the file, the field and what was expected."""


_LENGTH_UNITS = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4, "inch": 25.4, "pt": 25.4 / 72.0}
_TIME_UNITS = {"ms": 1e-3, "s": 1.0, "min": 60.0}
_NUMBER_UNIT = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-z/]*)\s*$")


def _split(value: Any, where: str, expected: str) -> tuple[float, str]:
    if isinstance(value, bool):
        raise ProfileError(f"{where}: expected {expected}, got {value!r}")
    if isinstance(value, (int, float)):
        return float(value), ""
    if isinstance(value, str):
        match = _NUMBER_UNIT.match(value)
        if match:
            return float(match.group(1)), match.group(2).lower()
    raise ProfileError(f"{where}: expected {expected}, got {value!r}")


def parse_length(value: Any, where: str = "length") -> float:
    """A length in millimetres from a number (mm) or a string with a unit (mm, cm, m, in, pt)."""
    number, unit = _split(value, where, "a length such as 300 or '300mm' or '11in'")
    if unit == "":
        return number
    if unit not in _LENGTH_UNITS:
        raise ProfileError(f"{where}: unknown length unit {unit!r} in {value!r}; use one of {sorted(_LENGTH_UNITS)}")
    return number * _LENGTH_UNITS[unit]


def parse_feed(value: Any, where: str = "feed") -> float:
    """A feed rate in mm/min from a number (mm/min) or a string such as '3000mm/min' or '50mm/s'."""
    number, unit = _split(value, where, "a feed such as 3000 or '3000mm/min' or '50mm/s'")
    if unit == "":
        return number
    length_unit, sep, time_unit = unit.partition("/")
    if not sep or length_unit not in _LENGTH_UNITS or time_unit not in _TIME_UNITS:
        raise ProfileError(f"{where}: unknown feed unit {unit!r} in {value!r}; use e.g. 'mm/min', 'mm/s', 'in/min'")
    return number * _LENGTH_UNITS[length_unit] * 60.0 / _TIME_UNITS[time_unit]


def parse_duration(value: Any, where: str = "duration") -> float:
    """A duration in seconds from a number (s) or a string such as '150ms' or '0.2s'."""
    number, unit = _split(value, where, "a duration such as 0.2 or '200ms'")
    if unit == "":
        return number
    if unit not in _TIME_UNITS:
        raise ProfileError(f"{where}: unknown time unit {unit!r} in {value!r}; use one of {sorted(_TIME_UNITS)}")
    return number * _TIME_UNITS[unit]


@dataclass(frozen=True)
class LaserOperation:
    """Settings of one laser operation on one material.

    Parameters
    ----------
    power : float
        Fraction of the machine's maximum power, 0..1.
    feed : float
        Feed in mm/min.
    passes : int
        Number of passes (>= 1).
    """

    power: float
    feed: float
    passes: int = 1

    def s_value(self, max_power: float) -> float:
        """The GRBL ``S`` word for this power on a machine whose ``$30`` is ``max_power``."""
        return self.power * max_power


@dataclass(frozen=True)
class Material:
    """A laser material with its cut and engrave settings (thickness and kerf in mm).

    ``kerf`` is the width of the strip the laser burns away in this material (measured with a kerf test: cut a
    square, measure it); ``None`` when the profile does not say.
    """

    name: str
    thickness: float
    cut: LaserOperation
    engrave: LaserOperation
    kerf: float | None = None

    def operation(self, kind: str) -> LaserOperation:
        """``"cut"`` or ``"engrave"``."""
        if kind == "cut":
            return self.cut
        if kind == "engrave":
            return self.engrave
        raise ProfileError(f"material {self.name!r}: unknown operation {kind!r}; expected 'cut' or 'engrave'")


@dataclass(frozen=True)
class LaserSettings:
    """Laser settings: ``max_power`` is GRBL's ``$30`` (S value of full power), ``laser_mode`` is ``$32``."""

    max_power: float = 1000.0
    laser_mode: bool = True
    frame_power: float = 0.01


@dataclass(frozen=True)
class PenSettings:
    """Pen lift of a plotter.

    ``mode="servo"``: pen up/down by ``M3 S<up>`` / ``M3 S<down>`` (servo on the spindle PWM);
    ``mode="z"``: pen up/down by ``G0 Z<up>`` / ``G1 Z<down>``. Delays (s) are dwells after each lift/drop.
    """

    mode: str = "servo"
    up: float = 50.0
    down: float = 30.0
    up_delay: float = 0.15
    down_delay: float = 0.15
    z_feed: float = 1000.0

    def up_commands(self) -> list[str]:
        """G-code lines that lift the pen (with the dwell)."""
        return self._commands(self.up, self.up_delay, lift=True)

    def down_commands(self) -> list[str]:
        """G-code lines that lower the pen (with the dwell)."""
        return self._commands(self.down, self.down_delay, lift=False)

    def _commands(self, value: float, delay: float, lift: bool) -> list[str]:
        if self.mode == "servo":
            lines = [f"M3 S{_fmt(value)}"]
        elif lift:
            lines = [f"G0 Z{_fmt(value)}"]
        else:
            lines = [f"G1 Z{_fmt(value)} F{_fmt(self.z_feed)}"]
        if delay > 0:
            lines.append(f"G4 P{_fmt(delay)}")
        return lines


@dataclass(frozen=True)
class PaperSettings:
    """Paper on a plotter's bed (mm): its size and the margin kept free on every side."""

    width: float = 210.0
    height: float = 297.0
    margin: float = 10.0


@dataclass(frozen=True)
class PlotSettings:
    """Feeds (mm/min) and the polyline simplification tolerance (mm) of plot jobs."""

    draw_feed: float = 3000.0
    travel_feed: float = 6000.0
    tolerance: float = 0.05


def _fmt(value: float) -> str:
    text = f"{value:.3f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


@dataclass(frozen=True)
class MachineProfile:
    """One GRBL machine.

    Parameters
    ----------
    name : str
        Human name.
    kind : str
        ``"plotter"`` or ``"laser"``.
    port : str
        Port URL for :func:`serial.serial_for_url`.
    baud : int
        Baud rate.
    width, height : float
        Work area (mm), i.e. GRBL's ``$130`` and ``$131``.
    origin : str
        Where work X0 Y0 sits on the work area: ``"front-left"`` or ``"center"``.
    max_feed : float
        Highest feed (mm/min) a job may ask for.
    laser, pen, paper, plot : settings or None
        ``laser`` for lasers; ``pen`` and ``paper`` for plotters; ``plot`` for both.
    materials : mapping of str to Material
        Laser materials by name (empty for plotters).
    source : str
        Where the profile came from (file path or ``builtin:NAME``).
    """

    name: str
    kind: str
    port: str
    baud: int = 115200
    width: float = 300.0
    height: float = 200.0
    origin: str = "front-left"
    max_feed: float = 6000.0
    laser: LaserSettings | None = None
    pen: PenSettings | None = None
    paper: PaperSettings | None = None
    plot: PlotSettings = field(default_factory=PlotSettings)
    materials: Mapping[str, Material] = field(default_factory=lambda: MappingProxyType({}))
    source: str = ""

    @property
    def is_laser(self) -> bool:
        return self.kind == "laser"

    def work_bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` of the work area in work coordinates (mm)."""
        if self.origin == "center":
            return (-self.width / 2, -self.height / 2, self.width / 2, self.height / 2)
        return (0.0, 0.0, self.width, self.height)

    def material(self, name: str) -> Material:
        """The material called ``name``; the error lists the known ones."""
        try:
            return self.materials[name]
        except KeyError:
            known = ", ".join(sorted(self.materials)) or "none"
            raise ProfileError(f"profile {self.name!r}: no material {name!r}; known: {known}") from None


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
    _check_keys(data, {"machine", "work_area", "laser", "pen", "paper", "plot", "materials"}, source)
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
            _check_keys(mat, {"thickness", "cut", "engrave", "kerf"}, where)
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
        _check_keys(table, {"mode", "up", "down", "up_delay", "down_delay", "z_feed"}, where)
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

    return MachineProfile(
        name=name, kind=kind, port=port, baud=baud, width=width, height=height, origin=origin, max_feed=max_feed,
        laser=laser, pen=pen, paper=paper, plot=plot, materials=MappingProxyType(materials), source=source,
    )


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ProfileError(f"{where}: expected a number, got {value!r}")
    return float(value)


def profile_from_toml(text: str, source: str = "<toml>") -> MachineProfile:
    """Parse TOML text into a profile."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise ProfileError(f"{source}: not valid TOML: {error}") from None
    return profile_from_dict(data, source)


def load_profile(path: str | Path) -> MachineProfile:
    """Load a profile from a TOML file, or a built-in one by name (``"plotter"``, ``"laser"``)."""
    if str(path) in BUILTIN_PROFILES and not Path(path).exists():
        return builtin_profile(str(path))
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ProfileError(f"profile {str(path)!r}: no such file (built-in profiles: "
                           f"{', '.join(builtin_profile_names())})") from None
    except (IsADirectoryError, PermissionError, UnicodeDecodeError) as error:
        raise ProfileError(f"profile {str(path)!r}: cannot read: {error}") from None
    return profile_from_toml(text, str(path))


#: The two profiles behind the station's default simulated devices; identical to examples/profiles/*.toml.
BUILTIN_PROFILES: dict[str, str] = {
    "plotter": """\
# A GRBL 1.1 pen plotter (servo pen lift on the spindle PWM pin), A3 bed.
[machine]
name = "GRBL pen plotter"
kind = "plotter"
port = "sim://grbl?profile=plotter"
baud = 115200

[work_area]
width = "420mm"          # $130
height = "297mm"         # $131
origin = "front-left"
max_feed = "8000mm/min"

[pen]
mode = "servo"           # pen up/down with M3 S<value>
up = 50
down = 30
up_delay = "150ms"
down_delay = "150ms"

[paper]
width = "297mm"          # A4 landscape on the front-left corner
height = "210mm"
margin = "15mm"

[plot]
draw_feed = "3000mm/min"
travel_feed = "6000mm/min"
tolerance = "0.05mm"
""",
    "laser": """\
# A GRBL 1.1 diode laser (laser mode $32=1, PWM 0..$30).
[machine]
name = "GRBL diode laser"
kind = "laser"
port = "sim://grbl?profile=laser"
baud = 115200

[work_area]
width = "400mm"          # $130
height = "400mm"         # $131
origin = "front-left"
max_feed = "6000mm/min"

[laser]
max_power = 1000         # $30
laser_mode = true        # $32=1 is required
frame_power = 0.01       # 1 % to trace the frame (visible, does not mark)

[plot]
draw_feed = "1500mm/min"
travel_feed = "6000mm/min"
tolerance = "0.05mm"

[materials.plywood_3mm]
thickness = "3mm"
kerf = "0.15mm"
cut = { power = 1.0, feed = "300mm/min", passes = 2 }
engrave = { power = 0.35, feed = "3000mm/min", passes = 1 }

[materials.mdf_3mm]
thickness = "3mm"
kerf = "0.15mm"
cut = { power = 1.0, feed = "240mm/min", passes = 3 }
engrave = { power = 0.3, feed = "3000mm/min", passes = 1 }

[materials.cardboard_2mm]
thickness = "2mm"
kerf = "0.2mm"
cut = { power = 0.8, feed = "600mm/min", passes = 1 }
engrave = { power = 0.2, feed = "4000mm/min", passes = 1 }

[materials.acrylic_3mm_black]
thickness = "3mm"
kerf = "0.12mm"
cut = { power = 1.0, feed = "150mm/min", passes = 3 }
engrave = { power = 0.4, feed = "2000mm/min", passes = 1 }
""",
}


def builtin_profile_names() -> list[str]:
    return sorted(BUILTIN_PROFILES)


def builtin_profile(name: str) -> MachineProfile:
    """A built-in profile by name (``"plotter"`` or ``"laser"``)."""
    try:
        text = BUILTIN_PROFILES[name]
    except KeyError:
        raise ProfileError(f"no built-in profile {name!r}; known: {', '.join(builtin_profile_names())}") from None
    return profile_from_toml(text, f"builtin:{name}")
