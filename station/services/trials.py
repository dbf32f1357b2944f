"""Physical trials as a service: build a trial from what the maker says and log it, list, show, export, import.

Used by ``station trial ...`` and the Trials screen. The rules of a trial's outcomes (which events must be given,
which are implied) are :func:`station.trialformat.complete_outcomes`'s; the database is :mod:`station.triallog`.
Every refusal is a :class:`ServiceError` whose ``field`` names the input (``outcome.EVENT``, ``time.EVENT``,
``as_built``, ``physics``, ``photo``, ``file``...) and whose message starts with it.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Callable, Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from common.datafiles import load_json, parse_toml
from design.contraption.catalog import resolve_scenario_path
from design.contraption.layout_io import layout_from_data, resolve_layout
from design.contraption.model import Scenario
from design.errors import DesignError
from station.errors import ServiceError, StationError, station_errors
from station.joblog import local_time
from station.paths import data_dir
from station.trialformat import (
    FORMAT,
    OUTCOMES,
    VERSION,
    YES,
    check_text,
    check_times,
    complete_outcomes,
    export_document,
    goal_reached,
    read_export,
    scenario_from_content,
    show_text,
    write_csv,
)
from station.triallog import TrialStore, new_uid, now_utc

#: CHECK.json (CONTRACT19), as the as-built check writes it.
CHECK_FORMAT, CHECK_VERSION = "chaos-station check", 1
#: A physics profile (CONTRACT20), as simulator calibration writes it.
PHYSICS_FORMAT, PHYSICS_VERSION = "chaos-station physics", 1

@station_errors
def open_store(url: str | None = None) -> TrialStore:
    """The station's trial log (:func:`station.db.database_url` unless ``url`` is given)."""
    return TrialStore(url)


@station_errors
def logged_trials(url: str | None = None) -> list[dict]:
    """Every trial in the station's trial log (the export format, oldest first): what ``station calibrate sim`` and
    the Calibrate screen's simulator panel fit to."""
    with open_store(url) as store:
        return store.trials()


@station_errors
def load_trial_scenario(text: str) -> Scenario:
    """A scenario by example name or path, read once: its text is what a trial stores, and the scenario is parsed
    from that same text (a file edited meanwhile cannot give a trial another scenario's hash)."""
    path = resolve_scenario_path(text)
    try:
        content = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise ServiceError(f"scenario: cannot read {str(path)!r} ({error})", field="scenario") from None
    return scenario_from_content(content, str(path))


@station_errors
def scenario_record(scenario: Scenario) -> dict[str, str]:
    """``{"name", "content_hash", "content"}`` of a scenario loaded by :func:`load_trial_scenario`."""
    content = Path(scenario.source).read_text(encoding="utf-8")
    if scenario_from_content(content, scenario.source).content_hash != scenario.content_hash:
        raise ServiceError(f"scenario: {scenario.source} changed since it was loaded; load it again",
                           field="scenario")
    return {"name": scenario.name, "content_hash": scenario.content_hash, "content": content}


@station_errors
def layout_values(scenario: Scenario, x: Sequence[float]) -> dict[str, float]:
    """A layout vector as ``{parameter: value}`` in design-space order."""
    return {name: float(value) for name, value in zip(scenario.design_space.names, x)}


@station_errors
def read_layout_values(scenario: Scenario, layout: str | None) -> dict[str, float]:
    """The layout ``layout`` names (a LAYOUT.json, or a layout named in the scenario; None or "": the scenario's own
    transforms) as ``{parameter: value}``."""
    x = resolve_layout(layout, scenario).x if layout else scenario.default_layout()
    return layout_values(scenario, x)


@station_errors
def parse_pairs(items: Iterable[str], field: str, expected: str) -> dict[str, str]:
    """``EVENT=VALUE`` strings as a dict; a missing ``=`` or an event given twice is refused naming ``field``."""
    pairs: dict[str, str] = {}
    for item in items:
        name, sep, value = item.partition("=")
        name, value = name.strip(), value.strip()
        if not sep or not name:
            raise ServiceError(f"{field}: expected EVENT={expected}, got {item!r}", field=field)
        if name in pairs:
            raise ServiceError(f"{field}.{name}: given twice", field=f"{field}.{name}")
        pairs[name] = value
    return pairs


