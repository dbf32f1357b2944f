"""Scenario-file validation: every error names the file, the field's path and what was expected."""

from __future__ import annotations

import copy
import json

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from design.contraption import ScenarioFormatError, load_layout, load_scenario, scenario_from_data
from design.errors import FileFormatError

BASE = {
    "scenario": {"name": "T"},
    "objects": [
        {"name": "floor", "type": "Plane"},
        {
            "name": "box",
            "type": "Box",
            "shape": {"size": [0.02, 0.02, 0.02]},
            "physics": {"mass": 0.01},
            "transform": {"z": 0.0101, "heading": 10},
            "ranges": {"x": [-0.1, 0.1], "heading": [0, 90]},
        },
        {"name": "ball", "type": "Ball", "shape": {"radius": 0.01}, "physics": {"mass": 0.01},
         "transform": {"x": 0.05, "z": 0.05}},
    ],
    "events": [
        {"name": "falls", "type": "Falling", "body": "ball"},
        {"name": "hits", "type": "Contact", "a": "ball", "b": "floor", "after": ["falls"]},
        {"name": "stops", "type": "Stopping", "body": "ball", "after": ["hits"]},
    ],
}


def load(mutate) -> None:
    data = copy.deepcopy(BASE)
    mutate(data)
    return scenario_from_data(data, file="t.toml")


def error_of(mutate) -> ScenarioFormatError:
    with pytest.raises(ScenarioFormatError) as info:
        load(mutate)
    assert isinstance(info.value, FileFormatError)
    assert str(info.value).startswith("t.toml: ")
    return info.value


def test_base_is_valid():
    scenario = load(lambda d: None)
    assert scenario.design_space.names == ("box.x", "box.heading")
    assert scenario.root == "falls"
    assert scenario.leaves() == ["stops"]


@pytest.mark.parametrize(
    ("mutate", "field", "words"),
    [
        (lambda d: d["objects"][1]["transform"].__setitem__("heading", "north"), "objects[1].transform.heading",
         "expected a number"),
        (lambda d: d["objects"][1]["ranges"].__setitem__("x", [0.1, -0.1]), "objects[1].ranges.x", "min < max"),
        (lambda d: d["objects"][1]["shape"].pop("size"), "objects[1].shape.size", "missing"),
        (lambda d: d["objects"][2]["shape"].__setitem__("radius", -1), "objects[2].shape.radius", "> 0"),
        (lambda d: d["objects"][2].__setitem__("type", "Sphere"), "objects[2].type", "expected one of"),
        (lambda d: d["objects"][2].__setitem__("parent", "nothing"), "objects[2].parent", "unknown object"),
        (lambda d: d["objects"][2].__setitem__("name", "box"), "objects[2].name", "unique"),
        (lambda d: d["objects"][1]["transform"].__setitem__("x", 0.5), "objects[1].transform.x", "inside its range"),
        (lambda d: d["objects"][1].__setitem__("colour", "red"), "objects[1].colour", "unknown field"),
        (lambda d: d["events"][1].__setitem__("b", "table"), "events[1].b", "unknown object 'table'"),
        (lambda d: d["events"][1].__setitem__("after", ["nothing"]), "events[1].after[0]", "unknown event"),
        (lambda d: d["events"][0].__setitem__("after", ["stops"]), "events", "exactly one root"),
        (lambda d: d["events"][1].__setitem__("after", ["falls", "stops"]), "after", "expected a DAG"),
        (lambda d: d["events"][2].__setitem__("join", "some"), "events[2].join", '"all" or "any"'),
        (lambda d: d["events"][2].__setitem__("timeout", 0), "events[2].timeout", "> 0"),
        (lambda d: d["events"][2].pop("body"), "events[2].body", "missing"),
        (lambda d: d["events"][2].__setitem__("body", "box[2]"), "events[2].body", "single body"),
        (lambda d: d.__setitem__("settings", {"time_step": -1}), "settings.time_step", "> 0"),
        (lambda d: d.__setitem__("layouts", {"s": {"box.x": 3}}), 'layouts.s."box.x"', "in [-0.1, 0.1]"),
        (lambda d: d.__setitem__("layouts", {"s": {"box.z": 0}}), "layouts.s.box.z", "unknown design parameter"),
        (lambda d: d.pop("events"), "events", "missing"),
        (lambda d: d["objects"].append({"name": "r", "type": "DominoRun", "shape": {"size": [0.01, 0.01, 0.04]}}),
         "objects[3].shape", "exactly one of 'poses' or 'path'"),
        (lambda d: d["objects"].append({"name": "p", "type": "Pivot", "shape": {"body": "floor2"}}),
         "objects[3].shape.body", "unknown object"),
        (lambda d: d["objects"].append({"name": "e", "type": "Empty", "shape": {}, "physics": {"mass": 1}}),
         "objects[3].physics.mass", "unknown field"),
    ],
)
def test_errors_name_field_and_expectation(mutate, field, words):
    error = error_of(mutate)
    assert field in str(error)
    assert words in str(error)


