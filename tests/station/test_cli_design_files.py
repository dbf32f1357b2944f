"""``--design FILE.json`` works the same on every drawing-machine command: pattern, plot, explore, fabricate."""

from __future__ import annotations

import json

import pytest

from station import cli

DESIGN = {"machine": "spirograph", "params": {"r_f": 7, "r_r": 2, "d": 1.5}}  # not the defaults
AS_SETS = ["--set", "r_f=7", "--set", "r_r=2", "--set", "d=1.5"]


def run(capsys, *argv):
    code = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def design_file(tmp_path):
    path = tmp_path / "five.json"
    path.write_text(json.dumps(DESIGN))
    return path


def test_plot_design_file_gives_the_same_job_as_sets(capsys, tmp_path, design_file):
    assert run(capsys, "plot", "spirograph", "--design", design_file, "--out", tmp_path / "a.gcode")[0] == 0
    assert run(capsys, "plot", "spirograph", *AS_SETS, "--out", tmp_path / "b.gcode")[0] == 0
    assert (tmp_path / "a.gcode").read_text() == (tmp_path / "b.gcode").read_text()
    # --set wins over the file
    assert run(capsys, "plot", "spirograph", "--design", design_file, "--set", "d=1", "--out",
               tmp_path / "c.gcode")[0] == 0
    assert (tmp_path / "c.gcode").read_text() != (tmp_path / "a.gcode").read_text()


def test_explore_design_file_starts_from_its_parameters(capsys, design_file):
    code, out, _ = run(capsys, "explore", "spirograph", "--design", design_file, "--json")
    assert code == 0
    assert json.loads(out)["params"] == pytest.approx(DESIGN["params"])


@pytest.mark.parametrize(("command", "out"), [
    (["pattern", "spirograph"], "p.svg"), (["plot", "spirograph"], "p.gcode"), (["explore", "spirograph"], "e.png"),
    (["fabricate", "spirograph", "--scale", "5"], "parts"),
])
def test_design_file_for_another_machine_is_one_clear_line(capsys, tmp_path, command, out):
    other = tmp_path / "hn.json"
    other.write_text(json.dumps({"machine": "hoot_nanny", "params": {}}))
    code, _, err = run(capsys, *command, "--design", other, "--out", tmp_path / out)
    assert code == 2
    assert err.count("\n") == 1 and "field 'machine' is 'hoot_nanny'" in err and "Traceback" not in err
    assert not (tmp_path / out).exists()


def test_fabricate_design_file_reads_its_parameters(capsys, tmp_path, design_file):
    code, out, _ = run(capsys, "fabricate", "spirograph", "--design", design_file, "--scale", "10",
                       "--out", tmp_path / "parts", "--json")
    assert code == 0
    assert json.loads(out)["params"] == pytest.approx(DESIGN["params"])


def test_plot_refuses_design_with_pattern(capsys, tmp_path, design_file):
    code, _, err = run(capsys, "plot", "--pattern", design_file, "--design", design_file)
    assert code == 2 and "--design" in err


def test_retrieve_results_are_a_design_file_taking_the_best_candidate_of_the_machine(capsys, tmp_path):
    ranked = [
        {"machine": "hoot_nanny", "params": {"r_t": 10}, "distance": 0.01},
        {"machine": "spirograph", "params": {"r_f": 7, "r_r": 2, "d": 1.5}, "distance": 0.02},
        {"machine": "spirograph", "params": {"r_f": 5, "r_r": 2, "d": 1.0}, "distance": 0.03},
    ]
    path = tmp_path / "hits.json"
    path.write_text(json.dumps(ranked))
    code, out, _ = run(capsys, "pattern", "spirograph", "--design", path, "--json")
    assert code == 0 and json.loads(out)["params"] == pytest.approx(ranked[1]["params"])
    code, _, err = run(capsys, "pattern", "cycloid_drawing_machine", "--design", path)
    assert code == 2 and "found machines ['hoot_nanny', 'spirograph']" in err
