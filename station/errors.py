"""Errors raised by ``station``. Every error is a :class:`StationError`, also a :class:`ValueError`."""

from __future__ import annotations


class StationError(ValueError):
    """Base of every error raised by ``station``."""


class UsageError(StationError):
    """A command line was well formed for argparse but means nothing (e.g. ``--set radius``)."""


class ConfigError(StationError):
    """The station's configuration file is malformed; the message names the file and the field."""
