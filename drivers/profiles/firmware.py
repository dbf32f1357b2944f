"""The ``[grbl]`` table of a machine profile: the firmware settings (``$N``) the machine holds.

A key is the setting's number (``100 = 80.0``, or ``"$100" = 80.0``) or its name (``x_steps_per_mm = 80.0``, see
:data:`SETTING_NAMES`); a value is a number (``true``/``false`` for the on/off settings). A setting the profile states
elsewhere has its one source there: ``$130``/``$131`` are the work area's ``width``/``height`` and, for a laser,
``$30``/``$32`` are ``[laser].max_power``/``laser_mode``. The table may repeat such a setting (e.g. pasted from
``$$``) only with the same value.

Example (the built-in pen plotter's firmware)::

    [grbl]
    20 = 1            # soft limits (needs homing)
    22 = 1            # homing cycle
    100 = 80.0        # X steps/mm
    110 = 8000.0      # X max rate, mm/min
    132 = 40.0        # Z max travel, mm
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from drivers.profiles.model import LaserSettings, ProfileError

__all__ = ["SETTING_NAMES", "check_grbl_settings", "parse_grbl_table"]

#: GRBL 1.1's settings by name (doc/markdown/settings.md), for a ``[grbl]`` table that prefers words to numbers.
SETTING_NAMES: dict[str, int] = {
    "step_pulse_us": 0, "step_idle_delay_ms": 1, "step_port_invert": 2, "direction_port_invert": 3,
    "step_enable_invert": 4, "limit_pins_invert": 5, "probe_pin_invert": 6, "status_report": 10,
    "junction_deviation": 11, "arc_tolerance": 12, "report_inches": 13, "soft_limits": 20, "hard_limits": 21,
    "homing_cycle": 22, "homing_dir_invert": 23, "homing_feed": 24, "homing_seek": 25, "homing_debounce_ms": 26,
    "homing_pull_off": 27, "max_spindle_speed": 30, "min_spindle_speed": 31, "laser_mode": 32,
    "x_steps_per_mm": 100, "y_steps_per_mm": 101, "z_steps_per_mm": 102, "x_max_rate": 110, "y_max_rate": 111,
    "z_max_rate": 112, "x_acceleration": 120, "y_acceleration": 121, "z_acceleration": 122, "x_max_travel": 130,
    "y_max_travel": 131, "z_max_travel": 132,
}

#: Settings GRBL stores as on/off (``$N=0`` or ``$N=1``).
SWITCHES = frozenset({13, 20, 21, 22, 32})
#: Settings GRBL stores as whole numbers (masks, microseconds, milliseconds).
INTEGERS = frozenset({0, 1, 2, 3, 4, 5, 6, 10, 23, 26}) | SWITCHES
#: The highest setting number GRBL's ``$N=value`` parser accepts (an 8-bit parameter index).
MAX_SETTING = 255


def _setting_number(key: str, where: str) -> int:
    text = key[1:] if key.startswith("$") else key
    if text.isdigit():
        number = int(text)
        if number > MAX_SETTING:
            raise ProfileError(f"{where}: setting {key!r} is out of range; expected a number 0..{MAX_SETTING}")
        return number
    if key in SETTING_NAMES:
        return SETTING_NAMES[key]
    raise ProfileError(f"{where}: unknown setting {key!r}; expected a number 0..{MAX_SETTING} (e.g. 100 or '$100') "
                       f"or a name such as {', '.join(sorted(SETTING_NAMES)[:4])} ...")


def _setting_value(number: int, value: Any, where: str) -> float:
    if isinstance(value, bool):
        if number not in SWITCHES:
            raise ProfileError(f"{where}: ${number} is a number, not on/off; got {value!r}")
        return 1.0 if value else 0.0
    if not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
        raise ProfileError(f"{where}: expected a non-negative number, got {value!r}")
    if number in SWITCHES and value not in (0, 1):
        raise ProfileError(f"{where}: ${number} is on/off; expected 0 or 1 (or true/false), got {value!r}")
    if number in INTEGERS and value != int(value):
        raise ProfileError(f"{where}: ${number} is a whole number, got {value!r}")
    return float(value)


def parse_grbl_table(table: Mapping[str, Any], where: str) -> dict[int, float]:
    """The ``[grbl]`` table as ``{setting number: value}``, every key and value validated.

    Raises
    ------
    ProfileError
        A key that is neither a number 0..255 nor a known name, a setting given twice (by number and by name),
        or a value that is not a non-negative number (0/1 for on/off settings, whole for integer ones).
    """
    settings: dict[int, float] = {}
    given_as: dict[int, str] = {}
    for key, value in table.items():
        number = _setting_number(str(key), where)
        if number in settings:
            raise ProfileError(f"{where}: ${number} is given twice ({given_as[number]!r} and {key!r}); give it once")
        settings[number] = _setting_value(number, value, f"{where}.{key}")
        given_as[number] = str(key)
    return settings


def check_grbl_settings(settings: Mapping[int, float], *, kind: str, width: float, height: float,
                        laser: LaserSettings | None, where: str) -> None:
    """Check the ``[grbl]`` settings against the rest of the profile and against GRBL's own rules.

    Raises
    ------
    ProfileError
        ``$130``/``$131`` other than the work area, ``$30``/``$32`` other than ``[laser]``, laser mode on a pen
        plotter, or soft limits (``$20=1``) without homing (``$22=1``), which GRBL refuses with error:10.
    """
    stated = {130: (width, "work_area.width"), 131: (height, "work_area.height")}
    if laser is not None:
        stated[30] = (laser.max_power, "laser.max_power")
        stated[32] = (1.0 if laser.laser_mode else 0.0, "laser.laser_mode")
    for number, (value, source) in stated.items():
        if number in settings and not math.isclose(settings[number], value, abs_tol=1e-6):
            raise ProfileError(f"{where}: ${number} = {settings[number]:g} differs from {source} ({value:g}); "
                               f"the profile states ${number} there: leave it out of [grbl] or make them equal")
    if kind == "plotter" and settings.get(32, 0.0):
        raise ProfileError(f"{where}: $32 = 1 (laser mode) on a pen plotter: its pen commands (M3 S...) would run "
                           "as laser power; expected 0")
    if settings.get(20, 0.0) and not settings.get(22, 0.0):
        raise ProfileError(f"{where}: $20 = 1 (soft limits) needs $22 = 1 (homing); GRBL refuses it (error:10)")
