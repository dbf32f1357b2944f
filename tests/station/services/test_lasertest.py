"""Laser material test cards: the card as a laser job, its round trip on the twins (burned by the laser twin,
photographed by the camera twin, read back), the settings written into the profile and used by ``station fabricate``,
and bad input as one line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from design.fabrication.lasercard import CardError, CardSpec, card_geometry, linear_steps, read_manifest
from drivers.gcode import interpret
from drivers.profiles import ProfileError, builtin_profile, load_profile, profile_from_toml
from drivers.profiles.loading import BUILTIN_PROFILES
from drivers.sim.laser_burn import line_kerf, sim_material
from station.cli import main
from vision.tags import tag_cells

SMALL = ["--power", "0.4:1:3", "--feed", "250:3000:3"]


def make_card(folder: Path, *extra: str, profile: str = "laser", material: str = "plywood_3mm") -> Path:
    code = main(["lasertest", "card", "--profile", profile, "--material", material, *SMALL, *extra, "--out",
                 str(folder)])
    assert code == 0
    return folder / "card.json"


def test_card_is_a_laser_job_with_every_cell_at_its_settings(tmp_path, capsys):
    card_json = make_card(tmp_path / "card", "--passes", "3")
    capsys.readouterr()
    manifest = json.loads(card_json.read_text())
    assert manifest["format"] == "chaos-station laser test card" and manifest["cut_passes"] == 3
    assert manifest["powers"] == [0.4, 0.7, 1.0] and manifest["feeds_mm_min"] == [250.0, 866.0, 3000.0]
    assert len(manifest["cells"]) == 9 and [t["id"] for t in manifest["tags"]] == [570, 571, 572, 573]
    lines = (tmp_path / "card" / "card.gcode").read_text().splitlines()
    path = interpret(lines)
    assert np.all(path.power[path.rapid] == 0)  # dark on every travel
    assert lines[-1] == "M5 S0"
    lo, hi = path.extent()
    width, height = manifest["card_mm"]
    assert lo[0] >= 0 and lo[1] >= 0 and hi[0] <= 5 + width + 1e-6 and hi[1] <= 5 + height + 1e-6
    ox, oy = manifest["offset_mm"]
    for cell in manifest["cells"]:
        # the cut line: burned at the cell's power and feed, three times
        (x0, y), (x1, _) = cell["cut_line_mm"]
        xs_lo, xs_hi = np.minimum(path.start[:, 0], path.end[:, 0]), np.maximum(path.start[:, 0], path.end[:, 0])
        on_line = (~path.rapid & (path.power > 0) & np.isclose(path.start[:, 1], oy + y)
                   & np.isclose(path.end[:, 1], oy + y) & (xs_lo >= ox + x0 - 1e-6) & (xs_hi <= ox + x1 + 1e-6))
        assert on_line.sum() == 3
        assert np.allclose(path.power[on_line], 1000 * cell["power"]) and np.allclose(path.feed[on_line],
                                                                                       cell["feed_mm_min"])
        # the square: scan lines inside it at the cell's settings, one pass
        sx0, sy0, sx1, sy1 = cell["square_mm"]
        x, y = path.start[:, 0] - ox, path.start[:, 1] - oy
        inside = (~path.rapid & (path.power > 0) & (x >= sx0 - 1e-6) & (x <= sx1 + 1e-6) & (y > sy0) & (y < sy1))
        assert inside.sum() == 80
        assert np.allclose(path.power[inside], 1000 * cell["power"])
    assert Image.open(tmp_path / "card" / "card.png").size[0] > 300
    assert read_manifest(manifest).cut_passes == 3


def test_card_tags_are_the_upstream_bitmaps():
    spec = CardSpec("plywood_3mm", 3.0, linear_steps(0.2, 1.0, 2), (300.0, 3000.0), 1, (0.35, 3000.0, 1),
                    (1.0, 300.0, 2))
    card = card_geometry(spec, tag_cells)
    tag_id, centre, size = card.tags[0]
    fill = [p for name, _, paths, _ in card.operations if name == "mark" for p in paths
            if abs(p[0, 0] - centre[0]) <= 5 * size / 8 and abs(p[0, 1] - centre[1]) <= 5 * size / 8]
    # rasterize the scan lines back into cells and compare with the bitmap (True = white)
    cells = np.ones((10, 10), dtype=bool)
    cell = size / 8.0
    for line in fill:
        row = int((centre[1] + 5 * cell - line[0, 1]) // cell)
        for x in np.arange(line[0, 0] + cell / 2, line[1, 0], cell):
            cells[row, int((x - (centre[0] - 5 * cell)) // cell)] = False
    assert np.array_equal(cells, tag_cells(tag_id))


@pytest.mark.parametrize(("material", "seed"), [("plywood_3mm", 1),
                                               pytest.param("mdf_3mm", 4, marks=pytest.mark.slow)])
def test_round_trip_on_the_twins_measures_the_kerf_and_fabricate_uses_it(tmp_path, capsys, material, seed):
    card_json = make_card(tmp_path / "card", material=material)
    frame = tmp_path / "frame.png"
    assert main(["lasertest", "render", "--card", str(card_json), "--out", str(frame), "--seed", str(seed),
                 "--json"]) == 0
    truth = json.loads(capsys.readouterr().out.strip().splitlines()[-1])["truth"]  # after the card's lines
    twin = sim_material(material)
    assert truth["kerf_mm"] == pytest.approx(line_kerf(twin, 1.0, builtin_profile("laser").material(material).cut.feed,
                                                       builtin_profile("laser").material(material).cut.passes),
                                             abs=1e-4)
    assert main(["calibrate", "material", "--image", str(frame), "--card", str(card_json), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    # the acceptance: the kerf read from the comb within 0.03 mm of the twin's truth (it comes within 0.01)
    assert abs(result["kerf_mm"] - truth["kerf_mm"]) <= 0.03
    assert abs(result["kerf_mm"] - truth["kerf_mm"]) <= 0.01
    assert 0 < result["kerf_uncertainty_mm"] < 0.02
    # which lines went through: every line the twin cut open by a camera pixel or more is seen through, none it left
    # closed is (a line just through, opened less than a pixel, may go either way: no light shows through it)
    seen = {c["name"]: c["cut_through"] for c in result["cells"]}
    for cell in truth["cells"]:
        if cell["cut_kerf_mm"] >= 1.0 / truth["camera"]["px_per_mm"]:
            assert seen[cell["name"]], cell
        elif not cell["through"]:
            assert not seen[cell["name"]], cell
    darkness = {c["name"]: c["darkness"] for c in result["cells"] if c["darkness"] is not None}
    # more energy per millimetre, darker: along each row (power up) and each column (feed down)
    by_settings = {(c["power"], c["feed_mm_min"]): c["darkness"] for c in result["cells"] if c["darkness"] is not None}
    for (power, feed), value in by_settings.items():
        for (other_power, other_feed), other in by_settings.items():
            if other_power >= power and other_feed <= feed and (other_power, other_feed) != (power, feed):
                assert other >= value - 0.02
    assert darkness and (tmp_path / "card" / "card-report.png").is_file()

    chosen = result["chosen"]
    assert result["profile_written"] and chosen["cut"] is not None and chosen["engrave"] is not None
    through = [c for c in result["cells"] if c["cut_through"]]
    assert chosen["cut"]["feed_mm_min"] == max(c["feed_mm_min"] for c in through)
    written = load_profile(result["profile_file"]).material(material)
    assert written.kerf == pytest.approx(result["kerf_mm"])
    assert (written.cut.power, written.cut.feed, written.cut.passes) == (
        chosen["cut"]["power"], chosen["cut"]["feed_mm_min"], chosen["cut"]["passes"])
    assert written.measured["kerf_uncertainty_mm"] == pytest.approx(result["kerf_uncertainty_mm"])
    assert written.measured["card"] == str(card_json.resolve()) and written.measured["frame"] == str(frame.resolve())

    # the next fabricate on the built-in profile's name takes the measured material
    assert main(["fabricate", "spirograph", "--set", "r_f=5", "--set", "r_r=3", "--set", "d=2", "--scale", "6",
                 "--material", material, "--out", str(tmp_path / "parts"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["kerf_mm"] == pytest.approx(result["kerf_mm"]) and summary["kerf_source"] == "material"
    assert summary["job"]["cut"] == {"power": chosen["cut"]["power"], "feed_mm_min": chosen["cut"]["feed_mm_min"],
                                     "passes": chosen["cut"]["passes"]}
    gcode = (tmp_path / "parts" / "laser.gcode").read_text()
    assert f"; cut: S{1000 * chosen['cut']['power']:g} " in gcode


def test_a_profile_file_of_yours_is_written_only_with_yes(tmp_path, capsys, station_home):
    mine = tmp_path / "shop.toml"
    text = BUILTIN_PROFILES["laser"].replace("[materials.mdf_3mm]", "# our MDF from the shop next door\n"
                                             "[materials.mdf_3mm]")
    mine.write_text(text)
    card_json = make_card(tmp_path / "card", profile=str(mine))
    frame = tmp_path / "frame.png"
    assert main(["lasertest", "render", "--card", str(card_json), "--out", str(frame), "--px-per-mm", "12"]) == 0
    capsys.readouterr()
    assert main(["calibrate", "material", "--image", str(frame), "--card", str(card_json)]) == 0
    out = capsys.readouterr().out
    assert "not written" in out and "--yes" in out and "[materials.plywood_3mm.measured]" in out
    assert mine.read_text() == text
    assert main(["calibrate", "material", "--image", str(frame), "--card", str(card_json), "--yes"]) == 0
    updated = mine.read_text()
    assert updated != text and "# our MDF from the shop next door\n[materials.mdf_3mm]" in updated
    profile = load_profile(mine)
    assert profile.material("plywood_3mm").measured["by"] == "station calibrate material"
    assert profile.material("mdf_3mm") == builtin_profile("laser").material("mdf_3mm")
    assert not (station_home / "profiles").exists()  # the station's copy is for built-in profiles only


def test_measured_table_must_hold_plain_values():
    text = BUILTIN_PROFILES["laser"] + "\n[materials.plywood_3mm.measured.deeper]\nx = 1\n"
    with pytest.raises(ProfileError, match=r"\[materials.plywood_3mm\].measured.deeper: expected text, a number"):
        profile_from_toml(text, "p.toml")


def test_manifest_errors_name_the_field():
    with pytest.raises(CardError, match=r"c.json.format: expected 'chaos-station laser test card'"):
        read_manifest({"format": "x"}, "c.json")


def bad(argv, capsys) -> str:
    try:
        code = main(argv)
    except SystemExit as stop:  # argparse's own refusals
        code = stop.code
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err, err
    return err


@pytest.mark.parametrize(("extra", "expected"), [
    (["--power", "0.2:1"], "--power '0.2:1': expected FIRST:LAST:COUNT"),
    (["--power", "0:2:3"], "--power '0:2:3': expected values from 0.001 to 1"),
    (["--power", "0.2:1:40"], "expected a COUNT from 1 to 12"),
    (["--feed", "100:9000:3"], "--feed '100:9000:3': expected values from 1 to 6000 mm/min"),
    (["--passes", "0"], "--passes 0: expected a whole number from 1 to 20"),
    (["--material", "balsa"], "no material 'balsa'"),
])
def test_card_bad_input_is_one_line(tmp_path, capsys, extra, expected):
    argv = ["lasertest", "card", "--material", "plywood_3mm", "--out", str(tmp_path / "c"), *extra]
    assert expected in bad(argv, capsys)


def test_calibrate_material_bad_input_is_one_line(tmp_path, capsys, station_home):
    card_json = make_card(tmp_path / "card")
    capsys.readouterr()
    blank = tmp_path / "blank.png"
    Image.fromarray(np.full((400, 600, 3), 200, np.uint8)).save(blank)
    not_json = tmp_path / "x.json"
    not_json.write_text("{")
    other = tmp_path / "other.json"
    other.write_text(json.dumps({**json.loads(card_json.read_text()), "cells": [{"row": 0}]}))
    cases = [
        (["--image", str(tmp_path / "none.png"), "--card", str(card_json)], "--image: no such file"),
        (["--image", str(blank), "--card", str(tmp_path / "none.json")], "--card '"),
        (["--image", str(blank), "--card", str(not_json)], "not valid JSON"),
        (["--image", str(blank), "--card", str(other)], "other.json.cells[0].cut_line_mm: expected two [x, y]"),
        (["--image", str(blank), "--card", str(card_json)], "found 0 of the card's reference tags"),
        (["--image", str(blank), "--card", str(card_json), "--darkness", "1.5"], "--darkness"),
        (["--card", str(card_json)], "give --image FRAME (a photo of the card) or --camera URL"),
    ]
    for extra, expected in cases:
        assert expected in bad(["calibrate", "material", *extra], capsys)
    assert not (station_home / "profiles").exists()


async def test_fabricate_screen_makes_a_test_card_and_queues_it(tmp_path, station_home):
    from ..tui.test_fabricate import opened, wait_for

    async with opened(tmp_path, "f", wait=False) as (app, pilot):
        screen = app.screen
        await wait_for(pilot, screen, lambda: screen.result is not None)
        await pilot.press("t")
        machines = app.get_screen("machines")
        await wait_for(pilot, screen, lambda: getattr(machines, "jobs", None))
        entry = machines.jobs[-1]
        assert entry.device == "laser" and entry.job.laser
        cards = sorted((station_home / "lasertest").glob("plywood_3mm-*/card.json"))
        assert len(cards) == 1
        assert entry.job.lines == (cards[0].parent / "card.gcode").read_text().splitlines()
        assert "test card (plywood_3mm)" in screen.last_message


@pytest.mark.parametrize(("power", "feed", "passes"), [(1.0, 300.0, 2), (0.6, 400.0, 2), (0.5, 300.0, 1)])
def test_the_laser_twins_burned_line_opens_its_true_kerf(power, feed, passes):
    from drivers.sim.laser_burn import burn_gcode

    material = sim_material("plywood_3mm")
    s = 1000 * power
    lines = ["G21 G90", "M4 S0", "G0 X2 Y5 S0"] + [f"G1 X18 Y5 S{s:g} F{feed:g}", "G0 X2 Y5 S0"] * passes + ["M5 S0"]
    sheet = burn_gcode(lines, material, (0.0, 0.0, 20.0, 10.0), px_per_mm=40.0)
    opened = sheet.through[:, 200].sum() / 40.0  # the column across the middle of the line
    assert opened == pytest.approx(line_kerf(material, power, feed, passes), abs=0.004)
    assert sheet.through[:, 20].sum() == 0  # before the line starts: nothing cut


def test_a_material_missing_from_the_profile_file_is_appended(tmp_path):
    from station.services.profiles import replace_material_table

    text = BUILTIN_PROFILES["laser"]
    block = ('[materials.balsa_2mm]\nthickness = "2mm"\nkerf = "0.1mm"\ncut = { power = 0.5, feed = "600mm/min" }\n'
             'engrave = { power = 0.2, feed = "3000mm/min" }\n\n[materials.balsa_2mm.measured]\nby = "hand"\n')
    updated = replace_material_table(text, "balsa_2mm", block, "p.toml")
    assert updated.startswith(text.rstrip("\n"))
    assert profile_from_toml(updated, "p.toml").material("balsa_2mm").measured["by"] == "hand"
    again = replace_material_table(updated, "balsa_2mm", block.replace('"hand"', '"card"'), "p.toml")
    assert again.count("[materials.balsa_2mm]") == 1 and 'by = "card"' in again and 'by = "hand"' not in again
    with pytest.raises(ProfileError, match="p.toml"):
        replace_material_table(text, "balsa_2mm", block.replace('"0.1mm"', '"9mm"'), "p.toml")
