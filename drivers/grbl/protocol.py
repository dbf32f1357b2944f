"""GRBL 1.1 messages: parsing of every line a GRBL controller sends, and the meaning of its codes in words."""

from __future__ import annotations

import re
from dataclasses import dataclass

from drivers.errors import ProtocolError

__all__ = [
    "ALARM_CODES",
    "CRITICAL_ALARMS",
    "HOMING_FAIL_ALARMS",
    "ERROR_CODES",
    "SYNC_COMMANDS",
    "Alarm",
    "Banner",
    "Error",
    "Feedback",
    "Garbled",
    "Ok",
    "ReplyParseError",
    "SettingLine",
    "StatusReport",
    "VersionInfo",
    "alarm_meaning",
    "error_meaning",
    "needs_sync",
    "parse_line",
    "parse_version",
]

#: GRBL 1.1 error codes (doc/csv/error_codes_en_US.csv).
ERROR_CODES: dict[int, str] = {
    1: "G-code words consist of a letter and a value. Letter was not found.",
    2: "Missing the expected G-code word value or numeric value format is not valid.",
    3: "Grbl '$' system command was not recognized or supported.",
    4: "Negative value received for an expected positive value.",
    5: "Homing cycle failure. Homing is not enabled via settings.",
    6: "Minimum step pulse time must be greater than 3usec.",
    7: "An EEPROM read failed. Auto-restoring affected EEPROM to default values.",
    8: "Grbl '$' command cannot be used unless Grbl is IDLE. Ensures smooth operation during a job.",
    9: "G-code commands are locked out during alarm or jog state.",
    10: "Soft limits cannot be enabled without homing also enabled.",
    11: "Max characters per line exceeded. Received command line was not executed.",
    12: "Grbl '$' setting value cause the step rate to exceed the maximum supported.",
    13: "Safety door detected as opened and door state initiated.",
    14: "Build info or startup line exceeded EEPROM line length limit. Line not stored.",
    15: "Jog target exceeds machine travel. Jog command has been ignored.",
    16: "Jog command has no '=' or contains prohibited g-code.",
    17: "Laser mode requires PWM output.",
    20: "Unsupported or invalid g-code command found in block.",
    21: "More than one g-code command from same modal group found in block.",
    22: "Feed rate has not yet been set or is undefined.",
    23: "G-code command in block requires an integer value.",
    24: "More than one g-code command that requires axis words found in block.",
    25: "Repeated g-code word found in block.",
    26: "No axis words found in block for g-code command or current modal state which requires them.",
    27: "Line number value is invalid.",
    28: "G-code command is missing a required value word.",
    29: "G59.x work coordinate systems are not supported.",
    30: "G53 only allowed with G0 and G1 motion modes.",
    31: "Axis words found in block when no command or current modal state uses them.",
    32: "G2 and G3 arcs require at least one in-plane axis word.",
    33: "Motion command target is invalid.",
    34: "Arc radius value is invalid.",
    35: "G2 and G3 arcs require at least one in-plane offset word.",
    36: "Unused value words found in block.",
    37: "G43.1 dynamic tool length offset is not assigned to configured tool length axis.",
    38: "Tool number greater than max supported value.",
}

#: GRBL 1.1 alarm codes (doc/csv/alarm_codes_en_US.csv).
ALARM_CODES: dict[int, str] = {
    1: "Hard limit triggered. Machine position is likely lost due to sudden halt. Re-homing is highly recommended.",
    2: "Soft limit alarm. G-code motion target exceeds machine travel. Machine position retained. "
    "Alarm may be safely unlocked.",
    3: "Reset while in motion. Machine position is likely lost due to sudden halt. Re-homing is highly recommended.",
    4: "Probe fail. Probe is not in the expected initial state before starting probe cycle.",
    5: "Probe fail. Probe did not contact the workpiece within the programmed travel.",
    6: "Homing fail. The active homing cycle was reset.",
    7: "Homing fail. Safety door was opened during homing cycle.",
    8: "Homing fail. Pull off travel failed to clear limit switch. Try increasing pull-off or check wiring.",
    9: "Homing fail. Could not find limit switch within search distances.",
    10: "Homing fail. Second dual axis limit switch failed to trigger within configured search distance.",
}

