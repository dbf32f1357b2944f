"""How long work reports progress and is stopped, as the faces (commands and screens) see it.

The contract itself lives in :mod:`common.progress`; the faces reach it here, so that they import only
``station.services`` (``tests/test_layering.py``).
"""

from __future__ import annotations

from common.progress import Cancelled, Progress, ProgressCallback, Reporter

__all__ = ["Cancelled", "Progress", "ProgressCallback", "Reporter"]
