"""The machine-job history: rows for started, progressing and finished jobs; interrupted jobs; `station jobs`."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from station import cli
from station.db import open_database
from station.joblog import INTERRUPTED, JobLog, local_time


@pytest.fixture
def log(tmp_path):
    connection = open_database(tmp_path / "s.sqlite3")
    yield JobLog(connection)
    connection.close()


def test_a_job_is_recorded_from_start_to_finish(log):
    job_id = log.start("run", "plotter", "star.gcode", 197, "test")
    (record,) = log.recent()
    assert (record.id, record.status, record.lines_acked, record.lines_total) == (job_id, "running", 0, 197)
    assert record.finished_at is None
    log.progress(job_id, 80)
    assert log.recent()[0].lines_acked == 80
    log.finish(job_id, "stopped", 120, "job stopped at line 121", resume_line=110)
    (record,) = log.recent()
    assert (record.status, record.lines_acked, record.resume_line) == ("stopped", 120, 110)
    assert record.message == "job stopped at line 121" and record.finished_at is not None


def test_newest_first_and_limited(log):
    ids = [log.start("frame", "laser", f"job {i}", 5) for i in range(4)]
    assert [r.id for r in log.recent(3)] == ids[::-1][:3]


def test_a_running_job_whose_process_is_gone_is_interrupted(log, tmp_path):
    # a station process that started a job and died without finishing it
    code = (
        "import sys; from station.db import open_database; from station.joblog import JobLog; "
        f"JobLog(open_database({str(tmp_path / 's.sqlite3')!r})).start('run', 'laser', 'cut.gcode', 10)"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
    (record,) = log.recent()
    assert record.status == INTERRUPTED
    mine = log.start("run", "laser", "mine.gcode", 10)  # this process is alive: still running
    assert log.recent()[0].id == mine and log.recent()[0].status == "running"


def test_database_errors_never_stop_a_job_and_are_reported_once(tmp_path):
    connection = open_database(tmp_path / "s.sqlite3")
    errors = []
    log = JobLog(connection, on_error=errors.append)
    connection.close()  # every statement now fails
    assert log.start("run", "plotter", "a.gcode", 3) == 0
    log.progress(1, 2)
    log.finish(1, "done", 3, "ok")
    assert len(errors) == 1
    none = JobLog(None)
    assert none.start("run", "plotter", "a.gcode", 3) == 0 and none.recent() == []


@pytest.mark.parametrize(("stamp", "expected_date"), [
    ("2026-12-01T16:12:59.323Z", "2026-12-01"), ("garbage-stamp-here", "garbage-stamp-he"),
])
def test_local_time_reads_sqlite_stamps(stamp, expected_date):
    assert local_time(stamp).startswith(expected_date)


def test_station_send_is_listed_by_station_jobs(capsys, tmp_path):
    job = tmp_path / "square.gcode"
    job.write_text("G21\nG90\nM3 S50\nG0 X10 Y10\nM3 S30\nG1 X20 Y10 F3000\nG1 X20 Y20\nM3 S50\n")
    assert cli.main(["jobs"]) == 0
    assert "no jobs yet" in capsys.readouterr().out
    assert cli.main(["send", str(job), "--port", "sim://grbl?profile=plotter&time_scale=0.01"]) == 0
    assert cli.main(["send", str(job), "--frame", "--port", "sim://grbl?profile=plotter&time_scale=0.01"]) == 0
    capsys.readouterr()
    assert cli.main(["jobs", "--json"]) == 0
    jobs = json.loads(capsys.readouterr().out)["jobs"]
    assert [(j["kind"], j["status"]) for j in jobs] == [("frame", "done"), ("run", "done")]
    assert jobs[1]["title"] == str(job) and jobs[1]["lines_acked"] == jobs[1]["lines_total"] == 8
    assert cli.main(["jobs", "--limit", "1"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 1 and "frame of" in out[0] and "done" in out[0]
    assert cli.main(["jobs", "--limit", "0"]) == 2
    capsys.readouterr()
    assert cli.main(["jobs"]) == 0
    assert capsys.readouterr().out.count("sim://grbl?profile=plotter&time_scale=0.01 ") == 2  # the port, whole


def test_station_jobs_shows_the_port_and_the_title_whole(log):
    from station.commands import jobs

    url = "sim://grbl?profile=plotter&time_scale=0.01&name=the-long-one"
    title = "/home/maker/projects/2026/very/long/folder/name/star-of-the-show.gcode"
    log.finish(log.start("run", url, title, 10), "done", 10, "ok")
    log.finish(log.start("frame", "laser", "frame of a.gcode", 5), "done", 5, "ok")
    records = log.recent()
    width_device, width_title = max(len(r.device) for r in records), max(len(r.title) for r in records)
    lines = [jobs.describe(r, width_device, width_title) for r in records]
    assert url in lines[1] and title in lines[1]
    assert lines[0].index("done") == lines[1].index("done")  # the columns still line up


@pytest.mark.parametrize(("status", "resume", "acked", "expected"), [
    ("stopped", 42, 50, "resume from line 42"),
    ("aborted", 7, 9, "resume from line 7"),
    ("error", None, 12, "resume at or before line 13"),
    ("position_lost", 30, 33, "resume from line 30 after homing ($H)"),
    ("aborted", None, 0, "resume at or before line 1"),
    ("done", None, 100, ""),
    ("refused", None, 0, ""),
])
def test_every_unfinished_job_says_where_to_resume(log, status, resume, acked, expected):
    from station.commands.jobs import describe

    log.finish(log.start("run", "laser", "cut.gcode", 100), status, acked, "m", resume_line=resume)
    (record,) = log.recent()
    assert record.resume_hint() == expected
    assert describe(record).endswith(f"{acked}/100" + (f"  {expected}" if expected else ""))


def test_an_interrupted_job_says_where_it_was(log, tmp_path):
    # a station killed mid-job recorded its progress, with the line being executed, before dying
    code = (
        "from station.db import open_database; from station.joblog import JobLog; "
        f"log = JobLog(open_database({str(tmp_path / 's.sqlite3')!r})); "
        "log.progress(log.start('run', 'laser', 'cut.gcode', 100), 61, 57)"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
    (record,) = log.recent()
    assert record.status == INTERRUPTED and record.lines_acked == 61
    assert record.resume_hint() == "resume from line 57"


@pytest.mark.parametrize("status", ["aborted", "stopped", "error", "position_lost", INTERRUPTED])
def test_an_ending_without_a_line_keeps_the_line_recorded_while_it_ran(log, status):
    # recorded every 2 s while the job ran: the machine was on line 195 when the station was told to stop
    job_id = log.start("run", "laser", "cut.gcode", 2028)
    log.progress(job_id, 214, 195)
    log.finish(job_id, status, 215, "stopped by Ctrl-C", None)
    (record,) = log.recent()
    assert (record.status, record.resume_line) == (status, 195)
    assert record.resume_hint().startswith("resume from line 195")
    log.finish(job_id, status, 215, "stopped", 190)  # a line the ending knows better wins
    assert log.recent()[0].resume_line == 190
    done = log.start("run", "laser", "cut.gcode", 100)  # a job that finished has no line to resume from
    log.progress(done, 90, 88)
    log.finish(done, "done", 100, "done", None)
    assert log.recent()[0].resume_line is None
