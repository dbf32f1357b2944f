"""The Calibrate > Simulator panel in a small app: fields, start, progress, stop, the result table, the profile."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path

import numpy as np
from textual.app import App, ComposeResult
from textual.widgets import Button, DataTable, Input, Static

from calibration.sim_fit import FitSettings
from design.contraption import load_scenario
from design.contraption.physics_profile import load_profile
from station.services.world import synthetic_trials
from station.services.world import trials_export as export
from station.tui.widgets.progress import ProgressPanel
from station.tui.widgets.sim_calibration import SimCalibrationPanel

SLIDE = Path(__file__).resolve().parents[2] / "data" / "calibration" / "slide.toml"


class Host(App):
    def __init__(self, settings: FitSettings) -> None:
        super().__init__()
        self.settings = settings

    def compose(self) -> ComposeResult:
        yield SimCalibrationPanel(str(SLIDE), id="panel")

    def on_mount(self) -> None:
        panel = self.query_one(SimCalibrationPanel)
        panel.simulation_workers, panel.fit_settings = 1, self.settings


def _trials(tmp_path) -> Path:
    slide = load_scenario(SLIDE)
    rng = np.random.default_rng(7)
    trials = synthetic_trials(slide, [[a] for a in rng.uniform(30, 38, 5)], {"wood.friction": 0.56}, seed=8)
    path = tmp_path / "trials.json"
    path.write_text(json.dumps(export(trials)))
    return path


async def _until(pilot, condition, seconds: float = 60.0) -> None:
    for _ in range(int(seconds / 0.05)):
        if condition():
            return
        await asyncio.sleep(0.05)
        await pilot.pause()
    raise AssertionError("condition not reached")


def _text(app, selector: str) -> str:
    return str(app.query_one(selector, Static).render())


async def test_calibrate_shows_values_and_writes_a_profile(tmp_path, station_home):
    app = Host(FitSettings(draws=2, sobol=4, rounds=1, per_round=2, held_out=0.0))
    async with app.run_test(size=(150, 50)) as pilot:
        panel = app.query_one(SimCalibrationPanel)
        assert "wood.friction 0.5 in [0.3, 0.8]" in _text(app, "#sim-uncertain")
        await pilot.click("#sim-start")
        await pilot.pause()
        assert "give a trial export file" in _text(app, "#sim-status")
        app.query_one("#sim-trials", Input).value = str(_trials(tmp_path))
        app.query_one("#sim-values", DataTable).focus()
        await pilot.press("c")
        await _until(pilot, lambda: not panel.calibrating and panel.result is not None)
        table = app.query_one("#sim-values", DataTable)
        assert table.row_count == 1 and str(table.get_row_at(0)[0]) == "wood.friction"
        assert app.query_one("#sim-events", DataTable).row_count == 2
        assert "5 trials fitted, 0 held out" in _text(app, "#sim-status")
        assert "simulations" in app.query_one(ProgressPanel).message
        await pilot.press("w")
        await pilot.pause()
        written = station_home / "data" if (station_home / "data").exists() else station_home
        profiles = list(written.rglob("physics/slide.toml"))
        assert len(profiles) == 1 and "wood.friction" in load_profile(profiles[0]).values


async def test_stop_key_stops_a_calibration(tmp_path):
    app = Host(FitSettings(draws=8, sobol=64, rounds=3, per_round=4, held_out=0.0))
    async with app.run_test(size=(150, 50)) as pilot:
        panel = app.query_one(SimCalibrationPanel)
        app.query_one("#sim-trials", Input).value = str(_trials(tmp_path))
        app.query_one("#sim-values", DataTable).focus()
        await pilot.press("c")
        await _until(pilot, lambda: "simulations" in app.query_one(ProgressPanel).message)
        assert app.query_one("#sim-stop", Button).disabled is False
        await pilot.press("s")
        await _until(pilot, lambda: not panel.calibrating)
        assert "stopped; finished simulations are cached" in _text(app, "#sim-status")
        assert panel.result is None and app.query_one("#sim-start", Button).disabled is False


async def test_every_material_box_lists_and_fits_the_plain_values_too(tmp_path):
    app = Host(FitSettings(draws=2, sobol=4, rounds=0, per_round=2, held_out=0.0))
    async with app.run_test(size=(150, 50)) as pilot:
        panel = app.query_one(SimCalibrationPanel)
        assert "pad.friction" not in _text(app, "#sim-uncertain")
        await pilot.click("#sim-every")
        await pilot.pause()
        assert panel.every_material
        assert "pad.friction 1 in [0.5, 1.5]" in _text(app, "#sim-uncertain")  # friction x 0.5-1.5
        app.query_one("#sim-trials", Input).value = str(_trials(tmp_path))
        app.query_one("#sim-values", DataTable).focus()
        await pilot.press("c")
        await _until(pilot, lambda: not panel.calibrating and panel.result is not None)
        table = app.query_one("#sim-values", DataTable)
        assert sorted(str(table.get_row_at(i)[0]) for i in range(table.row_count)) == ["pad.friction", "wood.friction"]
