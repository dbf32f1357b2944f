"""Plots of several layers, one pen each: a composition of two patterns and an SVG (with a ``<use>``, a ``<rect>``
and a hidden layer) written as one job with a pen change between layers, streamed on the simulated GRBL with a pause
at each pen change that says which pen to put in, the job history keeping the layer, a resume from that layer, and
vpype's sorting against none."""

from __future__ import annotations

import io
import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from cam.layers import PenLayer, write_layers_gcode
from cam.plot import WriterOptions
from drivers.gcode import drawn_polylines
from drivers.gcode_layers import layer_marks, pause_lines
from drivers.profiles import load_profile
from station.cli import main
from station.services import plot as plot_service
from station.services.machines import pattern_points as _sample

ROOT = Path(__file__).resolve().parents[3]
EXAMPLES = ROOT / "examples" / "plots"
FAST = "time_scale=0.002&wire=0"


@pytest.fixture
def composition(tmp_path) -> Path:
    """The example composition (two patterns and frame.svg) in a folder of its own, with the design it names."""
    folder = tmp_path / "plots"
    folder.mkdir()
    shutil.copy(EXAMPLES / "frame.svg", folder / "frame.svg")
    (tmp_path / "patterns").mkdir()
    shutil.copy(ROOT / "examples" / "patterns" / "hoot_nanny_star.json", tmp_path / "patterns")
    shutil.copy(EXAMPLES / "three-pens.toml", folder / "three-pens.toml")
    return folder / "three-pens.toml"


def drawn_length(polylines) -> float:
    return float(sum(np.linalg.norm(np.diff(p, axis=0), axis=1).sum() for p in polylines))


def sim_drawn_length(record: Path, pen_down: float) -> float:
    """What the simulated machine drew: the length of its feed blocks with the pen servo at ``pen_down``."""
    executed = json.loads(record.read_text())["executed"]
    total, previous = 0.0, None
    for _, text, end, power, _ in executed:
        end = np.array(end[:2])
        if previous is not None and text.upper().startswith("G1") and power == pen_down:
            total += float(np.hypot(*(end - previous)))
        previous = end
    return total


def test_the_writer_marks_each_layer_and_pauses_before_every_pen_but_the_first():
    square = np.array([[0, 0], [10, 0], [10, 10], [0, 10], [0, 0]], dtype=float)
    layers = [PenLayer("a", "black", "#000000", [square]), PenLayer("b (hatch)", 'red "fine"', "#d62728",
                                                                     [square + 20], draw_feed=1200),
              PenLayer("c", "blue", "#1f77b4", [square + 40])]
    stream = io.StringIO()
    options = WriterOptions(comment="test")
    write_layers_gcode(layers, stream, options, pen_change=("G0 X0 Y0", "M0"))
    lines = stream.getvalue().splitlines()
    marks = layer_marks(lines)
    assert [(m.number, m.count, m.name, m.pen) for m in marks] == [(1, 3, "a", "black"), (2, 3, "b hatch", "red fine"),
                                                                   (3, 3, "c", "blue")]
    assert marks[0].pause is None and [lines[m.pause] for m in marks[1:]] == ["M0", "M0"]
    assert pause_lines(lines) == [marks[1].pause, marks[2].pause]
    # each layer's pen change says which pen, and the layer draws at its own feed
    assert lines[marks[1].line + 1] == '(pen change: put in pen "red fine" for layer 2/3 "b hatch", then resume)'
    assert any(line.endswith("F1200") for line in lines[marks[1].line:marks[2].line])
    drawn = drawn_polylines(lines, options.pen_down, options.pen_up)
    assert len(drawn) == 3 and np.allclose(drawn[1], square + 20) and np.allclose(drawn[2], square + 40)


