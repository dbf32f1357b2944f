"""Errors of guided exploration, derived from the ``design`` error tree."""

from __future__ import annotations

from design.errors import DesignError, ParameterError


class ExploreError(DesignError):
    """Base of the errors raised by :mod:`design.explore`."""


class InvariantSpecError(ParameterError):
    """An invariant names an unknown type, a PoI that does not exist, or a PoI of the wrong type."""


class OverConstrainedError(ExploreError):
    """The invariants leave no freedom around the current design: remove one of them.

    Attributes
    ----------
    invariants : tuple of str
        Labels of the invariants in force (e.g. ``("position:3", "angle:7")``).
    """

    def __init__(self, message: str, invariants: tuple[str, ...] = ()):
        super().__init__(message)
        self.invariants = tuple(invariants)