def test_parent_cycle_is_an_error():
    def mutate(d):
        d["objects"][1]["parent"] = "ball"
        d["objects"][2]["parent"] = "box"

    assert "cycle" in str(error_of(mutate))


def test_domino_index_out_of_range():
    def mutate(d):
        d["objects"].append(
            {"name": "run", "type": "DominoRun", "shape": {"size": [0.005, 0.02, 0.04], "path": [[0, 0], [0.03, 0]],
                                                            "count": 3}}
        )
        d["events"][2]["body"] = "run[3]"

    assert "expected a domino index in [-3, 2]" in str(error_of(mutate))


def test_files_bad_syntax_suffix_and_encoding(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[scenario\nname = 1")
    with pytest.raises(ScenarioFormatError,
                       match=r"bad.toml: not valid TOML \(.* at line 1 column \d+\); expected a scenario"):
        load_scenario(bad)
    (tmp_path / "bad.json").write_text("{nope")
    with pytest.raises(ScenarioFormatError, match=r"bad.json: not valid JSON \(Expecting property name enclosed in "
                                                  r"double quotes at line 1 column 2\); expected a scenario"):
        load_scenario(tmp_path / "bad.json")
    (tmp_path / "s.yaml").write_text("a: 1")
    with pytest.raises(ScenarioFormatError, match="expected a .toml or .json"):
        load_scenario(tmp_path / "s.yaml")
    (tmp_path / "latin.toml").write_bytes(b"name = '\xe9'")
    with pytest.raises(ScenarioFormatError, match=r"latin.toml: not UTF-8 text \(.* at byte 8\); expected a scenario"):
        load_scenario(tmp_path / "latin.toml")
    (tmp_path / "nan.json").write_text('{"objects": NaN}')
    with pytest.raises(ScenarioFormatError, match=r"nan.json: not valid JSON \(NaN is not a JSON number\)"):
        load_scenario(tmp_path / "nan.json")


def test_json_scenario_equals_toml(tmp_path, simple, scenarios_dir):
    import tomllib

    data = tomllib.loads((scenarios_dir / "simple.toml").read_text())
    (tmp_path / "simple.json").write_text(json.dumps(data))
    again = load_scenario(tmp_path / "simple.json")
    assert again.content_hash == simple.content_hash
    assert again.design_space.names == simple.design_space.names


def test_layout_files(tmp_path, simple):
    (tmp_path / "a.json").write_text(json.dumps({"track.roll": 40}))
    x = load_layout(tmp_path / "a.json", simple)
    assert x.tolist() == [-0.06, 0.06, 40.0]
    (tmp_path / "b.json").write_text(json.dumps({"x": [-0.1, 0.1, 20]}))
    assert load_layout(tmp_path / "b.json", simple).tolist() == [-0.1, 0.1, 20.0]
    (tmp_path / "c.json").write_text(json.dumps({"track.yaw": 1}))
    with pytest.raises(ScenarioFormatError, match=r"c.json: track.yaw: unknown design parameter"):
        load_layout(tmp_path / "c.json", simple)
    (tmp_path / "d.json").write_text(json.dumps({"x": [0, 0]}))
    with pytest.raises(ScenarioFormatError, match=r"d.json: x: expected an array of 3 items"):
        load_layout(tmp_path / "d.json", simple)
    (tmp_path / "e.json").write_text(json.dumps({"track.roll": 90}))
    with pytest.raises(ScenarioFormatError, match=r"track.roll: expected a value in \[15, 75\]"):
        load_layout(tmp_path / "e.json", simple)


# --- fuzzing: malformed content never escapes as anything but ScenarioFormatError -------------------------------

json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-10, 10) | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=8),
    lambda children: st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=8), children, max_size=4),
    max_leaves=12,
)


def _paths(data, prefix=()):
    yield prefix
    if isinstance(data, dict):
        for key, value in data.items():
            yield from _paths(value, prefix + (key,))
    elif isinstance(data, list):
        for i, value in enumerate(data):
            yield from _paths(value, prefix + (i,))


