"""Errors raised by ``design``.

Every error is a :class:`DesignError`, which is also a :class:`ValueError`: what goes wrong in pure computation is
bad input (a parameter, a file, a constraint). Areas of ``design`` derive their own errors from these.
"""

from __future__ import annotations


class DesignError(ValueError):
    """Base of every error raised by ``design``."""


class ParameterError(DesignError):
    """A parameter is unknown, missing, of the wrong kind or out of its bounds.

    The message follows one template, built by :func:`parameter_error`.
    """


class ConstraintViolation(DesignError):
    """A design violates one of its model's constraints; the message says which one, in words and numbers."""

    def __init__(self, message: str, *, constraint: str = "", margin: float | None = None):
        super().__init__(message)
        self.constraint = constraint
        self.margin = margin


class FileFormatError(DesignError):
    """A data file (scenario, sketch, layout, ...) is malformed; the message names the file, field and expectation."""


def parameter_error(thing: str, name: str, expected: str, got: object) -> ParameterError:
    """Build the one message template for a bad parameter.

    Parameters
    ----------
    thing : str
        What the parameter belongs to (e.g. ``"spirograph"``).
    name : str
        The parameter's name.
    expected : str
        What was expected, in words (e.g. ``"an integer in [1, 100]"``).
    got : object
        The value that was given.
    """
    return ParameterError(f"{thing}: parameter {name!r} must be {expected}, got {got!r}")
