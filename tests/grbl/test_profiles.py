"""Machine profiles: units converted at load time, clear errors, examples equal to the built-ins."""

from __future__ import annotations

from pathlib import Path

import pytest

from drivers.profiles import (
    ProfileError,
    builtin_profile,
    load_profile,
    parse_duration,
    parse_feed,
    parse_length,
    profile_from_toml,
)

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "profiles"


@pytest.mark.parametrize(
    ("text", "expected"),
    [(12, 12.0), ("12mm", 12.0), ("3cm", 30.0), ("1in", 25.4), (" 0.5 m ", 500.0), ("-2mm", -2.0)],
)
def test_lengths_convert_to_mm(text, expected):
    assert parse_length(text) == pytest.approx(expected)


@pytest.mark.parametrize(
    ("text", "expected"), [(3000, 3000.0), ("3000mm/min", 3000.0), ("50mm/s", 3000.0), ("10in/min", 254.0)]
)
def test_feeds_convert_to_mm_per_min(text, expected):
    assert parse_feed(text) == pytest.approx(expected)


@pytest.mark.parametrize(("text", "expected"), [(0.2, 0.2), ("150ms", 0.15), ("2s", 2.0)])
def test_durations_convert_to_seconds(text, expected):
    assert parse_duration(text) == pytest.approx(expected)


@pytest.mark.parametrize("bad", ["12 furlongs", "abc", True, [1]])
def test_bad_length_names_field(bad):
    with pytest.raises(ProfileError, match="work_area.width"):
        parse_length(bad, "work_area.width")


@pytest.mark.parametrize(("file", "name"), [("grbl_pen_plotter.toml", "plotter"), ("grbl_diode_laser.toml", "laser")])
def test_examples_equal_builtins(file, name):
    loaded = load_profile(EXAMPLES / file)
    builtin = builtin_profile(name)
    assert loaded.kind == name
    assert {k: v for k, v in vars(loaded).items() if k != "source"} == {
        k: v for k, v in vars(builtin).items() if k != "source"
    }


def test_laser_profile_fields_for_the_laser_helper():
    laser = builtin_profile("laser")
    assert laser.is_laser and laser.laser.max_power == 1000 and laser.laser.laser_mode is True
    plywood = laser.material("plywood_3mm")
    assert plywood.thickness == 3.0
    assert plywood.cut.power == 1.0 and plywood.cut.feed == 300.0 and plywood.cut.passes == 2
    assert plywood.operation("engrave").s_value(laser.laser.max_power) == pytest.approx(350.0)
    with pytest.raises(ProfileError, match="no material 'steel'.*plywood_3mm"):
        laser.material("steel")


def test_plotter_pen_commands():
    pen = builtin_profile("plotter").pen
    assert pen.up_commands() == ["M3 S50", "G4 P0.15"]
    assert pen.down_commands() == ["M3 S30", "G4 P0.15"]


def test_profile_is_frozen():
    profile = builtin_profile("plotter")
    with pytest.raises(AttributeError):
        profile.width = 1.0


BASE = """
[machine]
kind = "laser"
[work_area]
width = "100mm"
height = "100mm"
[laser]
max_power = 1000
"""


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (
            "[materials.x]\nthickness=3\ncut={power=1.5, feed=100}\nengrave={power=0.1, feed=100}",
            r"materials.x\].cut.power",
        ),
        ("[materials.x]\nthickness=3\ncut={power=1, feed=100}", r"missing table 'engrave'"),
        ("[materials.x]\nthickness=3\ncut={power=1, feed=100, passes=0}\nengrave={power=0.1, feed=100}", "passes"),
        ("[plot]\ndraw_feed='9000mm/min'", "exceeds work_area.max_feed"),
        ("[pen]\nmode='servo'", "only for kind = 'plotter'"),
        ("[materials.x]\nthickness=3\nkerf='3mm'\ncut={power=1, feed=100}\nengrave={power=0.1, feed=100}",
         r"\[materials.x\].kerf: expected a kerf between 0 and 2 mm, got 3 mm"),
        ("[materials.x]\nthickness=3\nkerf='-0.1mm'\ncut={power=1, feed=100}\nengrave={power=0.1, feed=100}",
         r"\[materials.x\].kerf"),
    ],
)
def test_bad_profiles_name_the_field(extra, match):
    with pytest.raises(ProfileError, match=match):
        profile_from_toml(BASE + extra, "t.toml")


@pytest.mark.parametrize(("kerf", "expected"), [("kerf = '0.2mm'", 0.2), ("kerf = 0.1", 0.1), ("", None)])
def test_material_kerf_is_read_in_mm(kerf, expected):
    profile = profile_from_toml(
        BASE + f"[materials.x]\nthickness=3\n{kerf}\ncut={{power=1, feed=100}}\nengrave={{power=0.1, feed=100}}",
        "t.toml")
    assert profile.material("x").kerf == expected


def test_missing_kind_and_bad_toml():
    with pytest.raises(ProfileError, match=r"\[machine\].kind"):
        profile_from_toml("[machine]\nname='x'\n[work_area]\nwidth=1\nheight=1", "t.toml")
    with pytest.raises(ProfileError, match="not valid TOML"):
        profile_from_toml("[machine", "t.toml")
    with pytest.raises(ProfileError, match="no such file"):
        load_profile("/nonexistent/profile.toml")
