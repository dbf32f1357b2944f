"""The public formats' JSON Schemas (station/schemas) against what the station really writes.

Each command runs as a maker runs it (the ``station`` console script, in a workshop folder with a copy of
``examples/``, the station's data folder its own), and its output is validated against the schema shipped in the
package: LAYOUT.json, CHECK.json (a part in place and one misplaced), the guide manifest (with and without jigs),
jigs.json, the trial log's export (a trial with its check), ``station loop --json`` and ``station devices --json``.
A schema that would accept anything is caught too: each real output with a required field taken away, or a value
of the wrong type, must fail. The schemas let a later version add fields (a reader ignores what it does not know;
removing or retyping a field is a new version of the format), so a test also checks that every field the station
writes is described in its schema.
"""

from __future__ import annotations

import copy
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from jsonschema import Draft202012Validator
from referencing import Registry, Resource

from station.schemas import FORMATS, all_schemas, load_schema

from ..conftest import made_once

REPO = Path(__file__).resolve().parents[2]


def validator(name: str) -> Draft202012Validator:
    schemas = all_schemas()
    registry = Registry().with_resources((s["$id"], Resource.from_contents(s)) for s in schemas.values())
    return Draft202012Validator(schemas[name], registry=registry)


def problems(name: str, document) -> list[str]:
    return [f"{'/'.join(map(str, e.absolute_path)) or '(top)'}: {e.message[:200]}"
            for e in validator(name).iter_errors(document)]


@pytest.fixture(scope="module")
def outputs(workshop, tmp_path_factory):
    """The outputs of one maker's session, every command as typed: {name: parsed JSON}; made once per test run
    (``made_once``, tests/conftest.py) however the workers share this module's tests."""
    folder = made_once(tmp_path_factory, "format-outputs", lambda folder: make_outputs(workshop, folder))
    return json.loads((folder / "outputs.json").read_text())


def make_outputs(workshop: Path, folder: Path) -> None:
    """outputs.json in ``folder``: what :func:`outputs` gives. The layout (``station optimize simple --budget 40
    --seed 1``), the jigs and the laser test card are the prepared workshop's (tests/conftest.py), read from a
    copy; the rest runs here, with a station home of its own."""
    shutil.copytree(REPO / "examples", folder / "examples")
    for name in ("layout.json", "switch-jigs", "card"):
        copy_into = shutil.copytree if (workshop / name).is_dir() else shutil.copy2
        copy_into(workshop / name, folder / name)
    env = dict(os.environ)
    (folder / "home").mkdir()
    env["CHAOS_STATION_HOME"] = str(folder / "home")
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"

    def station(command: str) -> str:
        done = subprocess.run(["bash", "-c", f"station {command}"], cwd=folder, env=env, capture_output=True,
                              text=True, timeout=600)
        assert done.returncode == 0, f"station {command} exited {done.returncode}:\n{done.stderr[-2000:]}"
        return done.stdout

    out: dict[str, object] = {}
    out["devices"] = json.loads(station("devices --json"))
    out["devices --no-probe"] = json.loads(station("devices --json --no-probe"))
    out["layout"] = json.loads((folder / "layout.json").read_text())
    out["manifest"] = json.loads(station("guide simple layout.json --json"))
    out["jigs"] = json.loads((folder / "switch-jigs" / "jigs.json").read_text())
    out["manifest with jigs"] = json.loads(station("guide causalityswitch_ball success --jigs switch-jigs --json"))
    out["check"] = json.loads(station("check simple layout.json --camera sim://camera --predict 8 --json"))
    station("check simple layout.json --camera sim://camera --sim-offset track=9,-4,12 --predict 0 "
            "--out misplaced.json")
    out["check misplaced"] = json.loads((folder / "misplaced.json").read_text())
    station("check simple layout.json --camera sim://camera --predict 0 --out check.json")
    station("trial log simple layout.json --as-built check.json --outcome last_stops=yes --time last_stops=2.3 "
            "--who ann --predict 0")
    station("trial log simple success --outcome ball_hits_domino=no --notes 'ramp wobbled' --predict 0")
    station("trial export --out trials.json")
    out["trials"] = json.loads((folder / "trials.json").read_text())
    out["loop"] = json.loads(station("loop simple --world 'sim://world?seed=1' --attempts 1 --loops 1 --budget 20 "
                                     "--reoptimize-budget 20 --json"))
    out["test card"] = json.loads((folder / "card" / "card.json").read_text())
    (folder / "outputs.json").write_text(json.dumps(out))


