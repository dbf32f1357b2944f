"""Machine profiles: units converted at load time, clear errors, built-in profiles as package data (one source for
every machine setting, the simulated GRBL's EEPROM included)."""

from __future__ import annotations

from pathlib import Path

import pytest

from drivers.profiles import (
    BUILTIN_PROFILES,
    ProfileError,
    builtin_grbl_settings,
    builtin_profile,
    builtin_profile_names,
    load_profile,
    parse_duration,
    parse_feed,
    parse_length,
    profile_from_toml,
)

EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "profiles"


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


def test_builtin_profiles_are_package_data_read_with_importlib_resources():
    from importlib import resources

    folder = resources.files("drivers.profiles").joinpath("builtin")
    assert builtin_profile_names() == ["laser", "plotter"]
    for name in builtin_profile_names():
        text = folder.joinpath(f"{name}.toml").read_text(encoding="utf-8")
        assert BUILTIN_PROFILES[name] == text
        profile = builtin_profile(name)
        assert profile.kind == name and profile.source == f"builtin:{name}"
        assert load_profile(name) == profile  # --profile NAME


def test_no_example_profile_repeats_a_builtin():
    """One source for every machine setting: examples/profiles holds only machines that are not built in."""
    examples = sorted(EXAMPLES.glob("*.toml"))
    assert examples, "examples/profiles has the profile of a machine without homing"
    builtins = [builtin_profile(name) for name in builtin_profile_names()]
    for path in examples:
        example = load_profile(path)
        for builtin in builtins:
            assert (example.name, example.port) != (builtin.name, builtin.port), path.name


#: The EEPROM of the simulated GRBL machines as drivers/sim/grbl/machine.py held it (SIM_PROFILES) before the built-in
#: profiles became its one source: the values must not change on the way.
SIM_PROFILES_BEFORE = {
    "plotter": {
        10: 3, 20: 1, 22: 1, 23: 0, 30: 1000, 32: 0, 100: 80.0, 101: 80.0, 102: 400.0, 110: 8000.0, 111: 8000.0,
        112: 1000.0, 120: 800.0, 121: 800.0, 122: 200.0, 130: 420.0, 131: 297.0, 132: 40.0,
    },
    "laser": {
        10: 3, 20: 1, 22: 1, 23: 0, 30: 1000, 32: 1, 100: 80.0, 101: 80.0, 102: 400.0, 110: 6000.0, 111: 6000.0,
        112: 1000.0, 120: 1000.0, 121: 1000.0, 122: 200.0, 130: 400.0, 131: 400.0, 132: 20.0,
    },
}


@pytest.mark.parametrize("name", sorted(SIM_PROFILES_BEFORE))
def test_builtin_grbl_settings_are_the_simulators_eeprom(name):
    settings = builtin_grbl_settings(name)
    assert settings == SIM_PROFILES_BEFORE[name]
    assert all(isinstance(key, int) and isinstance(value, float) for key, value in settings.items())
    profile = builtin_profile(name)
    assert (settings[130], settings[131]) == (profile.width, profile.height)  # one source: the work area
    assert 130 not in profile.grbl and 131 not in profile.grbl
    settings[100] = 1.0  # a copy: the profile is not changed through it
    assert builtin_grbl_settings(name)[100] == 80.0


def test_grbl_table_takes_numbers_dollar_numbers_and_names():
    profile = profile_from_toml(
        BASE + "[grbl]\n100 = 80\n'$101' = 81.5\nz_steps_per_mm = 400\nhoming_cycle = true\nsoft_limits = 1\n",
        "t.toml")
    assert dict(profile.grbl) == {100: 80.0, 101: 81.5, 102: 400.0, 22: 1.0, 20: 1.0}
    assert profile.grbl_settings[130] == 100.0 and profile.grbl_settings[32] == 1.0
    assert profile_from_toml(BASE, "t.toml").grbl_settings == {30: 1000.0, 32: 1.0, 130: 100.0, 131: 100.0}


@pytest.mark.parametrize(
    ("table", "match"),
    [
        ("300 = 1", r"t.toml \[grbl\]: setting '300' is out of range; expected a number 0..255"),
        ("steps = 80", r"t.toml \[grbl\]: unknown setting 'steps'; expected a number 0..255"),
        ("100 = 80\nx_steps_per_mm = 81", r"\$100 is given twice \('100' and 'x_steps_per_mm'\)"),
        ("100 = 'fast'", r"\[grbl\].100: expected a non-negative number, got 'fast'"),
        ("100 = -80", r"\[grbl\].100: expected a non-negative number, got -80"),
        ("22 = 2", r"\[grbl\].22: \$22 is on/off; expected 0 or 1"),
        ("100 = true", r"\[grbl\].100: \$100 is a number, not on/off"),
        ("23 = 1.5", r"\[grbl\].23: \$23 is a whole number"),
        ("130 = 300", r"\$130 = 300 differs from work_area.width \(100\)"),
        ("30 = 255", r"\$30 = 255 differs from laser.max_power \(1000\)"),
        ("20 = 1\n22 = 0", r"\$20 = 1 \(soft limits\) needs \$22 = 1 \(homing\)"),
    ],
)
def test_bad_grbl_tables_name_the_setting(table, match):
    with pytest.raises(ProfileError, match=match):
        profile_from_toml(BASE + "[grbl]\n" + table, "t.toml")


def test_grbl_table_may_repeat_a_setting_with_its_value_and_refuses_laser_mode_on_a_plotter():
    assert profile_from_toml(BASE + "[grbl]\n130 = 100.0\n32 = 1", "t.toml").grbl[130] == 100.0
    plotter = "[machine]\nkind = 'plotter'\n[work_area]\nwidth = 300\nheight = 300\n[grbl]\n"
    assert profile_from_toml(plotter + "32 = 0", "p.toml").grbl_settings[32] == 0.0
    with pytest.raises(ProfileError, match=r"p.toml \[grbl\]: \$32 = 1 \(laser mode\) on a pen plotter"):
        profile_from_toml(plotter + "laser_mode = 1", "p.toml")


def test_bad_grbl_table_from_the_cli_is_one_line(tmp_path, capsys):
    from station.cli import main

    bad = tmp_path / "bad.toml"
    bad.write_text(BUILTIN_PROFILES["laser"].replace("102 = 400.0", "102 = 'four hundred'"))
    assert main(["plot", "spirograph", "--profile", str(bad), "--out", str(tmp_path / "x.gcode")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{bad} [grbl].102: expected a non-negative number" in err


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