#: Alarms after which GRBL answers nothing but a soft reset (hard and soft limits: ``protocol_exec_rt_system``
#: "Halt everything upon a critical event flag"); the driver sends that reset itself.
CRITICAL_ALARMS = frozenset({1, 2})

#: Homing failures: GRBL resets itself after them (``limits_go_home`` calls ``mc_reset``), so a banner follows.
HOMING_FAIL_ALARMS = frozenset(range(6, 11))

#: What a limit alarm says about the job or the machine: what is left to check once GRBL is reset (and unlocked).
ALARM_CAUSE: dict[int, str] = {
    1: "check what hit the limit switch",
    2: "the job goes outside the machine's travel: check its extent and the work offset",
}

#: Recovery advice per alarm, shown with the alarm (after 1 and 2 the driver sends the reset GRBL waits for).
ALARM_RECOVERY: dict[int, str] = {
    1: "check what hit the limit switch, then home ($H): the position is likely lost",
    2: "unlock ($X; the position is kept) or home ($H); " + ALARM_CAUSE[2],
    3: "position is lost: home ($H) before any job (or unlock with $X only if you re-zero by hand)",
    4: "check the probe wiring, then reset and unlock ($X)",
    5: "move the probe closer to the work, then reset and unlock ($X)",
    6: "home again ($H)",
    7: "close the door, then home again ($H)",
    8: "check the limit switches and the pull-off ($27), then home again ($H)",
    9: "check the limit switches and the homing directions ($23), then home again ($H)",
    10: "check the second limit switch of the dual axis, then home again ($H)",
}


class ReplyParseError(ProtocolError, ValueError):
    """A line from the controller that its protocol does not allow (e.g. a malformed status report); the message
    quotes the line. A :class:`~drivers.errors.ProtocolError`, and a ``ValueError`` for callers that parse text."""


def error_meaning(code: int) -> str:
    return ERROR_CODES.get(code, "Unknown error code.")


def alarm_meaning(code: int) -> str:
    return ALARM_CODES.get(code, "Unknown alarm code.")


@dataclass(frozen=True)
class Ok:
    """``ok``: the line was accepted (parsed and planned), not executed."""


@dataclass(frozen=True)
class Error:
    code: int

    @property
    def meaning(self) -> str:
        return error_meaning(self.code)

    def __str__(self) -> str:
        return f"error:{self.code} ({self.meaning})"


@dataclass(frozen=True)
class Alarm:
    code: int

    @property
    def meaning(self) -> str:
        return alarm_meaning(self.code)

    @property
    def recovery(self) -> str:
        return ALARM_RECOVERY.get(self.code, "reset, then unlock ($X) or home ($H)")

    @property
    def cause(self) -> str:
        """What is left to check once GRBL is reset and unlocked (the recovery advice for other alarms)."""
        return ALARM_CAUSE.get(self.code, self.recovery)

    def __str__(self) -> str:
        return f"ALARM:{self.code} ({self.meaning})"


@dataclass(frozen=True)
class Banner:
    """The welcome line after power-up or a soft reset: ``Grbl 1.1h ['$' for help]``."""

    version: str


@dataclass(frozen=True)
class Feedback:
    """A bracketed push message: ``[MSG:...]``, ``[GC:...]``, ``[OPT:...]``, ``[VER:...]``, ``[G54:...]`` ..."""

    kind: str
    text: str


@dataclass(frozen=True)
class SettingLine:
    key: int
    value: float


@dataclass(frozen=True)
class Garbled:
    """A line that is none of the above (noise, a corrupted reply)."""

    text: str


