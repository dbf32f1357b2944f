"""The design space of a scenario: its ranged transform components, their bounds and their normalization.

The names are ``"object.component"``, in file order of the objects and, for each object, in the order x, y, z,
heading, pitch, roll, whatever the order of the file's ``ranges`` table.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from design.contraption.errors import LayoutError


class DesignSpace:
    """The ranged transform components of a scenario, in a stable order, and their normalization to [0, 1]^d.

    Parameters
    ----------
    names : sequence of str
        ``"object.component"`` names.
    lower, upper : array_like
        Bounds in real units (m, degrees).
    default : array_like
        The values of the scenario file's transforms.
    """

    def __init__(self, names, lower, upper, default) -> None:
        self.names: tuple[str, ...] = tuple(names)
        self.lower = np.asarray(lower, dtype=float).reshape(-1)
        self.upper = np.asarray(upper, dtype=float).reshape(-1)
        self.default = np.asarray(default, dtype=float).reshape(-1)
        for array in (self.lower, self.upper, self.default):
            array.setflags(write=False)

    @property
    def dim(self) -> int:
        return len(self.names)

    def __len__(self) -> int:
        return self.dim

    def __repr__(self) -> str:
        return f"DesignSpace({list(self.names)!r})"

    def _check(self, x, what: str) -> np.ndarray:
        array = np.asarray(x, dtype=float)
        if array.shape[-1:] != (self.dim,) and not (self.dim == 0 and array.size == 0):
            raise LayoutError(f"{what}: expected {self.dim} values ({', '.join(self.names)}), got shape {array.shape}")
        if not np.all(np.isfinite(array)):
            raise LayoutError(f"{what}: every value must be finite, got {array.tolist()}")
        return array

    def to_normalized(self, x) -> np.ndarray:
        """Real units → [0, 1]^d (works on one vector or on rows of a matrix)."""
        x = self._check(x, "layout")
        span = np.where(self.upper > self.lower, self.upper - self.lower, 1.0)
        return (x - self.lower) / span

    def from_normalized(self, u) -> np.ndarray:
        """[0, 1]^d → real units (works on one vector or on rows of a matrix)."""
        u = self._check(u, "normalized layout")
        return self.lower + u * (self.upper - self.lower)

    def contains(self, x, tol: float = 1e-9) -> bool:
        x = self._check(x, "layout")
        span = self.upper - self.lower
        return bool(np.all(x >= self.lower - tol * span) and np.all(x <= self.upper + tol * span))

    def vector(self, values: Mapping[str, float] | None = None, *, what: str = "layout") -> np.ndarray:
        """A layout vector from ``{"object.component": value}`` (missing names keep their default)."""
        x = self.default.copy()
        for name, value in (values or {}).items():
            if name not in self.names:
                raise LayoutError(f"{what}: unknown design parameter {name!r}; expected one of {list(self.names)}")
            x[self.names.index(name)] = float(value)
        self.check_bounds(x, what=what)
        return x

    def as_dict(self, x) -> dict[str, float]:
        x = self._check(x, "layout")
        return {name: float(v) for name, v in zip(self.names, x)}

    def check_bounds(self, x, *, what: str = "layout") -> np.ndarray:
        """Raise :class:`LayoutError` naming the first component outside its range."""
        x = self._check(x, what)
        for name, value, lo, hi in zip(self.names, x, self.lower, self.upper):
            slack = 1e-9 * max(1.0, abs(hi - lo))
            if not lo - slack <= value <= hi + slack:
                raise LayoutError(f"{what}: {name} = {value:g} is outside its range [{lo:g}, {hi:g}]")
        return x
