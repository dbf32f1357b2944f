"""Physical trials as a service: build a trial from what the maker says and log it, list, show, export, import.

Used by ``station trial ...`` and the Trials screen. The rules of a trial's outcomes (which events must be given,
which are implied) are :func:`station.trialformat.complete_outcomes`'s; the database is :mod:`station.triallog`.
Every refusal is a :class:`ServiceError` whose ``field`` names the input (``outcome.EVENT``, ``time.EVENT``,
``as_built``, ``physics``, ``photo``, ``file``...) and whose message starts with it.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Collection, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from common.datafiles import load_json, parse_toml
from design.contraption.catalog import resolve_scenario_path
from design.contraption.layout_io import layout_from_data
from design.contraption.model import Scenario
from design.errors import DesignError
from station.joblog import local_time
from station.services.errors import ServiceError
from station.trialformat import (
    OUTCOMES,
    YES,
    check_times,
    complete_outcomes,
    export_document,
    goal_reached,
    read_export,
    scenario_from_content,
    write_csv,
)
from station.triallog import TrialStore, new_uid, now_utc

#: CHECK.json (CONTRACT19), as the as-built check writes it.
CHECK_FORMAT, CHECK_VERSION = "chaos-station check", 1
#: A physics profile (CONTRACT20), as simulator calibration writes it.
PHYSICS_FORMAT, PHYSICS_VERSION = "chaos-station physics", 1

def open_store(url: str | None = None) -> TrialStore:
    """The station's trial log (:func:`station.db.database_url` unless ``url`` is given)."""
    return TrialStore(url)


def logged_trials(url: str | None = None) -> list[dict]:
    """Every trial in the station's trial log (the export format, oldest first): what ``station calibrate sim`` and
    the Calibrate screen's simulator panel fit to."""
    with open_store(url) as store:
        return store.trials()


def load_trial_scenario(text: str) -> Scenario:
    """A scenario by example name or path, read once: its text is what a trial stores, and the scenario is parsed
    from that same text (a file edited meanwhile cannot give a trial another scenario's hash)."""
    path = resolve_scenario_path(text)
    try:
        content = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise ServiceError(f"scenario: cannot read {str(path)!r} ({error})", field="scenario") from None
    return scenario_from_content(content, str(path))


def scenario_record(scenario: Scenario) -> dict[str, str]:
    """``{"name", "content_hash", "content"}`` of a scenario loaded by :func:`load_trial_scenario`."""
    content = Path(scenario.source).read_text(encoding="utf-8")
    if scenario_from_content(content, scenario.source).content_hash != scenario.content_hash:
        raise ServiceError(f"scenario: {scenario.source} changed since it was loaded; load it again",
                           field="scenario")
    return {"name": scenario.name, "content_hash": scenario.content_hash, "content": content}


def layout_values(scenario: Scenario, x: Sequence[float]) -> dict[str, float]:
    """A layout vector as ``{parameter: value}`` in design-space order."""
    return {name: float(value) for name, value in zip(scenario.design_space.names, x)}


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


def parse_outcomes(items: Iterable[str]) -> dict[str, str]:
    """``--outcome EVENT=yes|no|not-reached`` strings (the words checked later, against the graph)."""
    pairs = parse_pairs(items, "outcome", "|".join(OUTCOMES))
    for name, word in pairs.items():
        if word not in OUTCOMES:
            raise ServiceError(f"outcome.{name}: expected yes, no or not-reached, got {word!r}",
                               field=f"outcome.{name}")
    return pairs


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


