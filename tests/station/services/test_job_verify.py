"""A job placed on the bed (cam.place, station send --place) and verified on the twin at virtual time
(drivers.grbl.planner, station.services.job_verify, station send --verify)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from cam.place import Placement, place_lines
from drivers.gcode import GcodeError, interpret
from drivers.grbl import Job, JobRunner
from drivers.grbl.planner import MotionBlock, plan_times
from drivers.profiles import load_profile
from station.cli import main
from station.services.job_verify import verify_job
from station.services.machines import job_seconds

from ...drivers.conftest import sim_url

SQUARE = ["G21", "G90", "M4 S0", "G0 X0 Y0", "G1 X40 Y0 F1500 S800", "G1 X40 Y30", "G1 X0 Y30", "G1 X0 Y0",
          "M5 S0"]
ARC = ["G21", "G90", "G0 X10 Y0", "G1 X20 Y0 F600 S500 M4", "G3 X20 Y20 I0 J10", "G2 X10 Y30 R10", "G91",
       "G1 X-5", "G90", "M5"]


def _turn(points: np.ndarray, placement: Placement) -> np.ndarray:
    return np.array([placement.apply(x, y) for x, y in points[:, :2]])


@pytest.mark.parametrize("placement", [Placement(100, 50, 0), Placement(100, 50, 30), Placement(-20, 300, -135)])
def test_a_placed_job_runs_every_point_turned_and_moved_arcs_included(placement):
    toolpath = interpret(ARC)
    placed = interpret(place_lines(ARC, placement))
    assert len(placed.end) == len(toolpath.end)
    assert np.allclose(placed.end[:, :2], _turn(toolpath.end, placement), atol=2e-3)
    assert np.allclose(placed.end[:, 2], toolpath.end[:, 2])


def test_a_placed_job_keeps_its_feeds_powers_and_comments():
    lines = ["(a comment)", *SQUARE]
    placed = place_lines(lines, Placement(10, 20, 90))
    assert placed[0] == "(a comment)" and placed[3] == "M4 S0"
    assert placed[5] == "G1 X10 Y60 F1500 S800"
    assert placed[6] == "G1 X-20 Y60"  # a line naming Y only gets its X too: a turn mixes them


@pytest.mark.parametrize(("lines", "expected"), [
    (["G18", "G2 X10 Z0 I5 K0 F100"], "line 2 (G2X10Z0I5K0F100): an arc in the XZ plane (G18)"),
    (["G92 X0 Y0"], "line 1 (G92X0Y0): G92 sets a work offset"),
    (["G53 G0 X10 Y10"], "line 1 (G53G0X10Y10): G53 moves in machine coordinates"),
    (["G55", "G0 X1 Y1"], "line 1 (G55): G55 selects another work coordinate system"),
    (["G0 X5"], "line 1 (G0X5): moves X alone before the job says where Y is"),
    (["G28 X0 Y0"], "line 1 (G28X0Y0): G28/G30 with an intermediate point cannot be placed"),
])
def test_what_cannot_be_placed_is_refused_naming_the_line(lines, expected):
    with pytest.raises(GcodeError, match=expected.replace("(", r"\(").replace(")", r"\)")):
        place_lines(lines, Placement(1, 2, 10))


def test_a_move_only_is_placed_axis_by_axis():
    assert place_lines(["G0 X5"], Placement(1, 2, 0)) == ["G0 X6"]


@pytest.mark.parametrize("text", ["1,2,x", "1", "1,2,3,4", "nan,1", "1,inf,0"])
def test_bad_placements_are_refused(text):
    with pytest.raises(GcodeError, match="placement"):
        Placement.parse(text)


# ----------------------------------------------------------------------------------------------------------- timing

LASER = {11: 0.01, 110: 6000.0, 111: 6000.0, 112: 1000.0, 120: 1000.0, 121: 1000.0, 122: 200.0}


def test_one_block_from_rest_to_rest_is_a_trapezoid():
    # 100 mm at 100 mm/s with 1000 mm/s^2: 0.1 s up, 0.1 s down (5 mm each), 0.9 s cruising
    planned = plan_times([MotionBlock((0, 0, 0), (100, 0, 0), False, 6000.0, True)], LASER)
    assert planned.total == pytest.approx(1.1, rel=1e-9)


def test_a_corner_is_passed_at_the_junction_deviation_speed_and_a_straight_line_without_slowing():
    corner = [MotionBlock((0, 0, 0), (50, 0, 0), False, 6000.0, True), MotionBlock((50, 0, 0), (50, 50, 0), False,
                                                                                   6000.0)]
    planned = plan_times(corner, LASER)
    sin_half = math.sqrt(0.5)  # 90 degrees
    along = 1000.0 * math.sqrt(2) * 3600  # the acceleration along the corner's bisector (-1, 1)/sqrt(2), mm/min^2
    junction = math.sqrt(along * 0.01 * sin_half / (1 - sin_half)) / 60.0  # mm/s, GRBL's formula
    assert planned.exit[0] == pytest.approx(junction, rel=1e-9)
    straight = [MotionBlock((0, 0, 0), (50, 0, 0), False, 6000.0, True), MotionBlock((50, 0, 0), (100, 0, 0), False,
                                                                                     6000.0)]
    assert plan_times(straight, LASER).total == pytest.approx(1.1, rel=1e-9)


def test_the_look_ahead_holds_fifteen_blocks():
    # 60 blocks of 0.25 mm in a line: 15 of them (3.75 mm) are not enough to stop from 100 mm/s (5 mm), so the
    # planner never reaches the feed; with the whole line known it would
    blocks = [MotionBlock((i * 0.25, 0, 0), ((i + 1) * 0.25, 0, 0), False, 6000.0, i == 0) for i in range(60)]
    windowed = plan_times(blocks, LASER)
    unbounded = plan_times(blocks, LASER, window=1000)
    assert windowed.entry.max() <= math.sqrt(2 * 1000 * 3.5) + 1e-6 < 100.0
    assert unbounded.entry.max() == pytest.approx(100.0)
    assert windowed.total > unbounded.total


def test_every_job_time_estimate_is_the_planners(make_connection):
    # one 100 mm move at the laser's rapid rate: 0.1 s to reach 100 mm/s at 1000 mm/s^2, 0.9 s cruising, 0.1 s to
    # stop; length over feed would say 1.0 s
    conn = make_connection(sim_url("laser", time_scale=1, clock="virtual"))
    runner = JobRunner(conn, Job("one", ["G21", "G91", "G1 X-100 F6000"]))
    assert runner.preflight()["estimate_s"] == pytest.approx(1.1, rel=1e-9)  # the streamer's ETA
    # the plot preview's and the job queue's layer times: on the plotter ($120 800 mm/s^2) 80 mm/s is reached in
    # 0.1 s over 4 mm, and lost as fast: 0.2 s, plus 92 mm at 80 mm/s
    plotter = load_profile("plotter")
    assert job_seconds("G21\nG90\nG0 X0 Y0\nG1 X100 Y0 F4800\n", plotter) == pytest.approx(0.2 + 92 / 80, rel=1e-9)


def test_the_twin_records_which_blocks_started_from_rest(make_connection):
    conn = make_connection(sim_url("plotter", time_scale=1, clock="virtual"))
    lines = ["G21", "G90", "G1 X10 Y0 F3000", "G1 X20 Y0", "G4 P0.2", "G1 X30 Y0", "G1 X30 Y10"]
    assert JobRunner(conn, Job("rest", lines)).run().ok
    executed = conn.port.machine.snapshot().executed
    assert [b.from_rest for b in executed] == [True, False, True, False]
    # the first leaves from where the head stood (machine 0: the plotter homed there), the others where the one
    # before ended
    assert executed[0].start == (0.0, 0.0, 0.0)
    assert [b.start[0] - conn.work_offset()[0] for b in executed[1:]] == pytest.approx([10, 20, 30])


# ----------------------------------------------------------------------------------------------------------- verify


def test_verify_times_a_job_with_acceleration_and_checks_travels_and_travel():
    done = verify_job(SQUARE, name="square", profile=load_profile("laser"))
    assert done.ok and done.state == "done"
    assert done.burn_mm == pytest.approx(140.0)
    # the planner's time is longer than length over feed: each corner and the start are taken from slower speeds
    assert done.estimate_s > 140.0 / 1000.0 * 60.0
    # and the ETA read from the G-code before it runs is that same planner: the blocks the twin ran after its first
    # travel (from wherever the head stood, which the G-code alone cannot know) take the same time
    assert done.preflight_s == pytest.approx(sum(done.block_seconds[1:]), rel=0.01)
    assert not done.lit_travels and done.within_travel
    placed = verify_job(place_lines(SQUARE, Placement(390, 0, 0)), name="off the bed", profile=load_profile("laser"))
    assert not placed.ok and not placed.within_travel and "leaves the machine's travel" in placed.message


def test_verify_finds_the_laser_on_during_travels_when_laser_mode_is_off():
    done = verify_job(["G21", "G90", "M3 S500", "G1 X10 Y10 F1000", "G0 X50 Y50", "G1 X60 Y50", "M5"],
                      name="lit", profile=load_profile("laser"), laser=False, settings={32: 0})
    assert done.state == "done" and not done.ok
    assert [text for _, text in done.lit_travels] == ["G0X50Y50"]


def test_station_send_place_and_verify_run_the_job_where_it_was_placed(tmp_path, capsys):
    job = tmp_path / "square.gcode"
    job.write_text("\n".join(SQUARE) + "\n")
    record = tmp_path / "record.json"
    url = f"sim://grbl?profile=laser&clock=virtual&record={record}"
    code = main(["send", str(job), "--profile", "laser", "--port", url, "--place", "100,80,30", "--verify",
                 "--json"])
    assert code == 0
    document = json.loads(capsys.readouterr().out)
    assert document["verify"]["ok"] and document["verify"]["estimate_s"] >= document["verify"]["preflight_s"] > 0
    executed = json.loads(record.read_text())["executed"]
    burned = np.array([row[2][:2] for row in executed if row[3] > 0]) + 400.0  # the twin's G54: machine - 400
    expected = _turn(np.array([[40.0, 0], [40, 30], [0, 30], [0, 0]]), Placement(100, 80, 30))
    assert np.allclose(burned, expected, atol=1e-3)


@pytest.mark.parametrize(("argv", "expected"), [
    (["--place", "1,2,x"], "argument --place: expected X,Y or X,Y,ANGLE as numbers"),
    (["--place", "390,0,0", "--verify"], "--verify: job 'square.gcode' fails on the twin: job 'square.gcode' "
     "leaves the machine's travel"),
])
def test_station_send_refuses_bad_placements_in_one_line(tmp_path, capsys, argv, expected):
    job = tmp_path / "square.gcode"
    job.write_text("\n".join(SQUARE) + "\n")
    with pytest.raises(SystemExit) as exited:
        code = main(["send", str(job), "--profile", "laser", "--port", "sim://grbl?profile=laser&clock=virtual",
                     *argv])
        raise SystemExit(code)
    assert exited.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert expected in err[-1] and "Traceback" not in "\n".join(err)


def test_station_send_refuses_a_job_it_cannot_place(tmp_path, capsys):
    job = tmp_path / "arc.gcode"
    job.write_text("G21\nG18\nG2 X10 Z0 I5 K0 F100\n")
    code = main(["send", str(job), "--profile", "laser", "--port", "sim://grbl?profile=laser&clock=virtual",
                 "--place", "1,2,3"])
    assert code == 2
    assert capsys.readouterr().err.strip() == ("station: error: --place: job 'arc.gcode': line 3 (G2X10Z0I5K0F100): "
                                               "an arc in the XZ plane (G18) cannot be turned or moved in XY; "
                                               "write it in G17")
