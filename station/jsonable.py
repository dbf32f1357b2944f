"""Plain JSON values from what the station's work returns (numpy numbers and arrays, tuples, paths)."""

from __future__ import annotations

from pathlib import Path
from typing import Any


def to_jsonable(value: Any) -> Any:
    """Convert numpy scalars and arrays, tuples, paths and dataclass-like objects to plain JSON values."""
    # numpy is imported on the first conversion, not with the module: every command imports this through
    # station.cli_util, and `station --help` stays quick without it.
    import numpy as np

    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    return value
