"""Over 100 seeded runs with injected faults: no line lost or sent twice, never an invented ok, and every abort
leaves the laser off at the next motion sample.

The default suite runs the first 25 seeds (five of each kind of fault); ``pytest -m slow`` runs the other 80."""

from __future__ import annotations

import time

import numpy as np
import pytest

from drivers.gcode import clean_line
from drivers.grbl import Job, JobRunner

FAULT_KINDS = ("drop", "corrupt", "stray-delay", "abort", "disconnect")


def _job(rng: np.random.Generator, n: int) -> Job:
    # a random walk with unique end points (so the machine position tells which line ran last)
    steps = rng.uniform(2.0, 6.0, size=(n, 2)) * rng.choice([-1, 1], size=(n, 2))
    points = np.clip(np.cumsum(steps, axis=0) + 100.0, 5.0, 300.0)
    points += np.arange(n)[:, None] * 1e-3
    lines = ["G21", "G90", "M4 S400", "F3000"]
    lines += [f"G1 X{x:.3f} Y{y:.3f}" for x, y in points]
    lines.append("G0 X0 Y0")
    return Job("walk", lines, laser=True)


def _motion_texts(job: Job) -> list[str]:
    return [clean_line(line) for line in job.lines if clean_line(line).startswith(("G1", "G0"))]


#: Seeds the default suite runs: the kind of fault is ``seed % 5``, so five runs of each.
DEFAULT_SEEDS = 25


@pytest.mark.parametrize("seed", [pytest.param(seed, marks=[pytest.mark.slow] if seed >= DEFAULT_SEEDS else [])
                                  for seed in range(105)])
def test_seeded_fault_run(seed, make_connection):
    rng = np.random.default_rng(seed)
    kind = FAULT_KINDS[seed % len(FAULT_KINDS)]
    latency = float(rng.choice([0.0, 0.002, 0.008]))
    query = {"time_scale": 0.005, "seed": seed, "latency": latency}
    job = _job(rng, 40)
    if kind == "drop":
        query["drop"] = 0.03
    elif kind == "corrupt":
        query["corrupt"] = 0.03
    elif kind == "stray-delay":
        query.update(stray=0.1, delay=0.2, delay_max=0.05)
    elif kind == "abort":
        query["time_scale"] = 0.3  # slow enough that the abort lands mid-job even on a busy machine
    elif kind == "disconnect":
        query["disconnect_at"] = int(rng.integers(8, 40))
    url = "sim://grbl?profile=laser&" + "&".join(f"{k}={v}" for k, v in query.items())
    conn = make_connection(url)
    machine = conn.port.machine
    expected = _motion_texts(job)

    if kind == "abort":
        runner = JobRunner(conn, job)
        runner.start()
        # abort once some lines are acknowledged (the machine is then moving with the laser on)
        deadline = time.monotonic() + 5.0
        target = int(rng.integers(3, 30))
        while runner.progress.lines_acked < target and runner.result is None and time.monotonic() < deadline:
            time.sleep(0.005)
        aborted_at = time.monotonic()
        runner.abort()
        result = runner.wait(10.0)
        record = machine.snapshot()
        assert result.state == "aborted", result.message
        if result.state == "aborted":
            assert result.laser_off
            resets = [t for t in record.resets if t >= aborted_at]
            assert resets, "the abort must reach the controller as a soft reset"
            after = [s for s in record.samples if s.t >= resets[0]]
            assert after and after[0].power == 0.0
            assert all(s.power == 0.0 for s in after), "laser must stay off after an abort"
        executed = [b.text for b in record.executed if not b.jog]
        assert executed == expected[: len(executed)]
    elif kind == "disconnect":
        result = JobRunner(conn, job).run()
        assert result.state == "position_lost", result.message
        assert conn.position_lost
        received = machine.snapshot().received
        assert received[-1] == "<unplugged>"
        # never resumes on its own: a new job is refused, nothing more reaches the machine
        again = JobRunner(conn, job).run()
        assert again.state == "position_lost"
        assert machine.snapshot().received == received
        executed = [b.text for b in machine.snapshot().executed]
        assert executed == expected[: len(executed)]
    else:
        result = JobRunner(conn, job).run()
        attempts = 0
        while result.state == "stopped" and result.resume_line is not None and attempts < 20:
            assert "lost ok" in result.message
            result = JobRunner(conn, job, from_line=result.resume_line).run()
            attempts += 1
        assert result.state == "done", result.message
        record = machine.snapshot()
        executed = [b.text for b in record.executed if not b.jog]
        assert executed == expected, "every motion line executed exactly once, in order"
    record = machine.snapshot()
    assert record.overflow_bytes == 0, "the RX buffer was never overfilled"
    assert conn.replies_accepted <= record.replies_delivered, "no ok was invented"