@station_errors
def parse_outcomes(items: Iterable[str]) -> dict[str, str]:
    """``--outcome EVENT=yes|no|not-reached`` strings (the words checked later, against the graph)."""
    pairs = parse_pairs(items, "outcome", "|".join(OUTCOMES))
    for name, word in pairs.items():
        if word not in OUTCOMES:
            raise ServiceError(f"outcome.{name}: expected yes, no or not-reached, got {word!r}",
                               field=f"outcome.{name}")
    return pairs


@station_errors
def parse_times(items: Iterable[str]) -> dict[str, float]:
    """``--time EVENT=SECONDS`` strings."""
    times: dict[str, float] = {}
    for name, text in parse_pairs(items, "time", "SECONDS").items():
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or value < 0:
            raise ServiceError(f"time.{name}: expected a number of seconds >= 0, got {text!r}", field=f"time.{name}")
        times[name] = value
    return times


@station_errors
def read_as_built(path: str | Path, scenario: Scenario, layout: Mapping[str, float]) -> tuple[dict, dict | None]:
    """``(as_built values, check or None)`` from a CHECK.json (of this scenario and this layout, checked by
    :func:`read_check`) or a layout file.

    Raises
    ------
    ServiceError
        ``field="as_built"``: not JSON, a layout file that does not fit the scenario, or a check :func:`read_check`
        refuses (``as_built: FILE: FIELD: ...``).
    """
    file = str(path)

    def fail(message: str) -> ServiceError:
        return ServiceError(f"as_built: {file}: {message}", field="as_built")

    try:
        data = load_json(path, "CHECK.json (`station check`) or a layout file", error=lambda m: fail(m))
    except OSError as error:
        raise fail(f"cannot read ({error.strerror or error})") from None
    if not (isinstance(data, dict) and data.get("format") == CHECK_FORMAT):
        try:
            loaded = layout_from_data(data, scenario, file=file)
        except DesignError as error:
            raise ServiceError(f"as_built: {error}", field="as_built") from None
        return layout_values(scenario, loaded.x), None
    return read_check(data, scenario, layout, fail).values, data


@dataclass(frozen=True)
class CheckedBuild:
    """What a CHECK.json says of the layout as built (:func:`read_check`).

    Attributes
    ----------
    values : dict
        ``{parameter: value}``, every design parameter: the measured ones as measured, the others as designed.
    position_sigma_m, angle_sigma_deg : float
        The placement error of the measured parameters (its ``residual_error``; 1 mm / 1 degree without one).
    not_measured : tuple of str
        The design parameters the check did not measure.
    """

    values: dict[str, float]
    position_sigma_m: float
    angle_sigma_deg: float
    not_measured: tuple[str, ...]


#: CHECK.json's ``residual_error``: the measurement's own error, in mm and degrees.
RESIDUAL_FIELDS = ("position_mm", "heading_deg")
#: A checked part of CHECK.json's ``parts`` (``station check --json``): each field and what it holds.
_PART_FIELDS = {"name": "text", "tag_id": "a tag id (a whole number)", "found": "true or false",
                "measured": "{center_mm: [u, v], heading_deg} or null",
                "error": "{du_mm, dv_mm, distance_mm, heading_deg} or null",
                "within_tolerance": "true, false or null", "instruction": "text", "cost": "a number or null"}


