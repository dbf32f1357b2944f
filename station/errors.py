"""Errors raised by ``station``. Every error is a :class:`StationError`, also a :class:`ValueError`."""

from __future__ import annotations


class StationError(ValueError):
    """Base of every error raised by ``station``."""


class UsageError(StationError):
    """A command line was well formed for argparse but means nothing (e.g. ``--set radius``)."""


class ConfigError(StationError):
    """The station's configuration is unusable: its data folder, or its config file (``station.toml``).

    A bad config file is reported as one line naming the file, the field and the expected value
    (``station.toml: devices[2].kind: expected one of plotter, laser, camera, projector, got 'lazer'``).

    Parameters
    ----------
    message : str
        What is wrong and what was expected.
    file : str, optional
        The config file, when the problem is in one; it prefixes the message.
    field : str, optional
        The path of the offending field in that file (``devices[2].kind``; "" for the whole file).

    Attributes
    ----------
    file, field : str
        As given ("" when not about a file or a field).
    reason : str
        ``message`` without the file and field.
    """

    def __init__(self, message: str, file: str = "", field: str = "") -> None:
        super().__init__("".join(f"{part}: " for part in (file, field) if part) + message)
        self.file = file
        self.field = field
        self.reason = message
