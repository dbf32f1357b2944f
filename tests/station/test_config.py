"""The station config file (station.toml): the devices it names, the default without it, one line per mistake."""

from __future__ import annotations

import json

import pytest

from station.cli import main
from station.config import (
    CONFIG_VARIABLE,
    DEFAULT_CONFIG_TEXT,
    config_location,
    configured_devices,
    devices_from_text,
    load_config,
    write_default_config,
)
from station.devices import DeviceEntry, default_devices, machine_profile
from station.errors import ConfigError, StationError

PLOTTER = '[[devices]]\nname = "p"\nkind = "plotter"\nurl = "sim://grbl?profile=plotter"\n'
CAMERA = '[[devices]]\nname = "c"\nkind = "camera"\nurl = "sim://camera"\n'
GRBL_FORMS = "sim://grbl?profile=NAME, /dev/tty*, COMn, socket://HOST:PORT, rfc2217://HOST:PORT, loop://"
CAMERA_FORMS = ("sim://camera, an index such as 0, /dev/video*, rtsp://..., http(s)://..., a video file "
                "(.mp4, .avi, .mkv, .mov, .webm)")
NAME_RULE = "a name of letters, digits, '-', '_' and '.' (at most 32)"

BAD = [
    ("devices = 3", "devices: expected [[devices]] tables (an array of tables), got a number (3)"),
    ('[devices.plotter]\nkind = "plotter"',
     "devices: expected [[devices]] tables (an array of tables), got a table ([devices] or [devices.NAME])"),
    ('colour = "red"\n' + PLOTTER, "colour: unknown field; expected one of: devices, database"),
    ("devices = [1]", "devices[0]: expected a table (mapping), got a number (1)"),
    ("[[devices]\n", "not valid TOML (Expected ']]' at the end of an array declaration at line 1 column 10); "
                      "expected a station config ([[devices]] tables)"),
    (PLOTTER + CAMERA + '[[devices]]\nname = "x"\nkind = "lazer"\nurl = "/dev/ttyUSB0"\n',
     "devices[2].kind: expected one of plotter, laser, camera, projector, got 'lazer'"),
    (PLOTTER + '[[devices]]\nname = "q"\nkind = 3\nurl = "x"\n',
     "devices[1].kind: expected one of plotter, laser, camera, projector, got a number (3)"),
    ('[[devices]]\nkind = "plotter"\nurl = "/dev/ttyUSB0"\n', f"devices[0].name: missing; expected {NAME_RULE}"),
    ('[[devices]]\nname = "big laser"\nkind = "laser"\nurl = "/dev/ttyUSB0"\n',
     f"devices[0].name: expected {NAME_RULE}, got 'big laser'"),
    ('[[devices]]\nname = "p"\nkind = "plotter"\n', f"devices[0].url: missing; expected a plotter URL ({GRBL_FORMS})"),
    ('[[devices]]\nname = "p"\nkind = "plotter"\nurl = 5\n',
     f"devices[0].url: expected a plotter URL ({GRBL_FORMS}), got a number (5)"),
    ('[[devices]]\nname = "p"\nkind = "plotter"\nurl = "ftp://x"\n',
     f"devices[0].url: device URL 'ftp://x' matches no driver; accepted: GRBL: {GRBL_FORMS}; camera: {CAMERA_FORMS}; "
     "projector: sim://projector, display:N; world: sim://world"),
    ('[[devices]]\nname = "p"\nkind = "plotter"\nurl = "sim://camera"\n',
     f"devices[0].url: expected a plotter URL ({GRBL_FORMS}), got a camera URL 'sim://camera'"),
    ('[[devices]]\nname = "c"\nkind = "camera"\nurl = "/dev/ttyUSB0"\n',
     f"devices[0].url: expected a camera URL ({CAMERA_FORMS}), got a GRBL URL '/dev/ttyUSB0'"),
    ('[[devices]]\nname = "p"\nkind = "plotter"\nurl = "sim://grbl?profile=laser"\n',
     "devices[0].url: expected a simulated plotter (profile=plotter), got profile=laser"),
    ('[[devices]]\nname = "p"\nkind = "plotter"\nurl = "sim://grbl?profile=nope"\n',
     "devices[0].url: expected a simulated plotter (profile=plotter), got profile=nope"),
    ('[[devices]]\nname = "l"\nkind = "laser"\nurl = "sim://grbl"\n',
     "devices[0].url: expected a simulated laser (sim://grbl?profile=laser), got 'sim://grbl', which names no "
     "profile"),
    (PLOTTER + PLOTTER, "devices[1].name: expected a name no other device has, got 'p' (devices[0] has it)"),
    ('[[devices]]\nname = "a"\nkind = "plotter"\nurl = "/dev/ttyUSB0"\n'
     '[[devices]]\nname = "b"\nkind = "laser"\nurl = "/dev/ttyUSB0"\n',
     "devices[1].url: expected a port no other device uses, got '/dev/ttyUSB0' (devices[0] uses it)"),
    (PLOTTER + 'colour = "red"\n',
     "devices[0].colour: unknown field; expected one of: name, kind, url, profile, options"),
    (PLOTTER + 'profile = "laser"\n', "devices[0].profile: expected a plotter profile, got a laser profile ('laser')"),
    (PLOTTER + "profile = 2\n",
     "devices[0].profile: expected a built-in profile (laser, plotter) or a profile file, got a number (2)"),
    (CAMERA + 'profile = "plotter"\n',
     "devices[0].profile: expected no profile on a camera (profiles are for plotters and lasers)"),
    (PLOTTER + "options = { baud = 9600 }\n", "devices[0].options.baud: unknown field; expected one of: timeout"),
    (PLOTTER + "options = { timeout = 0 }\n", "devices[0].options.timeout: expected a number > 0, got 0"),
    (PLOTTER + "options = { timeout = 60 }\n", "devices[0].options.timeout: expected at most 10 s, got 60"),
    (PLOTTER + 'options = { timeout = "2s" }\n', "devices[0].options.timeout: expected a number, got text ('2s')"),
    (PLOTTER + "options = 3\n", "devices[0].options: expected a table (mapping), got a number (3)"),
    (CAMERA + "options = { fps = 30 }\n", "devices[0].options.fps: unknown field; expected one of: laser"),
    (CAMERA + 'options = { laser = "shop-laser" }\n',
     "devices[0].options.laser: expected the name of a laser in this file (none), got 'shop-laser'"),
    (CAMERA + "options = { laser = 3 }\n", "devices[0].options.laser: expected a name of letters, digits, '-', '_' "
     "and '.' (at most 32), got a number (3)"),
]


