"""Errors of sketch retrieval, derived from the package bases so the CLI prints them as one line."""

from __future__ import annotations

from design.errors import DesignError, FileFormatError, ParameterError


class SketchError(DesignError):
    """A sketch cannot be used (empty, degenerate, not finite, ...); the message says what and what was expected."""


class SketchFileError(FileFormatError, SketchError):
    """A sketch file (JSON or SVG) is malformed or too large; the message names the file, field and expectation."""


class RetrievalSettingError(ParameterError):
    """A retrieval setting (symmetry order, number of candidates, machine name, ...) is out of its domain."""


class CandidateDatabaseError(DesignError):
    """A candidate database cannot be built or read (e.g. a model produced no feasible design)."""
