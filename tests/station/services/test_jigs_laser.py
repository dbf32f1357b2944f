"""The jigs' laser job: the G-code cuts each piece's kerf-offset outline, and the job runs to its end on the
simulated GRBL with the beam dark on every travel."""

from __future__ import annotations

import re

import numpy as np
import pytest
import shapely
from shapely import affinity
from shapely.geometry import Polygon

from drivers.grbl import GrblConnection, Job, JobRunner, frame_lines
from drivers.profiles import builtin_profile
from station.services.jig_plan import JigOptions
from station.services.jigs import make_jigs

WORD = re.compile(r"([GXYSF])(-?\d+(?:\.\d*)?)")


def burns(gcode: str, power: float) -> list[np.ndarray]:
    """The polylines the G-code burns at ``power`` (the S word, modal), in work mm."""
    position, s_word, current, paths = np.zeros(2), 0.0, None, []
    for raw in gcode.splitlines():
        line = raw.split(";")[0].strip()
        words = dict((k, float(v)) for k, v in WORD.findall(line))
        if "G" not in words and not ({"X", "Y"} & set(words)):
            continue
        s_word = words.get("S", s_word)
        target = np.array([words.get("X", position[0]), words.get("Y", position[1])])
        if words.get("G") == 1 and s_word == power:
            if current is None:
                current = [position.copy()]
            current.append(target)
        elif current is not None:
            paths.extend(loops(np.array(current)))
            current = None
        position = target
    if current is not None:
        paths.extend(loops(np.array(current)))
    return paths


def loops(path: np.ndarray) -> list[np.ndarray]:
    """A burned polyline split where it comes back to its start: a contour's passes follow one another without a
    travel between them."""
    pieces, start = [], 0
    for index in range(2, len(path)):
        if np.allclose(path[index], path[start], atol=1e-3):
            pieces.append(path[start:index + 1])
            start = index
    if start < len(path) - 1:
        pieces.append(path[start:])
    return pieces


@pytest.mark.parametrize("kerf", [0.15, 0.4])
def test_the_gcode_cuts_every_piece_on_its_kerf_offset_outline(kerf):
    result = make_jigs("simple", "success", JigOptions(kerf=kerf), tolerances=False)
    profile = builtin_profile("laser")
    output = result.sheets[0]
    cut_power = profile.material("plywood_3mm").cut.power * profile.laser.max_power
    cut = burns(output.gcode, cut_power)
    # two passes of each closed contour: the base's outline and slot, the plate's outline
    contours = [Polygon(path) for path in cut if np.allclose(path[0], path[-1], atol=1e-3)]
    assert len(contours) == len(cut) == 2 * 3
    pieces = {piece.name: piece for jig in result.plan.jigs for piece in jig.pieces}
    for part, placement in zip(output.sheet.parts, output.sheet.placements):
        designed = pieces[part.name].shape  # the piece as designed, in its own frame
        placed = affinity.translate(affinity.rotate(designed, placement.angle, origin=(0, 0)), placement.dx,
                                    placement.dy)
        expected = placed.buffer(kerf / 2.0, quad_segs=16, join_style="round")  # outline out, holes in, by kerf/2
        rings = [expected.exterior, *expected.interiors]
        for ring in rings:
            matches = [c for c in contours if shapely.hausdorff_distance(c.exterior, ring) < 0.02]
            assert len(matches) == 2, (part.name, len(matches))  # both passes on the offset ring
            # every point the beam passes is half a kerf off the designed edge, on the side away from the material
            points = shapely.points(np.asarray(matches[0].exterior.coords))
            assert shapely.distance(placed.boundary, points) == pytest.approx(kerf / 2.0, abs=0.011)
            assert not shapely.contains(placed, points).any()
    # the base's slot is designed 3 mm (the plywood) + 0.1 mm wide; the laser runs kerf/2 inside it on both sides,
    # so the strip it burns away leaves exactly the designed slot
    slot = min(contours, key=lambda c: c.area)
    corners = np.asarray(slot.minimum_rotated_rectangle.exterior.coords)
    sides = sorted(np.hypot(*np.diff(corners[:3], axis=0).T))
    assert sides[0] == pytest.approx(3.1 - kerf, abs=0.01)


def run_on_the_twin(gcode: str, extent):
    """The maker's sequence on the simulated laser: work origin at the sheet's corner, the frame at low power, the
    pre-flight, the job; returns the runner's result and what the machine executed."""
    profile = builtin_profile("laser")
    conn = GrblConnection("sim://grbl?profile=laser&time_scale=1&clock=virtual", poll_interval=0.05,
                          lost_ok_timeout=0.3, silence_timeout=0.6).open()
    try:
        conn.command("G10 L2 P1 X-400 Y-400")  # machine space is negative: work X0 Y0 at the front-left corner
        conn.refresh()
        lo, hi = extent
        frame = Job("frame", frame_lines(lo, hi, laser_power=profile.laser.frame_power * profile.laser.max_power),
                    laser=True)
        framed = JobRunner(conn, frame).run()
        assert framed.state == "done", framed.message
        runner = JobRunner(conn, Job.from_text("jigs", gcode, laser=True))
        checked = runner.preflight()
        assert checked["lines"] >= len(gcode.splitlines())
        done = runner.run()
        record = conn.port.machine.snapshot()
    finally:
        conn.close()
    return done, record


@pytest.mark.parametrize("scenario, layout", [("simple", "success"), ("causalityswitch_ball", "success"),
                                              ("branching", "success")])
def test_the_jig_job_runs_to_its_end_on_the_simulated_laser_dark_on_every_travel(scenario, layout):
    result = make_jigs(scenario, layout, tolerances=False)
    assert result.plan.jigs and result.sheets
    profile = builtin_profile("laser")
    for output in result.sheets:
        done, record = run_on_the_twin(output.gcode, output.job.extent())
        assert done.state == "done" and done.laser_off, done.message
        rapids = [b for b in record.executed if b.rapid]
        burned = [b for b in record.executed if not b.rapid and b.power > 0]
        assert len(rapids) >= len(output.job.paths) and all(b.power == 0 for b in rapids)
        cut = profile.material("plywood_3mm").cut.power * profile.laser.max_power
        engrave = profile.material("plywood_3mm").engrave.power * profile.laser.max_power
        frame = profile.laser.frame_power * profile.laser.max_power  # the frame traced first, at 1 %
        # cut, and the tags and names engraved
        assert {round(b.power) for b in burned} == {round(frame), round(cut), round(engrave)}
        # no light while a rapid block runs (a block runs from the previous block's end to its own)
        ends = [b.t_end for b in record.executed]
        for previous_end, block in zip([0.0, *ends], record.executed):
            if block.rapid:
                assert all(s.power == 0 for s in record.samples if previous_end < s.t < block.t_end)
        assert record.samples[-1].power == 0.0
