"""The one layout reader (design/contraption/layout_io.py): its forms, what it says it defaulted, and its errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from design.contraption import LayoutError, ScenarioFormatError, load_layout


def write(tmp_path, name, content):
    path = tmp_path / name
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content if isinstance(content, str) else json.dumps(content), encoding="utf-8")
    return path


def optimizer_file(simple, values, **extra):
    """A LAYOUT.json as design/robust/pipeline.py writes it (the fields the reader looks at, and some it does not)."""
    space = simple.design_space
    u = space.to_normalized(np.asarray(values, dtype=float))
    return {
        "format": "chaos-station robust layout 1",
        "scenario": simple.name,
        "content_hash": simple.content_hash,
        "parameters": [{"name": n, "value": float(v), "normalized": float(ui), "lower": float(lo), "upper": float(hi)}
                       for n, v, ui, lo, hi in zip(space.names, values, u, space.lower, space.upper)],
        "predicted_psp": 0.8,
        "psp_settings": {"n_initial": 48},
        **extra,
    }


def test_out_of_range_names_the_field_once(tmp_path, simple):
    # The field was written twice ("e.json: track.roll: track.roll: expected ..."): once as the error's field and
    # once at the start of its message.
    path = write(tmp_path, "e.json", {"track.roll": 90})
    with pytest.raises(ScenarioFormatError) as caught:
        load_layout(path, simple)
    assert str(caught.value) == f"{path}: track.roll: expected a value in [15, 75] deg, got 90"
    path = write(tmp_path, "x.json", {"x": [-0.06, 0.06, 90]})
    with pytest.raises(ScenarioFormatError) as caught:
        load_layout(path, simple)
    assert str(caught.value) == f"{path}: x[2]: expected a value in [15, 75] deg, got 90"


def test_the_three_forms_give_the_same_layout(tmp_path, simple):
    from design.contraption import read_layout

    values = [-0.1, 0.1, 20.0]
    forms = {
        "LAYOUT.json": optimizer_file(simple, values),
        "x": {"x": values},
        "parameters": {"parameters": dict(zip(simple.design_space.names, values))},
        "mapping": dict(zip(simple.design_space.names, values)),
    }
    for form, content in forms.items():
        layout = read_layout(write(tmp_path, f"{form}.json", content), simple)
        assert layout.format == form
        np.testing.assert_allclose(layout.x, values, rtol=0, atol=1e-12)
        assert layout.defaulted == () and layout.warnings == ()
    # TOML for the hand-written forms.
    toml = write(tmp_path, "l.toml", '[parameters]\n"track.x" = -0.1\n"track.z" = 0.1\n"track.roll" = 20\n')
    np.testing.assert_allclose(read_layout(toml, simple).x, values)


def test_a_minimal_hand_written_layout_takes_the_defaults_and_says_so(tmp_path, simple):
    from design.contraption import read_layout

    layout = read_layout(write(tmp_path, "m.json", {"parameters": {"track.x": -0.1}}), simple)
    assert layout.x.tolist() == [-0.1, 0.06, 30.0]
    assert layout.defaulted == ("track.z", "track.roll")
    assert layout.describe() == f"{tmp_path / 'm.json'} (" + '{"parameters": {name: value}})'
    assert read_layout(write(tmp_path, "f.json", {"track.roll": 40}), simple).defaulted == ("track.x", "track.z")


def test_a_layout_json_of_another_scenario_content_is_a_warning(tmp_path, simple):
    from design.contraption import read_layout

    content = optimizer_file(simple, [-0.1, 0.1, 20.0])
    content["content_hash"] = "ab" * 32
    layout = read_layout(write(tmp_path, "old.json", content), simple)
    assert layout.x.tolist() == [-0.1, 0.1, 20.0]
    assert len(layout.warnings) == 1
    assert "content_hash: written for 'SIMPLE' of another content (abababababab...)" in layout.warnings[0]
    # Parameters that do not fit as well: the error says why they might not (another scenario).
    content["parameters"] = content["parameters"][:2]
    with pytest.raises(ScenarioFormatError, match=r"old.json: parameters: lacks track.roll; .*content_hash"):
        read_layout(write(tmp_path, "old.json", content), simple)


@pytest.mark.parametrize(
    ("content", "expected"),
    [
        ("{", "bad.json: not valid JSON (Expecting property name enclosed in double quotes at line 1 column 2); "
              "expected a layout"),
        (b"\xff\xfe{}", "bad.json: not UTF-8 text (invalid start byte at byte 0); expected a layout"),
        ("[1, 2]", "bad.json: expected a table (a JSON object), got an array"),
        ('{"track.x": NaN}', "bad.json: not valid JSON (NaN is not a JSON number); expected a layout"),
        ('{"track.x": -0.1, "track.x": -0.05}', "bad.json: track.x: given twice"),
        ({"track.yaw": 1}, "bad.json: track.yaw: unknown design parameter; expected one of track.x, track.z, "
                           "track.roll"),
        ({"parameters": {"track.yaw": 1}}, "bad.json: parameters.track.yaw: unknown design parameter; expected one "
                                           "of track.x, track.z, track.roll"),
        ({"parameters": {"track.x": "left"}}, "bad.json: parameters.track.x: expected a number in [-0.15, 0] m, got "
                                              "text ('left')"),
        ({"parameters": {"track.x": True}}, "bad.json: parameters.track.x: expected a number in [-0.15, 0] m, got a "
                                            "boolean"),
        ({"parameters": 3}, "bad.json: parameters: expected a list of {name, value} (a LAYOUT.json) or a table"),
        ({"parameters": {}, "seed": 3}, "bad.json: seed: unknown field; expected parameters, scenario"),
        ({"x": [0, 0]}, "bad.json: x: expected an array of 3 items (track.x, track.z, track.roll), got 2"),
        ({"x": "0,0,0"}, "bad.json: x: expected an array of 3 numbers"),
        ({"parameters": [{"name": "track.yaw", "value": 1}]}, "bad.json: parameters[0].name: expected one of "
                                                              "track.x, track.z, track.roll, got text ('track.yaw')"),
        ({"parameters": [{"name": "track.x"}]}, "bad.json: parameters[0].value: missing"),
        ({"parameters": [{"name": "track.x", "value": -0.1}, {"name": "track.x", "value": -0.1}]},
         "bad.json: parameters[1].name: 'track.x' is listed twice"),
        ({"parameters": [{"name": "track.x", "value": 5}]}, "bad.json: parameters[0].value: expected a value in "
                                                            "[-0.15, 0] m, got 5"),
        ({"format": "other 2", "parameters": []}, "bad.json: format: expected 'chaos-station robust layout 1'"),
        ({"content_hash": 5, "parameters": []}, "bad.json: content_hash: expected the scenario's sha256 as text"),
    ],
)
def test_bad_layout_files_name_the_file_field_and_expectation(tmp_path, simple, content, expected):
    from design.contraption import read_layout

    path = write(tmp_path, "bad.json", content)
    with pytest.raises(ScenarioFormatError) as caught:
        read_layout(path, simple)
    message = str(caught.value)
    assert message.startswith(str(tmp_path) + "/"), message
    assert expected in message, message
    assert "\n" not in message


def test_named_layouts_and_files_resolve_from_one_argument(tmp_path, simple):
    from design.contraption import resolve_layout

    assert resolve_layout("success", simple).x.tolist() == [-0.06, 0.06, 30.0]
    assert resolve_layout("success", simple).describe() == f"'success' (named in {simple.source})"
    path = write(tmp_path, "l.json", {"x": [-0.1, 0.1, 20]})
    assert resolve_layout(str(path), simple).format == "x"
    with pytest.raises(LayoutError, match=r"layout 'nonsense': no such file and no layout of that name .* "
                                          r"\(its layouts: failure, success\)"):
        resolve_layout("nonsense", simple)
    with pytest.raises(FileNotFoundError):
        resolve_layout(str(tmp_path / "missing.json"), simple)
