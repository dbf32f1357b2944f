"""Progress of the robust-layout commands: plain lines off a terminal, the time left, and what will run up front."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest

from design.robust import Progress
from station.cli import main
from station.commands.robust import Countdown, ProgressBar, format_duration

ROOT = Path(__file__).resolve().parents[3]
SIMPLE = ROOT / "examples" / "scenarios" / "simple.toml"


class FakeClock:
    """A clock the test moves by hand (no test waits for, or asserts on, real time)."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_off_a_terminal_progress_is_a_line_per_phase_and_per_tenth():
    stream = io.StringIO()
    bar = ProgressBar(stream)
    for n in range(0, 101):
        bar(Progress("exploration" if n < 35 else "active learning", n, 100))
    bar.close()
    text = stream.getvalue()
    assert "\r" not in text
    assert text.splitlines() == [
        "exploration: 0/100 simulations", "exploration: 10/100 simulations", "exploration: 20/100 simulations",
        "exploration: 30/100 simulations", "active learning: 35/100 simulations",
        *[f"active learning: {n}/100 simulations" for n in range(40, 101, 10)],
    ]


def test_format_duration_reads_like_a_person_would_say_it():
    assert [format_duration(s) for s in (0, 44.6, 60, 400, 3600 + 5 * 60 + 20)] == [
        "0 s", "45 s", "1 min 00 s", "6 min 40 s", "1 h 05 min"]


def test_the_time_left_is_timed_from_the_first_unit_on():
    clock = FakeClock()
    countdown = Countdown(100, clock)
    countdown.advance(0)
    clock.now += 30  # worker start-up: not part of the rate
    countdown.advance(2)
    assert countdown.seconds_left() is None
    for done in range(3, 7):
        clock.now += 1
        countdown.advance(done)
    # 4 units in 4 s after the first ones: 94 left at 1 per second.
    assert countdown.seconds_left() == pytest.approx(94)


def test_the_bar_says_the_time_left_once_known_and_on_each_line_after():
    clock = FakeClock()
    stream = io.StringIO()
    bar = ProgressBar(stream, clock=clock)
    bar.expect(200, "new simulations")
    for n in range(0, 101):
        clock.now += 0.5
        bar(Progress("evaluation set", n, 200))
    lines = stream.getvalue().splitlines()
    assert lines[0] == "evaluation set: 0/200 simulations"
    # Timed from n = 1 at 2 per second: 195 left at n = 5, the first estimate.
    assert "estimate: about 1 min 38 s left for the 200 new simulations" in lines
    assert lines[-1] == "evaluation set: 100/200 simulations, about 50 s left"
    terminal = Terminal()
    bar = ProgressBar(terminal, clock=clock)
    bar.expect(200, "new simulations", done=lambda progress: progress.simulations)
    for n in range(0, 30):
        clock.now += 0.5
        bar(Progress("evaluation set", n, 200))
    bar.close()
    # On a terminal, rich's bar (redrawn in place) with the counts and the time left beside it.
    drawn = terminal.getvalue()
    assert "\r" in drawn and "━" in drawn
    assert "29/200 evaluation set" in drawn and "about 1 min 26 s left" in drawn
    assert "estimate: about" in drawn


def test_robustness_says_up_front_what_it_will_run_and_how_to_shorten_it(tmp_path, capsys):
    layout = tmp_path / "layout.json"
    layout.write_text(json.dumps({"parameters": [{"name": n, "value": v} for n, v in
                                                 [("track.x", -0.06), ("track.z", 0.06), ("track.roll", 30.0)]]}))
    argv = ["robustness", str(SIMPLE), str(layout), "--eval", "16", "--local", "4", "--workers", "1", "--json"]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert ("SIMPLE: 16 evaluation layouts + 4 local ones = 20 simulations at most (cached ones are not run again); "
            "fewer, and faster, with --eval N and --local N") in err
    assert "0 of the 20 simulations are cached; 20 to run" in err
    assert "\r" not in err
    assert main(argv) == 0
    assert "20 of the 20 simulations are cached; 0 to run" in capsys.readouterr().err
