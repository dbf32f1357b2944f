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
    width = "400mm"                 # $130
    height = "400mm"                # $131
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

    [grbl]                          # other firmware settings ($N), see drivers.profiles.firmware
    22 = 1                          # homing
    100 = 80.0                      # X steps/mm

A material may say its ``kerf`` (the width the laser burns away, a length); ``station calibrate material`` writes a
material's ``kerf``, ``cut`` and ``engrave`` from a test card read by the camera, with a
``[materials.NAME.measured]`` table of where they came from (text, numbers and true/false only: the card, the photo,
the measured values and their uncertainty).

A pen plotter has a ``[pen]`` table (``mode = "servo"`` with ``up``/``down`` S values, or ``mode = "z"`` with
``up``/``down`` heights; ``up_delay`` and ``down_delay``) and a ``[paper]`` table (``width``, ``height``,
``margin``); a ``[plot]`` table holds ``draw_feed``, ``travel_feed`` and ``tolerance``.

The package by topic: :mod:`~drivers.profiles.units` (numbers with units), :mod:`~drivers.profiles.model` (the
dataclasses), :mod:`~drivers.profiles.firmware` (the ``[grbl]`` table), :mod:`~drivers.profiles.loading` (TOML to a
profile, and the built-in profiles: ``builtin/*.toml``, package data).
"""

# The package's names are its modules' ``__all__``: each name is listed once, where it is defined.
from drivers.profiles import firmware, loading, model, units
from drivers.profiles.firmware import *  # noqa: F403
from drivers.profiles.loading import *  # noqa: F403
from drivers.profiles.model import *  # noqa: F403
from drivers.profiles.units import *  # noqa: F403

__all__ = sorted({*model.__all__, *units.__all__, *firmware.__all__, *loading.__all__})
