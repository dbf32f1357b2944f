"""The machine job queue (station.services.job_queue): typed states, the transition table, the stored resume line,
the job history it writes. Pure Python: no machine, no Textual."""

from __future__ import annotations

import pytest

from drivers.grbl import JobResult
from drivers.profiles import builtin_profile
from station.db import open_database
from station.errors import StationError
from station.joblog import JobLog
from station.services.job_queue import (
    ACTIVE_STATES,
    READY_STATES,
    JobMode,
    JobQueue,
    JobState,
    JobStateError,
    frame_job,
)

SQUARE = "G21\nG90\nM3 S50\nG0 X10 Y10\nM3 S30\nG1 X30 Y10 F3000\nG1 X30 Y30\nG1 X10 Y30\nG1 X10 Y10\nM3 S50\nG0 X0 Y0"


def result(state: str, resume_line: int | None = None, lines_acked: int = 3) -> JobResult:
    return JobResult(state=state, message=f"job ended {state}", lines_total=11, lines_acked=lines_acked,
                     elapsed=1.0, resume_line=resume_line)


@pytest.fixture
def log(tmp_path):
    connection = open_database(tmp_path / "s.sqlite3")
    yield JobLog(connection)
    connection.close()


def entry_in(state: JobState, queue: JobQueue | None = None):
    """A queue holding one job brought to ``state`` through the queue's own transitions."""
    queue = queue or JobQueue()
    entry = queue.add("plotter", SQUARE, "square")
    path = {
        JobState.QUEUED: [],
        JobState.RUNNING: [("run", None)],
        JobState.FRAMING: [("frame", None)],
        JobState.CHECKING: [("dry", None)],
        JobState.FRAMED: [("frame", "done")],
        JobState.CHECKED: [("dry", "done")],
    }.get(state, [("run", state.value)])
    for mode, outcome in path:
        queue.start(entry, mode)
        if outcome is not None:
            queue.finish(entry, result(outcome, resume_line=5 if outcome in ("stopped", "interrupted") else None))
    assert entry.state is state
    return queue, entry


# (state, action) -> next state, or "-" where the queue refuses. "finish:<outcome>" ends the send with a runner
# result in that state.
TRANSITIONS = """
queued         run                    running
queued         frame                  framing
queued         dry                    checking
queued         finish:done            -
framed         run                    running
framed         frame                  framing
checked        run                    running
checked        dry                    checking
stopped        run                    running
stopped        frame                  framing
stopped        finish:done            -
running        run                    -
running        frame                  -
running        finish:done            done
running        finish:stopped         stopped
running        finish:aborted         aborted
running        finish:refused         refused
running        finish:position_lost   position_lost
running        finish:error           error
running        finish:interrupted     interrupted
interrupted    run                    running
interrupted    frame                  framing
interrupted    finish:done            -
framing        finish:done            framed
framing        finish:aborted         queued
framing        finish:refused         queued
framing        dry                    -
checking       finish:done            checked
checking       finish:stopped         queued
checking       run                    -
done           run                    -
done           frame                  -
done           finish:done            -
aborted        run                    -
aborted        dry                    -
refused        run                    -
position_lost  run                    -
error          frame                  -
"""
TABLE = [(JobState(state), action, None if expected == "-" else JobState(expected))
         for state, action, expected in (row.split() for row in TRANSITIONS.strip().splitlines())]


@pytest.mark.parametrize("state, action, expected", TABLE, ids=[f"{s.value}-{a}" for s, a, _ in TABLE])
def test_transition_table(state, action, expected):
    queue, entry = entry_in(state)
    if action.startswith("finish:"):
        act = lambda: queue.finish(entry, result(action.split(":")[1]))  # noqa: E731
    else:
        act = lambda: queue.start(entry, action)  # noqa: E731
    if expected is None:
        with pytest.raises(JobStateError) as caught:
            act()
        error = caught.value
        assert (error.number, error.state, error.action) == (1, state, action.split(":")[0])
        assert entry.state is state  # a refusal changes nothing
        assert f"job 1 'square' ({state.value})" in str(error)
    else:
        act()
        assert entry.state is expected


def test_the_table_covers_every_state():
    assert {state for state, _, _ in TABLE} == set(JobState)
    assert set(ACTIVE_STATES.values()) | READY_STATES <= set(JobState)


def test_states_read_as_their_names():
    # The queue table, the quit question ("A job is running on ...") and the pilot tests read them as text.
    assert JobState.RUNNING == "running" and f"{JobState.POSITION_LOST}" == "position_lost"
    assert str(JobMode.DRY) == "dry" and JobMode.DRY.kind == "dry run"


def test_one_job_is_sent_at_a_time_across_devices():
    queue = JobQueue()
    first = queue.add("plotter", SQUARE, "first")
    second = queue.add("laser", SQUARE, "second", laser=True)
    queue.start(first, JobMode.RUN)
    with pytest.raises(JobStateError, match="job 1 'first' \\(running\\) is being sent"):
        queue.start(second, JobMode.FRAME)
    assert second.state is JobState.QUEUED and queue.active is first
    queue.finish(first, result("done"))
    assert queue.active is None
    queue.start(second, JobMode.FRAME)
    assert queue.active is second


