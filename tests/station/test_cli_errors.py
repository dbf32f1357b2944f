"""Every ``station`` command answers bad input with one line on stderr and exit 2, never usage or a traceback.

The commands are discovered from the parser, so a new command is checked without editing this file (and the
missing-file table below must say how to give it a missing file, or that it reads none). All cases stop before any
real work: argparse refuses the first two kinds, and a missing input file is found before anything is computed.
"""

from __future__ import annotations

import argparse
import subprocess
import sys

import pytest

from station.cli import build_parser, main


def _leaf_commands(parser: argparse.ArgumentParser,
                   path: tuple[str, ...] = ()) -> dict[tuple[str, ...], argparse.ArgumentParser]:
    """``{("scenario", "check"): parser, ...}``: every command that does something, nested groups walked."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            found = {}
            for name, sub in action.choices.items():
                found.update(_leaf_commands(sub, (*path, name)))
            return found
    return {path: parser}


def _groups(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    """Command groups that need a subcommand (``("scenario",)``); the top level is not one (it starts the TUI)."""
    groups = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            if path:
                groups.append(path)
            for name, sub in action.choices.items():
                groups.extend(_groups(sub, (*path, name)))
    return groups


PARSER = build_parser()
COMMANDS = _leaf_commands(PARSER)


def _numeric(action: argparse.Action) -> bool:
    """An option taking a number: ``int``, or one of station.cli_util's number types (``number(...)``)."""
    return action.type in (int, float) or hasattr(action.type, "expected")


def _placeholder(action: argparse.Action) -> str:
    """A value argparse accepts for ``action`` (the command never runs: every case here fails in parsing)."""
    if action.choices:
        return str(next(iter(action.choices)))
    if _numeric(action):
        return "1"
    return "x"


def _required_args(parser: argparse.ArgumentParser) -> list[str]:
    """Values for the required positionals and options, so the error under test is the one argparse reports."""
    argv: list[str] = []
    for action in parser._actions:
        if action.option_strings:
            if action.required:
                argv += [action.option_strings[0], _placeholder(action)]
        elif action.nargs not in ("?", "*", argparse.REMAINDER) and not isinstance(action, argparse._SubParsersAction):
            argv.append(_placeholder(action))
    return argv


def _typed_options(parser: argparse.ArgumentParser) -> list[str]:
    return [a.option_strings[0] for a in parser._actions if a.option_strings and _numeric(a)]


def _run(argv: list[str], capsys) -> tuple[int, str, str]:
    """Exit code, stdout and stderr of ``station ARGV`` run in-process (an exception fails the test: a traceback)."""
    try:
        code = main(argv)
    except SystemExit as stop:
        code = stop.code
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _assert_one_line_error(argv: list[str], capsys, *expected: str) -> str:
    code, out, err = _run(argv, capsys)
    assert code == 2, f"station {' '.join(argv)}: exit {code}, stderr {err!r}"
    assert len(err.splitlines()) == 1 and err.endswith("\n"), f"station {' '.join(argv)}: stderr {err!r}"
    assert "Traceback" not in err and "usage:" not in err
    assert out == "", f"station {' '.join(argv)}: stdout {out!r}"
    for text in expected:
        assert text in err, f"station {' '.join(argv)}: {text!r} not in {err!r}"
    return err


def _id(path: tuple[str, ...]) -> str:
    return " ".join(path)


def test_the_commands_are_discovered():
    # A guard that the walk finds the tree: the drawing-machine, machine and contraption commands and a nested one.
    assert {("pattern",), ("fabricate",), ("send",), ("optimize",), ("scenario", "check")} <= set(COMMANDS)


@pytest.mark.parametrize("path", sorted(COMMANDS), ids=_id)
def test_an_unknown_flag_is_one_line_naming_it_and_the_help(path, capsys):
    argv = [*path, *_required_args(COMMANDS[path]), "--no-such-flag"]
    _assert_one_line_error(argv, capsys, "--no-such-flag", f"station {_id(path)} --help")


TYPED = [(path, option) for path in sorted(COMMANDS) for option in _typed_options(COMMANDS[path])]


def test_every_typed_option_is_checked():
    # The commands with int/float options; a command losing all of them would silently drop out of the next test.
    assert {path for path, _ in TYPED} >= {("fabricate",), ("optimize",), ("robustness",), ("send",), ("retrieve",)}


@pytest.mark.parametrize(("path", "option"), TYPED, ids=[f"{_id(p)} {o}" for p, o in TYPED])
def test_a_bad_value_type_is_one_line_naming_the_option(path, option, capsys):
    parser = COMMANDS[path]
    argv = [*path, *_required_args(parser), option, "abc"]
    _assert_one_line_error(argv, capsys, f"argument {option}", "'abc'", f"station {_id(path)} --help")


