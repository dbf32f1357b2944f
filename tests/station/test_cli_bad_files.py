"""One way to report a bad data file, on every command that reads one: exit 2 and one line on stderr,
``station: error: FILE: not valid JSON (WHAT at line L column C); expected ...`` (or ``not UTF-8 text``, ``not valid
TOML``), the file named first. The one reader is :mod:`common.datafiles`."""

from __future__ import annotations

import pytest

from station.cli import main

#: Every command that reads a JSON (or TOML) file, with ``{file}`` where the file goes.
COMMANDS = {
    "retrieve": ["retrieve", "{file}"],
    "pattern --design": ["pattern", "spirograph", "--design", "{file}"],
    "plot --design": ["plot", "spirograph", "--design", "{file}", "--out", "{tmp}/x.gcode"],
    "plot --pattern": ["plot", "--pattern", "{file}", "--out", "{tmp}/x.gcode"],
    "explore --design": ["explore", "spirograph", "--design", "{file}"],
    "fabricate --design": ["fabricate", "spirograph", "--design", "{file}", "--scale", "8", "--out", "{tmp}/parts"],
    "simulate": ["simulate", "{file}"],
    "simulate --layout": ["simulate", "simple", "--layout", "{file}"],
    "scenario check": ["scenario", "check", "{file}"],
    "optimize": ["optimize", "{file}", "--out", "{tmp}/layout.json"],
    "optimize --settings": ["optimize", "simple", "--settings", "{file}", "--out", "{tmp}/layout.json"],
    "robustness": ["robustness", "{file}", "success"],
    "robustness LAYOUT": ["robustness", "simple", "{file}"],
    "compare": ["compare", "{file}"],
}

#: A bad file's bytes and what its one line says after ``FILE: ``.
BAD = {
    "syntax": (b'{"a": 1,\n  "b": }\n', "not valid JSON (Expecting value at line 2 column 8); expected "),
    "latin-1": (b'{"name": "caf\xe9"}', "not UTF-8 text (invalid continuation byte at byte 13); expected "),
    "NaN": (b'{"a": NaN}', "not valid JSON (NaN is not a JSON number); expected "),
}


@pytest.mark.parametrize("bad", sorted(BAD))
@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_malformed_json_file_is_one_line_naming_the_file(tmp_path, capsys, command, bad):
    raw, words = BAD[bad]
    path = tmp_path / "bad.json"
    path.write_bytes(raw)
    argv = [arg.format(file=path, tmp=tmp_path) for arg in COMMANDS[command]]
    assert main(argv) == 2
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith(f"station: error: {path}: {words}"), lines[0]
    assert captured.out == ""
    assert not (tmp_path / "parts").exists() and not (tmp_path / "layout.json").exists()


@pytest.mark.parametrize("command", ["simulate", "simulate --layout"])
def test_a_malformed_toml_file_is_reported_the_same_way(tmp_path, capsys, command):
    path = tmp_path / "bad.toml"
    path.write_text("[scenario\nname = 1\n")
    argv = [arg.format(file=path, tmp=tmp_path) for arg in COMMANDS[command]]
    assert main(argv) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith(f"station: error: {path}: not valid TOML (")
    assert " at line 1 column " in line and "); expected " in line


#: Commands that read a machine profile (TOML): ``drivers`` reads it through the same reader.
PROFILE_COMMANDS = {
    "plot --profile": ["plot", "spirograph", "--profile", "{file}", "--out", "{tmp}/x.gcode"],
    "fabricate --profile": ["fabricate", "spirograph", "--profile", "{file}", "--scale", "8", "--out", "{tmp}/parts"],
    "send --profile": ["send", "{tmp}/job.gcode", "--profile", "{file}"],
}


@pytest.mark.parametrize("command", sorted(PROFILE_COMMANDS))
@pytest.mark.parametrize("raw, words", [
    (b"[machine\nname = 1\n", "not valid TOML (Expected ']' at the end of a table declaration at line 1 column 9); "
                              "expected a machine profile"),
    (b'[machine]\nname = "caf\xe9"\n', "not UTF-8 text (invalid continuation byte at byte 21); expected "),
])
def test_a_malformed_profile_is_reported_the_same_way(tmp_path, capsys, command, raw, words):
    path = tmp_path / "bad.toml"
    path.write_bytes(raw)
    (tmp_path / "job.gcode").write_text("G21\nG90\nG0 X1 Y1\n")
    argv = [arg.format(file=path, tmp=tmp_path) for arg in PROFILE_COMMANDS[command]]
    assert main(argv) == 2
    captured = capsys.readouterr()
    (line,) = captured.err.splitlines()
    assert line.startswith(f"station: error: {path}: {words}"), line
