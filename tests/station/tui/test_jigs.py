"""The Assemble screen's j: the current layout's jigs written to the data folder, their laser job queued on the
Machines screen (and shown there when it opens)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from textual.widgets import DataTable, Static

from station.paths import data_dir

from ...conftest import opened, settle

SIMPLE = Path(__file__).resolve().parents[3] / "examples" / "scenarios" / "simple.toml"


@pytest.fixture(autouse=True)
def small_forecasts(monkeypatch):
    from station.tui.screens.assemble import AssembleScreen

    monkeypatch.setattr(AssembleScreen, "forecast_samples", 6)
    monkeypatch.setattr(AssembleScreen, "simulation_workers", 1)


async def test_j_writes_the_jigs_and_queues_their_laser_job(tmp_path):
    async with opened(tmp_path, "a") as (app, pilot):
        screen = app.screen
        await pilot.press("j")  # before a guide: said, nothing written
        assert "no guide yet" in str(screen.query_one("#status", Static).render())
        screen.open_layout(str(SIMPLE), "success")
        await settle(app, pilot)
        assert screen.job is not None
        await pilot.press("j")
        await settle(app, pilot)
        status = str(screen.query_one("#status", Static).render())
        assert status.startswith("wrote 1 jig to "), status
        assert "queued on the Machines screen" in status
        folders = list((data_dir() / "jigs").iterdir())
        assert len(folders) == 1 and folders[0].name.startswith("simple-success-")
        data = json.loads((folders[0] / "jigs.json").read_text())
        assert [jig["part"] for jig in data["jigs"]] == ["track"]
        (entry,) = app.machines_screen().jobs
        assert entry.title == "jigs of SIMPLE" and str(entry.state) == "queued"
        written = [line for line in (folders[0] / "jigs.gcode").read_text().splitlines() if line.startswith("G1")]
        assert [line for line in entry.job.lines if line.startswith("G1")] == written  # the job written, queued
        await pilot.press("escape", "m")
        await settle(app, pilot)
        queue = app.screen.query_one("#queue", DataTable)
        assert queue.row_count == 1 and "jigs of SIMPLE" in str(queue.get_row_at(0))
