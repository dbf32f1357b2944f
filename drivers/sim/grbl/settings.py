"""The simulated GRBL's EEPROM and its ``$`` system commands: defaults, the station's machines, the URL's options.

:data:`SIM_PROFILES` is read from the built-in machine profiles' ``[grbl]`` tables: every machine setting is written
down once, in ``drivers/profiles/builtin/*.toml``. :class:`SimConfig` reads a ``sim://grbl?...`` query (see
:mod:`drivers.sim.grbl` for the options); :class:`SystemCommands` is the part of the machine that answers ``$$``,
``$x=val``, ``$I``, ``$#``, ``$G``, ``$N``, ``$C``, ``$X``, ``$H``, ``$J=`` (handed to the G-code interpreter) and
``$RST=``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from drivers.errors import SimConfigError
from drivers.profiles import builtin_grbl_settings, builtin_profile_names
from drivers.profiles.firmware import INTEGERS
from drivers.sim.clock import CLOCKS

VERSION = "1.1h"
BUILD_DATE = "20190830"  # GRBL_VERSION_BUILD of gnea/grbl 1.1h (grbl.h)
BANNER = f"Grbl {VERSION} ['$' for help]"
PLANNER_BLOCKS = 15
RX_BUFFER_SIZE = 128
LINE_BUFFER_SIZE = 80

#: GRBL 1.1 defaults (defaults.h, generic).
DEFAULT_SETTINGS: dict[int, float] = {
    0: 10, 1: 25, 2: 0, 3: 0, 4: 0, 5: 0, 6: 0, 10: 1, 11: 0.010, 12: 0.002, 13: 0, 20: 0, 21: 0, 22: 0, 23: 0,
    24: 25.0, 25: 500.0, 26: 250, 27: 1.0, 30: 1000, 31: 0, 32: 0, 100: 250.0, 101: 250.0, 102: 250.0,
    110: 500.0, 111: 500.0, 112: 500.0, 120: 10.0, 121: 10.0, 122: 10.0, 130: 200.0, 131: 200.0, 132: 200.0,
}
#: Settings GRBL stores as whole numbers: the profiles' rule, so that the twin prints them as its profiles check them.
INTEGER_SETTINGS = INTEGERS
ZERO_DECIMAL_SETTINGS = {30, 31}

#: The station's simulated machines by built-in profile name: their EEPROM is the profile's ``[grbl]`` table (with
#: ``$130``/``$131`` from its work area and ``$30``/``$32`` from its ``[laser]`` table), the one place each machine
#: setting is written down (``drivers/profiles/builtin/*.toml``).
SIM_PROFILES: dict[str, dict[int, float]] = {name: builtin_grbl_settings(name) for name in builtin_profile_names()}


def _flag(value: str) -> bool:
    return value.lower() in ("1", "true", "yes", "on")


#: The URL's options by name: what each takes (for messages) and how its text becomes a value.
_OPTIONS: dict[str, tuple[str, object]] = {
    **{key: ("a number", float) for key in ("time_scale", "latency", "drop", "corrupt", "stray", "delay",
                                            "delay_max", "pace", "probe_z")},
    **{key: ("a whole number", int) for key in ("seed", "disconnect_at", "drop_reply_at")},
    **{key: ("0 or 1", _flag) for key in ("wire", "locked", "homing", "homed", "force_origin")},
    **{key: ("text", str) for key in ("profile", "name", "record")},
    "clock": (" or ".join(CLOCKS), str),
}


@dataclass
class SimConfig:
    """Settings of one simulated machine: the ``sim://grbl?...`` query's options (see :mod:`drivers.sim.grbl`).

    ``settings`` holds the ``sNN=value`` overrides of ``$NN``; ``clock`` is ``wall`` or ``virtual``
    (:mod:`drivers.sim.clock`).
    """

    profile: str = "plotter"
    name: str = ""  # shared between the opens of one name
    time_scale: float = 1.0  # real seconds per simulated second of motion, dwell and homing
    latency: float = 0.0  # seconds each way on the wire
    wire: bool = True  # False: no transfer time at the baud rate
    seed: int = 0  # of the fault injection's random numbers
    # fault injection: probabilities per reply or status line, the longest delay of a late one (s)
    drop: float = 0.0
    corrupt: float = 0.0
    stray: float = 0.0
    delay: float = 0.0
    delay_max: float = 0.05
    disconnect_at: int = 0  # the N-th G-code line unplugs the port
    drop_reply_at: int = 0  # the reply to the N-th G-code line is lost
    locked: bool = False  # power up in alarm
    homing: bool | None = None  # None: the profile's $22
    homed: bool = True  # with homing: set up and homed (False: GRBL as switched on, locked, G54 at 0)
    travel: tuple[float, ...] | None = None  # $130, $131 (and $132); None: the profile's
    force_origin: bool = False  # built with HOMING_FORCE_SET_ORIGIN ('Z' in [OPT:])
    probe_z: float | None = None  # the top of a touch plate (machine Z, mm): G38.x touches it; None: no plate
    record: str = ""  # a JSON file the record is written to when the machine stops
    clock: str = "wall"
    pace: float = 0.0  # virtual clock: at most this many simulated seconds per wall second (0: no limit)
    settings: dict[int, float] = field(default_factory=dict)

    @classmethod
    def from_query(cls, query: dict[str, str]) -> SimConfig:
        """The configuration a URL's query asks for (``{option: value}``, values as text).

        Raises
        ------
        SimConfigError
            An unknown option, a value of the wrong kind, an unknown profile or clock, a contradiction in the
            settings; the message names the option and what it takes.
        """
        config = cls()
        for key, value in query.items():
            if re.fullmatch(r"s\d+", key):
                config.settings[int(key[1:])] = _option_value(key, value, "a number", float)
            elif key == "travel":
                config.travel = _travel_option(value)
            elif key in _OPTIONS:
                expected, convert = _OPTIONS[key]
                setattr(config, key, _option_value(key, value, expected, convert))
            else:
                known = ", ".join(sorted([*_OPTIONS, "travel"]))
                raise SimConfigError(f"unknown sim option {key!r}; known: {known} and sNN (setting $NN)")
        if config.profile not in SIM_PROFILES:
            raise SimConfigError(f"unknown sim profile {config.profile!r}; known: {sorted(SIM_PROFILES)}")
        if config.time_scale <= 0:
            raise SimConfigError(f"time_scale must be positive, got {config.time_scale}")
        if config.clock not in CLOCKS:
            raise SimConfigError(f"sim option clock: expected {_OPTIONS['clock'][0]}, got {config.clock!r}")
        if config.pace < 0 or (config.pace and config.clock != "virtual"):
            raise SimConfigError(f"sim option pace: expected a positive number with clock=virtual, got "
                                 f"pace={config.pace:g} with clock={config.clock}")
        config.machine_settings()  # a contradiction in the URL is refused when the port opens
        return config

    def machine_settings(self) -> dict[int, float]:
        """The EEPROM settings of this machine: GRBL's defaults, the profile, then ``homing``, ``travel`` and the
        ``sNN`` overrides, with GRBL's own rule that soft limits need homing.

        Raises
        ------
        SimConfigError
            ``s20=1`` on a machine without homing (GRBL answers ``$20=1`` with error:10 there).
        """
        settings = dict(DEFAULT_SETTINGS)
        settings.update(SIM_PROFILES[self.profile])
        if self.homing is not None:
            settings[22] = float(self.homing)
        if self.travel is not None:
            for index, value in enumerate(self.travel):
                settings[130 + index] = value
        settings.update(self.settings)
        if int(settings[20]) and not int(settings[22]):
            if int(self.settings.get(20, 0)):
                raise SimConfigError("s20=1 needs homing (s22=1 or homing=1): GRBL refuses soft limits without homing "
                                 "(error:10)")
            settings[20] = 0.0  # $22=0 also switches soft limits off (settings.c)
        return settings


def _option_value(key: str, text: str, expected: str, convert):
    """``text`` of option ``key`` converted, or a SimConfigError naming the option and what it takes."""
    try:
        value = convert(text)
    except ValueError:
        raise SimConfigError(f"sim option {key}: expected {expected}, got {text!r}") from None
    if isinstance(value, float) and not math.isfinite(value):
        raise SimConfigError(f"sim option {key}: expected a finite number, got {text!r}")
    return value


def _travel_option(value: str) -> tuple[float, ...]:
    """``400x300`` or ``400x300x20`` (mm) as ``($130, $131[, $132])``."""
    parts = value.lower().split("x")
    try:
        travel = tuple(float(part) for part in parts)
    except ValueError:
        travel = ()
    if len(travel) not in (2, 3) or not all(math.isfinite(v) and v >= 0 for v in travel):
        raise SimConfigError(f"travel must be WxD or WxDxH in mm (e.g. travel=400x400), got {value!r}")
    return travel



class Halt(Exception):
    """Raised inside a line's generator (a ``$`` command or a G-code line being run) to abandon it: leaving check
    mode resets the machine, a soft limit alarm halts it."""


def xyz(vector) -> str:
    """Three coordinates as GRBL prints them: ``1.000,2.000,3.000``."""
    return ",".join(f"{float(x):.3f}" for x in vector)


class SystemCommands:
    """The ``$`` commands of :class:`drivers.sim.grbl.SimulatedGrbl` (a mixin: it works on the machine's settings,
    coordinate systems, state and output)."""

    def _format_setting(self, key: int) -> str:
        value = self.settings[key]
        if key in INTEGER_SETTINGS or key in ZERO_DECIMAL_SETTINGS:
            return f"${key}={int(round(value))}"
        return f"${key}={value:.3f}"

    def _system_command(self, text: str):
        idle_or_alarm = self._state in ("Idle", "Alarm", "Check") or self._check_mode
        if text == "$":
            self._emit("[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H ~ ! ? ctrl-x]")
            return 0
        if text == "$$":
            if not idle_or_alarm:
                return 8
            for key in sorted(self.settings):
                self._emit(self._format_setting(key))
            return 0
        if text == "$#":
            if not idle_or_alarm:
                return 8
            for n in range(54, 60):
                self._emit(f"[G{n}:{xyz(self.coords[n])}]")
            self._emit(f"[G28:{xyz(self.g28)}]")
            self._emit(f"[G30:{xyz(self.g30)}]")
            self._emit(f"[G92:{xyz(self.g92)}]")
            self._emit(f"[TLO:{self.tlo:.3f}]")
            self._emit(f"[PRB:{xyz(self.probe_position)}:{int(self.probe_succeeded)}]")
            return 0
        if text == "$G":
            m = self.modal
            spindle = f"M{m['spindle']}"
            self._emit(f"[GC:G{m['motion']} G{m['wcs']} G{m['plane']} G{m['units']} G{m['distance']} "
                       f"G{m['feedmode']} {spindle} M{m['coolant']} T{self.tool} F{self.feed:.0f} "
                       f"S{self.spindle_speed:.0f}]")
            return 0
        if text == "$I":
            if not idle_or_alarm:
                return 8
            self._emit(f"[VER:{VERSION}.{BUILD_DATE}:{self.build_info}]")
            self._emit(f"[OPT:V{'Z' if self.config.force_origin else ''},{PLANNER_BLOCKS},{RX_BUFFER_SIZE}]")
            return 0
        if text.startswith("$I="):
            if not idle_or_alarm:
                return 8
            self.build_info = text[3:]  # the line as GRBL keeps it: upper case, without spaces
            yield "sync"  # EEPROM write
            return 0
        if text == "$N":
            for i, line in enumerate(self.startup_lines):
                self._emit(f"$N{i}={line}")
            return 0
        if text == "$C":
            if self._check_mode:
                self._emit("[MSG:Disabled]")
                self._emit("ok", "reply")
                self._soft_reset(self._parse_time)
                raise Halt
            if self._state != "Idle":
                return 8
            self._check_mode = True
            self._state = "Check"
            self._emit("[MSG:Enabled]")
            return 0
        if text == "$X":
            if self._state == "Alarm":
                self._state = "Idle"
                self._emit("[MSG:Caution: Unlocked]")
                return 0
            return 0 if idle_or_alarm else 8
        if text == "$H":
            if not int(self.settings[22]):
                return 5
            if not idle_or_alarm or self._check_mode:
                return 8
            self._state = "Home"
            self._home_until = self._parse_time + 1.5 * self.config.time_scale
            self._wait = ("time", self._home_until)
            yield ("time", self._home_until)
            return 0
        if text.startswith("$J="):
            return (yield from self._jog(text[3:]))
        if text.startswith("$RST="):
            what = text[5:]
            if what not in ("$", "#", "*"):
                return 3
            if what in ("$", "*"):
                self.settings = self.config.machine_settings()  # this machine's EEPROM as shipped
            if what in ("#", "*"):
                for n in self.coords:
                    self.coords[n] = np.zeros(3)
                self.g28 = np.zeros(3)
                self.g30 = np.zeros(3)
            return 0
        match = re.fullmatch(r"\$N([01])=(.*)", text)
        if match:
            self.startup_lines[int(match.group(1))] = match.group(2)
            return 0
        match = re.fullmatch(r"\$(\d+)=(.*)", text)
        if match:
            if not idle_or_alarm:
                return 8
            key = int(match.group(1))
            try:
                value = float(match.group(2))
            except ValueError:
                return 2
            if key not in self.settings:
                return 3
            if value < 0:
                return 4
            if key == 0 and value < 3:
                return 6
            if key == 20 and value and not int(self.settings[22]):
                return 10
            self.settings[key] = float(int(value)) if key in INTEGER_SETTINGS else value
            if key == 22 and not int(value):
                self.settings[20] = 0.0  # GRBL force-disables soft limits with homing
            yield "sync"  # EEPROM write
            return 0
        return 3
