"""The cameras: the simulated twin (options, shared twins, projector light, faults) and the real OpenCV driver's own
code path without a camera: a video file written here, an MJPEG stream served here on 127.0.0.1, dead URLs."""

from __future__ import annotations

import http.server
import socket
import socketserver
import threading
import time

import cv2
import numpy as np
import pytest

from drivers.camera.opencv import OpenCVCamera
from drivers.devices import Camera, probe, resolve
from drivers.errors import DriverError, SimConfigError
from drivers.sim.camera import SimulatedCamera, camera_named, sim_camera
from drivers.sim.camera_scene import PlaneScene, TagItem
from drivers.sim.projector import sim_projector
from vision.detection import detect_tags

pytestmark = pytest.mark.usefixtures("fresh_twins")


# -- the simulated camera ----------------------------------------------------------------------------------------

def test_the_twin_renders_its_scene_and_knows_the_truth():
    url = "sim://camera?size=960x540&f=700&height=800&target=20,10&blur=0.6&noise=1.5&jpeg=90&seed=4"
    camera = resolve(url).factory(url)
    assert isinstance(camera, Camera) and camera.size == (960, 540)
    assert camera.camera_model.camera_matrix[0, 0] == 700 and np.allclose(camera.camera_model.centre_mm,
                                                                         [20, 10, 800])
    with pytest.raises(DriverError, match="is not open"):
        camera.grab()
    camera.set_scene(PlaneScene(tags=(TagItem(7, (30.0, 0.0), 40.0, heading_deg=35.0, height_mm=20.0),)))
    with camera:
        first, second = camera.grab(), camera.grab()
    assert first.shape == (540, 960, 3) and first.dtype == np.uint8
    assert not np.array_equal(first, second)  # each frame has its own noise (seed + frame number)
    (truth,) = camera.truth()
    (found,) = detect_tags(cv2.cvtColor(second, cv2.COLOR_RGB2GRAY))
    assert found.tag_id == 7 and truth.visible
    assert np.abs(found.corners - 0.5 - truth.corners_px).max() < 0.5


@pytest.mark.parametrize(("query", "message"), [
    ("colour=red", "unknown sim camera option 'colour'; known: "),
    ("size=1920", "sim camera option size: expected WxH in pixels from 16 to 16384"),
    ("f=-3", "sim camera option f: expected a focal length in pixels > 0, got '-3'"),
    ("target=1", "sim camera option target: expected u,v in mm"),
    ("tilt=95", "sim camera option tilt: expected an angle in degrees from -80 to 80, got '95'"),
    ("jpeg=0", "sim camera option jpeg: expected a whole number from 1 to 100, got '0'"),
    ("vignetting=2", "sim camera option vignetting: expected a number from 0 to 1, got '2'"),
    ("k1=x", "sim camera option k1: expected a distortion coefficient from -10 to 10, got 'x'"),
    ("name=", "sim camera option name: expected a name, got ''"),
])
def test_a_bad_option_is_one_line_naming_it(query, message):
    with pytest.raises(SimConfigError) as caught:
        SimulatedCamera(f"sim://camera?{query}")
    assert str(caught.value).startswith(message) and "\n" not in str(caught.value)
    assert probe(f"sim://camera?{query}").startswith("not available: " + message)


def test_a_named_twin_is_shared_between_opens():
    one = sim_camera("sim://camera?size=320x240&name=bench")
    two = sim_camera("sim://camera?size=320x240&name=bench&noise=3")
    assert one is two is camera_named("bench")
    with pytest.raises(SimConfigError, match="the shared camera 'bench' is 320x240, not 640x480"):
        sim_camera("sim://camera?size=640x480&name=bench")


def test_the_twin_sees_the_named_projectors_light():
    projector = sim_projector("sim://projector?size=320x200&name=wall&area=-160,-100,160,100")
    camera = sim_camera("sim://camera?size=640x360&f=500&height=600&projector=wall")
    camera.open()
    projector.open()
    dark = camera.grab()
    frame = np.zeros((200, 320, 3), np.uint8)
    frame[:, 160:] = 255  # the right half lit: u > 0
    projector.show(frame)
    lit = camera.grab()
    assert np.array_equal(dark[:, 330:], dark[:, 330:]) and lit[180, 400].min() == 255 and lit[180, 240, 0] == 200
    assert dark[180, 400, 0] == 200
    lonely = sim_camera("sim://camera?size=64x64&projector=nobody")  # no such projector open: it is off, no light
    lonely.open()
    unlinked = sim_camera("sim://camera?size=64x64")
    unlinked.open()
    assert np.array_equal(lonely.grab(), unlinked.grab())


def test_faults_are_injected_at_run_time():
    camera = SimulatedCamera("sim://camera?size=160x120&f=100")
    camera.set_scene(PlaneScene(background=(100, 100, 100)))
    camera.open()
    normal = camera.grab()
    camera.inject("black")
    assert not camera.grab().any()
    camera.inject(None)
    assert np.array_equal(camera.grab(), normal)
    camera.inject("frozen")
    camera.set_scene(PlaneScene(background=(50, 50, 50)))
    assert np.array_equal(camera.grab(), normal)  # the stalled stream repeats its last frame
    camera.inject("no-frame")
    with pytest.raises(DriverError, match=r"^camera sim://camera\?size=160x120&f=100: no frame within 2 s$"):
        camera.grab()
    camera.inject(None)
    assert camera.grab()[0, 0, 0] == 50
    camera.inject("unplugged")
    with pytest.raises(DriverError, match="unplugged"):
        camera.grab()
    camera.close()
    assert camera.state() == "not available: unplugged (injected fault)"
    with pytest.raises(SimConfigError, match="inject: expected one of no-frame, black, frozen, unplugged"):
        camera.inject("smoke")