#: (schema, output of the workshop) pairs: every schema has at least one real output.
CASES = [("devices", "devices"), ("devices", "devices --no-probe"), ("layout", "layout"),
         ("guide-manifest", "manifest"), ("guide-manifest", "manifest with jigs"), ("jigs", "jigs"),
         ("check", "check"), ("check", "check misplaced"), ("trials", "trials"), ("loop", "loop"),
         ("test-card", "test card")]


def test_every_format_has_a_valid_draft_2020_12_schema_named_as_its_file():
    assert {name for name, _ in CASES} == set(FORMATS)
    for name in FORMATS:
        schema = load_schema(name)
        Draft202012Validator.check_schema(schema)
        assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
        assert schema["$id"].endswith(f"/{name}.schema.json")
        assert (REPO / "station" / "schemas" / f"{name}.schema.json").is_file()


def test_the_schemas_are_package_data():
    text = (REPO / "pyproject.toml").read_text(encoding="utf-8")
    assert '"station.schemas" = ["*.schema.json"]' in text


@pytest.mark.parametrize(("schema", "output"), CASES)
def test_the_real_output_matches_its_schema(outputs, schema, output):
    assert problems(schema, outputs[output]) == []


def undescribed(document, schema: dict, path: str = "") -> list[str]:
    """The fields of ``document`` its schema does not describe. A schema leaves room for fields a later version
    adds (readers ignore what they do not know), so validation alone would let one go undocumented."""
    if "$ref" in schema:
        schema = load_schema(schema["$ref"].removesuffix(".schema.json"))
    for branch in schema.get("oneOf", []):
        if document is not None and branch.get("type") == "object" or "items" in branch:
            schema = branch
    found = []
    if isinstance(document, dict) and "properties" in schema:
        for key, value in document.items():
            if key not in schema["properties"]:
                found.append(f"{path}/{key}")
            else:
                found += undescribed(value, schema["properties"][key], f"{path}/{key}")
    elif isinstance(document, dict) and isinstance(schema.get("additionalProperties"), dict):
        for key, value in document.items():
            found += undescribed(value, schema["additionalProperties"], f"{path}/{key}")
    elif isinstance(document, list) and isinstance(schema.get("items"), dict):
        for index, value in enumerate(document):
            found += undescribed(value, schema["items"], f"{path}/{index}")
    return found


@pytest.mark.parametrize(("schema", "output"), CASES)
def test_every_field_of_the_real_output_is_in_its_schema(outputs, schema, output):
    assert sorted(set(undescribed(outputs[output], load_schema(schema)))) == []


def test_the_outputs_exercise_what_the_schemas_constrain(outputs):
    """The cases are not empty shells: the optional and nullable parts the schemas describe are really there."""
    assert outputs["manifest with jigs"]["jigs"] and outputs["jigs"]["jigs"]
    assert "model" in outputs["layout"] and "physical_success" in outputs["layout"]
    misplaced = next(p for p in outputs["check misplaced"]["parts"] if p["name"] == "track")
    assert misplaced["error"]["distance_mm"] > 5
    trials = outputs["trials"]["trials"]
    assert len(trials) == 2 and trials[0]["check"] is not None and trials[1]["check"] is None
    assert outputs["loop"]["loops"] and outputs["loop"]["baseline"]["attempts"] >= 1


@pytest.mark.parametrize(("schema", "output", "breaking"), [
    ("layout", "layout", lambda d: d.pop("content_hash")),
    ("layout", "layout", lambda d: d["parameters"][0].update(value="0.1")),
    ("check", "check", lambda d: d.update(version=2)),
    ("check", "check", lambda d: d["parts"][0]["error"].pop("du_mm")),
    ("guide-manifest", "manifest", lambda d: d["parts"][0]["parameters"][0].update(set_with="eye")),
    ("guide-manifest", "manifest with jigs", lambda d: d["jigs"][0].pop("footprint_mm")),
    ("jigs", "jigs", lambda d: d["jigs"][0].update(outline_mm=[[0, 0, 0]])),
    ("trials", "trials", lambda d: d["trials"][0]["check"].pop("as_built")),
    ("trials", "trials", lambda d: d["trials"][0]["outcomes"].update(ball_rolls="maybe")),
    ("loop", "loop", lambda d: d["loops"][0].update(success_rate=1.5)),
    ("devices", "devices", lambda d: d["devices"][0].update(kind="lazer")),
    ("test-card", "test card", lambda d: d["cells"][0].pop("cut_line_mm")),
    ("test-card", "test card", lambda d: d["comb"].update(power=1.5)),
])
def test_a_broken_output_fails_its_schema(outputs, schema, output, breaking):
    document = copy.deepcopy(outputs[output])
    breaking(document)
    assert problems(schema, document), f"{schema}.schema.json accepted a broken {output}"