@pytest.mark.parametrize(("text", "message"), BAD, ids=[m.split(":")[0] + f"-{i}" for i, (_, m) in enumerate(BAD)])
def test_bad_config_is_one_line_naming_file_field_and_expected_value(text, message, tmp_path):
    with pytest.raises(ConfigError) as caught:
        devices_from_text(text, "station.toml", tmp_path)
    assert str(caught.value) == f"station.toml: {message}"
    assert caught.value.file == "station.toml"
    assert caught.value.field == ("" if message.startswith("not valid TOML") else message.split(": ")[0])
    assert isinstance(caught.value, StationError) and isinstance(caught.value, ValueError)


def test_profile_files_are_relative_to_the_config_and_checked(tmp_path):
    profiles = tmp_path / "profiles"
    profiles.mkdir()
    (profiles / "a3.toml").write_text(_plotter_profile("A3 plotter"))
    (profiles / "broken.toml").write_text('[machine]\nname = "x"\nkind = "plotter"\n')
    text = '[[devices]]\nname = "big"\nkind = "plotter"\nurl = "/dev/ttyUSB0"\nprofile = "profiles/a3.toml"\n'
    (device,) = devices_from_text(text, "station.toml", tmp_path)
    assert device.profile == str((profiles / "a3.toml").resolve())
    assert machine_profile(device).name == "A3 plotter"
    with pytest.raises(ConfigError, match=r"^station.toml: devices\[0\].profile: .*no such file: .*none.toml\)$"):
        devices_from_text(text.replace("a3.toml", "none.toml"), "station.toml", tmp_path)
    with pytest.raises(ConfigError, match=r"^station.toml: devices\[0\].profile: .*broken.toml: missing table"):
        devices_from_text(text.replace("a3.toml", "broken.toml"), "station.toml", tmp_path)