@station_errors
def read_check(data: Any, scenario: Scenario, layout: Mapping[str, float],
               fail: Callable[[str], Exception]) -> CheckedBuild:
    """The as-built layout a CHECK.json's content (``data``) says, after checking every field the trial log and the
    predictions use: its format and version; that it is a check of ``scenario`` (its name, and its content hash
    when it gives one) and of ``layout`` (every parameter, compared as the check rounded it:
    :func:`calibration.check.same_layout_value`); ``as_built`` and ``as_measured`` (numbers, every design
    parameter, no other); ``not_measured``; ``residual_error`` (``position_mm`` and ``heading_deg`` >= 0);
    ``parts`` (the checked parts).

    ``fail(message)`` makes the error raised; ``message`` starts with the field (``residual_error: expected ...``).
    """
    from calibration.check import as_built_values, not_measured_names, same_layout_value  # heavy: scipy, shapely
    from calibration.sim_runs import residual_sigma  # heavy: pybullet, scipy

    if not isinstance(data, dict) or data.get("format") != CHECK_FORMAT:
        got = data.get("format") if isinstance(data, dict) else type(data).__name__
        raise fail(f"format: expected {CHECK_FORMAT!r} (the CHECK.json of `station check --out`), got {got!r}")
    version = data.get("version")
    if isinstance(version, bool) or version != CHECK_VERSION:
        raise fail(f"version: expected {CHECK_VERSION}, got {version!r}")
    if data.get("scenario") != scenario.name:
        raise fail(f"scenario: a check of scenario {data.get('scenario')!r}, not of {scenario.name!r}")
    if "content_hash" in data and data["content_hash"] != scenario.content_hash:
        raise fail(f"content_hash: a check of another scenario ({data.get('scenario')!r}, "
                   f"{str(data.get('content_hash'))[:12]}...); this is {scenario.name} "
                   f"({scenario.content_hash[:12]}...)")
    names = tuple(scenario.design_space.names)
    checked = data.get("layout")
    if not isinstance(checked, dict):
        raise fail(f"layout: expected {{parameter: value}}, got {checked!r:.40}")
    for name, value in layout.items():
        other = checked.get(name)
        if isinstance(other, bool) or not isinstance(other, (int, float)) or not same_layout_value(other, value):
            raise fail(f"layout.{name}: a check of another layout ({other!r} checked, {value!r} designed)")
    extra = sorted(set(checked) - set(layout))
    if extra:
        raise fail(f"layout.{extra[0]}: not a parameter of {scenario.name}; a check of another layout")
    built = as_built_values(data, fail)
    for table in ("as_built", "as_measured"):
        for name in data.get(table) or {}:
            if name not in names:
                raise fail(f"{table}.{name}: not a design parameter of {scenario.name} (expected one of "
                           f"{', '.join(names)})")
    missing = [name for name in names if name not in built]
    if missing:
        raise fail(f"as_built.{missing[0]}: expected a number, got None")
    unmeasured = not_measured_names(data, names, fail)
    _check_residual(data, fail)
    _check_parts(data, fail)
    position, angle = residual_sigma(data)
    return CheckedBuild({name: built[name] for name in names}, position, angle, unmeasured)


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _check_residual(data: Mapping[str, Any], fail: Callable[[str], Exception]) -> None:
    """``residual_error``: absent, or ``{"position_mm": mm, "heading_deg": degrees}``, both >= 0."""
    if "residual_error" not in data:
        return
    residual = data["residual_error"]
    expected = "{" + ", ".join(f'"{k}": a number >= 0' for k in RESIDUAL_FIELDS) + "}"
    if not isinstance(residual, dict):
        raise fail(f"residual_error: expected {expected}, got {residual!r:.40}")
    for key in residual:
        if key not in RESIDUAL_FIELDS:
            raise fail(f"residual_error.{key}: unknown field; expected {', '.join(RESIDUAL_FIELDS)}")
    for key in RESIDUAL_FIELDS:
        value = residual.get(key)
        if not _number(value) or value < 0:
            raise fail(f"residual_error.{key}: expected a number >= 0, got {value!r}")


