"""Errors of the service layer."""

from __future__ import annotations

from station.errors import StationError


class ServiceError(StationError):
    """Input a service cannot work with; the message names the value, not a CLI flag (a command may reword it).

    A :class:`station.errors.StationError`, hence also a :class:`ValueError`.
    """

    def __init__(self, message: str, *, field: str | None = None, value: object = None) -> None:
        super().__init__(message)
        #: The input the message is about (``"tolerance"``, ``"sheet"``...), so that a command can name its flag.
        self.field = field
        self.value = value
