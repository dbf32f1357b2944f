"""Bad input found by trying every command adversarially: frames the tag detector cannot take, files nested too
deeply, numbers that are not finite or not in range, outputs that cannot be written, manifests with NaN or 1e308,
scenarios and budgets that cannot finish. Each is refused before any work in one line naming the thing, the field
and what was expected, with exit 2: never a traceback, a crash, a late failure or exit 0.
"""

from __future__ import annotations

import argparse
import json
import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

from station.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[2]
SIMPLE = ROOT / "examples" / "scenarios" / "simple.toml"
SKETCH = ROOT / "examples" / "sketches" / "seven-star.json"
#: A folder no file can be created in, whatever the permissions say (tests run as root, too).
PROC = Path("/proc")


# -- the input files ---------------------------------------------------------------------------------------------
def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def blank_png(path: Path, width: int, height: int) -> Path:
    """A valid black grey PNG of any size, compressed as it is made (a 20000x20000 one is 2 MB, never in memory)."""
    packer = zlib.compressobj(1)
    rows = bytes(width + 1) * 256  # each row: filter byte 0, then the pixels
    data = [packer.compress(rows) for _ in range(height // 256)]
    data += [packer.compress(bytes(width + 1) * (height % 256)), packer.flush()]
    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", header) + _png_chunk(b"IDAT", b"".join(data))
                     + _png_chunk(b"IEND", b""))
    return path


def _manifest() -> dict:
    from station.services.guide import GuideRequest, make_guide

    return make_guide(GuideRequest(str(SIMPLE), "success", tolerances=False)).manifest()


def _bad_manifest(path: Path, change) -> Path:
    manifest = _manifest()
    change(manifest)
    path.write_text(json.dumps(manifest))  # json writes NaN as NaN, as a hand edit or another program might
    return path


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _scenario(path: Path, old: str, new: str) -> Path:
    text = SIMPLE.read_text()
    assert old in text
    path.write_text(text.replace(old, new))
    return path


def _objects(path: Path, count: int) -> Path:
    boxes = "".join(f'\n[[objects]]\nname = "box{i}"\ntype = "Box"\nshape = {{ size = [0.01, 0.01, 0.01] }}\n'
                    f'transform = {{ x = {0.02 * i:.2f}, z = 0.5 }}\nmaterial = "wood"\n' for i in range(count))
    path.write_text(SIMPLE.read_text() + boxes)
    return path


DOMINOES = "path = [[0.0, 0.0], [0.03, 0.0]], count = 3"

#: The files a case names as {name} in its arguments, made in the test's folder.
FILES = {
    "tiny": lambda d: blank_png(d / "tiny.png", 1, 1),
    "huge": lambda d: blank_png(d / "huge.png", 20000, 20000),
    "large": lambda d: blank_png(d / "large.png", 9000, 6000),
    "deep_arrays": lambda d: _write(d / "deep.toml", "a = " + "[" * 5000 + "]" * 5000),
    "deep_inline": lambda d: _write(d / "inline.toml", "a = " + "{b = " * 2000 + "1" + "}" * 2000),
    "nan_part": lambda d: _bad_manifest(d / "nan.json", lambda m: m["parts"][0]["center_mm"].__setitem__(0, np.nan)),
    "huge_tag": lambda d: _bad_manifest(d / "big.json",
                                        lambda m: m["reference_tags"][0]["center_mm"].__setitem__(0, 1e308)),
    "million": lambda d: _scenario(d / "million.toml", DOMINOES, "path = [[0.0, 0.0], [15000.0, 0.0]], "
                                   "count = 1000000"),
    "dense": lambda d: _scenario(d / "dense.toml", DOMINOES, "path = [[0.0, 0.0], [0.03, 0.0]], spacing = 1e-6"),
    "objects": lambda d: _objects(d / "objects.toml", 10_000),
}

#: Each case: its id, the command (``{name}``: a file of FILES, ``{out}``: a path in the test's folder) and the words
#: its one line must hold.
CASES = [
    # a frame the tag detector cannot take (a 1x1 one killed the process inside pupil-apriltags: SIGSEGV)
    ("check-1x1", ["check", "simple", "success", "--image", "{tiny}", "--predict", "0"],
     ["--image", "tiny.png", "1x1 pixels is too small", "at least 20x20"]),
    ("plane-1x1", ["calibrate", "plane", "--image", "{tiny}"], ["--image", "tiny.png", "at least 20x20"]),
    ("check-20000x20000", ["check", "simple", "success", "--image", "{huge}", "--predict", "0"],
     ["--image", "huge.png", "too large", "at most 50 megapixels"]),
    ("plane-20000x20000", ["calibrate", "plane", "--image", "{huge}"], ["--image", "at most 50 megapixels"]),
    ("check-54MP", ["check", "simple", "success", "--image", "{large}", "--predict", "0"],
     ["--image", "9000x6000 pixels (54 MP) is too large", "at most 50 megapixels"]),
    # files nested too deeply (a RecursionError)
    ("toml-arrays-5000-deep", ["scenario", "check", "{deep_arrays}"],
     ["deep.toml", "nested deeper than 100 levels", "expected a scenario"]),
    ("toml-inline-2000-deep", ["scenario", "check", "{deep_inline}"], ["inline.toml", "nested deeper than 100"]),
    # numbers that are not finite, or out of range, where they are parsed
    ("plot-tolerance-nan", ["plot", "spirograph", "--tolerance", "nan", "--out", "{out}.gcode"],
     ["argument --tolerance", "expected a number >= 0", "'nan'"]),
    ("plot-size-nan", ["plot", "spirograph", "--size", "nan", "--out", "{out}.gcode"],
     ["argument --size", "expected a number > 0", "'nan'"]),
    ("settle-nan", ["calibrate", "projector", "--settle", "nan"], ["argument --settle", "[0, 10]", "'nan'"]),
    ("settle-negative", ["calibrate", "projector", "--settle", "-1"], ["argument --settle", "[0, 10]", "'-1'"]),
    ("fabricate-scale-1e308", ["fabricate", "spirograph", "--scale", "1e308", "--out", "{out}"],
     ["scale", "at most 1000", "1e+308"]),
    ("sim-offset-1e308", ["check", "simple", "success", "--camera", "sim://camera", "--predict", "0", "--sim-offset",
                          "track=1e308,1e308"], ["--sim-offset", "at most 1000 mm", "track=1e308,1e308"]),
    # guide manifests: one reader for the check and the plane fix
    ("check-guide-nan", ["check", "simple", "success", "--camera", "sim://camera", "--predict", "0", "--guide",
                         "{nan_part}"], ["--guide", "nan.json", "NaN is not a JSON number"]),
    ("check-guide-1e308", ["check", "simple", "success", "--camera", "sim://camera", "--predict", "0", "--guide",
                           "{huge_tag}"], ["--guide", "'reference_tags[0].center_mm'", "within ±10000", "1e+308"]),
    ("plane-guide-1e308", ["calibrate", "plane", "--camera", "sim://camera", "--guide", "{huge_tag}"],
     ["--guide", "'reference_tags[0].center_mm'", "within ±10000"]),
    # what cannot finish
    ("a-million-dominoes", ["scenario", "check", "{million}"],
     ["million.toml", "objects[3].shape.count", "at most 2000 dominoes in a run", "got 1000000"]),
    ("dominoes-by-spacing", ["simulate", "{dense}"], ["objects[3].shape.spacing", "at most 2000 dominoes"]),
    ("ten-thousand-objects", ["scenario", "check", "{objects}"], ["objects: expected at most 2000 objects"]),
    ("budget-1e12", ["optimize", "simple", "--budget", "1000000000000", "--out", "{out}.json"],
     ["--budget must be at most 20000 simulations", "1000000000000", "days"]),
]


def _argv(template: list[str], folder: Path) -> list[str]:
    argv = []
    for word in template:
        for name, make in FILES.items():
            if f"{{{name}}}" in word:
                path = folder / f".{name}"  # made once per test
                if not path.exists():
                    path.write_text(str(make(folder)))
                word = word.replace(f"{{{name}}}", path.read_text())
        argv.append(word.replace("{out}", str(folder / "out")))
    return argv


def _one_line(code, out: str, err: str, argv: list[str], words) -> str:
    assert code == 2, f"station {' '.join(argv)}: exit {code}, stderr {err[-2000:]!r}"
    assert len(err.splitlines()) == 1 and "Traceback" not in err, f"station {' '.join(argv)}: {err[-2000:]!r}"
    assert out == ""
    for text in words:
        assert text in err, f"{text!r} not in {err!r}"
    return err


@pytest.mark.parametrize(("template", "words"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_input_is_one_line_and_exit_2(template, words, tmp_path, monkeypatch, capsys):
    argv = _argv(template, tmp_path)
    monkeypatch.chdir(tmp_path)
    if template[0] in ("check", "calibrate") and "{tiny}" in template:
        # In a process of its own: on a detector given the frame, the process dies (SIGSEGV) with no error line.
        done = subprocess.run([sys.executable, "-m", "station", *argv], capture_output=True, text=True, timeout=300,
                              env={**os.environ, "PYTHONPATH": str(ROOT)})
        _one_line(done.returncode, done.stdout, done.stderr, argv, words)
    else:
        try:
            code = main(argv)
        except SystemExit as stop:
            code = stop.code
        captured = capsys.readouterr()
        _one_line(code, captured.out, captured.err, argv, words)
    assert not list(tmp_path.glob("out*"))  # refused before anything was written


def test_the_check_and_the_plane_fix_refuse_a_manifest_in_the_same_words(tmp_path, capsys):
    from station.services.guide_manifest import read_manifest

    for name in ("huge_tag", "nan_part"):
        path = str(FILES[name](tmp_path))
        lines = []
        for argv in (["check", "simple", "success", "--camera", "sim://camera", "--predict", "0", "--guide", path],
                     ["calibrate", "plane", "--camera", "sim://camera", "--guide", path]):
            assert main(argv) == 2
            lines.append(capsys.readouterr().err)
        assert lines[0] == lines[1] and lines[0].startswith(f"station: error: --guide {path}: ")
    good = tmp_path / "good.json"
    good.write_text(json.dumps(_manifest()))
    assert read_manifest(good)["reference_tags"]  # the manifest `station guide --json` prints reads


def test_the_detector_refuses_what_would_kill_the_process():
    from vision.detection import TagDetector
    from vision.errors import VisionError

    detector = TagDetector(2.0)
    for shape in [(1, 1), (4, 100), (100, 4), (19, 640)]:
        with pytest.raises(VisionError, match=r"too small; expected at least 20x20"):
            detector.detect(np.zeros(shape, np.uint8))
    assert detector.detect(np.zeros((20, 20), np.uint8)) == []
    with pytest.raises(VisionError, match="at least 32x32"):  # 4 rows of quads at an eighth of the size
        TagDetector(8.0).detect(np.zeros((31, 640), np.uint8))


# -- numbers -----------------------------------------------------------------------------------------------------
def _options(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()):
    """(command path, option action) of every option of every command."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _options(sub, (*path, name))
        elif action.option_strings:
            yield path, action


OPTIONS = list(_options(build_parser()))
NUMBERS = [(path, action.option_strings[0]) for path, action in OPTIONS if hasattr(action.type, "expected")]


def test_no_option_takes_a_bare_float():
    # float() takes nan, inf and 1e999, which pass every later comparison: each number option says what it takes
    bare = [f"station {' '.join(path)} {action.option_strings[0]}" for path, action in OPTIONS if action.type is float]
    assert bare == []
    assert len(NUMBERS) >= 20


@pytest.mark.parametrize(("path", "option"), NUMBERS, ids=[f"{' '.join(p)} {o}" for p, o in NUMBERS])
@pytest.mark.parametrize("value", ["nan", "inf", "-1e999"])
def test_a_number_option_refuses_what_is_not_finite(path, option, value, capsys):
    parser = build_parser()
    with pytest.raises(SystemExit) as stop:
        parser.parse_args([*path, f"{option}={value}"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {option}: expected " in err and repr(value) in err


# -- outputs -----------------------------------------------------------------------------------------------------
#: Every command with an output file or folder: the command, its flag and the suffix (None: a folder).
OUTPUTS = [
    (["pattern", "spirograph"], "--out", ".png"),
    (["plot", "spirograph"], "--out", ".gcode"),
    (["explore", "spirograph"], "--out", ".png"),
    (["retrieve", str(SKETCH)], "--out", None),
    (["fabricate", "spirograph", "--scale", "8"], "--out", None),
    (["jigs", "simple", "success"], "--out", None),
    (["check", "simple", "success", "--camera", "sim://camera", "--predict", "0"], "--out", ".json"),
    (["check", "simple", "success", "--camera", "sim://camera", "--predict", "0"], "--overlay", ".png"),
    (["calibrate", "board"], "--pdf", ".pdf"),
    (["calibrate", "camera", "--images", str(ROOT)], "--out", ".json"),
    (["calibrate", "projector", "--camera", "sim://camera", "--projector", "sim://projector"], "--out", ".json"),
    (["calibrate", "sim", "simple"], "--out", ".toml"),
    (["simulate", "simple"], "--render", ".png"),
    (["optimize", "simple", "--budget", "20"], "--out", ".json"),
    (["robustness", "simple", "layout.json"], "--plot", ".png"),
    (["compare", "simple"], "--plot", ".png"),
    (["guide", "simple", "success"], "--pdf", ".pdf"),
    (["guide", "simple", "success"], "--svg", ".svg"),
    (["assemble", "simple", "success"], "--sheet", ".pdf"),
]


def _bad_places(folder: Path, suffix: str | None) -> list[tuple[str, list[str]]]:
    """(path, words) of outputs that cannot be written: under a file, where the file system takes no file, empty."""
    a_file = folder / "FILE"
    a_file.write_text("a file")
    name = f"x{suffix or ''}"
    places = [(str(a_file / name), ["FILE", "not a folder" if suffix else "is a file"]),
              ("", ["''", "expected a file name" if suffix else "expected a folder name"])]
    if PROC.is_dir():
        places.append((str(PROC / name), ["cannot create a file there" if suffix else "cannot make a folder"]))
    return places


@pytest.mark.parametrize(("command", "flag", "suffix"), OUTPUTS,
                         ids=[" ".join([w for w in c[:2] if "/" not in w] + [f]) for c, f, _s in OUTPUTS])
def test_an_output_that_cannot_be_written_is_refused_before_the_work(command, flag, suffix, tmp_path, monkeypatch,
                                                                     capsys):
    monkeypatch.chdir(tmp_path)
    for place, words in _bad_places(tmp_path, suffix):
        if flag == "--sheet" and place == "":
            continue  # `--sheet` alone (its value "") writes to the station's data folder
        argv = [*command, flag, place]
        try:
            code = main(argv)
        except SystemExit as stop:
            code = stop.code
        captured = capsys.readouterr()
        _one_line(code, captured.out, captured.err, argv, [flag, *words])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["FILE"]  # nothing made, nothing left


def test_checking_an_output_changes_nothing_there(tmp_path):
    from station.cli_util import check_output_file, check_output_folder

    existing = tmp_path / "kept.json"
    existing.write_text("the user's file")
    before = existing.stat().st_mtime_ns
    assert check_output_file(existing, {".json"}, "--out") == existing
    assert existing.read_text() == "the user's file" and existing.stat().st_mtime_ns == before
    assert check_output_file(tmp_path / "new.json", {".json"}, "--out") == tmp_path / "new.json"
    assert check_output_folder(tmp_path / "a" / "b", "--out") == tmp_path / "a" / "b"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept.json"]