def _check_parts(data: Mapping[str, Any], fail: Callable[[str], Exception]) -> None:
    """``parts``: absent, or a list of checked parts (``station check --json``'s form)."""
    if "parts" not in data:
        return
    parts = data["parts"]
    if not isinstance(parts, list):
        raise fail(f"parts: expected a list of checked parts ({{{', '.join(_PART_FIELDS)}}}), got {parts!r:.40}")
    for i, part in enumerate(parts):
        where = f"parts[{i}]"
        if not isinstance(part, dict):
            raise fail(f"{where}: expected a checked part ({{{', '.join(_PART_FIELDS)}}}), got {part!r:.40}")
        for key, expected in _PART_FIELDS.items():
            if key not in part:
                raise fail(f"{where}.{key}: missing; expected {expected}")
            if not _part_value(key, part[key]):
                raise fail(f"{where}.{key}: expected {expected}, got {part[key]!r:.40}")


def _part_value(key: str, value: Any) -> bool:
    """Whether ``value`` is what a checked part's ``key`` holds."""
    if key in ("name", "instruction"):
        return isinstance(value, str)
    if key == "tag_id":
        return isinstance(value, int) and not isinstance(value, bool)
    if key == "found":
        return isinstance(value, bool)
    if key == "within_tolerance":
        return value is None or isinstance(value, bool)
    if key == "cost":
        return value is None or _number(value)
    if value is None:
        return True
    if not isinstance(value, dict):
        return False
    if key == "measured":
        center = value.get("center_mm")
        return (isinstance(center, list) and len(center) == 2 and all(map(_number, center))
                and _number(value.get("heading_deg")))
    return all(_number(value.get(k)) for k in ("du_mm", "dv_mm", "distance_mm", "heading_deg"))


@station_errors
def check_values(check: Mapping[str, Any]) -> dict[str, float]:
    """A check's as-built layout for the trial log: its ``as_built``, the measured parameters as measured
    (:func:`calibration.check.as_built_values`)."""
    from calibration.check import as_built_values  # heavy: scipy, shapely

    return as_built_values(check, lambda message: ServiceError(f"check: {message}", field="check"))


@station_errors
def read_physics(path: str | Path) -> dict[str, str]:
    """``{"name", "content"}`` of a physics profile (TOML: ``[profile]`` with format, version and name)."""
    file = str(path)

    def fail(message: str) -> ServiceError:
        return ServiceError(f"physics: {file}: {message}", field="physics")

    try:
        raw = Path(path).read_bytes()
    except OSError as error:
        raise fail(f"cannot read ({error.strerror or error})") from None
    data = parse_toml(raw, file, "a physics profile (TOML)", error=lambda m: fail(m))
    profile = data.get("profile")
    if not isinstance(profile, dict):
        raise fail("profile: missing; expected a [profile] table (format, version, name)")
    if profile.get("format") != PHYSICS_FORMAT:
        raise fail(f"profile.format: expected {PHYSICS_FORMAT!r}, got {profile.get('format')!r}")
    if profile.get("version") != PHYSICS_VERSION:
        raise fail(f"profile.version: expected {PHYSICS_VERSION}, got {profile.get('version')!r}")
    name = profile.get("name")
    if not isinstance(name, str) or not name.strip():
        raise fail(f"profile.name: expected a name, got {name!r}")
    return {"name": name.strip(), "content": raw.decode("utf-8")}


@station_errors
def check_photos(paths: Iterable[str | Path]) -> list[str]:
    """Photo paths, absolute; each must be a file."""
    result = []
    for path in paths:
        file = Path(path).expanduser()
        if not file.is_file():
            raise ServiceError(f"photo: {str(path)!r} is not a file", field="photo")
        result.append(str(file.resolve()))
    return result


