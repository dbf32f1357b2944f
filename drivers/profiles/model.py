"""The frozen dataclasses of a machine profile (what :mod:`drivers.profiles.loading` builds from TOML).

Every length is in millimetres, every feed in mm/min and every duration in seconds: units are converted when a
profile is loaded, never here.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from drivers.errors import DriverError

__all__ = [
    "LaserOperation",
    "LaserSettings",
    "MachineProfile",
    "Material",
    "PaperSettings",
    "PenSettings",
    "PlotSettings",
    "ProfileError",
]


class ProfileError(DriverError, ValueError):
    """A machine profile is malformed; the message names the file, the field and what was expected."""


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
    square, measure it, or read a test card with ``station calibrate material``); ``None`` when the profile does not
    say. ``measured`` is the profile's record of where the settings came from (the card, the frame, the measured
    values and their uncertainty), empty when they were written by hand.
    """

    name: str
    thickness: float
    cut: LaserOperation
    engrave: LaserOperation
    kerf: float | None = None
    measured: Mapping[str, object] = field(default_factory=lambda: MappingProxyType({}), compare=False)

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
    ``change`` is what a multi-pen plot writes between two layers, the pen up: GRBL's program pause ``M0`` by
    default (the station tells which pen to put in and resumes with cycle start); a profile may move the head to
    where the pen is reached first (``["G0 X0 Y0", "M0"]``) or run a pen changer's own lines.
    """

    mode: str = "servo"
    up: float = 50.0
    down: float = 30.0
    up_delay: float = 0.15
    down_delay: float = 0.15
    z_feed: float = 1000.0
    change: tuple[str, ...] = ("M0",)

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
    grbl : mapping of int to float
        The profile's ``[grbl]`` table: firmware settings (``$N``) the machine holds that the profile does not state
        elsewhere, e.g. steps/mm, max rates, acceleration, homing. See :attr:`grbl_settings` for all of them.
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
    grbl: Mapping[int, float] = field(default_factory=lambda: MappingProxyType({}))

    @property
    def is_laser(self) -> bool:
        return self.kind == "laser"

    def work_bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` of the work area in work coordinates (mm)."""
        if self.origin == "center":
            return (-self.width / 2, -self.height / 2, self.width / 2, self.height / 2)
        return (0.0, 0.0, self.width, self.height)

    @property
    def grbl_settings(self) -> Mapping[int, float]:
        """The GRBL settings (``$N``) this profile states: its ``[grbl]`` table, ``$130``/``$131`` from the work
        area and, for a laser, ``$30``/``$32`` from ``[laser]``; each setting has one source in the file."""
        settings = {key: float(value) for key, value in self.grbl.items()}
        settings[130], settings[131] = float(self.width), float(self.height)
        if self.laser is not None:
            settings[30] = float(self.laser.max_power)
            settings[32] = 1.0 if self.laser.laser_mode else 0.0
        return MappingProxyType(dict(sorted(settings.items())))

    def material(self, name: str) -> Material:
        """The material called ``name``; the error lists the known ones."""
        try:
            return self.materials[name]
        except KeyError:
            known = ", ".join(sorted(self.materials)) or "none"
            raise ProfileError(f"profile {self.name!r}: no material {name!r}; known: {known}") from None


