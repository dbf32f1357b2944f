"""Errors raised by ``vision``. Every error is a :class:`VisionError`, also a :class:`ValueError`."""

from __future__ import annotations


class VisionError(ValueError):
    """Base of every error raised by ``vision``: a bad tag id, image or frame size."""
