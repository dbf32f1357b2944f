"""Errors raised by ``projector``. Every error is a :class:`ProjectorError`, also a :class:`ValueError`."""

from __future__ import annotations


class ProjectorError(ValueError):
    """Base of every error raised by ``projector``."""
