"""``station retrieve``: JSON output, contact sheet, and one-line errors for bad sketches (never a traceback)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from station.cli import main

EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "sketches"


def test_retrieve_json_and_contact_sheet(tmp_path, capsys):
    code = main(
        [
            "retrieve",
            str(EXAMPLES / "trefoil-sector.json"),
            "--machine",
            "spirograph",
            "--top",
            "3",
            "--json",
            "--out",
            str(tmp_path / "sheet"),
        ]
    )
    assert code == 0
    out, err = capsys.readouterr()
    # the first run builds the database: its progress as plain lines on stderr (not a terminal), never \r redraws
    lines = err.splitlines()
    assert lines[0].startswith("spirograph: building candidate database (once; cached in ")
    assert "spirograph: grid 1/" in err and any(line.startswith("spirograph: curves ") and line.endswith("(100%)")
                                                for line in lines)
    assert "\r" not in err and len(lines) < 40
    ranked = json.loads(out)
    # symmetry 3 fixes the fixed ring's radius: only r_f = 3 designs (3/1 and 3/2) are candidates
    assert [c["params"]["r_f"] for c in ranked] == [3, 3]
    assert {"machine", "params", "distance"} <= set(ranked[0])
    assert ranked[0]["machine"] == "spirograph" and ranked[0]["params"]["r_f"] == 3
    assert (tmp_path / "sheet" / "trefoil-sector-candidates.png").stat().st_size > 1000


def test_retrieve_text_output_with_symmetry_override(capsys):
    code = main(["retrieve", str(EXAMPLES / "star.svg"), "--machine", "spirograph", "--symmetry", "1", "--top", "2"])
    assert code == 0
    out = capsys.readouterr().out
    assert "1. " in out and "spirograph" in out and "r_f=5" in out


def _write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize(
    ("name", "text", "args", "words"),
    [
        ("empty.json", "[]", [], "empty"),
        ("one.json", "[[[1, 2]]]", [], "single point"),
        ("nan.json", "[[[0, 0], [1, NaN], [2, 0]]]", [], "finite"),
        ("same.json", "[[[0, 0], [1, 1]], [[0, 0], [1, 1]]]", [], "straight line"),
        ("ok.json", "[[[0, 0], [1, 0], [1, 1], [0, 1]]]", ["--top", "0"], "--top"),
        ("ok.json", "[[[0, 0], [1, 0], [1, 1], [0, 1]]]", ["--machine", "harmonograph"], "unknown machine"),
        ("ok.json", "[[[0, 0], [1, 0], [1, 1], [0, 1]]]", ["--symmetry", "0"], "symmetry order"),
        ("ok.json", "[[[0, 0], [1, 0], [1, 1], [0, 1]]]", ["--center", "a,b"], "--center"),
    ],
)
def test_bad_input_is_one_line_exit_2(tmp_path, capsys, name, text, args, words):
    path = _write(tmp_path, name, text)
    code = main(["retrieve", path, "--machine", "spirograph", *args])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("station: error:") and words in err
    assert "Traceback" not in err and err.count("\n") == 1


def test_no_machine_has_the_symmetry_order(tmp_path, capsys):
    path = _write(tmp_path, "k.json", '{"strokes": [[[1, 0], [2, 0.5], [1.5, 1]]], "symmetry": 40}')
    assert main(["retrieve", path, "--machine", "spirograph", "--json"]) == 1
    captured = capsys.readouterr()
    assert json.loads(captured.out) == []
    assert "no candidate" in captured.err and "40" in captured.err


def test_huge_svg_and_missing_file(tmp_path, capsys):
    huge = tmp_path / "huge.svg"
    huge.write_bytes(b"<svg>" + b"<path d='M 0 0 L 1 1'/>" * 500_000 + b"</svg>")
    assert main(["retrieve", str(huge)]) == 2
    assert "too large" in capsys.readouterr().err
    assert main(["retrieve", str(tmp_path / "missing.json")]) == 2
    assert "no such file" in capsys.readouterr().err
