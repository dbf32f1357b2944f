"""The station's one family of errors, and the one tuple of errors its faces report as a line.

Every error the station raises is a :class:`StationError`, also a :class:`ValueError`. The packages the station
wires raise their own (``design``, ``drivers``, ``calibration``, ``projector``, ``vision``, and ``common``'s data-file
reader); a service turns them into station errors where its work is called (:func:`station_errors`), with the same
message, so that the command line and the screens catch one tuple, :data:`USER_ERRORS`, and never name a package.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TypeVar

from calibration.errors import CalibrationError
from common.datafiles import DataFileError
from design.errors import DesignError
from drivers.errors import DriverError
from projector.errors import ProjectorError
from vision.errors import VisionError


class StationError(ValueError):
    """Base of every error raised by ``station``."""


class UsageError(StationError):
    """A command line was well formed for argparse but means nothing (e.g. ``--set radius``)."""


class ConfigError(StationError):
    """The station's configuration is unusable: its data folder, or its config file (``station.toml``).

    A bad config file is reported as one line naming the file, the field and the expected value
    (``station.toml: devices[2].kind: expected one of plotter, laser, camera, projector, got 'lazer'``).

    Parameters
    ----------
    message : str
        What is wrong and what was expected.
    file : str, optional
        The config file, when the problem is in one; it prefixes the message.
    field : str, optional
        The path of the offending field in that file (``devices[2].kind``; "" for the whole file).

    Attributes
    ----------
    file, field : str
        As given ("" when not about a file or a field).
    reason : str
        ``message`` without the file and field.
    """

    def __init__(self, message: str, file: str = "", field: str = "") -> None:
        super().__init__("".join(f"{part}: " for part in (file, field) if part) + message)
        self.file = file
        self.field = field
        self.reason = message


class ServiceError(StationError):
    """Input a service cannot work with; the message names the value, not a CLI flag (a command may reword it).

    A :class:`StationError`, hence also a :class:`ValueError`.
    """

    def __init__(self, message: str, *, field: str | None = None, value: object = None) -> None:
        super().__init__(message)
        #: The input the message is about (``"tolerance"``, ``"sheet"``...), so that a command can name its flag.
        self.field = field
        self.value = value


#: The errors of the packages the station wires: a bad input or a device's state, said in one line by the package.
PACKAGE_ERRORS: tuple[type[Exception], ...] = (
    DesignError, DriverError, CalibrationError, ProjectorError, VisionError, DataFileError)

#: What a face reports as one line (the command line: on stderr, exit 2) rather than as a bug: the station's errors
#: and the operating system's (a file missing or unwritable, a port gone).
USER_ERRORS: tuple[type[Exception], ...] = (StationError, OSError)

_STATION_CLASSES: dict[type[Exception], type[StationError]] = {}


def _station_class(cls: type[Exception]) -> type[StationError]:
    """``cls`` that is also a :class:`StationError`: same name, so a message or a log reads as the package wrote it,
    and still a ``cls``, so code that catches the package's own error keeps catching it."""
    if cls not in _STATION_CLASSES:
        _STATION_CLASSES[cls] = type(cls.__name__, (cls, StationError),
                                     {"__module__": cls.__module__, "__qualname__": cls.__qualname__,
                                      "__doc__": cls.__doc__, "__reduce__": _reduce})
    return _STATION_CLASSES[cls]


def _reduce(error: BaseException):
    # pickled by way of the package's class (the made class has no importable name), translated again on loading
    return _translated, (type(error).__mro__[1], error.args, vars(error))


def _translated(cls: type[Exception], args: tuple, fields: dict) -> BaseException:
    original = cls.__new__(cls, *args)
    original.args = args
    original.__dict__.update(fields)
    return as_station_error(original)


def as_station_error(error: BaseException) -> BaseException:
    """``error`` as a station error with the same message and attributes, when it is a package's error; any other
    error (a station error, a bug, a stop) is returned as it is."""
    if isinstance(error, StationError) or not isinstance(error, PACKAGE_ERRORS):
        return error
    cls = _station_class(type(error))
    translated = cls.__new__(cls, *error.args)
    translated.args = error.args
    translated.__dict__.update(vars(error))
    return translated


@contextmanager
def translated_errors() -> Iterator[None]:
    """Raise the packages' errors raised inside as station errors (:func:`as_station_error`)."""
    try:
        yield
    except PACKAGE_ERRORS as error:
        raise as_station_error(error).with_traceback(error.__traceback__) from error


Entry = TypeVar("Entry", bound=Callable)

#: The special methods of a service's class that its callers reach (the rest are Python's own protocols).
_ENTRY_DUNDERS = {"__init__", "__post_init__", "__call__", "__iter__", "__next__", "__enter__", "__exit__"}


def station_errors(entry: Entry) -> Entry:
    """``entry``, a service's function or class, raising the packages' errors as station errors: the service boundary.

    A generator function is wrapped as a generator, so that an error raised while it is iterated is translated too.
    On a class, every public method (static, class, property) and the special methods a caller reaches
    (construction, calling, iterating, ``with``) are wrapped.
    """
    if inspect.isclass(entry):
        for name, member in list(vars(entry).items()):
            if name.startswith("_") and name not in _ENTRY_DUNDERS:
                continue
            if isinstance(member, (staticmethod, classmethod)):
                setattr(entry, name, type(member)(station_errors(member.__func__)))
            elif isinstance(member, property):
                setattr(entry, name, member.getter(station_errors(member.fget)) if member.fget else member)
            elif inspect.isfunction(member):
                setattr(entry, name, station_errors(member))
        return entry
    function = entry
    if getattr(function, "__station_errors__", False):
        return function
    if inspect.isgeneratorfunction(function):
        @functools.wraps(function)
        def generator(*args, **kwargs):
            with translated_errors():
                return (yield from function(*args, **kwargs))
        generator.__station_errors__ = True
        return generator  # type: ignore[return-value]

    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        with translated_errors():
            return function(*args, **kwargs)
    wrapper.__station_errors__ = True
    return wrapper  # type: ignore[return-value]
