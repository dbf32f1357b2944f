"""JSON Schemas (draft 2020-12) of the station's public file formats, shipped as package data.

A program that reads what the station writes has a contract here rather than prose: ``LAYOUT.json``
(``layout``), ``CHECK.json`` (``check``), the guide manifest (``guide-manifest``), ``jigs.json`` (``jigs``), the
trial log's export (``trials``), ``station loop --json`` (``loop``), ``station devices --json`` (``devices``) and a
laser test card's ``card.json`` (``test-card``).
Breaking a schema is a new version of that format. Each schema's ``$id`` ends in its file name, so a ``$ref`` from
one to another (the trial export's ``check``) resolves within this folder; nothing is fetched.
"""

from __future__ import annotations

import json
from importlib import resources
from typing import Any

#: Each public format's schema name (the file is ``NAME.schema.json``) and the output it describes.
FORMATS = {
    "layout": "LAYOUT.json (station optimize --out)",
    "check": "CHECK.json (station check --json / --out)",
    "guide-manifest": "the guide manifest (station guide --json)",
    "jigs": "jigs.json (station jigs --out DIR, --json)",
    "trials": "the trial log's export (station trial export --out FILE.json)",
    "loop": "station loop --json",
    "devices": "station devices --json",
    "test-card": "card.json (station lasertest card --out DIR)",
}


def schema_text(name: str) -> str:
    """The text of schema ``name`` (one of :data:`FORMATS`)."""
    if name not in FORMATS:
        raise KeyError(f"no schema {name!r}; expected one of {', '.join(FORMATS)}")
    return resources.files(__name__).joinpath(f"{name}.schema.json").read_text(encoding="utf-8")


def load_schema(name: str) -> dict[str, Any]:
    """Schema ``name`` as a dict."""
    return json.loads(schema_text(name))


def all_schemas() -> dict[str, dict[str, Any]]:
    """Every schema by name, e.g. for a ``referencing.Registry`` that resolves the ``$ref`` between them."""
    return {name: load_schema(name) for name in FORMATS}