def _vector(text: str) -> tuple[float, ...]:
    return tuple(float(v) for v in text.split(","))


def _pair(text: str, first: str, second: str, kind=float) -> dict:
    a, b = (kind(v) for v in text.split(","))  # ValueError unless exactly two numbers
    return {first: a, second: b}


#: How each field of a status report becomes :class:`StatusReport` attributes (``Ln:``, ``Bf:`` ... GRBL 1.1).
_FIELD_PARSERS = {
    "MPos": lambda data: {"mpos": _vector(data)},
    "WPos": lambda data: {"wpos": _vector(data)},
    "WCO": lambda data: {"wco": _vector(data)},
    "Bf": lambda data: _pair(data, "planner_free", "rx_free", int),
    "Ln": lambda data: {"line_number": int(data)},
    "FS": lambda data: _pair(data, "feed", "spindle"),
    "F": lambda data: {"feed": float(data)},
    "Ov": lambda data: {"overrides": tuple(int(v) for v in data.split(","))},
    "Pn": lambda data: {"pins": data},
    "A": lambda data: {"accessories": data},
}


@dataclass(frozen=True)
class StatusReport:
    """A parsed ``<...>`` status report. Absent fields are None.

    Attributes
    ----------
    state : str
        ``Idle``, ``Run``, ``Hold``, ``Jog``, ``Alarm``, ``Door``, ``Check``, ``Home``, ``Sleep``.
    substate : int or None
        ``Hold:0`` (complete) / ``Hold:1`` (in progress), ``Door:n``.
    mpos, wpos, wco : 3-tuples or None
        Machine position, work position, work coordinate offset (WPos = MPos - WCO).
    planner_free, rx_free : int or None
        ``Bf``: free planner blocks and free bytes of the serial RX buffer.
    """

    state: str
    substate: int | None = None
    mpos: tuple[float, ...] | None = None
    wpos: tuple[float, ...] | None = None
    wco: tuple[float, ...] | None = None
    planner_free: int | None = None
    rx_free: int | None = None
    line_number: int | None = None
    feed: float | None = None
    spindle: float | None = None
    overrides: tuple[int, ...] | None = None
    pins: str = ""
    accessories: str = ""

    @classmethod
    def parse(cls, text: str) -> StatusReport:
        """Parse ``<Idle|MPos:0.000,0.000,0.000|Bf:15,128|FS:0,0>``.

        Raises
        ------
        ReplyParseError
            The text is not a status report, or a state, field or value in it is malformed.
        """
        if not (text.startswith("<") and text.endswith(">")):
            raise ReplyParseError(f"not a status report: {text!r}")
        fields = text[1:-1].split("|")
        state, _, sub = fields[0].partition(":")
        if state not in ("Idle", "Run", "Hold", "Jog", "Alarm", "Door", "Check", "Home", "Sleep"):
            raise ReplyParseError(f"unknown state {fields[0]!r} in {text!r}")
        try:
            values: dict = {"state": state, "substate": int(sub) if sub else None}
        except ValueError:
            raise ReplyParseError(f"malformed state {fields[0]!r} in {text!r}") from None
        for item in fields[1:]:
            name, sep, data = item.partition(":")
            if not sep:
                raise ReplyParseError(f"malformed field {item!r} in {text!r}")
            if name not in _FIELD_PARSERS:
                raise ReplyParseError(f"unknown field {name!r} in {text!r}")
            try:
                values.update(_FIELD_PARSERS[name](data))
            except ValueError:  # a number that is not one, or a list of the wrong length
                raise ReplyParseError(f"malformed field {item!r} in {text!r}") from None
        for key in ("mpos", "wpos", "wco"):
            if values.get(key) is not None and len(values[key]) < 3:
                raise ReplyParseError(f"short {key} in {text!r}")
        return cls(**values)

    @property
    def label(self) -> str:
        return self.state if self.substate is None else f"{self.state}:{self.substate}"

    def work_position(self, wco: tuple[float, ...] | None) -> tuple[float, ...] | None:
        if self.wpos is not None:
            return self.wpos
        if self.mpos is not None and wco is not None:
            return tuple(m - w for m, w in zip(self.mpos, wco))
        return None

    def machine_position(self, wco: tuple[float, ...] | None) -> tuple[float, ...] | None:
        if self.mpos is not None:
            return self.mpos
        if self.wpos is not None and wco is not None:
            return tuple(p + w for p, w in zip(self.wpos, wco))
        return None


