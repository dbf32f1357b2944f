"""Errors raised by ``drivers``. Every error is a :class:`DriverError`, also an :class:`OSError`."""

from __future__ import annotations


class DriverError(OSError):
    """Base of every error raised by ``drivers``."""


class PortError(DriverError):
    """A port cannot be opened, or it vanished (e.g. USB unplugged)."""


class ProtocolError(DriverError):
    """A device answered something its protocol does not allow; the message quotes the reply."""


class DeviceStateError(DriverError):
    """The device is in a state that forbids the request (alarm, position lost, laser mode off, ...)."""


class JobRefused(DriverError):
    """A job was refused before any motion (outside the work area, unsafe laser settings, ...)."""
