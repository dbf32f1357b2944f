"""How a job that ends early reports itself: no 100 % unless done, the lines GRBL confirmed with ok, and the line to
resume from: the one the machine was executing, found from where it stopped."""

from __future__ import annotations

import dataclasses

import pytest

from common.progress import Progress
from drivers.gcode import clean_line
from drivers.grbl import Job, JobProgress, JobRunner

from ..conftest import sim_url, start_until_acked

SQUARE = ["G21", "G90", "M4 S400", "G0 X10 Y10", "G1 X60 Y10 F3000", "G1 X60 Y60", "G1 X10 Y60", "G1 X10 Y10",
          "G0 X0 Y0"]


def first_unfinished_line(lines, record, since: float) -> int:
    """1-based line of the first motion the machine did not complete before ``since`` (a reset)."""
    done = [b.text for b in record.executed if b.t_end <= since]
    motion = [(number, clean_line(line)) for number, line in enumerate(lines, start=1)
              if clean_line(line).startswith(("G0", "G1"))]
    for (number, text), executed in zip(motion, done + [None] * len(motion)):
        if executed != text:
            return number
    return len(lines) + 1


def test_an_aborted_job_resumes_from_the_line_it_was_executing(make_connection):
    conn = make_connection(sim_url("laser", time_scale=0.5))
    job = Job("square", SQUARE, laser=True)
    updates = []
    runner = JobRunner(conn, job, on_progress=lambda p: updates.append(dataclasses.replace(p)))
    start_until_acked(runner, 7)
    runner.abort()
    result = runner.wait(10)
    record = conn.port.machine.snapshot()
    expected = first_unfinished_line(SQUARE, record, record.resets[-1])
    assert result.state == "aborted" and result.resume_line == expected
    assert f"resume from line {expected}" in result.message
    assert result.lines_acked >= 7 > expected - 1  # confirmed is not executed: the planner held the rest
    assert updates[-1].fraction < 1.0 and updates[-1].eta is None
    # unlock, resume there: every side of the square is drawn
    conn.command("$X")
    again = JobRunner(conn, job, from_line=result.resume_line).run()
    assert again.ok, again.message
    drawn = {b.end[:2] for b in conn.port.machine.snapshot().executed if b.power == 400}
    wco = conn.work_offset()
    assert {(x - wco[0], y - wco[1]) for x, y in drawn} >= {(60, 10), (60, 60), (10, 60), (10, 10)}


def test_a_job_stopped_by_an_error_resumes_where_the_machine_stopped(make_connection):
    conn = make_connection(sim_url("laser", time_scale=0.2))
    lines = SQUARE[:6] + ["G41"] + SQUARE[6:]
    result = JobRunner(conn, Job("bad", lines, laser=True)).run()
    record = conn.port.machine.snapshot()
    assert result.state == "stopped" and "error:20" in result.message
    assert result.resume_line == first_unfinished_line(lines, record, record.resets[-1])
    assert result.lines_acked == 6 - sum(1 for line in lines[:6] if not clean_line(line))  # G41 is not confirmed


def test_a_finished_job_has_no_resume_line_and_reaches_100_percent(make_connection):
    conn = make_connection(sim_url("laser", time_scale=0.002))
    updates = []
    result = JobRunner(conn, Job("square", SQUARE, laser=True),
                       on_progress=lambda p: updates.append(dataclasses.replace(p))).run()
    assert result.ok and result.resume_line is None
    assert [u.fraction for u in updates].index(1.0) == len(updates) - 1  # 100 % only in the last update (done)


def test_job_progress_is_the_one_progress_type_with_its_own_fields_kept():
    progress = JobProgress("running", 200, 90, 84, 0.42, 12.5, 65.0, "cutting", 83)  # the old positional order
    assert isinstance(progress, Progress)
    assert (progress.stage, progress.done, progress.total, progress.message) == ("running", 0.42, 1.0, "cutting")
    assert (progress.state, progress.fraction) == ("running", 0.42)
    assert (progress.lines_total, progress.lines_sent, progress.lines_acked) == (200, 90, 84)
    assert (progress.elapsed, progress.eta, progress.current_line) == (12.5, 65.0, 83)
    with pytest.raises(dataclasses.FrozenInstanceError):
        progress.lines_acked = 85
    with pytest.raises(AttributeError):
        progress.state = "done"  # a read-only alias
    later = dataclasses.replace(progress, stage="done", done=1.0)
    assert (later.state, later.fraction, later.lines_acked) == ("done", 1.0, 84)
    assert dataclasses.replace(progress) == progress
    with pytest.raises(ValueError, match="total must be 1"):
        JobProgress(total=200)


def test_a_job_ended_by_an_internal_error_still_says_where_to_resume(make_connection):
    # a bug in the caller's progress callback, mid-job: the runner resets the machine and ends as "error"
    conn = make_connection(sim_url("laser", time_scale=0.25))
    lines = ["G21 G90", "M4 S400", "G0 X10 Y10"] + [f"G1 X{10 + 10 * (i % 2)} Y{11 + i} F3000" for i in range(60)]
    raised = []

    def broken(progress) -> None:
        if progress.current_line >= 30 and not raised:  # the machine is half-way
            raised.append(progress)
            raise RuntimeError("a bug in the progress view")

    result = JobRunner(conn, Job("zigzag", lines, laser=True), on_progress=broken).run_safely()
    assert result.state == "error" and "a bug in the progress view" in result.message
    assert result.laser_off
    record = conn.port.machine.snapshot()
    expected = first_unfinished_line(lines, record, record.resets[-1])
    assert 4 < expected < len(lines)  # mid-job
    assert result.resume_line == expected and f"resume from line {expected}" in result.message