@station_errors
def build_trial(scenario: Scenario, layout: Mapping[str, float], outcomes: Mapping[str, str], *,
                times: Mapping[str, float] | None = None, as_built: Mapping[str, float] | None = None,
                check: Mapping[str, Any] | None = None, physics: Mapping[str, str] | None = None,
                who: str | None = None, notes: str | None = None, photos: Sequence[str] = ()) -> dict[str, Any]:
    """A checked trial record (the export's form, without ``id``): every event's outcome (implied ones filled
    in, see :func:`complete_outcomes`), times only for events that happened (at most the scenario's duration),
    success from the goal; ``who`` and ``notes`` plain text (:func:`station.trialformat.check_text`: no control or
    bidirectional characters; a note may have new lines and tabs)."""
    who, notes = check_text(who, "who"), check_text(notes, "notes", lines=True)
    full = complete_outcomes(scenario, outcomes)
    return {
        "uid": new_uid(), "scenario": scenario_record(scenario), "layout": dict(layout),
        "as_built": dict(as_built) if as_built is not None else None, "check": dict(check) if check else None,
        "physics": dict(physics) if physics else None, "outcomes": full,
        "times": check_times(scenario, dict(times or {}), full), "success": goal_reached(scenario, full),
        "who": who, "created_at": now_utc(), "notes": notes,
        "photos": list(photos),
    }


# -- logging, losing nothing ---------------------------------------------------------------------------------------
#: The folder of the data folder where a trial the database could not take is kept until it is logged.
PENDING_FOLDER = "pending-trials"


@station_errors
class TrialKept(ServiceError):
    """The database could not take the trial (still busy, unreachable, interrupted); it is kept in :attr:`path`, a
    trial export of that one trial, which the next :func:`log_trial` to the same database logs first (as ``station
    trial import PATH`` does). When even that file could not be written, :attr:`path` is None and
    :attr:`document` is what the file would have held, for the command to print."""

    def __init__(self, message: str, path: Path | None, document: dict[str, Any], *,
                 interrupted: bool = False) -> None:
        super().__init__(message, field="database")
        self.path, self.document, self.interrupted = path, document, interrupted


@dataclass(frozen=True)
class LoggedTrial:
    """A logged trial's id, and the kept trials logged just before it (:func:`log_trial`)."""

    id: int
    #: the ids of trials kept by earlier runs, logged now
    delivered: tuple[int, ...] = ()
    #: kept files that could not be logged (each a line saying why; the file stays where it is)
    problems: tuple[str, ...] = ()


@station_errors
def pending_folder() -> Path:
    """Where kept trials wait (:data:`PENDING_FOLDER` in the data folder)."""
    return data_dir() / PENDING_FOLDER


@station_errors
def pending_files() -> list[Path]:
    """The kept trials' files, oldest first."""
    folder = pending_folder()
    if not folder.is_dir():
        return []
    files = []
    for file in folder.glob("trial-*.json"):
        try:
            files.append((file.stat().st_mtime, file.name, file))
        except OSError:  # logged and removed by another process meanwhile
            continue
    return [file for _, _, file in sorted(files)]


@station_errors
def log_trial(record: Mapping[str, Any], *, url: str | None = None,
              on_wait: Callable[[str], None] | None = None) -> LoggedTrial:
    """Log a trial made by :func:`build_trial` in the station's database (``url``: another one), after the trials
    earlier runs kept (:func:`pending_files`) for the same database.

    The write is tried again while another process keeps the database busy (``on_wait``: see
    :meth:`station.db.Database.write`). What the maker said is never lost: when the database cannot take it (still
    busy, unreachable, a bad ``[database]`` setting, Ctrl-C while waiting) the trial is kept in a file and
    :class:`TrialKept` says where.
    """
    where = None
    try:
        with open_store(url) as store:
            where = store.where
            delivered, problems = deliver_pending(store, on_wait=on_wait)
            trial_id = store.add(record, on_wait=on_wait)
    except ServiceError:
        raise
    except StationError as error:  # station.db.DatabaseError, or a bad [database] setting
        raise _kept(record, getattr(error, "where", None) or where, str(error)) from None
    except KeyboardInterrupt:
        raise _kept(record, where, "interrupted before the trial was logged", interrupted=True) from None
    return LoggedTrial(trial_id, tuple(delivered), tuple(problems))