def _plotter_profile(name: str) -> str:
    from drivers.profiles import BUILTIN_PROFILES

    return BUILTIN_PROFILES["plotter"].replace('name = "GRBL pen plotter"', f'name = "{name}"')


def test_a_good_config_in_file_order_with_defaults(tmp_path):
    text = (PLOTTER + CAMERA + '[[devices]]\nname = "shop-laser"\nkind = "laser"\nurl = "/dev/ttyUSB0"\n'
            "options = { timeout = 2.5 }\n")
    plotter, camera, laser = devices_from_text(text, "station.toml", tmp_path)
    assert plotter == DeviceEntry("p", "plotter", "sim://grbl?profile=plotter", True, "plotter")
    assert camera == DeviceEntry("c", "camera", "sim://camera", True)
    assert (laser.simulated, laser.profile, dict(laser.options)) == (False, "laser", {"timeout": 2.5})
    assert machine_profile(laser).is_laser
    with pytest.raises(TypeError):
        laser.options["timeout"] = 1  # frozen all the way down


def test_the_default_config_text_is_the_built_in_default():
    assert devices_from_text(DEFAULT_CONFIG_TEXT, "station.toml") == default_devices()


def test_no_file_is_the_all_simulated_default(station_home, monkeypatch):
    monkeypatch.delenv(CONFIG_VARIABLE, raising=False)
    assert config_location() == (station_home / "station.toml", False)
    config = load_config()
    assert (config.path, config.devices) == (None, default_devices())
    assert configured_devices() == default_devices()


def test_every_section_is_optional_and_only_what_is_there_is_checked(station_home, monkeypatch, capsys):
    monkeypatch.delenv(CONFIG_VARIABLE, raising=False)
    monkeypatch.delenv("CHAOS_STATION_DATABASE", raising=False)
    for text in ("", "# nothing set yet\n", "[database]\n"):
        assert devices_from_text(text, "station.toml", station_home) == default_devices()
    # a file that only says where the database is: the simulated devices, and that database for the trial log
    (station_home / "station.toml").write_text('[database]\nurl = "shared.sqlite3"\n')
    config = load_config()
    assert config.devices == default_devices()
    assert config.database == str(station_home / "shared.sqlite3")
    assert main(["trial", "list"]) == 0
    assert capsys.readouterr().out == f"no trials yet (database {station_home / 'shared.sqlite3'})\n"
    assert main(["devices", "--no-probe", "--json"]) == 0
    assert [d["name"] for d in json.loads(capsys.readouterr().out)["devices"]] == [d.name for d in default_devices()]
    # what is there and wrong is still refused, with or without the other section
    (station_home / "station.toml").write_text('[database]\nurl = "mysql://x/y"\n')
    assert main(["trial", "list"]) == 2
    assert "station.toml: database.url: database URL 'mysql://x/y': expected" in capsys.readouterr().err
    (station_home / "station.toml").write_text('[database]\nurl = "shared.sqlite3"\n[[devices]]\nname = "x"\n')
    assert main(["trial", "list"]) == 2
    assert "station.toml: devices[0].kind: missing" in capsys.readouterr().err


def test_the_config_in_the_data_folder_is_read(station_home, monkeypatch):
    monkeypatch.delenv(CONFIG_VARIABLE, raising=False)
    (station_home / "station.toml").write_text(CAMERA)
    config = load_config()
    assert config.path == station_home / "station.toml"
    assert [d.name for d in config.devices] == ["c"]


def test_the_variable_names_a_file_that_must_exist(tmp_path, monkeypatch):
    chosen = tmp_path / "elsewhere.toml"
    monkeypatch.setenv(CONFIG_VARIABLE, str(chosen))
    with pytest.raises(ConfigError, match=f"^station config {CONFIG_VARIABLE}='.*elsewhere.toml': no such file; "
                       "expected a station.toml file$"):
        load_config()
    chosen.write_text(PLOTTER)
    assert [d.name for d in configured_devices()] == ["p"]
    assert load_config().path == chosen


def test_a_file_given_must_exist(tmp_path):
    with pytest.raises(ConfigError, match=r"^station config '.*none.toml': no such file; expected a station.toml "
                       "file$"):
        load_config(tmp_path / "none.toml")


