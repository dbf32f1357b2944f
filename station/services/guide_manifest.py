"""Reading a guide's manifest (what ``station guide --json`` prints): the one reader of the check and the plane fix.

``station check --guide``, ``station calibrate plane --guide`` and the screens that do the same read a manifest
here, so that a bad one is refused the same way by all of them, before any work, in one line naming the file, the
field and what was expected::

    guide G.json: field 'parts[0].center_mm': expected [u, v], two finite numbers of mm within ±10000, got [NaN, 0]

Every number the station uses is checked to be finite and in a range a guide on a table can have: a value of
``1e308`` mm passes every comparison and turns into infinities and NaN deep in the measurement.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from common.datafiles import load_json
from station.errors import ServiceError, station_errors

__all__ = ["MANIFEST", "MAX_COORDINATE_MM", "MAX_TAG_MM", "read_manifest", "reference_tags"]

#: What a manifest is, the end of the messages.
MANIFEST = "a guide manifest: what `station guide --json` prints"
#: Positions and heights on the guide's plane, in mm: a guide lies on a table, within metres of its origin.
MAX_COORDINATE_MM = 10_000.0
#: The largest tag side, in mm (the station prints 15-60 mm tags).
MAX_TAG_MM = 1_000.0

_REFERENCE = '{"id": int, "center_mm": [u, v], "size_mm": number}'


@station_errors
def read_manifest(path: str | Path, *, parts: bool = True) -> dict:
    """The manifest in the file ``path``, its reference tags and parts checked (``parts``: a parts list is required,
    as the check needs; the plane fix needs only the reference tags).

    Raises
    ------
    ServiceError
        ``field="guide"``: the file is missing or unreadable, not JSON (NaN included), or a field the station reads
        is missing or out of range.
    """
    path = Path(path)
    try:
        data = load_json(path, MANIFEST, error=lambda detail: ServiceError(f"guide {path}: {detail}", field="guide",
                                                                             value=str(path)))
    except FileNotFoundError:
        raise ServiceError(f"guide {path}: no such file (expected {MANIFEST})", field="guide",
                           value=str(path)) from None
    except OSError as error:
        raise ServiceError(f"guide {path}: cannot read it ({error.strerror or error})", field="guide",
                           value=str(path)) from None
    check = _Fields(path)
    if not isinstance(data, dict):
        raise check.fail("", f"expected {MANIFEST}, a JSON object", data)
    tags = data.get("reference_tags")
    if not isinstance(tags, list) or not tags:
        raise check.fail("reference_tags", f"missing or empty; expected a list of {_REFERENCE}", tags)
    for index, tag in enumerate(tags):
        where = f"reference_tags[{index}]"
        if not isinstance(tag, dict) or not {"id", "center_mm", "size_mm"} <= set(tag):
            raise check.fail(where, f"expected {_REFERENCE}", tag)
        check.tag_id(tag["id"], f"{where}.id")
        check.point(tag["center_mm"], f"{where}.center_mm")
        check.size(tag["size_mm"], f"{where}.size_mm")
    if parts or "parts" in data:
        if not isinstance(data.get("parts"), list):
            raise check.fail("parts", "missing; expected the list of parts `station guide --json` prints",
                             data.get("parts"))
        for index, part in enumerate(data["parts"]):
            _check_part(check, part, f"parts[{index}]")
    return data


@station_errors
def reference_tags(manifest: dict) -> list[tuple[int, tuple[float, float], float]]:
    """The reference tags of a manifest :func:`read_manifest` read, as (id, (u, v) mm, size mm)."""
    return [(int(t["id"]), (float(t["center_mm"][0]), float(t["center_mm"][1])), float(t["size_mm"]))
            for t in manifest["reference_tags"]]


def _check_part(check: _Fields, part: Any, where: str) -> None:
    if not isinstance(part, dict) or not isinstance(part.get("name"), str) or "center_mm" not in part:
        raise check.fail(where, 'expected a part: {"name": text, "center_mm": [u, v], ...}', part)
    check.point(part["center_mm"], f"{where}.center_mm")
    if part.get("tag_id") is not None:
        check.tag_id(part["tag_id"], f"{where}.tag_id")
    if part.get("tag_center_mm") is not None:
        check.point(part["tag_center_mm"], f"{where}.tag_center_mm")
    if "tag_size_mm" in part:
        check.size(part["tag_size_mm"], f"{where}.tag_size_mm")
    if "tag_height_mm" in part:
        check.coordinate(part["tag_height_mm"], f"{where}.tag_height_mm")
    for key in ("tag_heading_deg", "heading_deg"):
        if key in part:
            check.angle(part[key], f"{where}.{key}")
    tolerances = part.get("tolerances", [])
    if not isinstance(tolerances, list):
        raise check.fail(f"{where}.tolerances", "expected a list", tolerances)
    for k, tolerance in enumerate(tolerances):
        at = f"{where}.tolerances[{k}]"
        if not isinstance(tolerance, dict) or not {"parameter", "delta", "unit"} <= set(tolerance):
            raise check.fail(at, 'expected {"parameter", "delta", "unit", ...}', tolerance)
        for key in ("delta", "predicted", "measured"):
            if tolerance.get(key) is not None:
                check.number(tolerance[key], f"{at}.{key}")
    body_tags = part.get("body_tags", [])
    if not isinstance(body_tags, list):
        raise check.fail(f"{where}.body_tags", "expected a list", body_tags)
    keys = ("body", "tag_id", "tag_center_mm", "tag_size_mm", "tag_height_mm", "tag_heading_deg", "center_mm",
            "heading_deg")
    for k, tag in enumerate(body_tags):
        at = f"{where}.body_tags[{k}]"
        if not isinstance(tag, dict) or not set(keys) <= set(tag):
            raise check.fail(at, f"expected {{{', '.join(map(repr, keys))}}}".replace("'", '"'), tag)
        check.tag_id(tag["body"], f"{at}.body", what="a domino's index")
        check.tag_id(tag["tag_id"], f"{at}.tag_id")
        check.point(tag["tag_center_mm"], f"{at}.tag_center_mm")
        check.point(tag["center_mm"], f"{at}.center_mm")
        check.size(tag["tag_size_mm"], f"{at}.tag_size_mm")
        check.coordinate(tag["tag_height_mm"], f"{at}.tag_height_mm")
        check.angle(tag["tag_heading_deg"], f"{at}.tag_heading_deg")
        check.angle(tag["heading_deg"], f"{at}.heading_deg")


class _Fields:
    """Checks of a manifest's values, each failing as one line naming the file and the field."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, where: str, expected: str, got: Any) -> ServiceError:
        field = f"field {where!r}: " if where else ""
        return ServiceError(f"guide {self.path}: {field}{expected}, got {got!r:.80}", field="guide",
                            value=str(self.path))

    def number(self, value: Any, where: str, low: float = -math.inf, high: float = math.inf, *,
               above: bool = False, what: str = "a finite number") -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                or not low <= value <= high or (above and value == low):
            raise self.fail(where, f"expected {what}", value)
        return float(value)

    def coordinate(self, value: Any, where: str) -> float:
        return self.number(value, where, -MAX_COORDINATE_MM, MAX_COORDINATE_MM,
                           what=f"a finite number of mm within ±{MAX_COORDINATE_MM:g}")

    def point(self, value: Any, where: str) -> None:
        expected = f"[u, v], two finite numbers of mm within ±{MAX_COORDINATE_MM:g}"
        if not isinstance(value, list) or len(value) != 2:
            raise self.fail(where, f"expected {expected}", value)
        for number in value:
            if isinstance(number, bool) or not isinstance(number, (int, float)) or not math.isfinite(number) \
                    or abs(number) > MAX_COORDINATE_MM:
                raise self.fail(where, f"expected {expected}", value)

    def size(self, value: Any, where: str) -> None:
        self.number(value, where, 0.0, MAX_TAG_MM, above=True,
                    what=f"a tag side in mm, above 0 and at most {MAX_TAG_MM:g}")

    def angle(self, value: Any, where: str) -> None:
        self.number(value, where, what="a finite angle in degrees")

    def tag_id(self, value: Any, where: str, what: str = "a tag id") -> None:
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise self.fail(where, f"expected {what} (an integer >= 0)", value)