_BANNER = re.compile(r"^Grbl (\S+) \['\$' for help\]$")
_SETTING = re.compile(r"^\$(\d+)=([-+]?\d*\.?\d+)$")


def parse_line(text: str):
    """Classify one line (without its line ending) sent by GRBL."""
    if text == "ok":
        return Ok()
    if text.startswith("error:") and text[6:].isdigit():
        return Error(int(text[6:]))
    if text.startswith("ALARM:") and text[6:].isdigit():
        return Alarm(int(text[6:]))
    if text.startswith("<"):
        try:
            return StatusReport.parse(text)
        except ReplyParseError:
            return Garbled(text)
    match = _BANNER.match(text)
    if match:
        return Banner(match.group(1))
    if text.startswith("[") and text.endswith("]") and ":" in text:
        kind, _, body = text[1:-1].partition(":")
        if kind.isalnum():
            return Feedback(kind, body)
    match = _SETTING.match(text)
    if match:
        return SettingLine(int(match.group(1)), float(match.group(2)))
    return Garbled(text)


_SYNC = re.compile(r"^\$(?!J=)|G0*10(?![\d.])|G0*28\.1|G0*30\.1")

#: What must be sent with send-response (nothing else in flight): ``$`` commands (EEPROM writes disable GRBL's
#: serial interrupts), ``G10``, ``G28.1``, ``G30.1`` (EEPROM writes). ``$J=`` jogs stream like G-code.
SYNC_COMMANDS = ("$...", "G10", "G28.1", "G30.1")


def needs_sync(block: str) -> bool:
    """True if a cleaned block must be sent alone and its reply awaited (GRBL's interface rules)."""
    return bool(_SYNC.search(block))


@dataclass(frozen=True)
class VersionInfo:
    """What ``$I``'s first line says about the firmware.

    GRBL 1.1 prints ``[VER:<version>.<build date>:<build info>]`` (``report_build_info`` in report.c:
    ``"[VER:" GRBL_VERSION "." GRBL_VERSION_BUILD ":"``, then the build info string a user stores with ``$I=``, then
    ``]``), e.g. ``[VER:1.1h.20190830:]`` with an empty build info.

    Attributes
    ----------
    version : str
        ``GRBL_VERSION``, e.g. ``"1.1h"``.
    build : str
        ``GRBL_VERSION_BUILD``, the build date ``YYYYMMDD`` (``""`` if the line carries none).
    info : str
        The build info string (``""`` when none was stored).
    """

    version: str
    build: str = ""
    info: str = ""

    def __str__(self) -> str:
        details = [f"build {self.build}"] if self.build else []
        if self.info:
            details.append(f"info {self.info!r}")
        return f"GRBL {self.version}" + (f" ({', '.join(details)})" if details else "")


_VERSION_BUILD = re.compile(r"^(?P<version>.+)\.(?P<build>\d{8})$")


def parse_version(text: str) -> VersionInfo:
    """The body of a ``[VER:...]`` line (what follows ``VER:``), split into version, build date and build info.

    Only the first ``:`` ends the version part: the build info is free text and may hold ``:`` itself. A version
    part without an 8-digit build date (a fork's own format) is kept whole as the version.
    """
    head, _, info = text.partition(":")
    match = _VERSION_BUILD.match(head)
    if match:
        return VersionInfo(match["version"], match["build"], info)
    return VersionInfo(head, "", info)
