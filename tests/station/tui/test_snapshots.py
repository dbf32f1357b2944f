"""Snapshots of every screen: how home and each area screen look, so that a change to a screen's look shows in review.

Each screen is kept twice under ``tests/station/tui/snapshots/``: ``NAME.svg`` (the picture, colours and all; open
it in a browser) and ``NAME.txt`` (its characters, for a readable diff). The screens are the home screen and every area
:func:`station.tui.registry.discover_screens` finds, so a new screen fails here until its snapshot is made.

Make or update the snapshots after a deliberate change (then look at the SVGs, and commit them)::

    STATION_UPDATE_SNAPSHOTS=1 python -m pytest tests/station/tui/test_snapshots.py     (or: make snapshots)

What a screen shows that changes between runs is pinned: the clocks the screens read (``time`` in the
``station.tui`` modules: the Fabricate screen says how long it took), Python's global random generator (the
simulated devices seed their own), the database path shown on home (a relative path in a fixed folder), the devices
(the built-in simulated set, whose probes answer the same every time) and the terminal's size.
"""

from __future__ import annotations

import difflib
import io
import os
import random
import sys
import time
import types
from pathlib import Path

import pytest
from rich.console import Console
from textual.widgets import DataTable, Input, RichLog

from station.tui.registry import discover_screens

from ...conftest import settle

SNAPSHOTS = Path(__file__).resolve().parent / "snapshots"
SIZE = (120, 36)
UPDATE = os.environ.get("STATION_UPDATE_SNAPSHOTS") == "1"
REGENERATE = "STATION_UPDATE_SNAPSHOTS=1 python -m pytest tests/station/tui/test_snapshots.py"

#: Seconds a screen may take to settle after its workers are done (on a loaded machine).
SETTLE_SECONDS = 15.0

#: What a screen has done when its snapshot may be taken, beyond its workers being done (by the screen's name).
READY = {
    # the probes' answers are in (a probe is a worker; its answer widens the table's column on a later refresh)
    "home": lambda text: text.count("connected: Grbl 1.1h, Idle") == 2 and "open: 1280x800" in text,
    # connected to the simulated plotter on arrival: the connection's last word is said under the queue and in the
    # console, which scrolls to it on a later refresh
    "machines": lambda text: text.count("plotter: GRBL 1.1h connected") == 2,
}

#: The moment every frozen clock shows (2026-01-02 03:04:05 UTC).
FROZEN_EPOCH = 1767323045.0


def screen_names() -> list[str]:
    return ["home", *(entry.name for entry in discover_screens())]


class FrozenTime(types.ModuleType):
    """The :mod:`time` module with its clocks stopped at :data:`FROZEN_EPOCH` (sleeping still sleeps)."""

    def __init__(self) -> None:
        super().__init__("time")

    def __getattr__(self, name: str):
        return getattr(time, name)

    @staticmethod
    def time() -> float:
        return FROZEN_EPOCH

    perf_counter = monotonic = time
    perf_counter_ns = monotonic_ns = time_ns = staticmethod(lambda: int(FROZEN_EPOCH * 1e9))

    @staticmethod
    def localtime(seconds: float | None = None) -> time.struct_time:
        return time.gmtime(FROZEN_EPOCH if seconds is None else seconds)

    @staticmethod
    def strftime(format: str, moment: time.struct_time | None = None) -> str:
        return time.strftime(format, time.gmtime(FROZEN_EPOCH) if moment is None else moment)


def freeze_clocks(monkeypatch) -> list[str]:
    """Stop the clocks the station's screens and widgets read; the modules frozen."""
    frozen = FrozenTime()
    names = []
    for name, module in list(sys.modules.items()):
        if name.startswith("station.tui") and getattr(module, "time", None) is time:
            monkeypatch.setattr(module, "time", frozen)
            names.append(name)
    return names


def prompt(app) -> None:
    """Have Textual do what it leaves for a widget's next idle or the screen's next refresh, so that the picture does
    not depend on when a worker's answer came.

    A focused Input's cursor blinks on a timer of its own; it is shown steadily instead. A RichLog scrolls to a new
    line after a refresh. A DataTable widens a column for a new cell on its idle, but keeps the rows it drew in
    between (its render caches are keyed by a count that widening does not change): when a probe answers while the
    home screen is drawn, its column stays cut at "connected:" until something else redraws the table (a key, a
    resize). The snapshot shows the table as drawn afresh.
    """
    for widget in app.screen.walk_children(with_self=True):
        widget.check_idle()
        if isinstance(widget, Input):
            widget.cursor_blink = False  # a blinking cursor is on or off by when the picture is taken: shown, steady
        if isinstance(widget, DataTable):
            widget._clear_caches()  # Textual's own: no public way to redraw the rows
        elif isinstance(widget, RichLog) and widget.auto_scroll:
            widget.scroll_end(animate=False, immediate=True)  # what its next refresh would do
    app.screen.refresh()


