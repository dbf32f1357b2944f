"""Physical trials as data: the causal graph's outcome rules, the JSON export (a public contract) and the CSV export.

A trial is a plain dict in the export's form (:data:`FORMAT` version :data:`VERSION`)::

    {"id": 12, "uid": "3f2a...",                     # uuid4 hex: import refuses a trial it already has
     "scenario": {"name": "SIMPLE", "content_hash": "...", "content": "the scenario file's text"},
     "layout": {param: value}, "as_built": {param: value} | None, "check": CHECK.json | None,
     "physics": {"name": ..., "content": "profile TOML"} | None,
     "outcomes": {event: "yes" | "no" | "not-reached"},   # every event of the graph, in the graph's order
     "times": {event: seconds}, "success": bool, "who": str | None, "created_at": "2026-12-03T12:00:00.000Z",
     "notes": str | None, "photos": [paths]}

Outcomes follow the simulator's supervision (design/contraption/simulation.py): the root is always reached; an
event is reached when its parents happened (all of them, or one for ``join = "any"``), and only a reached event can
happen ("yes") or not ("no"); an unreached one is "not-reached". ``success`` is the goal: every leaf happened.
"""

from __future__ import annotations

import csv
import hashlib
import math
import re
import unicodedata
from collections.abc import Iterable, Mapping
from functools import lru_cache
from typing import Any, TextIO

from design.contraption.model import Scenario
from design.errors import DesignError
from station.errors import ServiceError

#: The export's ``format`` and ``version`` (CONTRACT20: h20fit's calibration reads it).
FORMAT, VERSION = "chaos-station trials", 1

YES, NO, NOT_REACHED = "yes", "no", "not-reached"
OUTCOMES = (YES, NO, NOT_REACHED)

#: A trial's fields, in the export's order.
FIELDS = ("id", "uid", "scenario", "layout", "as_built", "check", "physics", "outcomes", "times", "success", "who",
          "created_at", "notes", "photos")

