"""Errors raised by ``calibration``. Every error is a :class:`CalibrationError`, also a :class:`ValueError`."""

from __future__ import annotations


class CalibrationError(ValueError):
    """Base of every error raised by ``calibration``."""