# -- the real driver, without a camera ---------------------------------------------------------------------------

def numbered_frames(count=6, size=(160, 120)):
    """Frames whose grey level says their number (survives MJPEG)."""
    return [np.full((size[1], size[0], 3), 30 + 35 * n, np.uint8) for n in range(count)]


def test_a_video_file_is_read_frame_by_frame_as_rgb_and_starts_again(tmp_path):
    path = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10, (160, 120))
    frames = numbered_frames()
    frames[0][:, :, 2] = 250  # OpenCV writes BGR: the first frame is red, channel 0 once grabbed as RGB
    for frame in frames:
        writer.write(frame)
    writer.release()
    camera = resolve(str(path)).factory(str(path))
    assert isinstance(camera, OpenCVCamera) and isinstance(camera, Camera)
    assert camera.state() == "open: 160x120"
    grabbed = [camera.grab() for _ in range(len(frames) + 1)]
    camera.close()
    levels = [int(np.median(g[:, :, 1])) for g in grabbed]
    assert all(abs(level - (30 + 35 * (n % len(frames)))) <= 3 for n, level in enumerate(levels))
    assert grabbed[0][:, :, 0].mean() > 240 and grabbed[0][:, :, 2].mean() < 40  # BGR came back as RGB


def test_a_file_that_is_no_video_or_missing_is_one_line(tmp_path):
    bad = tmp_path / "notes.mp4"
    bad.write_text("not a video")
    for url, message in ((str(bad), "cannot read the video file"), (str(tmp_path / "gone.mkv"), "no such video file")):
        with pytest.raises(DriverError) as caught:
            OpenCVCamera(url).open()
        assert str(caught.value).startswith(f"camera {url}: {message}") and "\n" not in str(caught.value)


class _MJPEGServer:
    """An MJPEG stream (multipart/x-mixed-replace) on 127.0.0.1, as IP cameras and ESP32-CAMs serve it; ``stall``
    stops sending frames."""

    def __init__(self, frames):
        self.jpegs = [cv2.imencode(".jpg", frame)[1].tobytes() for frame in frames]
        self.stall = threading.Event()
        self.stalled = threading.Event()  # the stream has seen the stall: no frame is sent after this
        server = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self):
                self.send_response(200)
                self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=frame")
                self.end_headers()
                n = 0
                try:
                    while True:
                        if server.stall.is_set():
                            server.stalled.set()
                            time.sleep(0.05)
                            continue
                        jpeg = server.jpegs[n % len(server.jpegs)]
                        n += 1
                        self.wfile.write(b"--frame\r\nContent-Type: image/jpeg\r\nContent-Length: %d\r\n\r\n"
                                         % len(jpeg) + jpeg + b"\r\n")
                        time.sleep(0.02)
                except OSError:
                    pass

            def log_message(self, *args):
                pass

        self.httpd = socketserver.ThreadingTCPServer(("127.0.0.1", 0), Handler)
        self.httpd.daemon_threads = True
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/stream.mjpg"
        threading.Thread(target=self.httpd.serve_forever, daemon=True).start()

    def close(self):
        self.httpd.shutdown()
        self.httpd.server_close()


def test_an_mjpeg_stream_gives_the_newest_frames_and_a_stall_is_one_line():
    server = _MJPEGServer(numbered_frames())
    try:
        camera = OpenCVCamera(server.url, timeout=1.0, size=(640, 480), exposure=-5)
        camera.open()
        assert camera.size == (160, 120)
        assert camera.refused == ("size (gives 160x120)", "exposure")  # a stream takes no settings
        levels = {int(np.median(camera.grab())) for _ in range(8)}
        assert len(levels) >= 3 and levels <= {30 + 35 * n for n in range(6)} | {29, 31, 64, 66}
        assert camera.state().startswith("open: 160x120 (refused: size (gives 160x120), exposure)")
        server.stall.set()
        assert server.stalled.wait(5.0)
        started = time.monotonic()
        with pytest.raises(DriverError, match=r"^camera http://127\.0\.0\.1:\d+/stream\.mjpg: no frame within 1 s"):
            for _ in range(20):  # frames already in the socket's buffer may still come first
                camera.grab()
        assert time.monotonic() - started < 4.0
        camera.close()
    finally:
        server.close()


def test_dead_urls_are_one_line_within_the_timeout():
    with socket.socket() as sock:  # a port nobody listens on
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    started = time.monotonic()
    state = probe(f"http://127.0.0.1:{port}/stream.mjpg")
    assert state == "not available: cannot open the stream (unreachable, refused, or not a video stream)"
    assert probe("/dev/video99") == "not available: no such device (is the camera plugged in? `ls /dev/video*`)"
    # a server that accepts and never answers: the first frame's deadline
    silent = socket.socket()
    silent.bind(("127.0.0.1", 0))
    silent.listen()
    try:
        with pytest.raises(DriverError) as caught:
            OpenCVCamera(f"http://127.0.0.1:{silent.getsockname()[1]}/x", timeout=0.8).open()
    finally:
        silent.close()
    assert "\n" not in str(caught.value) and ("no frame within 0.8 s" in str(caught.value)
                                              or "cannot open the stream" in str(caught.value))
    assert time.monotonic() - started < 5.0
