"""Which drawing machines the station can fabricate (a light module: the CLI's parser reads it)."""

from __future__ import annotations

#: Machines with a parts builder in :mod:`design.fabrication.parts`.
FABRICABLE_MACHINES = ("spirograph", "elliptic_spirograph", "cycloid_drawing_machine", "hoot_nanny")
