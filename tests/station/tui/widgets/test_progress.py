"""The TUI's progress panel: the one progress type (common.progress.Progress) from a worker thread to a bar."""

from __future__ import annotations

import threading

from textual.app import App, ComposeResult

from common.progress import Progress
from station.tui.messages import ProgressReported
from station.tui.widgets.progress import ProgressPanel
from station.tui.work import run_work


class Host(App):
    """A panel and work in a thread worker (:func:`run_work`) that reports one step each time it is let go."""

    def __init__(self) -> None:
        super().__init__()
        self.step = threading.Semaphore(0)
        self.shown: list[Progress] = []

    def compose(self) -> ComposeResult:
        yield ProgressPanel("press go", describe=lambda p: f"{p.message} ({p.done:g} done)")

    def on_progress_reported(self, message: ProgressReported) -> None:
        self.shown.append(message.progress)
        self.query_one(ProgressPanel).show(message.progress)

    def start(self) -> None:
        def steps(report) -> None:
            for i in range(1, 4):
                self.step.acquire()
                report("grid", i, 4, f"radius {i}")
            self.step.acquire()
            report("nesting", 0, None, "placing parts")

        run_work(self, steps, group="steps")


async def wait_until(pilot, condition) -> None:
    for _ in range(200):
        await pilot.pause(0.01)
        if condition():
            return
    raise AssertionError("the progress did not arrive")


def test_panel_starts_idle_with_an_empty_bar():
    panel = ProgressPanel("press go", total=20)
    assert panel.stage == "" and panel.bar.total == 20 and panel.bar.progress == 0


async def test_the_bar_advances_and_the_stage_shows():
    app = Host()
    async with app.run_test(size=(80, 10)) as pilot:
        panel = app.query_one(ProgressPanel)
        assert "press go" in panel.message
        app.start()
        seen = []
        for i in range(1, 4):
            app.step.release()
            await wait_until(pilot, lambda i=i: len(app.shown) == i)
            seen.append(panel.bar.progress)
            assert panel.bar.total == 4 and panel.stage == "grid"
            assert f"radius {i} ({i} done)" in panel.message
        assert seen == [1, 2, 3]  # the bar advances with each report
        assert "grid" in str(panel.query_one(".progress-stage").render())
        # A stage of unknown length: an indeterminate bar, and the new stage's name.
        app.step.release()
        await wait_until(pilot, lambda: len(app.shown) == 4)
        assert panel.bar.total is None and panel.stage == "nesting"
        assert "nesting" in str(panel.query_one(".progress-stage").render())
        assert "placing parts" in panel.message
        await app.workers.wait_for_complete()
        panel.start(10, "again")
        assert panel.bar.progress == 0 and panel.bar.total == 10 and panel.stage == "" and "again" in panel.message
