"""``station fabricate``: output files, summary, errors as one line."""

from __future__ import annotations

import io
import json
import re
import sys

import numpy as np
import pytest
from PIL import Image

from common.progress import Progress, Reporter
from drivers.gcode import interpret
from station.cli import main


def test_fabricate_writes_svg_gcode_json_png(tmp_path, capsys):
    out = tmp_path / "spiro"
    code = main(["fabricate", "spirograph", "--set", "r_f=5", "--set", "r_r=3", "--set", "d=1.5", "--scale", "6",
                 "--kerf", "0.2", "--sheet", "250x180", "--out", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    assert "fixed ring" in text and "rolling gear" in text and "sheet usage" in text
    summary = json.loads((out / "parts.json").read_text())
    assert summary["sheet_mm"] == [250, 180] and summary["kerf_mm"] == 0.2
    assert {p["name"] for p in summary["parts"]} == {"fixed ring", "rolling gear"}
    assert 0 < summary["sheet_usage"] < 1
    assert summary["job"]["travel_mm"] <= summary["job"]["travel_mm_unordered"]
    assert summary["job"]["material"] == "plywood_3mm"
    lines = (out / "laser.gcode").read_text().splitlines()
    path = interpret(lines)
    lo, hi = path.extent()
    assert lo.min() >= 0 and hi[0] <= 250 and hi[1] <= 180
    assert np.all(path.power[path.rapid] == 0)
    assert lines[-1] == "M5 S0"
    assert (out / "parts.svg").read_text().count('inkscape:groupmode="layer"') == 2
    assert Image.open(out / "sheet.png").size[0] > 100


@pytest.mark.parametrize("machine", ["cycloid_drawing_machine", "hoot_nanny"])
def test_fabricate_turntable_machines_as_json(tmp_path, capsys, machine):
    code = main(["fabricate", machine, "--scale", "6", "--material", "cardboard_2mm", "--out", str(tmp_path),
                 "--json"])
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    names = {p["name"] for p in summary["parts"]}
    assert {"turntable gear", "base plate"} <= names
    assert summary["job"]["cut"]["passes"] == 1  # cardboard_2mm


def test_bad_inputs_are_one_line_errors(tmp_path, capsys):
    assert main(["fabricate", "spirograph", "--scale", "6", "--sheet", "big", "--out", str(tmp_path)]) == 2
    assert "--sheet" in capsys.readouterr().err
    assert main(["fabricate", "spirograph", "--scale", "6", "--material", "gold", "--out", str(tmp_path)]) == 2
    assert "no material 'gold'" in capsys.readouterr().err
    assert main(["fabricate", "spirograph", "--scale", "15", "--sheet", "100x100", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.splitlines()[-1].startswith("station: error:") and "no room for part" in err
    assert "Traceback" not in err
    assert main(["fabricate", "spirograph", "--scale", "6", "--set", "r_r=7", "--out", str(tmp_path)]) == 2
    assert "station: error:" in capsys.readouterr().err
    # A sheet larger than a (small) laser's work area: refused with the extent.
    from drivers.profiles import BUILTIN_PROFILES

    small = tmp_path / "small.toml"
    small.write_text(BUILTIN_PROFILES["laser"].replace('"400mm"', '"100mm"'))
    assert main(["fabricate", "spirograph", "--scale", "8", "--sheet", "200x200", "--profile", str(small),
                 "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "work area" in err and "X 0..100 mm" in err


def test_parts_that_do_not_fit_one_sheet_go_on_more_sheets(tmp_path, capsys):
    code = main(["fabricate", "hoot_nanny", "--scale", "5", "--sheet", "140x140", "--out", str(tmp_path), "--json"])
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    count = summary["sheet_count"]
    assert count >= 2 and len(summary["sheets"]) == count
    assert sorted(p["name"] for p in summary["parts"]) == sorted(n for s in summary["sheets"] for n in s["parts"])
    for sheet in summary["sheets"]:
        for name in sheet["files"].values():
            assert (tmp_path / name).exists()
        lines = (tmp_path / sheet["files"]["gcode"]).read_text().splitlines()
        lo, hi = interpret(lines).extent()
        assert lo.min() >= 0 and hi[0] <= 140 and hi[1] <= 140
    assert (tmp_path / "parts-2.svg").exists() and (tmp_path / "laser-2.gcode").exists()
    assert summary["job"]["estimate_seconds"]["total"] == pytest.approx(
        sum(s["job"]["estimate_seconds"]["total"] for s in summary["sheets"]), abs=0.5)
    assert main(["fabricate", "hoot_nanny", "--scale", "5", "--sheet", "140x140", "--max-sheets", "1",
                 "--out", str(tmp_path)]) == 2
    assert "no room for part" in capsys.readouterr().err


def test_a_centre_origin_profile_puts_the_sheet_in_its_work_area(tmp_path, capsys):
    from drivers.profiles import BUILTIN_PROFILES

    toml = BUILTIN_PROFILES["laser"].replace('origin = "front-left"', 'origin = "center"')
    profile = tmp_path / "centre.toml"
    profile.write_text(toml)
    code = main(["fabricate", "spirograph", "--scale", "6", "--sheet", "200x150", "--profile", str(profile),
                 "--out", str(tmp_path / "out"), "--json"])
    assert code == 0
    capsys.readouterr()
    lo, hi = interpret((tmp_path / "out" / "laser.gcode").read_text().splitlines()).extent()
    # The sheet's front-left corner sits at the work area's front-left corner (-200, -200).
    assert lo[0] == pytest.approx(-200.0) and lo[1] == pytest.approx(-200.0)
    assert hi[0] <= -200.0 + 200.0 and hi[1] <= -200.0 + 150.0


@pytest.mark.parametrize(("options", "kerf", "source"), [
    (["--material", "cardboard_2mm"], 0.2, "material"),  # the built-in laser profile's cardboard kerf
    (["--material", "acrylic_3mm_black"], 0.12, "material"),
    (["--material", "cardboard_2mm", "--kerf", "0.05"], 0.05, "given"),
])
def test_kerf_defaults_to_the_material(tmp_path, capsys, options, kerf, source):
    out = tmp_path / "spiro"
    code = main(["fabricate", "spirograph", "--scale", "6", *options, "--out", str(out), "--json"])
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    assert (summary["kerf_mm"], summary["kerf_source"]) == (kerf, source)


def test_kerf_without_a_material_value_is_the_default(tmp_path, capsys):
    profile = tmp_path / "laser.toml"
    profile.write_text(
        "[machine]\nkind = 'laser'\n[work_area]\nwidth = '400mm'\nheight = '400mm'\n[laser]\nmax_power = 1000\n"
        "[materials.card]\nthickness = 2\ncut = {power = 1, feed = 300}\nengrave = {power = 0.2, feed = 1000}\n"
    )
    code = main(["fabricate", "spirograph", "--scale", "6", "--profile", str(profile), "--out", str(tmp_path / "o"),
                 "--json"])
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    assert (summary["kerf_mm"], summary["kerf_source"]) == (0.15, "default")


def _never_build(*args, **kwargs):
    raise AssertionError("the parts were built: the refusal should have come first")


@pytest.mark.parametrize(("machine", "scale", "largest"), [("spirograph", "500", "36"), ("hoot_nanny", "1000", "19")])
def test_a_scale_too_large_for_the_sheet_is_refused_before_building(tmp_path, capsys, monkeypatch, machine, scale,
                                                                     largest):
    # These took 31 s and over 2 minutes before "no room for part": the sizes say it before any gear is generated.
    import design.fabrication

    monkeypatch.setattr(design.fabrication, "machine_parts", _never_build)
    out = tmp_path / "parts"
    assert main(["fabricate", machine, "--scale", scale, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("station: error: sheet 400x400 mm: no room for part")
    assert f"at {scale} mm per unit" in err and f"--scale {largest}" in err and "--sheet WxH" in err
    assert not out.exists()


def test_out_that_is_a_file_is_one_line_before_any_work(tmp_path, capsys, monkeypatch):
    import station.commands.fabricate as command

    monkeypatch.setattr(command, "fabricate", _never_build)
    existing = tmp_path / "notes.txt"
    existing.write_text("mine")
    assert main(["fabricate", "spirograph", "--scale", "6", "--out", str(existing)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--out '{existing}': is a file; expected a folder" in err
    assert main(["fabricate", "spirograph", "--scale", "6", "--out", str(existing / "parts")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is a file, so the folder cannot be made" in err
    assert existing.read_text() == "mine"


def test_progress_steps_cover_each_gear_and_end_at_one(tmp_path):
    from station.services.fabricate import FabricationRequest, fabricate

    steps = []
    result = fabricate(FabricationRequest("hoot_nanny", {}, 4.0), report=Reporter(steps.append))
    assert all(isinstance(step, Progress) for step in steps)  # the one progress type, for the CLI and the TUI
    # The stages come in order, each once, and within a stage the work done never goes back.
    stages = [step.stage for step in steps]
    assert list(dict.fromkeys(stages)) == ["sizes", "gears", "nesting", "sheets"]
    assert stages == sorted(stages, key=["sizes", "gears", "nesting", "sheets"].index)
    for stage in ("gears", "sheets"):
        done = [step.done for step in steps if step.stage == stage]
        assert done == sorted(done) and done[0] == 0
    assert steps[1].fraction == 0.0 and steps[-1].fraction == 1.0 and steps[-1].done == len(result.sheets)
    gears = [part for output in result.sheets for part in output.sheet.parts if "teeth" in part.info]
    assert len(gears) == 3
    for gear in gears:
        assert any(step.message.startswith(f"generating {gear.name} ({gear.info['teeth']} teeth)") for step in steps)
    teeth = [step for step in steps if step.stage == "gears"]
    assert teeth[-1].done == teeth[-1].total == sum(gear.info["teeth"] for gear in gears)


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_is_a_bar_on_a_terminal_and_plain_lines_otherwise(tmp_path, monkeypatch):
    # The command shows the steps with the station's progress view: plain "fabricate: ..." lines in a log (no
    # carriage returns), rich's bars on a terminal; either way stdout keeps only the summary.
    log = io.StringIO()
    monkeypatch.setattr(sys, "stderr", log)
    assert main(["fabricate", "spirograph", "--scale", "6", "--out", str(tmp_path / "log")]) == 0
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue() and lines and all(line.startswith("fabricate: ") for line in lines)
    assert lines[0].startswith("fabricate: sizes: 2/2  the 2 parts of spirograph at 6 mm per unit fit")
    # One line per step: each gear with its teeth, the end of the gears, the nesting, each sheet.
    assert re.fullmatch(r"fabricate: gears: 0/\d+  generating rolling gear \(\d+ teeth\)", lines[1])
    assert re.fullmatch(r"fabricate: gears: \d+/\d+  generating fixed ring \(\d+ teeth\)", lines[2])
    assert re.fullmatch(r"fabricate: gears: (\d+)/\1  generated the 2 parts \(\1 teeth\)", lines[3])
    assert lines[4].startswith("fabricate: nesting:  nesting 2 parts on ")
    assert lines[5] == "fabricate: sheets: 0/1  ordering the laser job of sheet 1 of 1"
    assert lines[-1] == "fabricate: sheets: 1/1  2 parts on 1 sheet"

    terminal = _Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    assert main(["fabricate", "spirograph", "--scale", "6", "--out", str(tmp_path / "tty")]) == 0
    text = terminal.getvalue()
    assert "\r\x1b[2K" in text  # rich's bars, redrawn in place
    for stage in ("sizes: 2/2", "gears: 0/", "nesting:", "sheets: 1/1  2 parts on 1 sheet"):
        assert stage in text
    assert "fabricate: " not in text
