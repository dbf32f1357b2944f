"""Projectors: the real one on a display (``display:N``, :mod:`drivers.projector.display`) and what both it and the
simulated twin (``sim://projector``, :mod:`drivers.sim.projector`) accept as a frame (:mod:`drivers.projector.frame`).

Both follow :class:`drivers.devices.Projector`: ``open()``, ``show(frame)``, ``blank()``, ``size``, ``close()``.
"""

from drivers.projector.display import DISPLAY_PROBE_TIMEOUT, DisplayProjector
from drivers.projector.frame import as_rgb, fit_to_screen

__all__ = ["DISPLAY_PROBE_TIMEOUT", "DisplayProjector", "as_rgb", "fit_to_screen"]
