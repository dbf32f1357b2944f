"""The one progress type (common.progress) and its command-line view (station.progress_view)."""

from __future__ import annotations

import io

import pytest

from common.progress import Cancelled, Progress, Reporter
from station.progress_view import ProgressView


def test_fraction_is_clipped_and_unknown_without_total():
    assert Progress("a", 3, 4).fraction == 0.75
    assert Progress("a", 9, 4).fraction == 1.0
    assert Progress("a", 3, None).fraction is None
    assert Progress("a", 3, 0).fraction is None


def test_reporter_reports_then_honours_cancel():
    seen = []
    stop = {"now": False}
    report = Reporter(seen.append, cancelled=lambda: stop["now"])
    report("grid", 1, 2, "one")
    stop["now"] = True
    with pytest.raises(Cancelled):
        report("grid", 2, 2, "two")
    assert [p.message for p in seen] == ["one", "two"]  # the report still lands before the stop
    assert Reporter.of(report) is report
    assert Reporter.of(None).callback is None


@pytest.mark.parametrize(
    "reports, expected",
    [
        ([("a", 0, 10), ("a", 0.5, 10), ("a", 1, 10), ("a", 10, 10)], ["a: 0/10", "a: 1/10", "a: 10/10"]),
        ([("a", 5, 10), ("b", 0, None), ("b", 3, None)], ["a: 5/10", "b:"]),
        ([("quiet", 1, 2), ("a", 2, 2)], ["a: 2/2"]),
    ],
)
def test_plain_lines_table(reports, expected):
    out = io.StringIO()
    with ProgressView(out, tty=False, quiet_stages=("quiet",)) as view:
        for stage, done, total in reports:
            view(Progress(stage, done, total))
    assert out.getvalue().splitlines() == expected
    assert "\r" not in out.getvalue()


def test_terminal_form_draws_a_bar():
    out = io.StringIO()
    with ProgressView(out, tty=True, describe=lambda p: f"{p.stage} {p.message}") as view:
        view(Progress("build", 5, 10, "half"))
        view.note("a note")
    text = out.getvalue()
    assert "build half" in text and "a note" in text


@pytest.mark.parametrize("clear", [False, True])
def test_closing_with_clear_erases_the_bars_on_a_terminal(clear):
    """close(clear=True) takes the bars off the screen (a line said after them reads alone); close() leaves them."""
    out = io.StringIO()
    view = ProgressView(out, tty=True)
    view(Progress("stage one", 1, 4))
    view.close(clear=clear)
    erase = "\x1b[1A\x1b[2K"  # the cursor up a line, the line erased
    assert out.getvalue().endswith(erase) == clear
