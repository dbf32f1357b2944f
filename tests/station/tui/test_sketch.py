"""The Sketch retrieval screen: draw on the pad, find designs in a worker, open one on the Drawing screen."""

from __future__ import annotations

import math

import pytest
from textual.widgets import ProgressBar

import station.tui.screens.sketch as sketch_screen
from common.progress import Progress, Reporter
from design.sketch import SketchRetriever
from design.sketch.candidates import DatabaseSettings
from station.tui.app import StationApp
from station.tui.widgets.sketch_pad import SketchPad

SMALL = {"spirograph": DatabaseSettings(max_radius=6, values_per_dimension=3, harmonics=48, points=256)}


@pytest.fixture
def small_retriever(monkeypatch, tmp_path):
    """A small database built in ``tmp_path``; returns the list of the screen's progress reports."""
    seen: list[Progress] = []

    def make(report: Reporter):
        def spy(update: Progress) -> Progress:
            seen.append(update)
            return update

        return SketchRetriever(["spirograph"], cache_dir=tmp_path, settings=SMALL, report=report.mapped(spy))

    monkeypatch.setattr(sketch_screen, "make_retriever", make)
    return seen


async def wait_for_candidates(app, pilot, screen):
    for _ in range(600):  # the worker builds a small database first; generous for a loaded machine
        await pilot.pause(0.1)
        if screen.candidates and screen.query("CandidatePreview"):
            return
    raise AssertionError(f"no candidates; status: {screen.query_one('#status').render()}")


async def test_draw_sector_find_and_open(tmp_path, small_retriever):
    app = StationApp(database=tmp_path / "t.sqlite3")
    async with app.run_test(size=(140, 44)) as pilot:
        await pilot.press("s")
        await pilot.pause()
        assert app.screen.name == "sketch"
        screen = app.screen
        pad = screen.query_one("#pad", SketchPad)
        # a mouse stroke on the pad: press, drag, release
        await pilot.mouse_down("#pad", offset=(10, 5))
        await pilot.hover("#pad", offset=(14, 7))
        await pilot.mouse_up("#pad", offset=(16, 8))
        await pilot.pause()
        assert len(pad.strokes) == 1 and len(pad.strokes[0]) >= 2
        pad.clear()
        # one third of a trefoil-like hypotrochoid (r_f = 3, r_r = 2), drawn in pad coordinates around the centre
        cx, cy = pad.center()
        points = []
        for i in range(40):
            t = 0.2 + (2 * math.pi * 2 / 3) * i / 39
            x = math.cos(t) + 1.3 * math.cos(t / 2)
            y = math.sin(t) - 1.3 * math.sin(t / 2)
            points.append((cx + 12 * x, cy + 12 * y))
        pad.add_stroke(points)
        symmetry = screen.query_one("#symmetry")
        symmetry.value = "3"
        await pilot.pause()
        assert pad.symmetry == 3
        await pilot.press("f")
        await wait_for_candidates(app, pilot, screen)
        # the database build reported the one Progress type, shown in the screen's bar
        assert {p.stage for p in small_retriever} == {"build", "grid", "curves"}
        assert small_retriever[-1].fraction == 1.0
        assert screen.query_one("#progress", ProgressBar).percentage == 1.0
        best = screen.candidates[0]
        assert best.machine == "spirograph" and best.params["r_f"] == 3
        await pilot.click("#candidate-1")
        await pilot.pause()
        assert app.screen.name == "drawing"
        machine, params = app.screen.current_design()
        assert machine == "spirograph" and params["r_f"] == best.params["r_f"] and params["r_r"] == best.params["r_r"]


async def test_bad_sketch_and_symmetry_show_a_message(tmp_path, small_retriever):
    app = StationApp(database=tmp_path / "t.sqlite3")
    async with app.run_test(size=(140, 44)) as pilot:
        await pilot.press("s")
        await pilot.pause()
        screen = app.screen
        await pilot.press("f")  # nothing drawn
        await pilot.pause()
        assert "empty" in str(screen.query_one("#status").render())
        screen.query_one("#symmetry").value = "99"
        await pilot.pause()
        screen.action_find()
        assert "symmetry order" in str(screen.query_one("#status").render())
        await pilot.press("3")  # no candidate yet
        await pilot.pause()
        assert app.screen.name == "sketch"
        # Enter in the symmetry field finds (f would type there) and gives the pad its keys back.
        symmetry = screen.query_one("#symmetry")
        symmetry.value = ""
        symmetry.focus()
        await pilot.press("2", "enter")
        await pilot.pause()
        assert "empty" in str(screen.query_one("#status").render())
        assert app.focused is screen.query_one("#pad", SketchPad) and screen.pad.symmetry == 2
        # a build's progress: its message and share as the status, its stage's counts in the bar
        screen.show_progress(Progress("curves", 3, 12, "spirograph: curves 3/12"))
        await pilot.pause()
        bar = screen.query_one("#progress", ProgressBar)
        assert (bar.progress, bar.total) == (3, 12)
        assert str(screen.query_one("#status").render()) == "spirograph: curves 3/12 (25%)"