def _kept(record: Mapping[str, Any], where: str | None, why: str, *, interrupted: bool = False) -> TrialKept:
    """Keep ``record`` in :func:`pending_folder` and say so, after ``why``, in one line."""
    document = {"format": FORMAT, "version": VERSION, "database": where, "trials": [dict(record)]}
    try:
        path = pending_folder() / f"trial-{record['uid']}.json"
        try:
            path.parent.mkdir(exist_ok=True)
        except OSError as error:
            raise ServiceError(f"pending: {str(path.parent)!r}: cannot make the folder ({error.strerror or error})",
                               field="pending") from None
        text = json.dumps(document, indent=1, allow_nan=False) + "\n"
        write_atomically(path, lambda stream: stream.write(text), field="pending")
    except StationError as error:
        return TrialKept(f"{why}; the trial could not be kept in a file either ({error}): it is printed as JSON on "
                         "stdout, save it and log it with `station trial import FILE`", None, document,
                         interrupted=interrupted)
    return TrialKept(f"{why}; the trial is kept in {path}: the next `station trial log` logs it first (or "
                     f"`station trial import {path}`)", path, document, interrupted=interrupted)


@station_errors
def deliver_pending(store: TrialStore, *, on_wait: Callable[[str], None] | None = None
                    ) -> tuple[list[int], list[str]]:
    """Log the kept trials (:func:`pending_files`) meant for ``store``'s database and remove their files:
    ``(new ids, problems)``. A trial already in the log (its uid) is not added twice; a file that cannot be read
    is left where it is, with a line in ``problems``.

    Raises
    ------
    station.db.DatabaseError
        The database failed (the files stay).
    """
    added: list[int] = []
    problems: list[str] = []
    for file in pending_files():
        try:
            data = load_json(file, "a kept trial (a trial export)",
                             error=lambda m, file=file: ServiceError(f"{file}: {m}", field="file"))
            if isinstance(data, dict) and data.get("database") not in (None, store.where):
                continue  # kept for another database: `station trial import` takes it there
            records = read_export(data, str(file))
        except FileNotFoundError:
            continue  # logged by another process meanwhile
        except (ServiceError, OSError) as error:
            problems.append(f"kept trial {file} not logged: {error}")
            continue
        ids, _ = store.import_trials(records, on_wait=on_wait)
        added.extend(ids)
        file.unlink(missing_ok=True)
    return added, problems


# -- export and import -------------------------------------------------------------------------------------------
@station_errors
def export_trials(store: TrialStore, path: str | Path, *, scenario: str | None = None,
                  ids: Collection[int] | None = None) -> int:
    """Write the log (or one scenario's trials, or those with the ``ids`` given) to ``path`` (``.json``: the
    contract's export; ``.csv``: one row per trial) and return how many. The file appears whole or not at all
    (written aside, then renamed)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".json", ".csv"):
        raise ServiceError(f"out: {str(path)!r}: expected a .json or .csv file, got {suffix or 'no suffix'!r}",
                           field="out")
    trials = store.trials(scenario=scenario)
    if ids is not None:
        wanted = set(ids)
        trials = [t for t in trials if t["id"] in wanted]

    def write(stream: TextIO) -> None:
        if suffix == ".json":
            json.dump(export_document(trials), stream, indent=1, allow_nan=False)
            stream.write("\n")
        else:
            write_csv(trials, stream)

    write_atomically(path, write, field="out")
    return len(trials)


@station_errors
def export_logged(path: str | Path, *, ids: Collection[int] | None = None, url: str | None = None) -> int:
    """:func:`export_trials` from the station's trial log (``url``: another database); how many were written."""
    with open_store(url) as store:
        return export_trials(store, path, ids=ids)


