"""The one way a screen's long work reports back: run_work's thread worker and its typed messages."""

from __future__ import annotations

import threading

from textual.app import App, ComposeResult
from textual.widgets import Static

from station.errors import StationError
from station.tui.messages import ProgressReported, WorkEnded
from station.tui.work import run_work


class Counted(WorkEnded):
    """The test work's end."""


class Host(App):
    """An app whose screen collects every message the work sends, in the order they arrive."""

    def __init__(self) -> None:
        super().__init__()
        self.seen: list[tuple[str, object]] = []
        self.ended: list[Counted] = []

    def compose(self) -> ComposeResult:
        yield Static("host")

    def on_progress_reported(self, message: ProgressReported) -> None:
        self.seen.append(("progress", message.progress.done))

    def on_counted(self, message: Counted) -> None:
        self.seen.append(("ended", message.result))
        self.ended.append(message)


async def wait_until(pilot, condition) -> None:
    for _ in range(500):
        await pilot.pause(0.01)
        if condition():
            return
    raise AssertionError("the messages did not arrive")


def counting(steps: int, gate: threading.Semaphore | None = None, fail_at: int | None = None):
    """Work that reports each step (waiting on ``gate`` before each when given) and returns the step count."""

    def call(report):
        for i in range(1, steps + 1):
            if gate is not None and not gate.acquire(timeout=10):  # never hang the suite on a failed test
                raise RuntimeError("the test never let the work go on")
            if i == fail_at:
                raise StationError(f"step {i}: expected a good step")
            report("count", i, steps, f"step {i}")
        return steps

    return call


async def test_progress_then_the_result_arrive_as_messages_in_order():
    app = Host()
    async with app.run_test() as pilot:
        run_work(app, counting(5), Counted, group="count")
        await wait_until(pilot, lambda: app.ended)
        assert app.seen == [("progress", 1), ("progress", 2), ("progress", 3), ("progress", 4), ("progress", 5),
                            ("ended", 5)]
        assert app.ended[0].ok and not app.ended[0].stopped and app.ended[0].error == ""


async def test_a_user_error_ends_the_work_with_its_one_line():
    app = Host()
    async with app.run_test() as pilot:
        run_work(app, counting(5, fail_at=3), Counted, group="count")
        await wait_until(pilot, lambda: app.ended)
        ended = app.ended[0]
        assert ended.error == "step 3: expected a good step" and ended.result is None and not ended.ok
        assert [kind for kind, _ in app.seen] == ["progress", "progress", "ended"]


async def test_stop_ends_the_work_at_its_next_check_as_stopped():
    app = Host()
    gate = threading.Semaphore(0)
    async with app.run_test() as pilot:
        work = run_work(app, counting(10, gate), Counted, group="count")
        gate.release()
        gate.release()
        await wait_until(pilot, lambda: len(app.seen) == 2)
        work.stop()
        gate.release()  # the third step reports, then its stop check raises
        for _ in range(10):
            gate.release()
        await wait_until(pilot, lambda: app.ended)
        assert app.ended[0].stopped and app.ended[0].result is None and not app.ended[0].ok
        assert app.ended[0].error == "stopped on request"  # what the stop said
        assert app.seen[:2] == [("progress", 1), ("progress", 2)]
        assert len(app.ended) == 1
        assert not work.running


async def test_a_newer_run_of_the_group_silences_the_older_one():
    app = Host()
    old_gate, new_gate = threading.Semaphore(0), threading.Semaphore(0)
    async with app.run_test() as pilot:
        old_done = threading.Event()
        old_count = counting(3, old_gate)

        def old_call(report):
            try:
                return old_count(report)
            finally:
                old_done.set()

        run_work(app, old_call, Counted, group="count")
        old_gate.release()
        await wait_until(pilot, lambda: app.seen == [("progress", 1)])
        run_work(app, counting(2, new_gate), Counted, group="count")  # exclusive: the old worker is cancelled
        for _ in range(3):
            old_gate.release()
        await wait_until(pilot, old_done.is_set)  # its thread ran out (Textual marks it cancelled at once)
        new_gate.release()
        new_gate.release()
        await wait_until(pilot, lambda: app.ended)
        # Only the newer run's progress and end: the older one stopped and said nothing more.
        assert app.seen == [("progress", 1), ("progress", 1), ("progress", 2), ("ended", 2)]
        assert len(app.ended) == 1