def test_a_stopped_run_resumes_from_its_stored_line():
    queue, entry = entry_in(JobState.RUNNING)
    queue.finish(entry, result("stopped", resume_line=7))
    assert (entry.state, entry.resume_line, entry.message) == (JobState.STOPPED, 7, "job ended stopped")
    assert queue.start(entry, "run") == 7
    queue.finish(entry, result("done"))
    assert entry.resume_line is None


def test_a_stopped_run_without_a_suggested_line_starts_over():
    queue, entry = entry_in(JobState.RUNNING)
    queue.finish(entry, result("stopped", resume_line=None))
    assert queue.start(entry, "run") == 1


def test_only_a_stopped_run_resumes():
    # As the screen always did: a frame or a dry run of a stopped job, then g, runs the job from its first line.
    queue, entry = entry_in(JobState.STOPPED)
    assert entry.resume_line == 5
    assert queue.start(entry, "frame") == 1
    queue.finish(entry, result("done"))
    assert entry.state is JobState.FRAMED and entry.resume_line is None
    assert queue.start(entry, "run") == 1
    # an aborted run keeps no resume line (it cannot be sent again)
    queue.finish(entry, result("aborted", resume_line=9))
    assert entry.resume_line is None


def test_next_for_a_device_skips_jobs_that_cannot_be_sent():
    queue = JobQueue()
    done = queue.add("plotter", SQUARE, "a")
    queue.start(done, "run")
    queue.finish(done, result("done"))
    laser = queue.add("laser", SQUARE, "b", laser=True)
    plotter = queue.add("plotter", SQUARE, "c")
    assert queue.next_for("plotter") is plotter
    assert queue.next_for("laser") is laser
    assert queue.next_for(None) is laser
    assert queue.next_for("mill") is None


def test_add_numbers_and_titles_jobs_and_refuses_an_empty_one():
    queue = JobQueue()
    first = queue.add("plotter", SQUARE)
    second = queue.add("laser", SQUARE, "burn", laser=True, pen_up=("M5",))
    assert (first.number, first.title, first.job.name) == (1, "job 1", "job-1")
    assert (second.number, second.title, second.job.laser, second.job.lines) == (2, "burn", True,
                                                                                    SQUARE.splitlines())
    with pytest.raises(StationError, match="the job is empty"):
        queue.add("plotter", "  \n ")
    assert len(queue.jobs) == 2


def test_each_send_is_recorded_in_the_job_history(log):
    ticks = iter([0.0, 0.5, 3.0])
    queue = JobQueue(log, source="test", clock=lambda: next(ticks))
    entry = queue.add("plotter", SQUARE, "square")
    queue.start(entry, "frame", lines_total=6)
    queue.finish(entry, JobResult("done", "frame done", 6, 6, 0.1))
    queue.start(entry, "run")
    queue.progress(entry, 2)
    queue.progress(entry, 3)  # within the interval: not written
    assert log.recent()[0].lines_acked == 2
    queue.progress(entry, 4)
    assert log.recent()[0].lines_acked == 4
    queue.finish(entry, result("stopped", resume_line=6, lines_acked=5))
    run, frame = log.recent()
    assert (frame.kind, frame.title, frame.status, frame.lines_total) == ("frame", "frame of square", "done", 6)
    assert (run.kind, run.title, run.status, run.lines_acked, run.resume_line) == ("run", "square", "stopped", 5, 6)
    assert run.lines_total == len(SQUARE.splitlines())


def test_a_queue_without_history_records_nothing():
    queue, entry = entry_in(JobState.RUNNING)
    queue.progress(entry, 3)
    assert queue.finish(entry, result("done")) is JobState.DONE and entry.log_id == 0


def test_frame_job_traces_the_extent_with_the_pen_up_or_the_laser_at_frame_power():
    plotter = builtin_profile("plotter")
    queue = JobQueue()
    entry = queue.add("plotter", SQUARE, "square", pen_up=tuple(plotter.pen.up_commands()))
    frame = frame_job(entry.job, entry.title, plotter)
    assert frame.name == "frame of square" and not frame.laser
    assert "G0 X30.000 Y30.000" in frame.lines and not any(line.startswith(("G1", "M4")) for line in frame.lines)
    laser_profile = builtin_profile("laser")
    burn = queue.add("laser", SQUARE.replace("M3 S30", "M4 S500"), "burn", laser=True)
    lines = frame_job(burn.job, burn.title, laser_profile).lines
    power = laser_profile.laser.frame_power * laser_profile.laser.max_power
    assert f"M3 S{power:g}" in lines and "M5 S0" in lines
    assert frame_job(queue.add("plotter", "G21\nG90", "nothing").job, "nothing", plotter) is None
