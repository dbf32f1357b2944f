"""Laser job: order of operations, dark travels (parsed and on the simulated GRBL), work area, estimates."""

from __future__ import annotations

import io
import time

import numpy as np
import pytest
import serial

from cam.laser import (
    OperationSettings,
    check_work_area,
    order_paths,
    path_travel,
    plan_laser_job,
    write_laser_gcode,
)
from drivers.errors import JobRefused
from drivers.gcode import clean_line, interpret, tokenize
from drivers.grbl.planner import line_seconds
from drivers.profiles import builtin_profile

ENGRAVE = OperationSettings(power=0.3, feed=3000.0, passes=1)
CUT = OperationSettings(power=1.0, feed=600.0, passes=2)


def square(x, y, size):
    return np.array([[x, y], [x + size, y], [x + size, y + size], [x, y + size], [x, y]], dtype=float)


def synthetic_job(seed=0, parts=6):
    rng = np.random.default_rng(seed)
    strokes, groups = [], []
    for _ in range(parts):
        x, y = rng.uniform(10, 150, size=2)
        strokes.append(np.array([[x + 2, y + 2], [x + 8, y + 2]]))
        groups.append(([square(x + 10, y + 10, 4), square(x + 20, y + 10, 3)], square(x, y, 30)))
    return strokes, groups


def gcode_of(job, bounds=(0, 0, 400, 400)):
    out = io.StringIO()
    write_laser_gcode(job, out, bounds)
    return out.getvalue().splitlines()


def test_every_line_parses_and_the_program_frames_the_laser():
    strokes, groups = synthetic_job()
    lines = gcode_of(plan_laser_job(strokes, groups, ENGRAVE, CUT, 1000.0))
    for line in lines:
        tokenize(clean_line(line))
    path = interpret(lines)
    assert lines[-1] == "M5 S0"
    assert any(line.startswith("M4") for line in lines)
    assert not any(line.startswith("M3") for line in lines)
    # Dark on every travel move, burning at the operation's S on every cut move.
    assert path.rapid.sum() > 10
    assert np.all(path.power[path.rapid] == 0)
    burning = ~path.rapid & (np.linalg.norm(path.end - path.start, axis=1) > 0)
    assert set(np.unique(path.power[burning])) == {300.0, 1000.0}
    lo, hi = path.extent()
    assert lo[0] >= 0 and lo[1] >= 0 and hi[0] <= 400 and hi[1] <= 400


def test_engrave_before_cut_and_holes_before_each_outline():
    strokes, groups = synthetic_job()
    job = plan_laser_job(strokes, groups, ENGRAVE, CUT, 1000.0)
    operations = [p.operation for p in job.paths]
    assert operations == sorted(operations, key=lambda op: op != "engrave")
    for index, (inner, outer) in enumerate(groups):
        positions = [i for i, p in enumerate(job.paths) if p.part == index]
        outline_area = np.ptp(outer[:, 0]) * np.ptp(outer[:, 1])
        areas = [np.ptp(job.paths[i].points[:, 0]) * np.ptp(job.paths[i].points[:, 1]) for i in positions]
        assert len(positions) == len(inner) + 1
        assert areas[-1] == pytest.approx(outline_area)  # the outline comes last
        assert positions == list(range(positions[0], positions[0] + len(positions)))  # a part is cut in one go


def test_a_part_inside_another_parts_hole_is_cut_first():
    ring_outer = np.array([[0, 0], [100, 0], [100, 100], [0, 100], [0, 0]], dtype=float)
    ring_hole = np.array([[10, 10], [90, 10], [90, 90], [10, 90], [10, 10]], dtype=float)
    small = square(40, 40, 10)
    job = plan_laser_job([], [([ring_hole], ring_outer), ([], small)], ENGRAVE, CUT, 1000.0)
    assert [p.part for p in job.paths] == [1, 0, 0]


def test_ordering_shortens_travel_and_keeps_every_path():
    strokes, groups = synthetic_job(seed=3, parts=25)
    ordered = plan_laser_job(strokes, groups, ENGRAVE, CUT, 1000.0)
    plain = plan_laser_job(strokes, groups, ENGRAVE, CUT, 1000.0, optimize=False)
    assert ordered.travel < 0.8 * plain.travel
    assert ordered.travel_unordered == pytest.approx(plain.travel_unordered)
    assert len(ordered.paths) == len(plain.paths)
    for op in ("engrave", "cut"):
        assert ordered.burn_length(op) == pytest.approx(plain.burn_length(op))


def test_two_opt_is_at_least_as_good_as_nearest_neighbour_alone():
    rng = np.random.default_rng(1)
    paths = [np.array([p, p + rng.normal(size=2)]) for p in rng.uniform(0, 200, size=(60, 2))]
    ordered, order = order_paths(paths, [False] * len(paths))
    assert sorted(order.tolist()) == list(range(60))
    # A pure nearest-neighbour tour for comparison.
    position, remaining, tour = np.zeros(2), list(range(60)), []
    while remaining:
        d = [min(np.linalg.norm(paths[i][0] - position), np.linalg.norm(paths[i][-1] - position)) for i in remaining]
        i = remaining.pop(int(np.argmin(d)))
        path = paths[i] if np.linalg.norm(paths[i][0] - position) <= np.linalg.norm(paths[i][-1] - position) \
            else paths[i][::-1]
        tour.append(path)
        position = path[-1]
    assert path_travel(ordered) <= path_travel(tour) + 1e-9