def test_a_three_layer_composition_plots_on_the_simulated_grbl_with_two_pen_changes(composition, tmp_path, capsys,
                                                                                    monkeypatch):
    job, record = tmp_path / "three.gcode", tmp_path / "record.json"
    assert main(["plot", "--compose", str(composition), "--out", str(job), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert [layer["name"] for layer in summary["layers"]] == ["rosette", "star", "frame"]
    assert summary["pen_changes"] == 2
    lines = job.read_text().splitlines()
    marks = layer_marks(lines)
    assert [m.pen for m in marks] == ["blue 0.3 mm", "red 0.5 mm", "green 0.5 mm"]
    assert sum(1 for line in lines if line == "M0") == 2

    # the SVG's layer: the <rect> and the four <use> corners, 180 x 150 mm as drawn; its hidden layer (a circle
    # 200 mm across and two lines through the page) is not drawn
    profile = load_profile("plotter")
    result = plot_service.plot(plot_service.load_composition(composition, _load_design), profile, sample=_sample)
    frame = result.document.layers[2]
    assert len(frame.polylines) == 5
    lo, hi = plot_service._bounds(frame.polylines)
    assert np.allclose(hi - lo, [170, 140], atol=0.01)
    assert np.allclose((lo + hi) / 2, [297 / 2, 210 / 2], atol=0.01)  # centred on the A4 paper
    rect_and_corners = 2 * (170 + 140) + 4 * 20
    assert frame_length(frame) == pytest.approx(rect_and_corners, abs=0.5)

    # on the simulated GRBL: a pause at each pen change naming the pen, Enter resumes, everything drawn once
    monkeypatch.setattr(sys, "stdin", io.StringIO("\n\n"))
    port = f"sim://grbl?profile=plotter&{FAST}&record={record}"
    assert main(["send", str(job), "--port", port]) == 0
    err = capsys.readouterr().err
    prompts = [line for line in err.splitlines() if "pen change: put in pen" in line]
    assert prompts == [
        'station: pen change: put in pen "red 0.5 mm" for layer 2/3 "star": press Enter to resume (Ctrl-C aborts)',
        'station: pen change: put in pen "green 0.5 mm" for layer 3/3 "frame": press Enter to resume (Ctrl-C aborts)',
    ]
    expected = drawn_length(p for layer in result.document.layers for p in layer.polylines)
    assert sim_drawn_length(record, profile.pen.down) == pytest.approx(expected, rel=1e-3)


def frame_length(layer) -> float:
    return drawn_length(layer.polylines)


def _load_design(path, machine):
    from station.services.designs import load_design

    return load_design(path, machine)


def test_a_plot_stopped_at_a_pen_change_is_recorded_at_its_layer_and_resumes_there(composition, tmp_path, capsys,
                                                                                    monkeypatch):
    job = tmp_path / "three.gcode"
    assert main(["plot", "--compose", str(composition), "--out", str(job)]) == 0
    marks = layer_marks(job.read_text().splitlines())
    # nobody at the machine (standard input at its end): the job stops at the first pen change
    monkeypatch.setattr(sys, "stdin", io.StringIO(""))
    assert main(["send", str(job), "--port", f"sim://grbl?profile=plotter&{FAST}", "--json"]) == 1
    out, err = capsys.readouterr()
    ended = json.loads(out.strip().splitlines()[-1])
    assert ended["state"] == "aborted" and "standard input closed at the pen change" in err
    assert ended["resume_line"] == marks[1].pause + 1  # the pause again: the pen was not changed
    assert ended["layer"]["number"] == 2 and ended["layer"]["pen"] == "red 0.5 mm"

    assert main(["jobs", "--json"]) == 0
    (last, *_) = json.loads(capsys.readouterr().out)["jobs"]
    assert last["layer"]["number"] == 2 and last["layer"]["name"] == "star"
    assert main(["jobs"]) == 0
    assert '--from-layer 2 starts it again' in capsys.readouterr().out

    # from layer 2: its pen change first, then layer 3's; layer 1 is not drawn again
    record = tmp_path / "record.json"
    monkeypatch.setattr(sys, "stdin", io.StringIO("\n\n"))
    port = f"sim://grbl?profile=plotter&{FAST}&record={record}"
    assert main(["send", str(job), "--port", port, "--from-layer", "2"]) == 0
    err = capsys.readouterr().err
    assert 'starting at layer 2/3 "star"' in err
    assert [line.split(" for ")[1].split(":")[0] for line in err.splitlines() if "put in pen" in line] == [
        'layer 2/3 "star"', 'layer 3/3 "frame"']
    profile = load_profile("plotter")
    lines = job.read_text().splitlines()
    later = drawn_polylines(lines[:1] + ["G21 G90 G94"] + lines[marks[1].line:], profile.pen.down_commands(),
                            profile.pen.up_commands())
    assert sim_drawn_length(record, profile.pen.down) == pytest.approx(drawn_length(later), rel=1e-3)
    everything = drawn_polylines(lines, profile.pen.down_commands(), profile.pen.up_commands())
    assert drawn_length(later) < 0.8 * drawn_length(everything)


def test_vpype_sorting_travels_less_than_the_paths_as_drawn(tmp_path):
    rng = np.random.default_rng(7)
    paths = []
    for _ in range(120):
        x, y = rng.uniform(10, 170, 2)
        angle = rng.uniform(0, np.pi)
        paths.append(f'<path d="M {x:.2f},{y:.2f} l {8 * np.cos(angle):.2f},{8 * np.sin(angle):.2f}"/>')
    svg = tmp_path / "strokes.svg"
    svg.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="180mm" height="180mm" viewBox="0 0 180 180">'
                   '<g style="fill:none;stroke:black">' + "".join(paths) + "</g></svg>")
    profile = load_profile("plotter")
    composition = plot_service.Composition([plot_service.SvgSource(svg)])
    sorted_ = plot_service.plot(composition, profile, sort=True)
    as_drawn = plot_service.plot(composition, profile, sort=False)
    assert sorted_.travel_mm < 0.5 * as_drawn.travel_mm
    # the same drawing either way
    assert drawn_length(sorted_.document.layers[0].polylines) == pytest.approx(
        drawn_length(as_drawn.document.layers[0].polylines), rel=1e-6)
    assert sum(layer.time_s for layer in sorted_.layers) < sum(layer.time_s for layer in as_drawn.layers)


def test_station_plot_an_svg_alone_with_a_preview(tmp_path, capsys):
    from PIL import Image

    job, picture = tmp_path / "frame.gcode", tmp_path / "frame.png"
    assert main(["plot", "--svg", str(EXAMPLES / "frame.svg"), "--out", str(job), "--preview", str(picture)]) == 0
    err = capsys.readouterr().err
    assert "1 layer, 0 pen changes" in err and f"wrote {job} and {picture}" in err
    assert [m.name for m in layer_marks(job.read_text().splitlines())] == ["frame"]
    image = np.asarray(Image.open(picture).convert("RGB"))
    green = np.all(image == (0x2C, 0xA0, 0x2C), axis=2)
    red = (image[..., 0] > 200) & (image[..., 1] < 60) & (image[..., 2] < 60)
    assert green.sum() > 1000 and red.sum() == 0  # the frame in its colour; the hidden red layer nowhere


def test_a_pattern_at_a_scale_keeps_its_size_in_mm_per_unit():
    from design.machines import get_machine

    model = get_machine("spirograph")
    curve = model.sample(model.validate({}), n=512, spacing="arclength")
    composition = plot_service.Composition([plot_service.PatternSource("spirograph", {}, scale=6.0, points=512,
                                                                       offset=(10.0, -5.0))])
    document = plot_service.compose(composition, load_profile("plotter"), sample=_sample)
    lo, hi = plot_service._bounds(document.layers[0].polylines)
    assert np.allclose(hi - lo, 6.0 * np.ptp(curve, axis=0), atol=1e-9)
    assert np.allclose((lo + hi) / 2, [297 / 2 + 10, 210 / 2 - 5], atol=1e-9)


def test_several_designs_make_one_layer_each(tmp_path, capsys):
    design = tmp_path / "d.json"
    design.write_text(json.dumps({"machine": "spirograph", "params": {"d": 1.0}}))
    job = tmp_path / "two.gcode"
    assert main(["plot", "spirograph", "--design", str(design), "--design", str(design), "--size", "80",
                 "--out", str(job), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert [layer["name"] for layer in summary["layers"]] == ["d", "d 2"] and summary["pen_changes"] == 1
    assert summary["layers"][0]["color"] != summary["layers"][1]["color"]


@pytest.mark.parametrize("text, words", [
    ("[[patterns]]\nmachine = 'spirograph'\nsize = -3\n", "patterns[1].size: expected a number > 0, got -3"),
    ("[[patterns]]\nmachine = 'spirograph'\nsise = 3\n", "patterns[1]: unknown field 'sise'"),
    ("[[svg]]\nfile = 'missing.svg'\n", "missing.svg: no such SVG file"),
    ("[[svg]]\nfile = 'frame.svg'\nscale = 3\n", "reaches"),
    ("[[layers]]\nname = 'a'\ncolor = 'red'\n[[svg]]\nfile = 'frame.svg'\n",
     "layers[1].color: expected a colour as #rrggbb, got 'red'"),
    ("", "nothing to plot"),
    ("[[patterns]]\nmachine = 'spirograph'\nsize = 50\nscale = 2\n", "patterns[1]: give size (mm, its largest side) "
     "or scale (mm per unit), not both"),
])
def test_a_bad_composition_is_one_line_naming_the_file_and_field(tmp_path, capsys, text, words):
    shutil.copy(EXAMPLES / "frame.svg", tmp_path / "frame.svg")
    path = tmp_path / "c.toml"
    path.write_text(text)
    assert main(["plot", "--compose", str(path), "--out", str(tmp_path / "x.gcode")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err and (str(path) in err or "missing.svg" in err
                                                            or "SVG" in err)


def test_from_layer_is_refused_out_of_range_and_on_a_job_without_layers(tmp_path, capsys):
    job = tmp_path / "one.gcode"
    assert main(["plot", "spirograph", "--out", str(job)]) == 0
    capsys.readouterr()
    assert main(["send", str(job), "--port", f"sim://grbl?profile=plotter&{FAST}", "--from-layer", "2"]) == 2
    assert "--from-layer needs a plot of layers" in capsys.readouterr().err
    layered = tmp_path / "svg.gcode"
    assert main(["plot", "--svg", str(EXAMPLES / "frame.svg"), "--out", str(layered)]) == 0
    capsys.readouterr()
    assert main(["send", str(layered), "--port", f"sim://grbl?profile=plotter&{FAST}", "--from-layer", "4"]) == 2
    assert "--from-layer must be between 1 and 1" in capsys.readouterr().err


def test_a_bad_pen_change_macro_in_a_profile_is_refused(tmp_path):
    from drivers.profiles import ProfileError
    from drivers.profiles.loading import BUILTIN_PROFILES

    text = BUILTIN_PROFILES["plotter"]
    assert 'change = ["G0 X0 Y0", "M0"]' in text
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('change = ["G0 X0 Y0", "M0"]', 'change = ["G0 X0 Y0", "M30"]'))
    with pytest.raises(ProfileError, match=r"\[pen\]\.change: 'M30' ends the program"):
        load_profile(str(bad))


def test_a_hold_the_maker_asks_for_is_not_a_pause_of_the_program():
    import time

    from drivers.grbl import GrblConnection, Job, JobRunner

    lines = ["G21 G90 G94", "M3 S50", "G0 X10 Y10", *(f"G1 X{10 + i} Y10 F300" for i in range(1, 21)), "M0",
             "G1 X10 Y20"]
    seen: list[str] = []
    with GrblConnection("sim://grbl?profile=plotter&clock=virtual&pace=3") as conn:
        runner = JobRunner(conn, Job("pause", lines), on_progress=lambda p: seen.append(p.state))
        runner.start()
        deadline = time.monotonic() + 60  # a liveness guard: the machine runs on the virtual clock

        def until(predicate) -> None:
            while not predicate():
                assert time.monotonic() < deadline, "condition not reached in time"
                time.sleep(0.02)

        until(lambda: runner.progress.lines_acked > 4)
        runner.hold()
        until(lambda: conn.status is not None and conn.status.label == "Hold:0")
        reports: list[object] = []
        conn.add_listener(lambda event, data: reports.append(data) if event == "status" else None)
        until(lambda: len(reports) >= 3)  # status reports keep coming while held: none of them is a pause
        assert runner.progress.state == "holding" and runner.pause_line is None
        runner.resume()
        until(lambda: runner.progress.state == "paused")
        assert runner.pause_line == lines.index("M0")
        assert runner.progress.message == f"program pause (M0) at line {lines.index('M0') + 1}"
        runner.resume()
        assert runner.wait(60).state == "done"
    assert "paused" in seen  # told to whoever draws the progress
