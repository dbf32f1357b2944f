"""``station explore`` from the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from design.machines import get_machine
from station import cli


def run_json(capsys, *argv):
    code = cli.main(["explore", *argv, "--json"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return json.loads(captured.out)


def test_json_has_pois_sliders_and_moves_in_the_pattern_frame(capsys):
    design = ["--set", "r_t=7", "--set", "r_e=4", "--set", "d_tf=9", "--set", "theta_te=2.4", "--set", "r_s=3.5"]
    doc = run_json(
        capsys, "cycloid_drawing_machine", *design, "--set", "d_fh=10.5",
        "--keep", "curvature:0", "--move", "0=1", "--move", "1=-0.5",
    )
    model = get_machine("cycloid_drawing_machine")
    assert {"pois", "sliders", "moves"} <= doc.keys()
    for p in doc["pois"]:
        assert {"id", "type", "xy"} <= p.keys()
    # Same frame as `station pattern`: every PoI lies on the sampled curve.
    curve = model.sample(doc["params"], n=20000, spacing="arclength")
    for p in doc["pois"][:10]:
        assert np.min(np.hypot(*(curve - p["xy"]).T)) < 0.01 * doc["size"]
    assert len(doc["moves"]) == 2
    for move in doc["moves"]:
        model.validate(move["params"])
        (error,) = move["invariant_error"]
        assert error["invariant"] == "curvature:0" and error["unit"] == "relative"
        assert error["error"] < 0.02
        target = doc["invariants"][0]["target"][0]
        assert move["features_after"]["poi 0"]["curvature"] == pytest.approx(target, rel=0.02)
    assert doc["moves"][0]["params"] != doc["params"]


def test_text_output_lists_pois_sliders_and_errors(capsys, tmp_path):
    out = tmp_path / "explore.png"
    code = cli.main(["explore", "elliptic_spirograph", "--keep", "distance:0,2", "--move", "0=1", "--out", str(out)])
    text = capsys.readouterr().out
    assert code == 0
    assert "points of interest" in text and "axis 1" in text
    assert "error distance:0,2" in text and "re-projected" in text
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["spirograph", "--keep", "position:0"], "over-constrained"),
        (["spirograph", "--keep", "bogus:0"], "type must be one of"),
        (["spirograph", "--keep", "position"], "expected TYPE:POI"),
        (["spirograph", "--keep", "position:x"], "PoI ids must be integers"),
        (["spirograph", "--keep", "angle:0"], "must be an intersection PoI"),
        (["spirograph", "--move", "a=1"], "integer slider index"),
        (["spirograph", "--move", "0=inf"], "finite"),
        (["spirograph", "--move", "3=1"], "slider index must be in 0..0"),
        (["spirograph", "--set", "d=99"], "'d'"),
        (["no_such_machine"], "no_such_machine"),
        (["spirograph", "--out", "x.svg"], ".png"),
    ],
)
def test_bad_input_is_one_clear_line_and_exit_2(capsys, argv, message):
    code = cli.main(["explore", *argv])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("station: error:") and message in err
    assert "Traceback" not in err
