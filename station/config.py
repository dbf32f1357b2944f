"""The station's config file: which devices it has (``station.toml`` in its data folder).

Format
------
Every section is optional: without ``[[devices]]`` tables the station has its built-in devices (all simulated),
without ``[database]`` the local SQLite file; a section that is there is checked. One ``[[devices]]`` table per
device, in the order the station lists them::

    [[devices]]
    name = "plotter"                  # unique: letters, digits, '-', '_', '.' (at most 32)
    kind = "plotter"                  # plotter, laser, camera or projector
    url = "/dev/ttyUSB0"              # see drivers.devices for the accepted forms of each kind
    profile = "plotter"               # plotters and lasers only: a built-in profile or a profile file
    options = { timeout = 2.5 }       # plotters and lasers: seconds a probe waits for the machine
                                      # a camera: { laser = "NAME" }, the laser whose bed it looks down on

An array of tables rather than ``[devices.NAME]`` tables: the order is the file's, the name is a field like the
others, and a message names the entry as it is counted (``devices[2].kind``). ``profile`` defaults to the profile
named in a ``sim://grbl?profile=NAME`` URL (which must name one of the device's kind), else to the built-in
profile of the kind; a relative profile path is
relative to the config file's folder. Unknown fields, duplicate names, a URL no driver accepts and a URL of another
kind (a camera URL on a plotter) are refused with one line naming the file, the field and the expected value.

Where
-----
``CHAOS_STATION_CONFIG`` names the file (it must exist), as ``CHAOS_STATION_HOME`` names the data folder; otherwise
``station.toml`` in the data folder (:func:`station.paths.data_dir`). Without that file the station uses its
built-in default, every device simulated (:func:`station.devices.default_devices`). The station reads the file and
never writes it, except :func:`write_default_config`, which makes one only where none exists.

Validation is hand-written on :class:`design.contraption.fields.Checker`, as the scenario format's is (see
:mod:`design.contraption.validation` for why not pydantic).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any
from urllib.parse import parse_qs, urlsplit

from common.datafiles import parse_toml
from design.contraption.fields import Checker, describe, join_path
from station.db_url import parse_url
from station.devices import GRBL_KINDS, REGISTRY_KIND, DeviceEntry, default_devices
from station.errors import ConfigError, StationError
from station.paths import data_dir

CONFIG_VARIABLE = "CHAOS_STATION_CONFIG"
CONFIG_NAME = "station.toml"

TOP_KEYS = ("devices", "database")
DEVICE_KEYS = ("name", "kind", "url", "profile", "options")
KINDS = tuple(REGISTRY_KIND)
NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,31}$")
NAME_EXPECTED = "a name of letters, digits, '-', '_' and '.' (at most 32)"

#: The longest probe wait a device may ask for, in seconds (a board that resets on open answers in about 2).
MAX_PROBE_TIMEOUT = 10.0

#: How the registry's kinds are named in messages.
_KIND_WORDS = {"grbl": "GRBL", "camera": "camera", "projector": "projector"}

#: The file :func:`write_default_config` writes: the built-in default, with the format explained.
DEFAULT_CONFIG_TEXT = """\
# The devices of this Crafting Chaos station, one [[devices]] table each, listed in this order.
#   name     unique: letters, digits, '-', '_', '.'
#   kind     plotter, laser, camera or projector
#   url      plotter, laser: sim://grbl?profile=NAME (simulated), /dev/ttyUSB0, COM3, socket://HOST:PORT
#            camera: sim://camera, 0 (an index), /dev/video0, rtsp://...   projector: sim://projector, display:1
#   profile  plotters and lasers: a built-in profile (plotter, laser) or a profile file (relative to this folder)
#   options  plotters and lasers: { timeout = 2.5 } seconds a probe waits (a board that resets on open needs ~2)
# The simulated camera sees what the simulated projector it names (projector=NAME) throws on the table (640 x 400 mm
# in the middle of its view, or area=u0,v0,u1,v1 in mm): `station calibrate projector` measures the pair as real ones.
# `station devices` lists them with their state.