_UID = re.compile(r"^[0-9a-f]{32}$")
_STAMP = re.compile(r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(\.\d+)?(Z|[+-]\d\d:\d\d)$")


def text_hash(text: str) -> str:
    """The sha256 of a text (the database stores each scenario text once under it)."""
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


# -- text a terminal or a spreadsheet would act on --------------------------------------------------------------------
#: Format characters that are harmless inside words: the zero-width (non-)joiners of emoji and of several scripts.
_JOINERS = frozenset("\u200c\u200d")


def hidden_character(char: str) -> bool:
    """Whether ``char`` changes how a terminal shows the text around it rather than showing itself: a control
    character (C0, DEL, C1: escape sequences, carriage returns), a format character (the bidirectional embeddings,
    overrides, isolates and marks, which can make a line read otherwise than it is stored; zero-width and tag
    characters), a line or paragraph separator."""
    return unicodedata.category(char) in ("Cc", "Cf", "Zl", "Zp", "Cs") and char not in _JOINERS


def show_text(text: str) -> str:
    """``text`` for a terminal: every :func:`hidden_character` shown as its escape (``\\u202e``, ``\\x1b``,
    ``\\n``), the rest as it is."""
    if not any(hidden_character(c) for c in text):
        return text
    return "".join(c.encode("unicode_escape").decode("ascii") if hidden_character(c) else c for c in text)


def check_text(value: Any, where: str, *, lines: bool = False) -> str | None:
    """A name or a note as a trial keeps it: text (None, or blank: None) without :func:`hidden_character`s
    (``lines``: new lines and tabs allowed, as in a note).

    Raises
    ------
    ServiceError
        ``field=where``: not text, or the first hidden character, escaped.
    """
    if value is None:
        return None
    if not isinstance(value, str):
        raise ServiceError(f"{where}: expected text, got {type(value).__name__} {str(value)[:40]!r}", field=where)
    allowed = "\n\t" if lines else ""
    for char in value:
        if hidden_character(char) and char not in allowed:
            escaped = char.encode("unicode_escape").decode("ascii")
            raise ServiceError(f"{where}: expected plain text{' (new lines and tabs allowed)' if lines else ''}, "
                               f"got a control or bidirectional character ({escaped}) in '{show_text(value)[:60]}'",
                               field=where)
    return value.strip() or None


# -- the causal graph's outcome rules --------------------------------------------------------------------------------
def _reached(scenario: Scenario, name: str, outcomes: Mapping[str, str]) -> bool | None:
    """Whether ``name``'s parents let it be reached: True, False, or None while a parent is unknown."""
    spec = scenario.event(name)
    if not spec.after:
        return True
    states = [outcomes.get(parent) for parent in spec.after]
    if spec.join == "all":
        if any(s in (NO, NOT_REACHED) for s in states):
            return False
        return True if all(s == YES for s in states) else None
    if any(s == YES for s in states):
        return True
    return False if all(s in (NO, NOT_REACHED) for s in states) else None


def _parents_words(scenario: Scenario, name: str, outcomes: Mapping[str, str]) -> str:
    spec = scenario.event(name)
    joined = ", ".join(f"{p} is {outcomes.get(p, 'not given')!r}" for p in spec.after)
    rule = "all of them" if spec.join == "all" else "one of them"
    return f"it waits for {', '.join(spec.after)} ({rule}); {joined}"


def complete_outcomes(scenario: Scenario, given: Mapping[str, str], *, field: str = "outcome") -> dict[str, str]:
    """Every event's outcome, in the graph's order, from those ``given``; implied ones filled in.

    Implied: an event whose parents did not let it be reached is "not-reached"; the parents that an event given
    "yes" or "no" needed to be reached (all of them under ``join = "all"``, the only one otherwise) are "yes". Any
    other event missing is refused: whether it happened is the maker's to say.

    Raises
    ------
    ServiceError
        ``field`` is set to the offending ``outcome.EVENT`` (or ``outcome``): an unknown event or outcome word, a
        "yes" or "no" for an event that cannot have been reached, "not-reached" for one that was, the root
        "not-reached", or an event missing that nothing implies (the first in the graph's order).
    """
    events = scenario.graph_order
    for name, word in given.items():
        if name not in events:
            raise ServiceError(f"{field}.{name}: unknown event; the scenario {scenario.name} has "
                               f"{', '.join(events)}", field=f"{field}.{name}")
        if word not in OUTCOMES:
            raise ServiceError(f"{field}.{name}: expected yes, no or not-reached, got {word!r}",
                               field=f"{field}.{name}")
    result, problems = resolve_outcomes(scenario, given, field=field)
    if problems:
        raise problems[0]
    return {name: word for name, word in result.items() if word is not None}


def resolve_outcomes(scenario: Scenario, given: Mapping[str, str], *,
                     field: str = "outcome") -> tuple[dict[str, str | None], list[ServiceError]]:
    """:func:`complete_outcomes` without raising, for a form being filled in (the Trials screen): every event's
    outcome in the graph's order (None: still to be said) and the problems, in the graph's order. ``given`` holds
    known events and outcome words only."""
    events = scenario.graph_order
    outcomes = dict(given)
    implied_by: dict[str, str] = {}  # an implied "yes" -> the given event that implied it (for messages)
    # A "yes" or "no" says the event was reached: the parents it needed happened (join "all"; an only parent).
    changed = True
    while changed:
        changed = False
        for name in events:
            if outcomes.get(name) not in (YES, NO):
                continue
            spec = scenario.event(name)
            needed = spec.after if spec.join == "all" or len(spec.after) == 1 else ()
            for parent in needed:
                if parent not in outcomes:
                    outcomes[parent] = YES
                    implied_by[parent] = implied_by.get(name, name)
                    changed = True
    result: dict[str, str | None] = {}
    problems: list[ServiceError] = []

    def problem(where: str, message: str) -> None:
        problems.append(ServiceError(f"{where}: {message}", field=where))

    for name in events:  # parents come first: each event's reachability is known when it is checked
        reached = _reached(scenario, name, result)
        word = outcomes.get(name)
        where = f"{field}.{name}"
        result[name] = word
        if word is None:
            if reached is False:
                result[name] = NOT_REACHED
            elif reached:
                why = "its parents happened" if scenario.event(name).after else "the root is always reached"
                problem(where, f"missing; {why}, so say whether it happened (yes or no)")
        elif word == NOT_REACHED and reached:
            if not scenario.event(name).after:
                problem(where, "the root event is always reached; expected yes or no, got 'not-reached'")
            else:
                problem(where, "expected yes or no, got 'not-reached', but it was reached: "
                        f"{_parents_words(scenario, name, result)}")
        elif word in (YES, NO) and reached is False:
            if name in implied_by:  # the maker gave a later event: name that one
                origin = implied_by[name]
                problem(f"{field}.{origin}", f"{given[origin]!r} means {name} happened before it, but "
                        f"{_parents_words(scenario, name, result)}")
            else:
                problem(where, f"expected 'not-reached', got {word!r}: an event can happen only after its "
                        f"parents; {_parents_words(scenario, name, result)}")
    return result, problems


def goal_reached(scenario: Scenario, outcomes: Mapping[str, str]) -> bool:
    """The goal: every leaf event happened (the simulator's global success)."""
    return all(outcomes.get(leaf) == YES for leaf in scenario.leaves())


def check_times(scenario: Scenario, times: Mapping[str, Any], outcomes: Mapping[str, str], *,
                field: str = "time") -> dict[str, float]:
    """Event times (seconds from the start), only for events that happened, in the graph's order; at most the
    scenario's ``[settings] max_duration`` (the simulator says an event later than that never happened)."""
    longest = float(scenario.settings.max_duration)
    for name, value in times.items():
        where = f"{field}.{name}"
        if name not in outcomes:
            raise ServiceError(f"{where}: unknown event; the scenario {scenario.name} has "
                               f"{', '.join(scenario.graph_order)}", field=where)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
            raise ServiceError(f"{where}: expected a number of seconds >= 0, got {value!r}", field=where)
        if value > longest:
            raise ServiceError(f"{where}: expected at most {longest:g} s, the scenario {scenario.name}'s duration "
                               f"([settings] max_duration), got {value:g}", field=where)
        if outcomes[name] != YES:
            raise ServiceError(f"{where}: a time is for an event that happened; its outcome is "
                               f"{outcomes[name]!r}", field=where)
    return {name: float(times[name]) for name in scenario.graph_order if name in times}


# -- reading an export --------------------------------------------------------------------------------------------
@lru_cache(maxsize=32)
def scenario_from_content(content: str, file: str = "<trial>") -> Scenario:
    """A scenario from its file's text (TOML, or JSON when it starts with ``{``), validated (raises
    :class:`design.errors.DesignError` naming ``file``)."""
    from design.contraption.validation import parse_text, scenario_from_data

    suffix = ".json" if content.lstrip().startswith("{") else ".toml"
    return scenario_from_data(parse_text(content.encode("utf-8"), file, suffix), file=file)


class _Reader:
    """Checks one export document; every refusal names the file and the field (``trials[3].outcomes.ball_rolls``)."""

    def __init__(self, file: str) -> None:
        self.file = file

    def fail(self, where: str, message: str) -> ServiceError:
        return ServiceError(f"{self.file}: {where}: {message}", field=where)

    def kind(self, value: Any, types: type | tuple[type, ...], where: str, expected: str,
             nullable: bool = False) -> Any:
        if value is None and nullable:
            return None
        if isinstance(value, bool) and bool not in (types if isinstance(types, tuple) else (types,)):
            raise self.fail(where, f"expected {expected}, got {value!r}")
        if not isinstance(value, types):
            raise self.fail(where, f"expected {expected}, got {type(value).__name__} {str(value)[:40]!r}")
        return value

    def text(self, value: Any, where: str, *, lines: bool = False) -> str | None:
        """A name or a note (text or null), as :func:`check_text` takes it from a maker."""
        self.kind(value, str, where, "text or null", nullable=True)
        try:
            return check_text(value, where, lines=lines)
        except ServiceError as error:
            raise self.fail(where, str(error).split(": ", 1)[1]) from None

    def values(self, value: Any, where: str, names: tuple[str, ...], *, nullable: bool = False) -> dict | None:
        table = self.kind(value, dict, where, "{parameter: number}", nullable)
        if table is None:
            return None
        if set(table) != set(names):
            missing, extra = sorted(set(names) - set(table)), sorted(set(table) - set(names))
            raise self.fail(where, f"expected the scenario's parameters ({', '.join(names)}); "
                            + (f"missing {', '.join(missing)}" if missing else f"unknown {', '.join(extra)}"))
        for name in names:
            number = table[name]
            if isinstance(number, bool) or not isinstance(number, (int, float)) or not math.isfinite(number):
                raise self.fail(f"{where}.{name}", f"expected a finite number, got {number!r}")
        return {name: float(table[name]) for name in names}

    def document(self, data: Any) -> list[dict]:
        top = self.kind(data, dict, "format", f'an object {{"format": "{FORMAT}", "version": {VERSION}, ...}}')
        if top.get("format") != FORMAT:
            raise self.fail("format", f"expected {FORMAT!r}, got {top.get('format')!r}")
        version = top.get("version")
        if version != VERSION or isinstance(version, bool):
            raise self.fail("version", f"expected {VERSION} (this station reads version {VERSION}), got {version!r}")
        items = self.kind(top.get("trials"), list, "trials", "a list of trials")
        trials = [self.trial(item, f"trials[{i}]") for i, item in enumerate(items)]
        seen: dict[str, int] = {}
        for i, trial in enumerate(trials):
            if trial["uid"] in seen:
                raise self.fail(f"trials[{i}].uid", f"the same as trials[{seen[trial['uid']]}].uid; each trial has "
                                "its own")
            seen[trial["uid"]] = i
        return trials

    def trial(self, item: Any, at: str) -> dict:
        item = self.kind(item, dict, at, "a trial object")
        unknown = sorted(set(item) - set(FIELDS))
        if unknown:
            raise self.fail(f"{at}.{unknown[0]}", f"unknown field; a trial has {', '.join(FIELDS)}")
        for name in FIELDS[1:]:
            if name not in item:
                raise self.fail(f"{at}.{name}", "missing")
        uid = self.kind(item["uid"], str, f"{at}.uid", "a uuid4 as 32 hex digits")
        if not _UID.match(uid):
            raise self.fail(f"{at}.uid", f"expected a uuid4 as 32 lower-case hex digits, got {uid!r}")
        head = self.kind(item["scenario"], dict, f"{at}.scenario", "{name, content_hash, content}")
        for key in ("name", "content_hash", "content"):
            self.kind(head.get(key), str, f"{at}.scenario.{key}", "text")
        try:
            scenario = scenario_from_content(head["content"], f"{at}.scenario.content")
        except DesignError as error:
            raise self.fail(f"{at}.scenario.content", f"not a valid scenario ({error})") from None
        if scenario.content_hash != head["content_hash"]:
            raise self.fail(f"{at}.scenario.content_hash", f"expected the content's hash {scenario.content_hash}, "
                            f"got {head['content_hash']!r}")
        names = tuple(scenario.design_space.names)
        layout = self.values(item["layout"], f"{at}.layout", names)
        as_built = self.values(item["as_built"], f"{at}.as_built", names, nullable=True)
        check = self.kind(item["check"], dict, f"{at}.check", "a CHECK.json object or null", nullable=True)
        physics = self.kind(item["physics"], dict, f"{at}.physics", "{name, content} or null", nullable=True)
        if physics is not None:
            for key in ("name", "content"):
                self.kind(physics.get(key), str, f"{at}.physics.{key}", "text")
            physics = {"name": physics["name"], "content": physics["content"]}
        outcomes = self.kind(item["outcomes"], dict, f"{at}.outcomes", "{event: yes | no | not-reached}")
        missing = [e for e in scenario.graph_order if e not in outcomes]
        if missing:
            raise self.fail(f"{at}.outcomes.{missing[0]}", "missing; a trial has every event's outcome")
        try:
            outcomes = complete_outcomes(scenario, outcomes, field=f"{at}.outcomes")
            times = check_times(scenario, self.kind(item["times"], dict, f"{at}.times", "{event: seconds}"),
                                outcomes, field=f"{at}.times")
        except ServiceError as error:
            raise self.fail(error.field, str(error).split(": ", 1)[1]) from None
        success = self.kind(item["success"], bool, f"{at}.success", "true or false")
        if success != goal_reached(scenario, outcomes):
            raise self.fail(f"{at}.success", f"expected {goal_reached(scenario, outcomes)} (the goal events "
                            f"{', '.join(scenario.leaves())} happened or not), got {success}")
        stamp = self.kind(item["created_at"], str, f"{at}.created_at", "an ISO 8601 UTC time")
        if not _STAMP.match(stamp):
            raise self.fail(f"{at}.created_at", f"expected an ISO 8601 time like 2026-12-03T12:00:00Z, got {stamp!r}")
        photos = self.kind(item["photos"], list, f"{at}.photos", "a list of paths")
        for i, photo in enumerate(photos):
            self.kind(photo, str, f"{at}.photos[{i}]", "a path")
        return {
            "uid": uid, "scenario": {"name": head["name"], "content_hash": head["content_hash"],
                                     "content": head["content"]},
            "layout": layout, "as_built": as_built, "check": check, "physics": physics, "outcomes": outcomes,
            "times": times, "success": success,
            "who": self.text(item["who"], f"{at}.who"),
            "created_at": stamp,
            "notes": self.text(item["notes"], f"{at}.notes", lines=True),
            "photos": list(photos),
        }


def read_export(data: Any, file: str = "<data>") -> list[dict]:
    """The trials of a parsed JSON export, checked (every one against its own scenario's causal graph), without
    their ``id`` (the importing database gives new ones).

    Raises
    ------
    ServiceError
        One line naming ``file`` and the field (``trials.json: version: expected 1 ..., got 2``).
    """
    return _Reader(file).document(data)


def export_document(trials: Iterable[Mapping[str, Any]]) -> dict[str, Any]:
    """The JSON export of ``trials`` (dicts as :meth:`station.triallog.TrialStore.trials` gives them)."""
    return {"format": FORMAT, "version": VERSION, "trials": [{k: t[k] for k in FIELDS} for t in trials]}


# -- CSV ----------------------------------------------------------------------------------------------------------
#: The CSV's fixed columns; then one column per event outcome (``outcome:EVENT``), event time (``time:EVENT``),
#: designed and as-built parameter (``layout:PARAM``, ``as_built:PARAM``), in order of first appearance.
CSV_COLUMNS = ("id", "uid", "created_at", "who", "scenario", "content_hash", "success", "physics", "checked",
               "notes", "photos")

#: What a spreadsheet reads as the start of a formula (OWASP, CSV injection): = + - @, a tab, a carriage return,
#: and their full-width forms, which some spreadsheets take as the same.
_FORMULA_STARTS = frozenset("=+-@\t\r\uff1d\uff0b\uff0d\uff20")
#: A plain decimal number (``-0.05``, ``1e-3``): a spreadsheet reads it as that number, never as a formula.
_PLAIN_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")


def spreadsheet_cell(value: Any) -> str:
    """``value`` as a CSV cell a spreadsheet shows and never runs: text whose first character (after spaces) could
    start a formula gets a leading ``'`` (OWASP's CSV-injection advice); a plain number, negative ones included, is
    left a number. :func:`write_csv` puts every cell in double quotes."""
    text = "" if value is None else str(value)
    head = text.lstrip(" ")[:1]
    if head and head in _FORMULA_STARTS and not _PLAIN_NUMBER.match(text):
        return "'" + text
    return text


def write_csv(trials: list[Mapping[str, Any]], stream: TextIO) -> None:
    """One row per trial, for a spreadsheet: trials of several scenarios share the columns of the events and
    parameters they have (empty elsewhere). Photos are joined with ``;``. Every cell goes through
    :func:`spreadsheet_cell` (a note ``=HYPERLINK(...)`` stays text). Not read back: import takes the JSON."""
    extra: dict[str, None] = {}
    for trial in trials:
        for prefix in ("outcome", "time"):
            source = trial["outcomes"] if prefix == "outcome" else trial["times"]
            extra.update({f"{prefix}:{name}": None for name in source})
        for prefix in ("layout", "as_built"):
            extra.update({f"{prefix}:{name}": None for name in trial[prefix] or {}})
    # every cell in double quotes (OWASP): a spreadsheet that splits on ';' (a locale's separator) keeps a note
    # "a;=1+1" one cell; a quoted number is still read as a number
    writer = csv.writer(stream, lineterminator="\n", quoting=csv.QUOTE_ALL)
    writer.writerow([spreadsheet_cell(column) for column in (*CSV_COLUMNS, *extra)])
    for trial in trials:
        row: dict[str, Any] = {
            "id": trial["id"], "uid": trial["uid"], "created_at": trial["created_at"], "who": trial["who"] or "",
            "scenario": trial["scenario"]["name"], "content_hash": trial["scenario"]["content_hash"],
            "success": "yes" if trial["success"] else "no",
            "physics": trial["physics"]["name"] if trial["physics"] else "",
            "checked": "yes" if trial["check"] else "no", "notes": trial["notes"] or "",
            "photos": ";".join(trial["photos"]),
        }
        row.update({f"outcome:{k}": v for k, v in trial["outcomes"].items()})
        row.update({f"time:{k}": repr(v) for k, v in trial["times"].items()})
        for prefix in ("layout", "as_built"):
            row.update({f"{prefix}:{k}": repr(v) for k, v in (trial[prefix] or {}).items()})
        writer.writerow([spreadsheet_cell(row.get(column, "")) for column in (*CSV_COLUMNS, *extra)])
