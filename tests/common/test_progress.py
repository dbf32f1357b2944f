"""The one progress type and the one way to report and stop (common.progress), and its command-line view
(station.progress_view)."""

from __future__ import annotations

import ast
import io
from pathlib import Path

import pytest

from common.progress import Cancelled, Progress, Reporter
from station.progress_view import ProgressView


def test_fraction_is_clipped_and_unknown_without_total():
    assert Progress("a", 3, 4).fraction == 0.75
    assert Progress("a", 9, 4).fraction == 1.0
    assert Progress("a", 3, None).fraction is None
    assert Progress("a", 3, 0).fraction is None


def test_reporter_reports_then_honours_a_stop():
    seen = []
    stop = {"now": False}
    report = Reporter(seen.append, stop=lambda: stop["now"])
    report("grid", 1, 2, "one")
    report.check()
    assert not report.stopping
    stop["now"] = True
    assert report.stopping
    with pytest.raises(Cancelled):
        report("grid", 2, 2, "two")
    assert [p.message for p in seen] == ["one", "two"]  # the report still lands before the stop
    with pytest.raises(Cancelled):
        report.check()
    report.tell(Progress("job", 3, 4))  # told without being stopped (a thread that must not raise)
    assert seen[-1].stage == "job"


def test_a_function_given_no_reporter_reports_to_nobody_and_runs_to_its_end():
    report = Reporter.of(None)
    assert report.callback is None and not report.stopping
    report("grid", 1, 2)
    report.check()
    report.emit(Progress("x"))
    kept = Reporter(print)
    assert Reporter.of(kept) is kept
    seen = []
    wrapped = Reporter.of(seen.append)  # a bare progress callback: reported to, never stopped
    wrapped("a", 1, 1)
    assert [p.stage for p in seen] == ["a"] and not wrapped.stopping
    with pytest.raises(TypeError, match="report must be a Reporter"):
        Reporter.of(3)


def test_a_mapped_reporter_keeps_the_stop_and_relabels_the_progress():
    seen = []
    stop = {"now": False}
    outer = Reporter(seen.append, stop=lambda: stop["now"])
    inner = outer.mapped(lambda p: Progress(f"loop 1: {p.stage}", p.done, p.total))
    inner("optimize", 1, 10)
    assert [(p.stage, p.done) for p in seen] == [("loop 1: optimize", 1)]
    stop["now"] = True
    with pytest.raises(Cancelled):
        inner("optimize", 2, 10)
    assert Reporter(stop=lambda: False).mapped(lambda p: p).callback is None  # nobody listening: nothing to call


def test_cancelled_is_one_runtime_error_that_says_what_was_kept(tmp_path):
    plain = Cancelled()
    assert isinstance(plain, RuntimeError) and str(plain) == "stopped on request"
    assert (plain.new_simulations, plain.cache, plain.partial) == (0, None, None)
    kept = Cancelled("stopped; 3 kept", new_simulations=3, cache=tmp_path / "c.sqlite3", partial={"run": 1})
    assert (kept.new_simulations, kept.cache, kept.partial) == (3, tmp_path / "c.sqlite3", {"run": 1})


#: The names the one reporter and the one Cancelled replace: none may come back.
GONE_NAMES = {"SimulationCancelled", "RunStopped", "LoopStopped", "StopCheck", "CancelCheck"}
GONE_PARAMETERS = {"should_stop", "cancelled"}
#: An optional parameter by this name is a progress callback beside the reporter (a Progress value is no option).
GONE_OPTIONS = {"progress"}
ROOT = Path(__file__).resolve().parents[1]
SOURCES = ("common", "design", "calibration", "projector", "vision", "cam", "drivers", "station", "bench", "tests",
           "examples")


def test_no_other_stop_parameter_or_exception_is_left_in_the_source():
    found = []
    for folder in SOURCES:
        for path in sorted((ROOT / folder).rglob("*.py")) if (ROOT / folder).is_dir() else ():
            tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
            where = path.relative_to(ROOT)
            for node in ast.walk(tree):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                    arguments = node.args
                    for argument in (*arguments.posonlyargs, *arguments.args, *arguments.kwonlyargs):
                        if argument.arg in GONE_PARAMETERS:
                            found.append(f"{where}:{node.lineno}: parameter {argument.arg}")
                    positional = [*arguments.posonlyargs, *arguments.args]
                    optional = [a.arg for a in positional[len(positional) - len(arguments.defaults):]]
                    optional += [a.arg for a, d in zip(arguments.kwonlyargs, arguments.kw_defaults) if d is not None]
                    found += [f"{where}:{node.lineno}: option {name}=" for name in GONE_OPTIONS & set(optional)]
                elif isinstance(node, ast.keyword) and node.arg in GONE_PARAMETERS:
                    found.append(f"{where}:{node.value.lineno}: keyword {node.arg}=")
                elif isinstance(node, ast.Name) and node.id in GONE_NAMES:
                    found.append(f"{where}:{node.lineno}: {node.id}")
                elif isinstance(node, ast.Attribute) and node.attr in GONE_NAMES:
                    found.append(f"{where}:{node.lineno}: .{node.attr}")
                elif isinstance(node, ast.alias) and node.name.split(".")[-1] in GONE_NAMES:
                    found.append(f"{where}: import {node.name}")
    assert found == [], "report= and common.progress.Cancelled only:\n" + "\n".join(found)


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
