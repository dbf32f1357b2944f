"""A bad JSON file is reported one way: FileFormatError, one line naming the file, the line and what was expected."""

from __future__ import annotations

import pytest

from design.datafiles import load_json
from design.errors import FileFormatError
from station.cli import main

#: Bad files and words their message must have (besides the file's name and "expected").
BAD = {
    "syntax.json": (b'{"points": [[0, 0],\n  [1 1]]}', "not valid JSON (Expecting ',' delimiter at line 2 column 6)"),
    "latin.json": (b'{"name": "caf\xe9"}', "not UTF-8 text (invalid continuation byte at byte 13)"),
    "deep.json": (b"[" * 100_000, "nested deeper than 100 levels of arrays and tables"),
    "nan.json": (b'{"points": [[NaN, 0]]}', "not valid JSON (NaN is not a JSON number)"),
    "empty.json": (b"", "not valid JSON (Expecting value at line 1 column 1)"),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_load_json_raises_one_file_format_error(tmp_path, name):
    raw, words = BAD[name]
    path = tmp_path / name
    path.write_bytes(raw)
    with pytest.raises(FileFormatError) as info:
        load_json(path, "a pattern")
    message = str(info.value)
    assert message == f"{path}: {words}; expected a pattern"
    assert "\n" not in message


def test_load_json_reads_json_and_lets_os_errors_through(tmp_path):
    path = tmp_path / "ok.json"
    path.write_text('{"points": [[0, 1.5]]}')
    assert load_json(path, "x") == {"points": [[0, 1.5]]}
    with pytest.raises(FileNotFoundError):
        load_json(tmp_path / "missing.json", "x")


@pytest.mark.parametrize("name", sorted(BAD))
def test_plot_pattern_bad_file_is_one_line_exit_2(tmp_path, capsys, name):
    # --pattern raised UsageError for bad JSON (FileFormatError for the same file given to --design), and a
    # traceback for a file that is not UTF-8 or nested too deeply.
    raw, words = BAD[name]
    path = tmp_path / name
    path.write_bytes(raw)
    assert main(["plot", "--pattern", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.strip().splitlines() == [f"station: error: {path}: {words}; expected the JSON of `station pattern "
                                        "--json` with a 'points' list"]


@pytest.mark.parametrize(
    ("content", "words"),
    [
        ("[1, 2]", "expected the JSON of `station pattern --json` with a 'points' list"),
        ('{"points": [[0, "a"]]}', "'points' must be a list of [x, y] numbers"),
        ('{"points": [[0, 1]]}', "'points' must be at least two finite [x, y] pairs, got shape (1, 2)"),
    ],
)
def test_plot_pattern_bad_content_names_the_file_first(tmp_path, capsys, content, words):
    path = tmp_path / "p.json"
    path.write_text(content)
    assert main(["plot", "--pattern", str(path)]) == 2
    assert capsys.readouterr().err.strip() == f"station: error: {path}: {words}"


# A deeply nested file escaped these two readers as a RecursionError (a traceback).
def test_design_file_nested_too_deeply_is_one_line(tmp_path, capsys):
    path = tmp_path / "deep.json"
    path.write_bytes(b"[" * 100_000)
    assert main(["pattern", "spirograph", "--design", str(path)]) == 2
    assert "nested deeper than 100 levels" in capsys.readouterr().err


def test_sketch_file_nested_too_deeply_is_a_file_format_error(tmp_path):
    from design.sketch.files import load_sketch

    path = tmp_path / "deep.json"
    path.write_bytes(b"[" * 100_000)
    with pytest.raises(FileFormatError):
        load_sketch(path)


#: Files nested deeper than common.datafiles.MAX_DEPTH (100): TOML that tomllib cannot read (a RecursionError), and
#: files that read but that the code walking them would recurse through.
DEEP = {
    "arrays.toml": "a = " + "[" * 5000 + "]" * 5000,
    "inline.toml": "a = " + "{b = " * 2000 + "1" + "}" * 2000,
    "tables.toml": "[" + ".".join(["a"] * 5000) + "]",
    "inline-150.toml": "a = " + "{b = " * 150 + "1" + "}" * 150,
    "arrays-150.json": "[" * 150 + "]" * 150,
}


@pytest.mark.parametrize("name", sorted(DEEP))
def test_a_file_nested_too_deeply_is_refused_whatever_its_format(tmp_path, name):
    from common.datafiles import DataFileError, parse_data

    with pytest.raises(DataFileError) as info:
        parse_data(DEEP[name].encode(), name, "a scenario")
    assert str(info.value) == f"{name}: nested deeper than 100 levels of arrays and tables; expected a scenario"


def test_a_file_nested_to_the_limit_reads():
    from common.datafiles import parse_data

    def depth(value) -> int:
        return 1 + depth(value[0]) if isinstance(value, list) and value else 1

    # The TOML file's own table is the first level.
    assert depth(parse_data(("[" * 100 + "]" * 100).encode(), "a.json", "x")) == 100
    assert depth(parse_data(("a = " + "[" * 99 + "]" * 99).encode(), "a.toml", "x")["a"]) == 99
