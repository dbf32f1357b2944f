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


class SimConfigError(DriverError, ValueError):
    """A simulated device's options are wrong (an unknown ``sim://`` query option, a bad value); the message names
    the option and what it takes. Also a :class:`ValueError`, which callers of the option parser caught before."""
