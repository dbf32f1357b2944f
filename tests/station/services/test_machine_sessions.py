"""MachineSessions, the one service ``station send`` and the Machines screen drive, on the GRBL twin's virtual clock:
send, abort, interrupt, pre-flight refusal, the homing/frame policy answered both ways, placement, a multi-pen plot
resumed from a layer, and the job history of each."""

from __future__ import annotations

import io
import threading
import time

import numpy as np
import pytest

from cam.layers import PenLayer, write_layers_gcode
from cam.plot import WriterOptions
from drivers.profiles import load_profile
from station.joblog import JobLog
from station.services.job_queue import JobState
from station.services.machine_sessions import (
    MachineSessions,
    SendPolicy,
    job_layer_marks,
    load_job,
    parse_placement,
)

SQUARE = ["G21", "G90", "M4 S0", "G0 X10 Y10", "G1 X50 Y10 F1500 S800", "G1 X50 Y40", "G1 X10 Y40", "G1 X10 Y10",
          "M5 S0"]


def virtual(profile: str, **query) -> str:
    """A twin on the virtual clock (a job runs as fast as it is streamed, with the simulated timing); ``pace`` keeps
    a long job running long enough in wall time to act on it."""
    return f"sim://grbl?profile={profile}&clock=virtual" + "".join(f"&{k}={v}" for k, v in query.items())


@pytest.fixture
def history(tmp_path):
    log = JobLog.open_shared(tmp_path / "jobs.sqlite3")  # a send records from the thread that sends
    yield log
    log.close()


@pytest.fixture
def sessions(history):
    service = MachineSessions(history, source="test")
    yield service
    service.close()


class Answers(SendPolicy):
    """A policy that answers from a script and keeps what it was asked."""

    def __init__(self, frame: bool = False, start: bool = True, resume_pauses: bool = True) -> None:
        self.frame, self.start, self.resume_pauses = frame, start, resume_pauses
        self.asked: list[str] = []

    def frame_first(self, job) -> bool:
        self.asked.append("frame first")
        return self.frame

    def start_after_frame(self, job) -> bool:
        self.asked.append("start")
        return self.start

    def paused(self, message, resume, stop) -> None:
        self.asked.append(message)
        (resume if self.resume_pauses else stop)()


def until(predicate, timeout: float = 60.0) -> None:
    """A liveness guard, not a timing check: returns as soon as ``predicate`` holds."""
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, "condition not reached"
        time.sleep(0.01)


def test_a_job_is_sent_done_and_recorded(sessions, history):
    conn = sessions.connect("plotter", virtual("plotter"))
    entry = sessions.add("plotter", "\n".join(["G21", "G90", "G0 X10 Y10", "G1 X40 Y10 F2000", "G1 X40 Y30"]),
                         "line")
    seen = []
    result = sessions.send("plotter", entry, report=seen.append)
    assert result.ok and entry.state is JobState.DONE
    assert seen and seen[-1].state == "done"
    executed = conn.port.machine.snapshot().executed
    assert [b.end[:2] for b in executed[-2:]] == [
        pytest.approx(np.add(p, conn.work_offset()[:2])) for p in ((40, 10), (40, 30))]
    (row,) = history.recent()
    assert (row.kind, row.device, row.title, row.status, row.lines_acked) == ("run", "plotter", "line", "done", 5)


def test_a_job_outside_the_travel_is_refused_before_anything_moves(sessions, history):
    conn = sessions.connect("plotter", virtual("plotter"))
    entry = sessions.add("plotter", "G21\nG90\nG0 X5000 Y10\n", "far")
    result = sessions.send("plotter", entry)
    assert result.state == "refused" and entry.state is JobState.REFUSED
    assert "travel" in result.message
    assert not conn.port.machine.snapshot().executed
    assert history.recent()[0].status == "refused"


def _sending(sessions, device, entry, **options):
    """Send in a thread (the caller acts on the job meanwhile); the result lands in the returned list."""
    results = []
    thread = threading.Thread(target=lambda: results.append(sessions.send(device, entry, **options)))
    thread.start()
    until(lambda: sessions.runner is not None and sessions.runner.progress.lines_acked > 3)
    return thread, results


def long_laser_job(passes: int = 40) -> str:
    lines = ["G21", "G90", "M4 S0", "G0 X10 Y10"]
    for _ in range(passes):
        lines += ["G1 X90 Y10 F600 S500", "G1 X90 Y60", "G1 X10 Y60", "G1 X10 Y10"]
    return "\n".join(lines + ["M5 S0"])


def test_abort_stops_the_job_with_the_laser_off_and_says_where_to_resume(sessions, history):
    conn = sessions.connect("laser", virtual("laser", pace=20))
    entry = sessions.add("laser", long_laser_job(), "long", laser=True)
    thread, results = _sending(sessions, "laser", entry)
    assert sessions.abort() is True
    thread.join(30)
    (result,) = results
    assert result.state == "aborted" and result.laser_off and entry.state is JobState.ABORTED
    assert result.resume_line is not None and 4 <= result.resume_line < len(entry.job.lines)
    assert conn.port.machine.snapshot().samples[-1].power == 0
    row = history.recent()[0]
    assert (row.status, row.resume_line) == ("aborted", result.resume_line)
    assert not sessions.sending


def test_interrupt_ends_the_send_interrupted_and_a_next_run_resumes_there(sessions, history):
    sessions.connect("laser", virtual("laser", pace=20))
    entry = sessions.add("laser", long_laser_job(), "long", laser=True)
    thread, results = _sending(sessions, "laser", entry)
    sessions.interrupt("SIGTERM")
    thread.join(30)
    (result,) = results
    assert result.state == "interrupted" and result.laser_off
    assert result.message.startswith("interrupted by SIGTERM: job aborted, soft reset sent; laser off")
    assert entry.state is JobState.INTERRUPTED and entry.resume_line == result.resume_line
    assert sessions.queue.start_line(entry, "run") == result.resume_line
    assert history.recent()[0].status == "interrupted"