def render(app) -> tuple[str, str]:
    """The app's screen as an SVG picture and as text (as :meth:`textual.app.App.export_screenshot` draws it)."""
    width, height = app.size
    console = Console(width=width, height=height, file=io.StringIO(), force_terminal=True, color_system="truecolor",
                      record=True, legacy_windows=False, safe_box=False)
    console.print(app.screen._compositor.render_update(full=True, screen_stack=app._background_screens,
                                                        simplify=True))
    text = console.export_text(clear=False)
    svg = console.export_svg(title=app.title, clear=True)
    return svg, "\n".join(line.rstrip() for line in text.splitlines()) + "\n"


async def shot(name: str, tmp_path: Path, monkeypatch) -> tuple[str, str]:
    from station.tui.app import StationApp

    monkeypatch.chdir(tmp_path)  # home shows the database as given: a relative path reads the same in every run
    random.seed(0)  # nothing on the screens draws from it today; a screen that does later is pinned too
    app = StationApp(database="station.sqlite3")
    freeze_clocks(monkeypatch)
    async with app.run_test(size=SIZE) as pilot:
        if name != "home":
            await pilot.press(next(entry.key for entry in app.areas if entry.name == name))
        await settle(app, pilot)
        assert app.screen.name == name, f"pressing its key on home showed {app.screen.name!r}, not {name!r}"
        ready = READY.get(name, lambda text: True)
        # a worker's answer is drawn on a later refresh (a table widens its column; the Machines screen hands a
        # connection's lines over on a timer): the screen is ready, then the same picture three times in a row
        pictures = [render(app)]
        deadline = time.monotonic() + SETTLE_SECONDS
        while time.monotonic() < deadline:
            prompt(app)
            await pilot.pause(0.05)
            pictures.append(render(app))
            if ready(pictures[-1][1]) and len(pictures) >= 3 and pictures[-1] == pictures[-2] == pictures[-3]:
                return pictures[-1]
        raise AssertionError(f"the {name!r} screen was not ready and still within {SETTLE_SECONDS} s (a clock or "
                             f"an animation the snapshot must pin?); it showed:\n{pictures[-1][1]}")


@pytest.mark.parametrize("name", screen_names())
async def test_screen_looks_as_reviewed(name, tmp_path, monkeypatch):
    svg, text = await shot(name, tmp_path, monkeypatch)
    svg_path, text_path = SNAPSHOTS / f"{name}.svg", SNAPSHOTS / f"{name}.txt"
    if UPDATE:
        SNAPSHOTS.mkdir(exist_ok=True)
        svg_path.write_text(svg, encoding="utf-8")
        text_path.write_text(text, encoding="utf-8")
        return
    if not svg_path.exists() or not text_path.exists():
        pytest.fail(f"the {name!r} screen has no snapshot in {SNAPSHOTS}: make it with `{REGENERATE}`, look at "
                    f"{name}.svg and commit both files")
    expected_text = text_path.read_text(encoding="utf-8")
    if text != expected_text or svg != svg_path.read_text(encoding="utf-8"):
        (tmp_path / f"{name}.svg").write_text(svg, encoding="utf-8")
        diff = "\n".join(difflib.unified_diff(expected_text.splitlines(), text.splitlines(), "snapshot", "now",
                                              lineterm=""))
        pytest.fail(f"the {name!r} screen changed (the new picture: {tmp_path / name}.svg); if the change is "
                    f"meant, update the snapshots with `{REGENERATE}` and review them.\n"
                    + (diff or "the characters are the same: the colours or styles changed"))


def test_no_snapshot_is_left_of_a_screen_that_is_gone():
    names = set(screen_names())
    stale = sorted(p.name for p in SNAPSHOTS.glob("*.*") if p.stem not in names)
    assert not stale, f"snapshots of screens that no longer exist in {SNAPSHOTS}: delete {stale}"


def test_the_clocks_are_frozen_where_screens_read_them(monkeypatch):
    # the Fabricate screen says how long its parts took (time.perf_counter): frozen, it says 0.0 s every run
    discover_screens()
    frozen = freeze_clocks(monkeypatch)
    assert "station.tui.screens.fabricate" in frozen
    from station.tui.screens import fabricate

    assert fabricate.time.perf_counter() - fabricate.time.perf_counter() == 0.0
