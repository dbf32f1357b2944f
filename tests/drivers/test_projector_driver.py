"""The projectors: the simulated twin (frames kept, PNGs written, options checked) and the real SDL driver's own code
path on SDL's offscreen video driver, read back from the window's surface."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest
from PIL import Image

from drivers.devices import Projector, probe, resolve
from drivers.errors import DriverError, SimConfigError
from drivers.projector.display import DisplayProjector, display_index
from drivers.projector.frame import as_rgb, fit_to_screen
from drivers.sim.projector import SimulatedProjector, forget_projectors, projector_named, sim_projector

HAS_PYGAME = importlib.util.find_spec("pygame") is not None
needs_pygame = pytest.mark.skipif(not HAS_PYGAME, reason="pygame-ce is not installed (pip install '.[projector]')")


def noise(width: int, height: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (height, width, 3), dtype=np.uint8)


@pytest.fixture(autouse=True)
def _no_shared_projectors():
    forget_projectors()
    yield
    forget_projectors()


# -- frames ------------------------------------------------------------------------------------------------------------

def test_frames_of_every_accepted_kind_become_rgb():
    grey = np.arange(12, dtype=np.uint8).reshape(3, 4)
    assert (as_rgb(grey)[:, :, 1] == grey).all() and as_rgb(grey).shape == (3, 4, 3)
    rgba = np.dstack([noise(4, 3), np.zeros((3, 4), np.uint8)])
    assert (as_rgb(rgba) == rgba[:, :, :3]).all()
    picture = noise(5, 2)
    assert (as_rgb(Image.fromarray(picture)) == picture).all()
    assert (as_rgb(Image.fromarray(picture).convert("L")) >= 0).all()


@pytest.mark.parametrize("frame", [np.zeros((4, 4)), np.zeros((4, 4, 2), np.uint8), np.zeros((0, 4), np.uint8),
                                   "frame.png", [[0, 1]]])
def test_a_bad_frame_is_one_line(frame):
    with pytest.raises(DriverError, match=r"^frame: expected a uint8 array H x W \(grey\) or H x W x 3") as caught:
        as_rgb(frame)
    assert "\n" not in str(caught.value)


def test_a_frame_of_another_size_is_letterboxed_and_said_so():
    same, note = fit_to_screen(noise(64, 40), (64, 40))
    assert note is None and same.shape == (40, 64, 3)
    wide = np.full((10, 40, 3), 200, np.uint8)  # 4:1 on a 64 x 40 screen: 64 x 16, centred
    fitted, note = fit_to_screen(wide, (64, 40))
    assert note == "frame 40x10 is not the screen's 64x40: scaled by 1.6 and letterboxed (not pixel for pixel)"
    rows = np.flatnonzero(fitted.max(axis=(1, 2)))
    assert (rows[0], rows[-1]) == (12, 27) and fitted[:, :, 0].min(axis=0).max() == 0


# -- the simulated twin ------------------------------------------------------------------------------------------------

def test_the_twin_keeps_the_frames_and_writes_them(tmp_path):
    folder = tmp_path / "shown"
    projector = resolve(f"sim://projector?size=64x40&folder={folder}&keep=2").factory(
        f"sim://projector?size=64x40&folder={folder}&keep=2")
    assert isinstance(projector, Projector)
    with pytest.raises(DriverError, match="is not open: open"):
        projector.show(noise(64, 40))
    projector.open()
    frames = [noise(64, 40, seed) for seed in range(3)]
    for frame in frames:
        assert projector.show(frame) is None
    frames[2][:] = 0  # the caller reusing its array does not change what was shown
    assert projector.frames_shown == 3 and len(projector.frames) == 2
    assert (projector.frames[-1] == noise(64, 40, 2)).all() and (projector.frames[0] == frames[1]).all()
    written = sorted(p.name for p in folder.iterdir())
    assert written == ["frame_0001.png", "frame_0002.png", "frame_0003.png"]
    assert (np.asarray(Image.open(folder / "frame_0002.png")) == frames[1]).all()
    image, size = projector.current()
    assert size == (64, 40) and (image == noise(64, 40, 2)).all()
    projector.blank()
    assert projector.current()[0].max() == 0 and projector.light()["blank"]
    projector.close()
    projector.close()


def test_the_twin_tells_a_camera_where_its_light_lands():
    projector = sim_projector("sim://projector?size=100x50&area=0,0,200,100")
    projector.open()
    frame = np.zeros((50, 100), np.uint8)
    frame[0, 0] = 255  # the top-left pixel
    projector.show(frame)
    light = projector.light()
    assert light["size"] == [100, 50] and light["frames_shown"] == 1 and not light["blank"]
    assert light["image"][0, 0].tolist() == [255, 255, 255]
    plane_from_pixel = np.array(light["plane_from_pixel"])
    # the top-left pixel's centre lands 1 mm in from the area's top-left corner (2 mm pixels), v up
    assert np.allclose(plane_from_pixel @ [0, 0, 1], [1.0, 99.0, 1.0])
    assert np.allclose(plane_from_pixel @ [99, 49, 1], [199.0, 1.0, 1.0])
    assert set(light) == {"size", "image", "blank", "frames_shown", "plane_from_pixel", "note"}


def test_a_named_twin_is_shared_between_opens_and_a_probe_leaves_it_showing():
    first = resolve("sim://projector?name=bench").factory("sim://projector?name=bench")
    first.open()
    first.show(noise(1280, 800))
    assert probe("sim://projector?name=bench") == "open: 1280x800 (showing frame 1)"
    assert first.is_open and not first.light()["blank"]  # the probe's close left the guide's open alone
    again = sim_projector("sim://projector?name=bench")
    assert again is first and projector_named("bench") is first
    with pytest.raises(SimConfigError, match="the shared projector 'bench' is 1280x800, not 640x480"):
        sim_projector("sim://projector?name=bench&size=640x480")


@pytest.mark.parametrize(("url", "message"), [
    ("sim://projector?sise=1", "unknown sim projector option 'sise'; known: area, folder, keep, name, size"),
    ("sim://projector?size=1280", "sim projector option size: expected WxH in pixels from 1 to 16384"),
    ("sim://projector?keep=0", "sim projector option keep: expected a whole number >= 1, got '0'"),
    ("sim://projector?area=0,0,10", "sim projector option area: expected u0,v0,u1,v1 in mm"),
])
def test_a_bad_twin_option_is_one_line(url, message):
    with pytest.raises(SimConfigError, match="^" + message.replace("(", r"\(")):
        SimulatedProjector(url)
    assert probe(url) == "not available: " + str(pytest.raises(SimConfigError, SimulatedProjector, url).value)


def test_a_twin_whose_folder_cannot_be_made_is_one_line(tmp_path):
    (tmp_path / "file").write_text("x")
    url = f"sim://projector?folder={tmp_path / 'file' / 'frames'}"
    with pytest.raises(DriverError, match=r"cannot make the frame folder .*frames'"):
        SimulatedProjector(url).open()
    assert probe(url).startswith("not available: projector sim://projector?folder=")


# -- the real driver ---------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("url", ["display:", "display:x", "screen:1", "display:-1"])
def test_a_bad_display_url_is_one_line(url):
    with pytest.raises(DriverError, match=r"expected display:N \(N = SDL's display number, from 0\)$"):
        display_index(url)


def test_without_pygame_the_driver_says_how_to_install_it(monkeypatch):
    import drivers.projector.display as display

    monkeypatch.setattr(display.importlib.util, "find_spec", lambda name: None)
    with pytest.raises(DriverError) as caught:
        DisplayProjector("display:1").open()
    assert str(caught.value) == ("projector display:1: pygame-ce is not installed; install the extra: pip install "
                                 "'chaos-station[projector]' (pygame-ce)")
    assert probe("display:1").startswith("not available: pygame-ce is not installed")


@needs_pygame
def test_no_screen_is_not_a_projector(monkeypatch):
    # SDL falls back to drawing into memory when it finds no screen; the driver does not call that a projector
    monkeypatch.setenv("SDL_VIDEODRIVER", "offscreen,x11")  # what a machine without $DISPLAY ends up with
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    state = probe("display:0")
    assert state.startswith("not available: no video device"), state


@needs_pygame
def test_the_real_driver_shows_frames_on_an_offscreen_display(monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "offscreen")  # SDL's own offscreen driver: one 1024 x 768 display
    assert probe("display:0") == "open: 1024x768 (display 0 of 1, offscreen)"
    assert probe("display:3") == "not available: no display 3: SDL sees 1 display (0)"
    with pytest.raises(DriverError, match=r"^projector display:2: no display 2: SDL sees 1 display \(0\)$"):
        DisplayProjector("display:2").open()
    projector = DisplayProjector("display:0")
    assert isinstance(projector, Projector)
    with pytest.raises(DriverError, match="is not open"):
        projector.show(noise(8, 8))
    with projector:
        assert projector.size == (1024, 768) and projector.driver == "offscreen"
        frame = noise(1024, 768, seed=5)
        assert projector.show(frame) is None
        assert (projector.screen_pixels() == frame).all()  # what SDL's window surface holds
        # a grey frame of another size: scaled by 4 and letterboxed (1024 x 512 in the middle)
        small = np.full((128, 256), 180, np.uint8)
        assert projector.show(small).startswith("frame 256x128 is not the screen's 1024x768: scaled by 4")
        shown = projector.screen_pixels()
        assert shown[128:640].min() == 180 and shown[:128].max() == 0 and shown[640:].max() == 0
        projector.blank()
        assert projector.screen_pixels().max() == 0
        assert projector.state() == "open: 1024x768 (showing, offscreen)"
    projector.close()
    with pytest.raises(DriverError, match="is not open"):
        projector.blank()


@pytest.fixture
def xvfb(monkeypatch):
    """A virtual X server (Xvfb, 800 x 600) for the test, as $DISPLAY; skipped where there is none."""
    import shutil
    import subprocess

    from PIL import features

    if shutil.which("Xvfb") is None or not features.check("xcb"):
        pytest.skip("Xvfb (apt install xvfb) and Pillow with XCB are needed to look at a real X screen")
    server = subprocess.Popen(["Xvfb", "-displayfd", "1", "-screen", "0", "800x600x24", "-nolisten", "tcp"],
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    try:
        number = server.stdout.readline().decode().strip()
        if not number.isdigit():
            pytest.skip("Xvfb did not start")
        monkeypatch.setenv("DISPLAY", f":{number}")
        monkeypatch.delenv("SDL_VIDEODRIVER", raising=False)
        monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
        yield f":{number}"
    finally:
        server.terminate()
        server.wait(5)


@needs_pygame
def test_the_real_driver_covers_an_x_screen_without_a_border(xvfb):
    # read back from the X server, not from SDL: the window covers the whole screen from its corner, frame and all
    import time

    from PIL import ImageGrab

    assert probe("display:0") == "open: 800x600 (display 0 of 1, x11)"
    with DisplayProjector("display:0") as projector:
        assert (projector.size, projector.driver) == ((800, 600), "x11")
        frame = noise(800, 600, seed=9)
        projector.show(frame)
        for _ in range(20):  # the X server composes the window a moment after the flip
            screen = np.asarray(ImageGrab.grab(xdisplay=xvfb).convert("RGB"))
            if (screen == frame).all():
                break
            time.sleep(0.05)
        assert (screen == frame).all()
