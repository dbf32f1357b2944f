"""A projector's calibration belongs to the projector it was measured on: kept under its key, read by the guide and
the check on that projector only (the CLI and the TUI through one service)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from calibration.projector_map import ProjectorMap, save_projector_map
from drivers.devices import projector_identity
from drivers.sim.projector import SimulatedProjector
from station.cli import main
from station.devices import default_devices
from station.errors import ServiceError
from station.services.guide import GuideRequest, make_guide, show_step
from station.services.projector_calibration import projector_map_file
from station.services.projectors import projector_device, projector_homography, projector_key, projector_mapping

SIMPLE = Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "simple.toml"
CAMERA = "sim://camera?size=320x180&f=220&supersample=1&projector=wall"
WALL = "sim://projector?name=wall&size=320x200&area=-140,-85,150,95"
#: The station's own projector when no station.toml names one: the twin the default camera sees.
STATIONS = next(device.url for device in default_devices() if device.kind == "projector")


@pytest.fixture(autouse=True)
def _twins(fresh_twins):
    return fresh_twins


def calibrate(capsys, *extra: str) -> str:
    assert main(["calibrate", "projector", "--camera", CAMERA, "--projector", WALL, *extra]) == 0
    return capsys.readouterr().out


def projected(capsys, *extra: str) -> str:
    assert main(["guide", "simple", "success", "--no-tolerances", "--project", *extra]) == 0
    return next(line for line in capsys.readouterr().out.splitlines() if line.startswith("projected "))


def test_a_map_measured_on_one_projector_is_kept_and_used_for_that_projector_only(capsys):
    out = calibrate(capsys)
    assert f"saved {projector_map_file('wall')}" in out
    assert not projector_map_file("projector").exists()  # not the station's own projector's
    saved = json.loads(projector_map_file("wall").read_text(encoding="utf-8"))
    assert saved["device"] == "sim://projector?name=wall" and saved["projector"] == WALL
    # the same projector (the twin named wall, however its URL is written) draws through it
    line = projected(capsys, "--projector", "sim://projector?size=320x200&name=wall")
    assert line == (f"projected the calibrate frame on wall (sim://projector?size=320x200&name=wall), at true scale "
                    f"(its map {projector_map_file('wall')}, landing error p95 "
                    f"{saved['landing_error_mm']['p95']:.2f} mm)")
    # the station's configured projector has no calibration of its own, and says so
    assert projected(capsys) == (f"projected the calibrate frame on projector ({STATIONS}), fitted to the "
                                 "screen, NOT at true scale: projector has no calibration of its own (`station "
                                 "calibrate projector`)")
    line = projected(capsys, "--projector", "sim://projector?name=hall&size=320x200", "--step", "2")
    assert line.startswith("projected step 2 of 3 on hall (sim://projector?name=hall&size=320x200), fitted to the "
                           "screen, NOT at true scale: hall has no calibration of its own")


def test_the_steps_on_an_open_projector_go_through_its_own_map(capsys):
    calibrate(capsys)
    job = make_guide(GuideRequest("simple", "success", tolerances=False))
    with SimulatedProjector("sim://projector?size=320x200") as unnamed:
        assert show_step(job, unnamed, 1) is False and projector_homography(unnamed) is None
    with SimulatedProjector("sim://projector?name=wall&size=320x200") as wall:
        assert show_step(job, wall, 1) is True
        plane_from_pixel = projector_mapping(WALL, (320, 200)).projector_map.plane_from_pixel
        assert np.allclose(projector_homography(wall) @ plane_from_pixel / (projector_homography(wall)
                                                                             @ plane_from_pixel)[2, 2], np.eye(3))


def test_a_configured_projector_reads_the_map_measured_on_it_by_url(capsys, station_home):
    (station_home / "station.toml").write_text(
        '[[devices]]\nname = "shop"\nkind = "projector"\nurl = "sim://projector?name=wall&size=320x200"\n\n'
        '[[devices]]\nname = "camera"\nkind = "camera"\nurl = "sim://camera"\n', encoding="utf-8")
    out = calibrate(capsys)  # given by its URL: the configured projector of that twin, named shop
    assert f"saved {projector_map_file('shop')}" in out and out.startswith("projector 'shop' (")
    assert "at true scale" in projected(capsys)  # the station's projector, shop
    assert projector_device(WALL).name == "shop"


def test_a_map_kept_under_a_name_of_its_own_still_belongs_to_its_projector(capsys):
    out = calibrate(capsys, "--name", "bench-map")
    assert f"saved {projector_map_file('bench-map')}" in out
    assert "at true scale (its map " + str(projector_map_file("bench-map")) in projected(
        capsys, "--projector", WALL)
    assert "NOT at true scale" in projected(capsys)
    # a map under wall's key that records another projector is not wall's
    save_projector_map(projector_mapping(WALL, (320, 200)).projector_map, projector_map_file("wall"),
                       extra={"device": "display:3"})
    assert projector_mapping(WALL, (320, 200)).path == projector_map_file("bench-map")


def test_a_map_recording_no_projector_stays_its_keys():
    """Maps written before maps recorded their projector: the file of the station's projector stays its own."""
    legacy = ProjectorMap(np.array([[0.5, 0.0, -300.0], [0.0, -0.5, 200.0], [0.0, 0.0, 1.0]]), (1280, 800),
                          {"p50": 0.2, "p95": 0.4, "max": 0.6}, {})
    save_projector_map(legacy, projector_map_file("projector"))
    assert "device" not in json.loads(projector_map_file("projector").read_text(encoding="utf-8"))
    assert projector_mapping(STATIONS, (1280, 800)).true_scale
    other = projector_mapping("sim://projector?name=wall", (1280, 800))
    assert not other.true_scale and other.reason.startswith("wall has no calibration of its own")


