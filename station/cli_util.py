"""Helpers shared by CLI commands: ``--set NAME=VALUE`` parsing, JSON output, output files."""

from __future__ import annotations

import json
import math
import os
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any, TextIO

from design.datafiles import load_json
from design.errors import FileFormatError
from station.errors import UsageError
from station.services.errors import ServiceError


def parse_assignments(items: Iterable[str] | None, option: str = "--set") -> dict[str, float]:
    """Parse ``NAME=VALUE`` strings into a dict of floats.

    Raises
    ------
    UsageError
        On a missing ``=``, an empty name, a value that is not a finite number, or a name given twice.
    """
    values: dict[str, float] = {}
    for item in items or ():
        name, sep, text = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise UsageError(f"{option} {item!r}: expected NAME=VALUE, e.g. {option} d=2.5")
        try:
            value = float(text)
        except ValueError:
            raise UsageError(f"{option} {item!r}: value of {name!r} must be a number, got {text!r}") from None
        if not math.isfinite(value):
            raise UsageError(f"{option} {item!r}: value of {name!r} must be finite, got {text!r}")
        if name in values:
            raise UsageError(f"{option}: {name!r} is given twice")
        values[name] = value
    return values


def flag_error(error: ServiceError, flags: dict[str, str] | None = None) -> UsageError:
    """A service's refusal as the command line says it: the field that starts the message becomes its flag.

    ``ServiceError("top must be an integer in [1, 100], got 0", field="top")`` becomes ``--top must be ...``.
    ``flags`` maps a field to its flag where the two differ (default ``--`` + the field, ``_`` as ``-``); a
    message that does not start with its field is kept as it is.
    """
    field = error.field or ""
    flag = (flags or {}).get(field, "--" + field.replace("_", "-"))
    message = str(error)
    if field and message.startswith(field):
        message = flag + message[len(field):]
    return UsageError(message)


def to_jsonable(value: Any) -> Any:
    """Convert numpy scalars and arrays, tuples, paths and dataclass-like objects to plain JSON values."""
    try:
        import numpy as np
    except ImportError:  # pragma: no cover
        np = None
    if np is not None:
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


def emit_json(obj: Any, stream: TextIO | None = None) -> None:
    """Print ``obj`` as JSON on one line (stdout by default)."""
    stream = stream or sys.stdout
    json.dump(to_jsonable(obj), stream, allow_nan=False)
    stream.write("\n")


def output_suffix(path: str | Path, allowed: Iterable[str]) -> str:
    """The lower-case suffix of ``path``, checked against ``allowed`` (e.g. ``{".svg", ".png"}``)."""
    suffix = Path(path).suffix.lower()
    allowed = sorted(allowed)
    if suffix not in allowed:
        raise UsageError(f"output file {str(path)!r}: expected one of {', '.join(allowed)}, got {suffix or 'none'!r}")
    return suffix


#: What a ``--design`` file should be, the end of the message for a file that is not JSON.
DESIGN_FILE = ('a design: what `station pattern --json` prints, {"params": {...}}, {name: value} or the list of '
               '`station retrieve --json`')


def add_design_options(parser) -> None:
    """``--design FILE.json`` and ``--set NAME=VALUE`` (repeatable, wins over the file) on a drawing-machine command."""
    parser.add_argument(
        "--design",
        metavar="FILE.json",
        help='start from a design file: what `station pattern --json` prints, or {"params": {...}}',
    )
    parser.add_argument(
        "--set", action="append", metavar="NAME=VALUE", default=[], help="a parameter value (repeatable, wins)"
    )


def design_parameters(args, machine_name: str) -> dict[str, Any]:
    """The parameters given by ``--design`` (if any), updated by ``--set``; unset ones take the machine's defaults."""
    params = load_design(args.design, machine_name) if args.design else {}
    params.update(parse_assignments(args.set))
    return params


def load_design(path: str | Path, machine_name: str) -> dict[str, Any]:
    """Parameters from a design file: ``{"machine": ..., "params": {...}}`` (what ``--json`` prints), a flat
    ``{name: value}`` mapping, or a ranked list of designs (what ``station retrieve --json`` prints), from which the
    first one for ``machine_name`` is taken.

    Raises
    ------
    FileFormatError
        Not JSON (:func:`design.datafiles.load_json`'s one line: file, line and column, what was expected), not an
        object or list, ``params`` not an object, a ``machine`` other than ``machine_name``, or a
        list with no design for ``machine_name``.
    """
    path = Path(path)
    document = load_json(path, DESIGN_FILE)
    if isinstance(document, list):
        ranked = [d for d in document if isinstance(d, dict) and d.get("machine") == machine_name]
        if not ranked:
            found = sorted({str(d.get("machine")) for d in document if isinstance(d, dict)})
            raise FileFormatError(f"{path}: expected a list of designs with one for {machine_name!r}, "
                                  f"found machines {found}")
        document = ranked[0]
    if not isinstance(document, dict):
        raise FileFormatError(f"{path}: expected a JSON object, got {type(document).__name__}")
    if "params" in document:
        machine = document.get("machine", machine_name)
        if machine != machine_name:
            raise FileFormatError(f"{path}: field 'machine' is {machine!r}, but the command draws {machine_name!r}")
        params = document["params"]
        if not isinstance(params, dict):
            raise FileFormatError(f"{path}: field 'params' must be an object of name: value, got {params!r:.60}")
    else:
        params = document
    return dict(params)


def check_output_folder(path: str | Path, option: str = "--out", contents: str = "the output files") -> Path:
    """``path`` as the output folder of ``option``, refused before any work if it cannot be made or written.

    The folder may be missing (it is created, with its parents, when the outputs are written); it must not be a
    file, nor lie under one, and the nearest existing folder must be writable. Nothing is created here, so a
    refusal later leaves no empty folder behind.

    Raises
    ------
    UsageError
        Naming the option, the path and what is wrong.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise UsageError(f"{option} {str(path)!r}: is a file; expected a folder (it gets {contents}), "
                         "e.g. a new folder name")
    existing = path
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise UsageError(f"{option} {str(path)!r}: {str(existing)!r} is a file, so the folder cannot be made; "
                         "expected a folder path")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise UsageError(f"{option} {str(path)!r}: cannot write in {str(existing)!r} (permission denied)")
    return path


def check_output_file(path: str | Path, suffixes: set[str], option: str) -> Path:
    """``path`` as an output file of ``option``, refused before any work if it cannot be written at the end.

    A run takes minutes to hours; a missing folder, a folder given as the file, a wrong suffix or a folder one may
    not write in must not be found only when the result is ready.
    """
    path = Path(path)
    output_suffix(path, suffixes)
    folder = path.parent
    if path.is_dir():
        raise UsageError(f"{option} {path}: is a folder; expected a file name ending in {', '.join(sorted(suffixes))}")
    if not folder.exists():
        raise UsageError(f"{option} {path}: the folder {folder} does not exist (create it first, or choose another)")
    if not folder.is_dir():
        raise UsageError(f"{option} {path}: {folder} is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise UsageError(f"{option} {path}: cannot write there (permission denied)")
    return path


def add_physics_option(parser) -> None:
    """``--physics PROFILE.toml``: simulate with a physics profile's material values instead of the scenario's."""
    parser.add_argument("--physics", metavar="PROFILE.toml", default=None,
                        help="simulate with the material values of a physics profile (`station calibrate sim "
                        "--out`) instead of the scenario's own")