[[devices]]
name = "plotter"
kind = "plotter"
url = "sim://grbl?profile=plotter"
profile = "plotter"

[[devices]]
name = "laser"
kind = "laser"
url = "sim://grbl?profile=laser"
profile = "laser"

[[devices]]
name = "camera"
kind = "camera"
url = "sim://camera?projector=projector"

[[devices]]
name = "projector"
kind = "projector"
url = "sim://projector?name=projector"
"""


@dataclass(frozen=True)
class StationConfig:
    """The station's configuration.

    Parameters
    ----------
    path : Path or None
        The file it was read from; None for the built-in default (no file).
    devices : tuple of DeviceEntry
        The devices, in the file's order.
    database : str or None
        ``[database] url``: the station database's URL (see :mod:`station.db`); None: the local SQLite file.
    """

    path: Path | None
    devices: tuple[DeviceEntry, ...]
    database: str | None = None


class _ConfigChecker(Checker):
    """The scenario format's typed field access, raising :class:`ConfigError` (file, field, expected value)."""

    def fail(self, path: str, message: str) -> ConfigError:
        return ConfigError(message, self.file, path)

    def choice(self, value: Any, path: str, choices: tuple[str, ...]) -> str:
        if not isinstance(value, str) or value not in choices:
            got = repr(value) if isinstance(value, str) else describe(value)
            raise self.fail(path, f"expected one of {', '.join(choices)}, got {got}")
        return value

    def required(self, table: dict, path: str, key: str, expected: str) -> Any:
        if key not in table:
            raise self.fail(join_path(path, key), f"missing; expected {expected}")
        return table[key]


def config_location() -> tuple[Path, bool]:
    """Where the config file is, and whether it was chosen (``CHAOS_STATION_CONFIG``) rather than the default
    ``station.toml`` in the data folder (a chosen file must exist; a missing default means the built-in one)."""
    chosen = os.environ.get(CONFIG_VARIABLE)
    if chosen:
        return Path(chosen).expanduser(), True
    return data_dir() / CONFIG_NAME, False


def load_config(path: str | Path | None = None) -> StationConfig:
    """The station's configuration from ``path``, else from :func:`config_location`.

    Raises
    ------
    ConfigError
        When the file is malformed (the message names the file, the field and the expected value), or when a file
        given (``path``, ``CHAOS_STATION_CONFIG``) does not exist.
    """
    if path is None:
        path, chosen = config_location()
        where = f"{CONFIG_VARIABLE}={str(path)!r}"
    else:
        path, chosen = Path(path), True
        where = repr(str(path))
    if not path.exists():
        if not chosen:
            return StationConfig(None, default_devices())
        raise ConfigError(f"station config {where}: no such file; expected a station.toml file")
    file = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as error:
        raise ConfigError(f"expected UTF-8 text ({error.reason} at byte {error.start})", file) from None
    except OSError as error:  # a folder, no permission
        raise ConfigError(f"cannot read: {error.strerror or error}", file) from None
    devices = devices_from_text(text, file, path.parent)
    return StationConfig(path, devices, database_from_text(text, file, path.parent))


def configured_devices() -> tuple[DeviceEntry, ...]:
    """The station's devices: from its config file, else every device simulated (see :func:`load_config`)."""
    return load_config().devices


def devices_from_text(text: str, file: str = "<text>", folder: Path | None = None) -> tuple[DeviceEntry, ...]:
    """The devices of a config file's TOML ``text``; relative profile paths are taken from ``folder`` (default the
    working folder). Raises :class:`ConfigError` as :func:`load_config`."""
    data = parse_toml(text.encode("utf-8"), file, "a station config ([[devices]] tables)",
                      error=lambda detail: ConfigError(detail, file))
    return devices_from_data(data, file, folder if folder is not None else Path.cwd())