@pytest.mark.parametrize("start", [True, False])
def test_a_laser_without_homing_asks_for_the_frame_first(sessions, history, start):
    conn = sessions.connect("laser", virtual("laser", homing=0))
    entry = sessions.add("laser", "\n".join(SQUARE), "square", laser=True)
    policy = Answers(frame=True, start=start)
    result = sessions.send("laser", entry, profile=load_profile("laser"), policy=policy)
    assert policy.asked == ["frame first", "start"]
    kinds = [(row.kind, row.status) for row in reversed(history.recent())]
    executed = conn.port.machine.snapshot().executed
    frame_power = load_profile("laser").laser.frame_power * load_profile("laser").laser.max_power
    # the frame traced the job's bounding box at frame power, before anything else
    assert {b.power for b in executed[:5] if not b.rapid} == {frame_power}
    if start:
        assert result.ok and entry.state is JobState.DONE
        assert kinds == [("frame", "done"), ("run", "done")]
        assert 800 in {b.power for b in executed}
    else:
        assert result.ok and entry.state is JobState.FRAMED  # the frame's result: the job was not started
        assert kinds == [("frame", "done")]
        assert 800 not in {b.power for b in executed}


def test_a_laser_without_homing_runs_at_once_when_the_frame_is_declined(sessions, history):
    conn = sessions.connect("laser", virtual("laser", homing=0))
    entry = sessions.add("laser", "\n".join(SQUARE), "square", laser=True)
    policy = Answers(frame=False)
    assert sessions.send("laser", entry, profile=load_profile("laser"), policy=policy).ok
    assert policy.asked == ["frame first"]
    assert [row.kind for row in history.recent()] == ["run"]
    assert {b.power for b in conn.port.machine.snapshot().executed if not b.rapid} == {800}


def test_a_machine_with_homing_is_not_asked(sessions):
    sessions.connect("laser", virtual("laser"))
    policy = Answers(frame=True)
    assert sessions.send("laser", sessions.add("laser", "\n".join(SQUARE), "square", laser=True),
                         profile=load_profile("laser"), policy=policy).ok
    assert policy.asked == []


def test_a_placed_job_runs_where_it_was_placed(sessions, tmp_path):
    path = tmp_path / "square.gcode"
    path.write_text("\n".join(SQUARE) + "\n")
    job = load_job(path, profile=load_profile("laser"), place=parse_placement("100,50,90"))
    assert job.laser
    conn = sessions.connect("laser", virtual("laser"))
    assert sessions.send("laser", sessions.add("laser", job)).ok
    wco = np.array(conn.work_offset()[:2])
    burned = [np.array(b.end[:2]) - wco for b in conn.port.machine.snapshot().executed if not b.rapid]
    # (50, 10) turned 90 degrees about the work zero, then moved to (100, 50)
    assert burned[0] == pytest.approx((100 - 10, 50 + 50))


def three_pen_plot() -> list[str]:
    square = np.array([[0, 0], [20, 0], [20, 20], [0, 20], [0, 0]], dtype=float)
    layers = [PenLayer(name, name, "#000000", [square + offset])
              for name, offset in (("red", (10, 10)), ("green", (40, 10)), ("blue", (70, 10)))]
    stream = io.StringIO()
    write_layers_gcode(layers, stream, WriterOptions.from_profile(load_profile("plotter")))
    return stream.getvalue().splitlines()


def test_a_plot_resumed_from_its_layer_pauses_for_that_pen_then_draws_only_what_is_left(sessions, history):
    lines = three_pen_plot()
    marks = job_layer_marks(lines)
    assert [m.name for m in marks] == ["red", "green", "blue"]
    conn = sessions.connect("plotter", virtual("plotter"))
    entry = sessions.add("plotter", "\n".join(lines), "three")
    policy = Answers()
    result = sessions.send("plotter", entry, from_line=marks[1].line + 1, policy=policy)
    assert result.ok
    # the green layer's pen change first, then the blue one's; never the red layer
    assert len(policy.asked) == 2 and "green" in policy.asked[0] and "blue" in policy.asked[1]
    wco = np.array(conn.work_offset()[:2])
    drawn_x = [b.end[0] - wco[0] for b in conn.port.machine.snapshot().executed if not b.rapid]
    assert min(drawn_x) >= 40 - 1e-6
    assert history.recent()[0].status == "done"


def test_a_pen_change_nobody_answers_stops_the_job_there(sessions):
    sessions.connect("plotter", virtual("plotter"))
    entry = sessions.add("plotter", "\n".join(three_pen_plot()), "three")
    result = sessions.send("plotter", entry, policy=Answers(resume_pauses=False))
    assert result.state == "aborted" and entry.state is JobState.ABORTED
    marks = job_layer_marks(entry.job.lines)
    assert result.resume_line == marks[1].pause + 1  # the pen change comes again first


def test_one_job_at_a_time_and_only_on_a_connected_machine(sessions):
    from station.errors import ServiceError

    entry = sessions.add("plotter", "G0 X1\n", "one")
    with pytest.raises(ServiceError, match="plotter: not connected"):
        sessions.send("plotter", entry)
    sessions.connect("laser", virtual("laser", pace=20))
    running = sessions.add("laser", long_laser_job(), "long", laser=True)
    thread, _ = _sending(sessions, "laser", running)
    with pytest.raises(ServiceError, match="one job at a time"):
        sessions.send("laser", sessions.add("laser", "G0 X1\n", "two"))
    sessions.abort()
    thread.join(30)
