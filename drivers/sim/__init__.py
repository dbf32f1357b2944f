"""Simulated devices, reachable through the same port URLs as the real ones.

``sim://grbl?profile=plotter`` (or ``laser``) is a simulated GRBL 1.1 controller behind a pyserial port object:
:func:`register` adds this package to ``serial.protocol_handler_packages`` so that
``serial.serial_for_url("sim://grbl?...")`` finds :mod:`drivers.sim.protocol_sim`. See
:mod:`drivers.sim.grbl` for the query parameters (time scale, ``clock=virtual``, faults, settings).

``sim://projector`` (:mod:`drivers.sim.projector`) keeps the frames shown and says what light it throws;
``sim://camera`` (:mod:`drivers.sim.camera`) renders the guide plane it looks at (:mod:`drivers.sim.camera_render`
from the plain description in :mod:`drivers.sim.camera_scene`), that projector's light included, with the truth of
every tag. Twins opened with the same ``name=`` are one (:mod:`drivers.sim.shared`).
"""

from __future__ import annotations

import serial


def register() -> None:
    """Make ``sim://`` URLs known to :func:`serial.serial_for_url` (idempotent)."""
    if __name__ not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(__name__)


register()