def database_from_text(text: str, file: str = "<text>", folder: Path | None = None) -> str | None:
    """The ``[database]`` table's ``url`` (a relative SQLite path is taken from ``folder``), None without one.

    ``url`` is a PostgreSQL URL (``postgresql://USER:PASSWORD@HOST/DB``), ``sqlite:///PATH`` or a file path.
    """
    data = parse_toml(text.encode("utf-8"), file, "a station config ([[devices]] tables)",
                      error=lambda detail: ConfigError(detail, file))
    check = _ConfigChecker(file)
    top = check.table(data, "")
    if "database" not in top:
        return None
    table = check.table(top["database"], "database")
    check.only(table, "database", ("url",))
    if "url" not in table:  # an empty [database]: the local SQLite file, as without one
        return None
    expected = "a database URL (postgresql://USER:PASSWORD@HOST/DB, sqlite:///PATH or a file path)"
    url = check.string(check.required(table, "database", "url", expected), "database.url", what=expected).strip()
    try:
        dialect, target = parse_url(url)
    except StationError as error:
        raise check.fail("database.url", str(error)) from None
    if dialect == "sqlite" and not Path(target).is_absolute():
        return str((folder if folder is not None else Path.cwd()) / target)
    return url


def devices_from_data(data: Any, file: str, folder: Path) -> tuple[DeviceEntry, ...]:
    """The devices of parsed config ``data`` (see the module docstring for the format); the built-in default
    (:func:`station.devices.default_devices`) when it has no ``devices``."""
    check = _ConfigChecker(file)
    top = check.table(data, "")
    check.only(top, "", TOP_KEYS)
    if "devices" not in top:  # every section is optional: a file that sets only the database keeps the default
        return default_devices()
    expected = "[[devices]] tables (an array of tables)"
    listed = top["devices"]
    if isinstance(listed, dict):
        raise check.fail("devices", f"expected {expected}, got a table ([devices] or [devices.NAME])")
    if not isinstance(listed, list):
        raise check.fail("devices", f"expected {expected}, got {describe(listed)}")
    devices: list[DeviceEntry] = []
    for index, value in enumerate(listed):
        path = f"devices[{index}]"
        device = _device(check, value, path, folder)
        for other_index, other in enumerate(devices):
            if other.name == device.name:
                raise check.fail(f"{path}.name", f"expected a name no other device has, got {device.name!r} "
                                 f"(devices[{other_index}] has it)")
            if other.url == device.url and not device.simulated:
                raise check.fail(f"{path}.url", f"expected a port no other device uses, got {device.url!r} "
                                 f"(devices[{other_index}] uses it)")
        devices.append(device)
    lasers = [d.name for d in devices if d.kind == "laser"]
    for index, device in enumerate(devices):
        if device.options.get("laser") is not None and device.options["laser"] not in lasers:
            raise check.fail(f"devices[{index}].options.laser", f"expected the name of a laser in this file "
                             f"({', '.join(lasers) or 'none'}), got {device.options['laser']!r}")
    return tuple(devices)


def _device(check: _ConfigChecker, value: Any, path: str, folder: Path) -> DeviceEntry:
    """One ``[[devices]]`` table."""
    from drivers.devices import FORMS, UnknownDeviceURL, resolve

    table = check.table(value, path)
    check.only(table, path, DEVICE_KEYS)
    name = check.string(check.required(table, path, "name", NAME_EXPECTED), f"{path}.name", pattern=NAME,
                        what=NAME_EXPECTED)
    kind = check.choice(check.required(table, path, "kind", f"one of {', '.join(KINDS)}"), f"{path}.kind", KINDS)
    wanted = REGISTRY_KIND[kind]
    url = check.string(check.required(table, path, "url", f"a {kind} URL ({FORMS[wanted]})"), f"{path}.url",
                       what=f"a {kind} URL ({FORMS[wanted]})").strip()
    try:
        info = resolve(url)
    except UnknownDeviceURL as error:
        raise check.fail(f"{path}.url", str(error)) from None
    if info.kind != wanted:
        raise check.fail(f"{path}.url", f"expected a {kind} URL ({FORMS[wanted]}), got a {_KIND_WORDS[info.kind]} "
                         f"URL {url!r}")
    profile = ""
    if kind in GRBL_KINDS:
        profile = _simulated_profile(check, url, f"{path}.url", kind) if info.simulated else kind
        if "profile" in table:
            profile = _profile(check, table["profile"], f"{path}.profile", kind, folder)
    elif "profile" in table:
        raise check.fail(f"{path}.profile", f"expected no profile on a {kind} (profiles are for plotters and "
                         "lasers)")
    options = _options(check, table.get("options", {}), f"{path}.options", kind)
    return DeviceEntry(name, kind, url, info.simulated, profile, MappingProxyType(options))