def test_keys():
    assert projector_key(STATIONS) == "projector"  # the default station's projector
    assert projector_key("sim://projector?name=projector&size=1280x800") == "projector"  # the same twin
    assert projector_key("sim://projector?size=640x400") == "sim-projector"  # an unnamed twin is another one
    assert projector_key("sim://projector?name=wall&area=0,0,600,400") == "wall"
    assert projector_key(" display:1 ") == "display-1"
    assert projector_identity("display:1") == "display:1"
    hashed = projector_key("sim://projector?name=camera")  # the configured camera's name: another key
    assert hashed.startswith("camera-") and len(hashed) == len("camera-") + 6
    assert projector_key("sim://projector?name=my%20wall").startswith("my-wall-")
    with pytest.raises(ServiceError, match=r"^projector: 'sim://camera' is not a projector the station can drive "
                                           r"\(it names a camera\)$"):
        projector_key("sim://camera")
    with pytest.raises(ServiceError, match="^projector: unknown sim projector option 'nme'"):
        projector_key("sim://projector?nme=wall")


def test_a_guide_refuses_a_url_that_is_no_projector(capsys):
    assert main(["guide", "simple", "success", "--project", "--projector", "sim://camera"]) == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        "station: error: --projector: 'sim://camera' is not a projector the station can drive (it names a camera)")
    assert main(["guide", "simple", "success", "--json", "--projector", WALL]) == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == "station: error: --projector goes with --project"


async def test_the_assemble_screen_says_whether_its_projector_has_a_map_of_its_own(tmp_path):
    from textual.widgets import Static

    from ..conftest import opened, settle

    plane_from_pixel = np.array([[0.5, 0.0, -320.0], [0.0, -0.5, 200.0], [0.0, 0.0, 1.0]])
    measured = ProjectorMap(plane_from_pixel, (1280, 800), {"p50": 0.2, "p95": 0.4, "max": 0.6}, {})
    # a map of the twin named wall kept under the station's projector's key: not the station's projector's
    save_projector_map(measured, projector_map_file("projector"), extra={"device": "sim://projector?name=wall"})
    async with opened(tmp_path, "a") as (app, pilot):
        app.screen.open_layout(str(SIMPLE), "success")
        await settle(app, pilot)
        status = str(app.screen.query_one("#status", Static).render())
        assert ("NOT at true scale: projector has no calibration of its own (`station calibrate projector`); "
                f"{projector_map_file('projector')} was measured on sim://projector?name=wall") in status
    save_projector_map(measured, projector_map_file("projector"), extra={"device": projector_identity(STATIONS)})
    async with opened(tmp_path, "a") as (app, pilot):
        app.screen.open_layout(str(SIMPLE), "success")
        await settle(app, pilot)
        status = str(app.screen.query_one("#status", Static).render())
        assert f"at true scale (its map {projector_map_file('projector')}, landing error p95 0.40 mm)" in status
