"""Helpers shared by CLI commands: ``--set NAME=VALUE`` parsing, number options, JSON output, output files."""

from __future__ import annotations

import argparse
import errno
import json
import math
import os
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any, TextIO

from station.errors import ServiceError, UsageError
from station.jsonable import to_jsonable
from station.services.designs import load_design


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


def number(low: float | None = None, high: float | None = None, *, above: bool = False,
           why: str = "") -> Callable[[str], float]:
    """An argparse ``type`` for a number option: a finite float in ``[low, high]`` (``above``: greater than ``low``).

    ``float`` alone takes ``nan``, ``inf`` and ``1e999``, which pass every later ``<`` check unnoticed (a plot of
    no moves, a sleep for ever); a bad value is refused where it is parsed, as argparse says it: ``argument --size:
    expected a number > 0, got 'nan'``. ``why`` (a few words) follows a range that is the station's own choice.
    """
    if low is None and high is None:
        expected = "a finite number"
    elif high is None:
        expected = f"a number {'>' if above else '>='} {low:g}"
    elif low is None:
        expected = f"a number <= {high:g}"
    else:
        expected = f"a number in {'(' if above else '['}{low:g}, {high:g}]"
    if why:
        expected += f" ({why})"

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and (low is None or value > low or (value == low and not above))
                and (high is None or value <= high)):
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}")
        return value

    parse.__name__ = "number"
    parse.expected = expected  # type: ignore[attr-defined]
    return parse


#: The number types most options take: any finite number, one above zero, one not below zero.
FINITE = number()
POSITIVE = number(0, above=True)
NON_NEGATIVE = number(0)


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


def check_output_folder(path: str | Path, option: str = "--out", contents: str = "the output files") -> Path:
    """``path`` as the output folder of ``option``, refused before any work if it cannot be made or written.

    The folder may be missing (it is created, with its parents, when the outputs are written); it must not be a
    file, nor lie under one, and a file must be creatable in it: tried by making the first missing folder (or a
    file in the folder) and removing it at once, so that a refusal later leaves nothing behind and a folder the
    permissions allow but the file system refuses (``/proc``, a read-only mount) is found now.

    Raises
    ------
    UsageError
        Naming the option, the path and what is wrong.
    """
    if str(path) == "":
        raise UsageError(f"{option} '': expected a folder name")
    path = Path(path)
    try:
        if path.exists() and not path.is_dir():
            raise UsageError(f"{option} {str(path)!r}: is a file; expected a folder (it gets {contents}), "
                             "e.g. a new folder name")
        existing = path
        while not existing.exists() and existing != existing.parent:
            existing = existing.parent
        if not existing.is_dir():
            raise UsageError(f"{option} {str(path)!r}: {str(existing)!r} is a file, so the folder cannot be made; "
                             "expected a folder path")
    except OSError as error:  # a name too long, a loop of links
        raise UsageError(f"{option} {str(path)!r}: cannot make that folder ({_reason(error)})") from None
    if existing == path:
        _try_file(path / f".station-write-test-{os.getpid()}", option, path)
    else:
        first = path
        while first.parent != existing:
            first = first.parent
        try:
            first.mkdir()
        except OSError as error:
            raise UsageError(f"{option} {str(path)!r}: cannot make a folder in {str(existing)!r} "
                             f"({_reason(error)})") from None
        first.rmdir()
    return path


def check_output_file(path: str | Path, suffixes: Iterable[str], option: str) -> Path:
    """``path`` as an output file of ``option``, refused before any work if it cannot be written at the end.

    The one check of every command's output file: a run takes seconds to hours, and an empty name, a wrong suffix,
    a folder given as the file, a missing folder or one under a file, or a place the file cannot be created must not
    be found only when the result is ready. The file is created and removed at once (an existing one is opened for
    appending and left as it is), so that what the file system refuses (``/proc``, a read-only mount, a name too
    long) is refused now, whatever the permissions say.

    Raises
    ------
    UsageError
        Naming the option, the path and what was expected.
    """
    suffixes = sorted(suffixes)
    if str(path) == "":
        raise UsageError(f"{option} '': expected a file name ending in {', '.join(suffixes)}")
    path = Path(path)
    output_suffix(path, suffixes)
    try:
        if path.is_dir():
            raise UsageError(f"{option} {path}: is a folder; expected a file name ending in {', '.join(suffixes)}")
        folder = path.parent
        blocker = folder
        while not blocker.exists() and blocker != blocker.parent:
            blocker = blocker.parent
        if not blocker.is_dir():
            raise UsageError(f"{option} {path}: {blocker} is not a folder")
        if not folder.exists():
            raise UsageError(f"{option} {path}: the folder {folder} does not exist (create it first, or choose "
                             "another)")
    except OSError as error:  # a name too long, a loop of links: what pathlib's checks do not take for "no"
        raise UsageError(f"{option} {path}: cannot create a file there ({_reason(error)})") from None
    _try_file(path, option, path)
    return path


def _try_file(path: Path, option: str, named: Path) -> None:
    """Create ``path`` and remove it (or open an existing one for appending, changing nothing), or refuse ``option``
    ``named`` with the system's reason."""
    try:
        if path.exists():
            with path.open("ab"):
                pass
            return
        descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
    except OSError as error:
        raise UsageError(f"{option} {named}: cannot create a file there ({_reason(error)})") from None
    os.close(descriptor)
    path.unlink()


def _reason(error: OSError) -> str:
    """Why the system refused, in words for a folder known to exist (where "no such file" would mislead)."""
    if error.errno in (errno.EACCES, errno.EPERM):
        return "permission denied"
    if error.errno == errno.ENOENT:
        return "the file system there takes no new files"
    return error.strerror or str(error)


def add_physics_option(parser) -> None:
    """``--physics PROFILE.toml``: simulate with a physics profile's material values instead of the scenario's."""
    parser.add_argument("--physics", metavar="PROFILE.toml", default=None,
                        help="simulate with the material values of a physics profile (`station calibrate sim "
                        "--out`) instead of the scenario's own")