def test_unreadable_files_are_one_line(tmp_path):
    folder = tmp_path / "station.toml"
    folder.mkdir()
    with pytest.raises(ConfigError, match=r"station.toml: cannot read: Is a directory$"):
        load_config(folder)
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\xff\xfe devices")
    with pytest.raises(ConfigError, match=r"binary.toml: expected UTF-8 text \(invalid start byte at byte 0\)$"):
        load_config(binary)


def test_init_writes_the_default_once_and_never_over_a_file(tmp_path):
    target = tmp_path / "station.toml"
    assert write_default_config(target) == target
    assert load_config(target).devices == default_devices()
    target.write_text(CAMERA)
    with pytest.raises(ConfigError, match="already exists; the station never writes over it"):
        write_default_config(target)
    assert target.read_text() == CAMERA


def test_a_bad_config_stops_the_tui_with_one_line(station_home, monkeypatch, capsys):
    monkeypatch.delenv(CONFIG_VARIABLE, raising=False)
    (station_home / "station.toml").write_text(PLOTTER.replace('"plotter"\nurl', '"lazer"\nurl'))
    assert main([]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert err == (f"station: error: {station_home / 'station.toml'}: devices[0].kind: expected one of plotter, "
                   "laser, camera, projector, got 'lazer'\n")


def test_devices_command_json_contract(station_home, monkeypatch, capsys):
    monkeypatch.delenv(CONFIG_VARIABLE, raising=False)
    assert main(["devices", "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)
    assert listed["config"] is None
    assert listed["devices"] == [
        {"name": "plotter", "kind": "plotter", "url": "sim://grbl?profile=plotter", "simulated": True,
         "driver": "grbl-serial", "state": "connected: Grbl 1.1h, Idle"},
        {"name": "laser", "kind": "laser", "url": "sim://grbl?profile=laser", "simulated": True,
         "driver": "grbl-serial", "state": "connected: Grbl 1.1h, Idle"},
        {"name": "camera", "kind": "camera", "url": "sim://camera?projector=projector", "simulated": True,
         "driver": "sim-camera", "state": "open: 1920x1080"},
        {"name": "projector", "kind": "projector", "url": "sim://projector?name=projector", "simulated": True,
         "driver": "sim-projector", "state": "open: 1280x800"},
    ]


def test_devices_command_lists_a_configured_real_device(station_home, monkeypatch, capsys):
    monkeypatch.delenv(CONFIG_VARIABLE, raising=False)
    (station_home / "station.toml").write_text(
        '[[devices]]\nname = "shop"\nkind = "laser"\nurl = "/dev/ttyUSB99"\n' + CAMERA)
    assert main(["devices"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"config: {station_home / 'station.toml'}"
    assert lines[1].split() == ["NAME", "KIND", "MODE", "URL", "DRIVER", "STATE"]
    assert lines[2].split() == ["shop", "laser", "real", "/dev/ttyUSB99", "grbl-serial", "not", "connected:", "no",
                                "such", "port"]
    assert lines[3].split() == ["c", "camera", "simulated", "sim://camera", "sim-camera", "open:", "1920x1080"]
    assert main(["devices", "--no-probe", "--json"]) == 0
    states = [d["state"] for d in json.loads(capsys.readouterr().out)["devices"]]
    assert states == ["not probed", "not probed"]


def test_devices_init_refuses_to_overwrite(station_home, monkeypatch, capsys):
    monkeypatch.delenv(CONFIG_VARIABLE, raising=False)
    assert main(["devices", "--init", "--no-probe"]) == 0
    assert capsys.readouterr().out.startswith(f"wrote {station_home / 'station.toml'}")
    assert main(["devices", "--init"]) == 2
    assert "already exists; the station never writes over it" in capsys.readouterr().err


def test_a_camera_names_the_laser_whose_bed_it_looks_down_on():
    text = ('[[devices]]\nname = "shop-laser"\nkind = "laser"\nurl = "sim://grbl?profile=laser"\n' + CAMERA
            + 'options = { laser = "shop-laser" }\n')
    devices = devices_from_text(text)
    assert dict(devices[1].options) == {"laser": "shop-laser"}