#: How each command is given an input file that does not exist (None: it reads no file). Every discovered command
#: must be listed, so a new command decides here what its missing file looks like.
MISSING_FILE = {
    ("check",): ["check", "simple", "missing.json", "--image", "frame.png", "--out", "OUT.json"],
    ("compare",): ["compare", "missing.toml"],
    ("devices",): None,  # its file is CHAOS_STATION_CONFIG's: tests/station/test_config.py
    ("explore",): ["explore", "spirograph", "--design", "missing.json"],
    ("fabricate",): ["fabricate", "spirograph", "--design", "missing.json", "--scale", "5", "--out", "OUT"],
    ("jobs",): None,
    ("machines",): None,
    ("optimize",): ["optimize", "missing.toml", "--out", "OUT.json"],
    ("pattern",): ["pattern", "spirograph", "--design", "missing.json"],
    ("plot",): ["plot", "spirograph", "--design", "missing.json", "--out", "OUT.gcode"],
    ("ports",): None,
    ("retrieve",): ["retrieve", "missing.json"],
    ("robustness",): ["robustness", "simple", "missing.json"],
    ("predict",): ["predict", "simple", "missing.json"],
    ("loop",): ["loop", "missing.toml", "--world", "sim://world"],
    ("assemble",): ["assemble", "missing.toml", "success"],
    ("scenario", "check"): ["scenario", "check", "missing.toml"],
    ("send",): ["send", "missing.gcode", "--port", "sim://grbl"],
    ("simulate",): ["simulate", "missing.toml"],
    ("tolerances",): ["tolerances", "simple", "missing.json"],
    ("guide",): ["guide", "simple", "missing.json", "--pdf", "OUT.pdf"],
    ("jigs",): ["jigs", "simple", "missing.json", "--out", "OUT"],
    ("trial", "log"): ["trial", "log", "missing.toml", "success", "--outcome", "last_stops=yes"],
    ("trial", "list"): None,
    ("trial", "show"): None,
    ("trial", "export"): None,  # writes a file; its --out refusals are tests/station/services/test_trial_cli.py's
    ("trial", "import"): ["trial", "import", "missing.json"],
    ("calibrate", "board"): None,
    ("calibrate", "camera"): ["calibrate", "camera", "--images", "missing.d", "--out", "OUT.json"],
    ("calibrate", "plane"): ["calibrate", "plane", "--image", "missing.png"],
    ("calibrate", "bed"): ["calibrate", "bed", "--image", "missing.png", "--out", "OUT.png"],
    ("calibrate", "material"): ["calibrate", "material", "--card", "missing.json", "--image", "missing.png"],
    ("lasertest", "card"): ["lasertest", "card", "--profile", "missing.toml", "--material", "plywood_3mm", "--out",
                            "OUT"],
    ("lasertest", "render"): ["lasertest", "render", "--card", "missing.json", "--out", "OUT.png"],
    ("serve",): None,  # reads no file; its --cert/--key refusals are tests/station/test_serve.py's
    ("calibrate", "sim"): ["calibrate", "sim", "simple", "--trials-json", "missing.json"],
    ("calibrate", "projector"): ["calibrate", "projector", "--camera", "sim://camera", "--projector",
                                  "sim://projector", "--plane", "missing.json"],
}


def test_every_command_has_a_missing_file_case():
    assert set(MISSING_FILE) == set(COMMANDS)


@pytest.mark.parametrize("path", [p for p in sorted(MISSING_FILE) if MISSING_FILE[p]], ids=_id)
def test_a_missing_file_is_one_line_naming_it(path, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    argv = [a.replace("OUT", str(tmp_path / "out")) for a in MISSING_FILE[path]]
    missing = next(a for a in argv if a.startswith("missing."))
    _assert_one_line_error(argv, capsys, missing)
    assert not list(tmp_path.glob("out*"))  # refused before anything was written


@pytest.mark.parametrize("path", _groups(PARSER), ids=_id)
def test_a_bare_command_group_names_its_subcommands_in_one_line(path, capsys):
    group = PARSER._subparsers._group_actions[0].choices[path[0]]
    for name in path[1:]:
        group = group._subparsers._group_actions[0].choices[name]
    subcommands = next(a for a in group._actions if isinstance(a, argparse._SubParsersAction)).choices
    err = _assert_one_line_error(list(path), capsys, f"station {_id(path)} --help", *subcommands)
    assert err.startswith(f"station {_id(path)}: error:")


def test_an_unknown_command_is_one_line():
    # Run as a user runs it: the real exit status and stderr of the console script's module.
    done = subprocess.run([sys.executable, "-m", "station", "no-such-command"], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "invalid choice: 'no-such-command'" in done.stderr
    assert "(see station --help)" in done.stderr and done.stdout == ""


@pytest.mark.parametrize("argv", [["jobs"], []], ids=["jobs", "tui"])
def test_a_station_home_that_is_a_file_is_one_line_naming_the_variable(argv, tmp_path, monkeypatch, capsys):
    home = tmp_path / "home.txt"
    home.write_text("not a folder")
    monkeypatch.setenv("CHAOS_STATION_HOME", str(home))
    # [] would start the TUI: the home folder is made before the first screen, so this ends before any drawing.
    err = _assert_one_line_error(argv, capsys, "CHAOS_STATION_HOME", str(home), "is a file", "must be a folder")
    assert err.startswith("station: error:")
    assert home.read_text() == "not a folder"


def test_a_station_home_under_a_file_names_the_variable(tmp_path, monkeypatch):
    from station import paths
    from station.errors import ConfigError

    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv("CHAOS_STATION_HOME", str(blocker / "home"))
    with pytest.raises(ConfigError, match="CHAOS_STATION_HOME=.*has a file among its parents"):
        paths.data_dir()
    # The cache folder inside a good home, but a file is in its place.
    monkeypatch.setenv("CHAOS_STATION_HOME", str(tmp_path))
    (tmp_path / "cache").write_text("")
    with pytest.raises(ConfigError, match=r"cache folder .*cache.* under CHAOS_STATION_HOME=.* is a file"):
        paths.cache_dir()