def test_outside_the_work_area_is_refused_with_the_extent():
    strokes, groups = synthetic_job()
    job = plan_laser_job(strokes, groups, ENGRAVE, CUT, 1000.0, offset=(300, 0))
    with pytest.raises(JobRefused, match=r"X 0\.00\.\.4[0-9]{2}\.[0-9]{2} mm"):
        check_work_area(job, (0, 0, 400, 400))
    with pytest.raises(JobRefused, match="work area"):
        gcode_of(job)
    with pytest.raises(JobRefused, match="laser mode"):
        write_laser_gcode(plan_laser_job(strokes, groups, ENGRAVE, CUT), io.StringIO(), laser_mode=False)


def test_the_estimate_is_grbls_planner_on_the_job_as_the_streamer_reads_it():
    settings = builtin_profile("laser").grbl_settings
    strokes = [np.array([[20.0, 20.0], [60.0, 25.0], [90.0, 20.0]])]
    job = plan_laser_job(strokes, [([], square(10, 40, 50))], ENGRAVE, CUT, 1000.0, machine_settings=settings)
    estimate = job.estimate_seconds()
    lines = gcode_of(job)
    # the streamer's ETA of the written job: the same planner, the same total
    eta = line_seconds(interpret(lines), lines, settings, laser_mode=True).sum()
    assert estimate["total"] == pytest.approx(eta, rel=1e-9)
    assert estimate["total"] == pytest.approx(estimate["cut"] + estimate["travel"] + estimate["engrave"])
    # each corner and each start is taken slower than the feed: longer than length over feed
    assert estimate["cut"] > 200.0 * 2 / 600.0 * 60.0
    assert estimate["travel"] > job.travel / settings[110] * 60.0


def stream(port, lines, timeout=60.0):
    """Send one line at a time and wait for its ok (the simplest correct GRBL streaming)."""
    deadline = time.monotonic() + timeout
    for line in lines:
        port.write((line + "\n").encode())
        while True:
            reply = port.readline().decode().strip()
            if reply == "ok":
                break
            assert not reply.startswith(("error", "ALARM")), f"{line!r}: {reply}"
            assert time.monotonic() < deadline, "the simulated machine did not answer"


@pytest.mark.parametrize("laser_mode", [1, 0])
def test_laser_is_dark_on_every_travel_on_the_simulated_machine(laser_mode):
    import drivers.sim  # noqa: F401  (registers sim:// URLs)

    profile = builtin_profile("laser")
    strokes, groups = synthetic_job(parts=3)
    job = plan_laser_job(strokes, groups, profile.material("plywood_3mm").engrave, CUT, profile.laser.max_power)
    lines = gcode_of(job, profile.work_bounds())
    # Soft limits off: the simulated machine's travel is in negative machine space, the job in work space.
    url = f"sim://grbl?profile=laser&time_scale=0.002&wire=0&s20=0&s32={laser_mode}"
    port = serial.serial_for_url(url, timeout=2.0)
    try:
        port.readline()
        stream(port, lines)
        port.write(b"G4 P0\n")  # waits for the planner to empty
        assert port.readline().decode().strip() == "ok"
        record = port.machine.snapshot()
    finally:
        port.close()
    rapids = [b for b in record.executed if b.rapid]
    burns = [b for b in record.executed if not b.rapid]
    assert len(rapids) >= len(job.paths) and burns
    assert all(b.power == 0 for b in rapids)
    assert max(b.power for b in burns) == pytest.approx(1000.0)
    # Sampled output: no light while a rapid block runs (a block runs from the previous block's end to its own).
    ends = [b.t_end for b in record.executed]
    for previous_end, block in zip([0.0, *ends], record.executed):
        if block.rapid:
            during = [s for s in record.samples if previous_end < s.t < block.t_end]
            assert all(s.power == 0 for s in during), (block, previous_end, during)
    # One clock: a block starts (a Run sample) after the spindle change its line made, so nothing between a block's
    # start and its end says Idle. With a second clock reading in the parser, the spindle change of a burn landed in
    # the next travel's window on a loaded machine.
    for start in (s.t for s in record.samples if s.state == "Run"):
        end = min(t for t in ends if t >= start)
        idle = [s for s in record.samples if start < s.t < end and s.state == "Idle"]
        assert not idle, (start, end, idle)


def test_a_fabricated_job_is_framed_then_run_by_the_grbl_driver():
    """The maker's sequence: set the sheet's corner as work origin, frame the job at low power, then cut."""
    from drivers.grbl import GrblConnection, Job, JobRunner, frame_lines
    from station.services.fabricate import FabricationRequest, fabricate

    profile = builtin_profile("laser")
    result = fabricate(FabricationRequest("spirograph", {"r_f": 5, "r_r": 3, "d": 1.0}, 3.0, sheet_size=(120.0, 80.0),
                                          material="cardboard_2mm"))
    conn = GrblConnection("sim://grbl?profile=laser&time_scale=0.0005", poll_interval=0.05, lost_ok_timeout=0.3,
                          silence_timeout=0.6).open()
    try:
        # Machine space is negative (GRBL default): work X0 Y0 at the front-left corner of the travel.
        conn.command("G10 L2 P1 X-400 Y-400")
        conn.refresh()
        lo, hi = result.job.extent()
        frame = Job("frame", frame_lines(lo, hi, laser_power=profile.laser.frame_power * profile.laser.max_power),
                    laser=True)
        framed = JobRunner(conn, frame).run()
        assert framed.state == "done", framed.message
        job = Job.from_text("parts", result.gcode, laser=True)
        runner = JobRunner(conn, job)
        checked = runner.preflight()
        assert checked["lines"] >= len(result.gcode.splitlines())
        done = runner.run()
        assert done.state == "done", done.message
        record = conn.port.machine.snapshot()
    finally:
        conn.close()
    cuts = [b for b in record.executed if not b.rapid and b.power > 0]
    assert cuts and all(b.power == 0 for b in record.executed if b.rapid)
    assert max(b.power for b in cuts) == pytest.approx(0.8 * profile.laser.max_power)