def _simulated_profile(check: _ConfigChecker, url: str, path: str, kind: str) -> str:
    """The built-in profile a ``sim://grbl?profile=NAME`` URL simulates; the URL must name one, of the device's
    kind."""
    from drivers.profiles import builtin_profile, builtin_profile_names

    names = parse_qs(urlsplit(url).query).get("profile", [])
    of_kind = [n for n in builtin_profile_names() if builtin_profile(n).kind == kind]
    if not names:  # the twin's own default is a plotter: a laser on it would be simulated as one
        raise check.fail(path, f"expected a simulated {kind} ({' or '.join(f'sim://grbl?profile={n}' for n in of_kind)}"
                         f"), got {url!r}, which names no profile")
    if names[-1] not in of_kind:
        raise check.fail(path, f"expected a simulated {kind} (profile={' or profile='.join(of_kind)}), got "
                         f"profile={names[-1]}")
    return names[-1]


def _profile(check: _ConfigChecker, value: Any, path: str, kind: str, folder: Path) -> str:
    """A ``profile`` field: a built-in name as given, or a profile file's absolute path; it must load and be a
    profile of the device's kind."""
    from drivers.profiles import ProfileError, builtin_profile, builtin_profile_names, load_profile

    names = builtin_profile_names()
    expected = f"a built-in profile ({', '.join(names)}) or a profile file"
    text = check.string(value, path, what=expected)
    if text in names:
        source, loaded = text, builtin_profile(text)
    else:
        file = Path(text).expanduser()
        file = file if file.is_absolute() else folder / file
        if not file.is_file():
            raise check.fail(path, f"expected {expected}, got {text!r} (no such file: {file})")
        source = str(file.resolve())
        try:
            loaded = load_profile(source)
        except ProfileError as error:
            raise check.fail(path, str(error)) from None
    if loaded.kind != kind:
        raise check.fail(path, f"expected a {kind} profile, got a {loaded.kind} profile ({text!r})")
    return source


def _options(check: _ConfigChecker, value: Any, path: str, kind: str) -> dict[str, Any]:
    """A device's ``options`` table: GRBL machines take ``timeout``; a camera ``laser`` (the name of the laser whose
    bed it looks down on: ``station calibrate bed`` and the Machines screen's placement use it); projectors none."""
    table = check.table(value, path)
    if kind == "camera":
        check.only(table, path, ("laser",))
        if "laser" in table:
            return {"laser": check.string(table["laser"], f"{path}.laser", pattern=NAME, what=NAME_EXPECTED)}
        return {}
    if kind not in GRBL_KINDS:
        for key in table:
            raise check.fail(join_path(path, key), f"unknown option; a {kind} takes no options yet")
        return {}
    check.only(table, path, ("timeout",))
    options: dict[str, Any] = {}
    if "timeout" in table:
        timeout = check.number(table["timeout"], f"{path}.timeout", minimum=0.0, strict=True)
        if timeout > MAX_PROBE_TIMEOUT:
            raise check.fail(f"{path}.timeout", f"expected at most {MAX_PROBE_TIMEOUT:g} s, got {timeout:g}")
        options["timeout"] = timeout
    return options


def write_default_config(path: str | Path | None = None) -> Path:
    """Write :data:`DEFAULT_CONFIG_TEXT` to ``path`` (default :func:`config_location`) and return the path.

    Raises
    ------
    ConfigError
        When a file is already there: the station never writes over a config the user made.
    """
    target = Path(path) if path is not None else config_location()[0]
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        with open(target, "x", encoding="utf-8") as stream:
            stream.write(DEFAULT_CONFIG_TEXT)
    except FileExistsError:
        raise ConfigError(f"station config {str(target)!r} already exists; the station never writes over it "
                          "(edit it, or move it away first)") from None
    return target
