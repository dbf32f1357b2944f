"""The device registry: which URL names which kind, and what a brief probe says (of one device, of all)."""

from __future__ import annotations

import threading
import time
from types import MappingProxyType

import pytest

from drivers.devices import Camera, GrblDevice, GrblSerialDevice, Projector, UnknownDeviceURL, probe, resolve
from station.devices import DeviceEntry, default_devices, probe_device, probe_devices


@pytest.mark.parametrize(("url", "kind", "simulated", "available"), [
    ("sim://grbl?profile=plotter", "grbl", True, True),
    ("sim://grbl", "grbl", True, True),
    ("/dev/ttyUSB0", "grbl", False, True),
    ("/dev/ttyACM1", "grbl", False, True),
    ("COM3", "grbl", False, True),
    ("socket://192.168.1.5:23", "grbl", False, True),
    ("rfc2217://host:2217", "grbl", False, True),
    ("loop://", "grbl", False, True),
    ("sim://camera", "camera", True, True),
    ("sim://camera?size=640x480&name=bench", "camera", True, True),
    ("0", "camera", False, True),
    ("/dev/video2", "camera", False, True),
    ("rtsp://cam.local/stream", "camera", False, True),
    ("http://127.0.0.1:8080/stream.mjpg", "camera", False, True),
    ("clips/run.mp4", "camera", False, True),
    ("sim://projector", "projector", True, True),
    ("sim://projector?size=640x480&name=bench", "projector", True, True),
    ("display:1", "projector", False, True),
])
def test_registry_table(url, kind, simulated, available):
    info = resolve(url)
    assert (info.kind, info.simulated, info.available) == (kind, simulated, available)


@pytest.mark.parametrize("url", ["", "ftp://x", "sim://toaster", "display:", "COM"])
def test_unknown_url_names_it_and_the_accepted_forms(url):
    with pytest.raises(UnknownDeviceURL, match="matches no driver; accepted: GRBL: sim://grbl") as caught:
        resolve(url)
    assert repr(url) in str(caught.value)


def test_cameras_have_drivers_and_say_their_state(tmp_path):
    assert (resolve("/dev/video0").driver, resolve("sim://camera").driver) == ("opencv", "sim-camera")
    assert probe("sim://camera") == "open: 1920x1080"
    assert probe("sim://camera?size=640x480") == "open: 640x480"
    assert probe("sim://camera?tilt=95") == ("not available: sim camera option tilt: expected an angle in degrees "
                                             "from -80 to 80, got '95'")
    assert probe(str(tmp_path / "none.avi")) == "not available: no such video file"


def test_projectors_have_drivers_and_say_their_state(monkeypatch):
    assert (resolve("display:1").driver, resolve("sim://projector").driver) == ("sdl-display", "sim-projector")
    assert probe("sim://projector") == "open: 1280x800"
    assert probe("sim://projector?size=800x600") == "open: 800x600"
    assert probe("sim://projector?size=big") == ("not available: sim projector option size: expected WxH in pixels "
                                                 "from 1 to 16384 (e.g. size=1280x800), got 'big'")
    monkeypatch.setenv("SDL_VIDEODRIVER", "offscreen")
    state = probe("display:9")  # one line whether or not pygame-ce is installed
    assert state.startswith("not available: ") and "\n" not in state


def test_a_real_projector_probe_gets_time_to_start_its_process():
    from drivers.projector.display import DISPLAY_PROBE_TIMEOUT
    from station.devices import probe_wait

    assert probe_wait(DeviceEntry("p", "projector", "display:1", False)) == DISPLAY_PROBE_TIMEOUT
    assert probe_wait(DeviceEntry("p", "projector", "sim://projector", True)) == 0.5
    assert probe_wait(DeviceEntry("m", "plotter", "loop://", False, "plotter", MappingProxyType({"timeout": 2}))) == 2


def test_probe_sim_grbl_reads_banner_and_status():
    assert probe("sim://grbl?profile=plotter") == "connected: Grbl 1.1h, Idle"


def test_probe_missing_port():
    assert probe("/dev/ttyUSB99") == "not connected: no such port"


def test_grbl_serial_device_is_a_grbl_device():
    device = GrblSerialDevice("sim://grbl?profile=laser")
    assert isinstance(device, GrblDevice)
    device.close()
    device.close()
    assert not isinstance(device, (Camera, Projector))
    assert isinstance(resolve("sim://projector").factory("sim://projector"), Projector)


def test_probe_of_a_missing_port_answers_at_once():
    started = time.monotonic()
    assert probe("/dev/ttyUSB99", timeout=5.0) == "not connected: no such port"
    assert time.monotonic() - started < 0.5


def test_probing_every_device_is_bounded_in_time(monkeypatch):
    # A probe stuck in a slow connect (pyserial's socket:// waits up to 5 s) does not hold up the answer.
    import station.devices as station_devices

    released = threading.Event()  # the stuck connect ends with the test, not after a guessed while

    def stuck_or_quick(device):
        if device.name == "stuck":
            released.wait(30)
        return f"answered {device.name}"

    monkeypatch.setattr(station_devices, "probe_device", stuck_or_quick)
    monkeypatch.setattr(station_devices, "PROBE_GRACE", 0.2)
    devices = (DeviceEntry("quick", "plotter", "/dev/ttyUSB98", False),
               DeviceEntry("stuck", "plotter", "socket://10.255.255.1:23", False))
    started = time.monotonic()
    try:
        assert station_devices.probe_devices(devices) == ["answered quick", "not connected: no answer within 0.7 s"]
        assert time.monotonic() - started < 1.5
    finally:
        released.set()


def test_probe_device_uses_its_timeout_option():
    slow = DeviceEntry("loop", "plotter", "loop://", False, "plotter", MappingProxyType({"timeout": 0.3}))
    assert probe_device(slow) == "not connected: no GRBL banner within 0.3 s"
    assert probe_devices(default_devices()) == ["connected: Grbl 1.1h, Idle"] * 2 + ["open: 1920x1080",
                                                                                     "open: 1280x800"]