ALL_PATHS = [p for p in _paths(BASE) if p]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(ALL_PATHS), json_values, st.booleans())
def test_fuzz_structure(path, value, delete):
    data = copy.deepcopy(BASE)
    target = data
    for key in path[:-1]:
        target = target[key]
    if delete:
        del target[path[-1]]
    else:
        target[path[-1]] = value
    try:
        scenario_from_data(data, file="fuzz.json")
    except ScenarioFormatError as error:
        assert str(error).startswith("fuzz.json: ")


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=200))
def test_fuzz_bytes(tmp_path_factory, raw):
    folder = tmp_path_factory.mktemp("fuzz")
    for suffix in (".toml", ".json"):
        path = folder / f"f{suffix}"
        path.write_bytes(raw)
        try:
            load_scenario(path)
        except ScenarioFormatError:
            pass


@settings(max_examples=150, deadline=None)
@given(json_values)
def test_fuzz_whole_document(value):
    try:
        scenario_from_data(value, file="doc.json")
    except ScenarioFormatError:
        pass


def test_apriltag_on_a_part():
    def mutate(d):
        d["objects"][1]["tag"] = {"id": 7, "x": 0.0, "y": 0.0, "z": 0.01, "size": 0.015}

    tag = load(mutate).object("box").tag
    assert (tag.id, tag.z, tag.size) == (7, 0.01, 0.015)

    def bad(d):
        d["objects"][1]["tag"] = {"id": -1}

    assert "objects[1].tag.id" in str(error_of(bad))

    def missing(d):
        d["objects"][1]["tag"] = {"size": 0.02}

    assert "objects[1].tag.id: missing" in str(error_of(missing))

    def turned(d):
        d["objects"][1]["tag"] = {"id": 7, "angle": 90}

    assert load(turned).object("box").tag.angle == 90.0

    def on_a_body(d):  # only a DominoRun's tags name a body
        d["objects"][1]["tag"] = [{"id": 7, "body": 0}]

    assert "objects[1].tag: expected a table" in str(error_of(on_a_body))


def test_a_domino_runs_tags_sit_on_its_first_and_last_dominoes():
    import tomllib

    from design.contraption.catalog import resolve_scenario_path

    data = tomllib.loads(resolve_scenario_path("simple").read_text())
    run = next(o for o in data["objects"] if o["name"] == "dominoes")
    run["tag"] = [{"id": 5, "body": 0, "z": 0.02}, {"id": 6, "body": -1, "z": 0.02}]
    spec = scenario_from_data(data).object("dominoes")
    assert spec.tag is None and [(t.id, t.body) for t in spec.body_tags] == [(5, 0), (6, 2)]
    run["tag"] = [{"id": 5, "body": 3}]
    with pytest.raises(ScenarioFormatError, match=r"tag\[0\]\.body: expected a domino's index from -3 to 2"):
        scenario_from_data(data)


def test_sleeping_flag_defaults_and_type():
    scenario = load(lambda d: d["objects"][2].__setitem__("sleeping", True))
    assert scenario.object("ball").starts_asleep and not scenario.object("box").starts_asleep
    error = error_of(lambda d: d["objects"][2].__setitem__("sleeping", "yes"))
    assert "objects[2].sleeping: expected true or false" in str(error)


@pytest.mark.parametrize(
    ("obj", "field", "words"),
    [
        ({"name": "run", "type": "DominoRun", "shape": {"size": [0.005, 0.02, 0.04], "path": [[0, 0], [0, 0], [0.1, 0]],
                                                        "count": 4}}, "objects[3].shape.path[1]", "distinct"),
        ({"name": "p", "type": "Pivot", "shape": {"body": "box", "other": "box"}}, "objects[3].shape.other",
         "other than"),
        ({"name": "f", "type": "Fastener", "shape": {"bodies": ["box", "box"]}}, "objects[3].shape.bodies",
         "two different"),
        ({"name": "r", "type": "TensionRope", "shape": {"ends": ["ball", "ball"]}}, "objects[3].shape.ends",
         "two different"),
        ({"name": "r", "type": "RopePulley", "shape": {"ends": ["ball", "box"], "pulleys": ["box"]}},
         "objects[3].shape.pulleys[0]", "expected a Pulley"),
        ({"name": "g", "type": "Goblet", "shape": {"height": 0.1, "radius_top": 0.01, "radius_bottom": 0.01,
                                                   "thickness": 0.02}}, "objects[3].shape.thickness", "thinner"),
    ],
)
def test_constraint_and_complex_primitive_errors(obj, field, words):
    error = error_of(lambda d: d["objects"].append(obj))
    assert field in str(error) and words in str(error)