@station_errors
def write_atomically(path: str | Path, write: Callable[[TextIO], None], *, field: str = "out") -> None:
    """A text file (UTF-8) whole or not at all: ``write(stream)`` writes it aside, in a hidden file of the same
    folder, which then replaces ``path`` in one rename.

    Raises
    ------
    ServiceError
        ``field=field``: the path is a folder, its folder does not exist, or the file cannot be created or written
        there. The message names ``field`` and ``path`` as given, never the file written aside.
    """
    path = Path(path)

    def fail(reason: str) -> ServiceError:
        return ServiceError(f"{field}: {str(path)!r}: {reason}", field=field)

    if path.is_dir():
        raise fail("is a folder; expected a file to write")
    folder = path.parent
    if not folder.is_dir():
        raise fail(f"the folder {str(folder)!r} does not exist")
    try:
        handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", dir=folder)
    except OSError as error:
        raise fail(f"cannot create a file in {str(folder)!r} ({error.strerror or error})") from None
    try:
        with os.fdopen(handle, "w", encoding="utf-8", newline="") as stream:
            write(stream)
        os.replace(temporary, path)
    except OSError as error:
        Path(temporary).unlink(missing_ok=True)
        raise fail(f"cannot write it ({error.strerror or error})") from None
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


@station_errors
def import_trials(store: TrialStore, path: str | Path) -> tuple[list[int], list[str]]:
    """Add the trials of a JSON export: ``(new ids, uids refused as already in the log)``. The whole file is
    checked first (format, version, every trial against its scenario's graph): a bad one adds nothing."""
    file = str(path)

    def fail(message: str) -> ServiceError:
        return ServiceError(f"{file}: {message}", field="file")

    try:
        data = load_json(path, "a trial export ({\"format\": \"chaos-station trials\", ...})",
                         error=lambda m: fail(m))
    except OSError as error:
        raise fail(f"cannot read ({error.strerror or error})") from None
    return store.import_trials(read_export(data, file))


# -- words -------------------------------------------------------------------------------------------------------
@station_errors
def happened_count(trial: Mapping[str, Any]) -> str:
    outcomes = trial["outcomes"]
    return f"{sum(v == YES for v in outcomes.values())}/{len(outcomes)} events"


@station_errors
def trial_line(trial: Mapping[str, Any]) -> str:
    """One line: ``#12  2026-12-03 13:05  SIMPLE  success  5/5 events  as built (check)  physics fit-1  ann``."""
    built = "as built (check)" if trial["check"] else ("as built" if trial["as_built"] else "as designed")
    parts = [f"#{trial['id']:<4} {local_time(trial['created_at'])}", show_text(trial["scenario"]["name"]),
             "success" if trial["success"] else "failure", happened_count(trial), built]
    if trial["physics"]:
        parts.append(f"physics {show_text(trial['physics']['name'])}")
    if trial["who"]:
        parts.append(show_text(trial["who"]))
    return "  ".join(parts)


@station_errors
def describe_trial(trial: Mapping[str, Any]) -> list[str]:
    """Lines for ``station trial show``: the summary, every event's outcome in the graph's order, the layouts.
    Text from the log is shown with its control and bidirectional characters escaped
    (:func:`station.trialformat.show_text`): a note's new line reads ``\\n``, on the note's one line."""
    lines = [trial_line(trial), f"  uid {show_text(trial['uid'])}, scenario hash "
             f"{show_text(trial['scenario']['content_hash'][:16])}..."]
    width = max((len(show_text(e)) for e in trial["outcomes"]), default=0)
    for event, outcome in trial["outcomes"].items():
        at = f"  at {trial['times'][event]:.3f} s" if event in trial["times"] else ""
        lines.append(f"  {show_text(event):<{width}}  {outcome}{at}")
    as_built = trial["as_built"] or {}
    for name, value in trial["layout"].items():
        built = f"  as built {as_built[name]:.6g} ({as_built[name] - value:+.3g})" if name in as_built else ""
        lines.append(f"  {show_text(name)} = {value:.6g}{built}")
    if trial["notes"]:
        lines.append(f"  notes: {show_text(trial['notes'])}")
    lines.extend(f"  photo: {show_text(photo)}" for photo in trial["photos"])
    return lines
