"""The laser's bed registered by camera (station calibrate bed) and a job placed on the stock the camera sees: on
the twins, the cut lands on the stock where it was meant to."""

from __future__ import annotations

import dataclasses
import json
from dataclasses import replace

import numpy as np
import pytest

from cam.place import place_lines
from drivers.devices import resolve
from drivers.grbl import GrblConnection, Job, JobRunner
from drivers.sim.protocol_sim import machine_named
from station.cli import main
from station.services import bed

LASER = "sim://grbl?profile=laser&clock=virtual&wire=0&name={}"
#: A 50 x 30 mm rectangle cut from its own work zero (its lower-left corner).
RECTANGLE = ["G21", "G90", "M4 S0", "G0 X0 Y0", "G1 X50 Y0 S1000 F900", "G1 X50 Y30", "G1 X0 Y30", "G1 X0 Y0",
             "M5 S0"]


@pytest.fixture
def twins(request):
    """The laser twin's URL and the camera over its bed (the station's simulated bed camera, linked by the twin's
    name, one of each test's own)."""
    name = f"bed-{request.node.name[:40].replace('[', '-').replace(']', '')}"
    url = bed.SIM_BED_CAMERA + f"&laser={name}"
    yield LASER.format(name), resolve(url).factory(url)
    machine = machine_named(name)
    if machine is not None:
        machine.stop()


def test_a_job_placed_on_the_stock_by_camera_lands_on_it_within_half_a_millimetre(twins):
    laser, camera = twins
    done = bed.calibrate_bed(bed.BedCalibrationRequest(port=laser, camera=camera.url))
    registration = done.registration
    assert registration.residual_max_mm < 0.3
    assert bed.load_registration("laser").homography == pytest.approx(registration.homography)
    # a new sheet, elsewhere and turned the other way (the marks were burned on the sheet taken away)
    since = len(machine_named(camera.bed_view.laser).snapshot().executed)
    view = replace(camera.bed_view, stock=(-150.0, -40.0, 180.0, 120.0, -9.0), since=since)
    camera.bed_view = view
    with camera:
        frame = camera.grab()
    stock = bed.find_stock(frame, registration)
    truth = view.machine_from_plane(view.stock_corners())
    assert np.abs(stock - truth).max() < 0.3
    with GrblConnection(laser) as conn:
        wco = conn.work_offset()
        placement = bed.placement_on_stock(stock, wco, (0.0, 0.0), margin=5.0)
        before = len(conn.port.machine.snapshot().executed)
        result = JobRunner(conn, Job("rectangle", place_lines(RECTANGLE, placement), laser=True)).run()
        assert result.ok, result.message
        executed = conn.port.machine.snapshot().executed[before:]
    burned = np.array([b.end[:2] for b in executed if b.power > 0])
    # where the rectangle's corners were meant to be: 5 mm inside the true sheet's lower-left corner, along its edge
    angle = np.radians(-9.0)
    along, across = np.array([np.cos(angle), np.sin(angle)]), np.array([-np.sin(angle), np.cos(angle)])
    meant = np.array([truth[0] + (5 + x) * along + (5 + y) * across for x, y in ((50, 0), (50, 30), (0, 30), (0, 0))])
    assert np.abs(burned - meant).max() < 0.5
    # and the burn is on the stock as the camera sees it: the picture shows the outline over it
    picture = bed.bed_picture(frame, registration, bed.placed_outline_machine(RECTANGLE, placement, wco),
                              stock_mm=stock)
    corner_px = np.round(registration.to_pixels(meant[:1])[0]).astype(int)
    assert tuple(picture[corner_px[1], corner_px[0]]) != tuple(frame[corner_px[1], corner_px[0]])


def test_the_marks_are_told_apart_by_size_however_the_camera_is_turned(twins):
    laser, camera = twins
    camera.bed_view = replace(camera.bed_view, bed=(200.0, 200.0, 90.0))
    done = bed.calibrate_bed(bed.BedCalibrationRequest(port=laser, camera=camera.url))
    assert done.registration.residual_max_mm < 0.3


def test_the_request_is_frozen_and_a_bad_power_in_it_is_refused_in_one_line_naming_it():
    request = bed.BedCalibrationRequest(port="sim://grbl?profile=laser&clock=virtual&wire=0", power=1.5)
    with pytest.raises(dataclasses.FrozenInstanceError):
        request.power = 0.3  # type: ignore[misc]
    with pytest.raises(bed.ServiceError) as refused:
        bed.calibrate_bed(request)  # refused before the laser is opened
    assert refused.value.field == "power" and len(str(refused.value).splitlines()) == 1
    assert "power" in str(refused.value)


def test_station_calibrate_bed_reports_the_residual_and_refuses_bad_input(tmp_path, capsys, twins):
    laser, camera = twins
    out = tmp_path / "bed.png"
    assert main(["calibrate", "bed", "--port", laser, "--camera", camera.url, "--out", str(out), "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert 0 <= document["residual_rms_mm"] <= document["residual_max_mm"] < 0.3
    assert out.stat().st_size > 0
    for argv, expected in (
            (["--area", "1,2,3"], "argument --area: expected X0,Y0,X1,Y1 in work mm"),
            (["--area", "100,100,110,110"], "--area must be x0,y0,x1,y1 with at least 30 mm between the marks"),
            (["--laser", "nope"], "--laser must name a configured laser (laser), got 'nope'"),
            (["--power", "0"], "argument --power: expected a number in (0, 1]")):
        with pytest.raises(SystemExit) as exited:
            raise SystemExit(main(["calibrate", "bed", "--port", laser, "--camera", camera.url, *argv]))
        assert exited.value.code == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert expected in err[-1], err


def test_a_frame_without_the_marks_is_refused_in_one_line(twins):
    _, camera = twins
    with camera:
        frame = camera.grab()  # nothing engraved yet
    with pytest.raises(bed.ServiceError, match="found 0 dark square"):
        bed.register_bed(frame, bed.mark_positions((130, 150, 270, 250)))


@pytest.mark.parametrize(("option", "expected"), [
    ("stock=1,2,3", "sim camera option stock: expected u,v,w,h,angle (mm, degrees), w and h > 0, got '1,2,3'"),
    ("stock=0,0,-5,10,0", "sim camera option stock: expected u,v,w,h,angle (mm, degrees), w and h > 0, got "
     "'0,0,-5,10,0'"),
    ("bed=1,x,0", "sim camera option bed: expected u,v,angle (mm, mm, degrees), got '1,x,0'"),
    ("kerf=0", "kerf"),
])
def test_the_simulated_bed_camera_refuses_bad_options_in_one_line(option, expected):
    from drivers.errors import SimConfigError
    from drivers.sim.camera import SimulatedCamera

    with pytest.raises(SimConfigError) as error:
        SimulatedCamera(f"sim://camera?{option}")
    assert expected in str(error.value) and "\n" not in str(error.value)
