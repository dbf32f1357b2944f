"""Simulated devices, reachable through the same port URLs as the real ones.

``sim://grbl?profile=plotter`` (or ``laser``) is a simulated GRBL 1.1 controller behind a pyserial port object:
:func:`register` adds this package to ``serial.protocol_handler_packages`` so that
``serial.serial_for_url("sim://grbl?...")`` finds :mod:`drivers.sim.protocol_sim`. See
:mod:`drivers.sim.grbl` for the query parameters (time scale, ``clock=virtual``, faults, settings).
"""

from __future__ import annotations

import serial


def register() -> None:
    """Make ``sim://`` URLs known to :func:`serial.serial_for_url` (idempotent)."""
    if __name__ not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(__name__)


register()