def read_as_built(path: str | Path, scenario: Scenario, layout: Mapping[str, float]) -> tuple[dict, dict | None]:
    """``(as_built values, check or None)`` from a CHECK.json (of this scenario and this layout) or a layout file.

    Raises
    ------
    ServiceError
        ``field="as_built"``: not JSON, a check of another version, scenario (content hash) or layout (its
        ``layout`` values), an ``as_built`` table without every parameter, or a layout file that does not fit
        the scenario.
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
    if data.get("version") != CHECK_VERSION:
        raise fail(f"version: expected {CHECK_VERSION}, got {data.get('version')!r}")
    if data.get("content_hash") != scenario.content_hash:
        raise fail(f"content_hash: a check of another scenario ({data.get('scenario')!r}, "
                   f"{str(data.get('content_hash'))[:12]}...); this trial is of {scenario.name} "
                   f"({scenario.content_hash[:12]}...)")
    from calibration.check import as_built_values, same_layout_value

    checked = data.get("layout")
    if not isinstance(checked, dict):
        raise fail(f"layout: expected {{parameter: value}}, got {checked!r:.40}")
    for name, value in layout.items():
        other = checked.get(name)
        if isinstance(other, bool) or not isinstance(other, (int, float)) or not same_layout_value(other, value):
            raise fail(f"layout.{name}: a check of another layout ({other!r} checked, {value!r} in this trial's "
                       "layout)")
    extra = sorted(set(checked) - set(layout))
    if extra:
        raise fail(f"layout.{extra[0]}: not a parameter of {scenario.name}; a check of another layout")

    built = as_built_values(data, fail)
    values = {}
    for name in layout:
        if name not in built:
            raise fail(f"as_built.{name}: expected a number, got None")
        values[name] = built[name]
    return values, data


def check_values(check: Mapping[str, Any]) -> dict[str, float]:
    """A check's as-built layout for the trial log: its ``as_built``, the measured parameters as measured
    (:func:`calibration.check.as_built_values`)."""
    from calibration.check import as_built_values

    return as_built_values(check, lambda message: ServiceError(f"check: {message}", field="check"))


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


def check_photos(paths: Iterable[str | Path]) -> list[str]:
    """Photo paths, absolute; each must be a file."""
    result = []
    for path in paths:
        file = Path(path).expanduser()
        if not file.is_file():
            raise ServiceError(f"photo: {str(path)!r} is not a file", field="photo")
        result.append(str(file.resolve()))
    return result


def build_trial(scenario: Scenario, layout: Mapping[str, float], outcomes: Mapping[str, str], *,
                times: Mapping[str, float] | None = None, as_built: Mapping[str, float] | None = None,
                check: Mapping[str, Any] | None = None, physics: Mapping[str, str] | None = None,
                who: str | None = None, notes: str | None = None, photos: Sequence[str] = ()) -> dict[str, Any]:
    """A checked trial record (the export's form, without ``id``): every event's outcome (implied ones filled
    in, see :func:`complete_outcomes`), times only for events that happened, success from the goal."""
    full = complete_outcomes(scenario, outcomes)
    return {
        "uid": new_uid(), "scenario": scenario_record(scenario), "layout": dict(layout),
        "as_built": dict(as_built) if as_built is not None else None, "check": dict(check) if check else None,
        "physics": dict(physics) if physics else None, "outcomes": full,
        "times": check_times(scenario, dict(times or {}), full), "success": goal_reached(scenario, full),
        "who": (who or "").strip() or None, "created_at": now_utc(), "notes": (notes or "").strip() or None,
        "photos": list(photos),
    }


# -- export and import -------------------------------------------------------------------------------------------
def export_trials(store: TrialStore, path: str | Path, *, scenario: str | None = None,
                  ids: Collection[int] | None = None) -> int:
    """Write the log (or one scenario's trials, or those with the ``ids`` given) to ``path`` (``.json``: the
    contract's export; ``.csv``: one row per trial) and return how many. The file appears whole or not at all
    (written aside, then renamed)."""
    import json

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".json", ".csv"):
        raise ServiceError(f"out: {str(path)!r}: expected a .json or .csv file, got {suffix or 'no suffix'!r}",
                           field="out")
    trials = store.trials(scenario=scenario)
    if ids is not None:
        wanted = set(ids)
        trials = [t for t in trials if t["id"] in wanted]
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ServiceError(f"out: {str(path)!r}: the folder {str(folder)!r} does not exist", field="out")
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", dir=folder)
    try:
        with os.fdopen(handle, "w", encoding="utf-8", newline="") as stream:
            if suffix == ".json":
                json.dump(export_document(trials), stream, indent=1, allow_nan=False)
                stream.write("\n")
            else:
                write_csv(trials, stream)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return len(trials)


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
def happened_count(trial: Mapping[str, Any]) -> str:
    outcomes = trial["outcomes"]
    return f"{sum(v == YES for v in outcomes.values())}/{len(outcomes)} events"


def trial_line(trial: Mapping[str, Any]) -> str:
    """One line: ``#12  2026-12-03 13:05  SIMPLE  success  5/5 events  as built (check)  physics fit-1  ann``."""
    built = "as built (check)" if trial["check"] else ("as built" if trial["as_built"] else "as designed")
    parts = [f"#{trial['id']:<4} {local_time(trial['created_at'])}", trial["scenario"]["name"],
             "success" if trial["success"] else "failure", happened_count(trial), built]
    if trial["physics"]:
        parts.append(f"physics {trial['physics']['name']}")
    if trial["who"]:
        parts.append(trial["who"])
    return "  ".join(parts)


def describe_trial(trial: Mapping[str, Any]) -> list[str]:
    """Lines for ``station trial show``: the summary, every event's outcome in the graph's order, the layouts."""
    lines = [trial_line(trial), f"  uid {trial['uid']}, scenario hash {trial['scenario']['content_hash'][:16]}..."]
    width = max((len(e) for e in trial["outcomes"]), default=0)
    for event, outcome in trial["outcomes"].items():
        at = f"  at {trial['times'][event]:.3f} s" if event in trial["times"] else ""
        lines.append(f"  {event:<{width}}  {outcome}{at}")
    as_built = trial["as_built"] or {}
    for name, value in trial["layout"].items():
        built = f"  as built {as_built[name]:.6g} ({as_built[name] - value:+.3g})" if name in as_built else ""
        lines.append(f"  {name} = {value:.6g}{built}")
    if trial["notes"]:
        lines.append(f"  notes: {trial['notes']}")
    lines.extend(f"  photo: {photo}" for photo in trial["photos"])
    return lines
