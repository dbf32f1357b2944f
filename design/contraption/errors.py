"""Errors of the contraption area, derived from the package bases of :mod:`design.errors`."""

from __future__ import annotations

from design.errors import DesignError, FileFormatError, ParameterError


class ScenarioFormatError(FileFormatError):
    """A scenario or layout file is malformed.

    The message always names the file, the field's path (``objects[3].transform.heading``) and what was expected.

    Attributes
    ----------
    file : str
        The file (or ``"<data>"`` for in-memory data).
    field : str
        The path of the offending field ("" for the whole file).
    """

    def __init__(self, file: str, field: str, message: str) -> None:
        where = f"{file}: {field}: " if field else f"{file}: "
        super().__init__(where + message)
        self.file = file
        self.field = field


class LayoutError(ParameterError):
    """A layout vector or named layout does not fit the scenario's design space."""


class ScenarioNotFoundError(DesignError):
    """A scenario named on a command line or in a field is neither a file nor an example.

    Attributes
    ----------
    name : str
        What was given.
    examples : list of str
        The example names one could have given.
    """

    def __init__(self, name: str, examples: list[str]) -> None:
        listed = ", ".join(examples) or "none found"
        super().__init__(f"scenario {name!r}: no such file and no example of that name; expected a .toml or .json "
                         f"scenario file or one of the examples: {listed}")
        self.name = name
        self.examples = examples


class SimulationError(DesignError):
    """The simulation could not be set up for this scenario (e.g. a pybullet client that is gone)."""
