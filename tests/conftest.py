"""Suite-wide fixtures: the station never writes into the real user's folders during tests.

Also helpers shared by test files in different folders (imported as ``from .conftest import ...`` or
``from ..conftest import ...``, as tests/drivers imports its own conftest), and the prepared workshop (``workshop``): a
maker's folder and station home made once per test run by the station's own commands, which the CLI examples and
the public formats' tests start from."""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import signal
import subprocess
import sys
from contextlib import asynccontextmanager, contextmanager
from pathlib import Path

import pytest

from drivers.grbl import GrblConnection

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def station_home(tmp_path_factory, monkeypatch):
    home = tmp_path_factory.mktemp("station-home")
    monkeypatch.setenv("CHAOS_STATION_HOME", str(home))
    return home


@pytest.fixture
def fresh_twins():
    """No simulated camera or projector shared by name (``sim://...?name=``) before the test, nor left after it."""
    from drivers.sim.camera import forget_cameras
    from drivers.sim.projector import forget_projectors

    forget_cameras()
    forget_projectors()
    yield
    forget_cameras()
    forget_projectors()


async def settle(app, pilot):
    """Let a Textual app under test settle: three rounds of a pause and a wait for all its workers, then a pause."""
    for _ in range(3):
        await pilot.pause()
        await app.workers.wait_for_complete()
    await pilot.pause()


def station_app(tmp_path, *, without: tuple[str, ...] = (), **options):
    """A :class:`station.tui.app.StationApp` with its database in ``tmp_path``; ``without`` leaves those areas out
    (e.g. ``("drawing",)``: an app without the Drawing screen)."""
    from station.tui.app import StationApp
    from station.tui.registry import discover_screens

    if without:
        options["areas"] = [entry for entry in discover_screens() if entry.name not in without]
    return StationApp(database=tmp_path / "t.sqlite3", **options)


@asynccontextmanager
async def opened(tmp_path, key: str | None = None, size: tuple[int, int] = (160, 50), *, wait: bool = True,
                 **options):
    """Run a station app under test (see :func:`station_app`) and press ``key`` on its home screen; yields
    ``(app, pilot)``. ``wait``: :func:`settle` after the key (all workers done), else one pause."""
    app = station_app(tmp_path, **options)
    async with app.run_test(size=size) as pilot:
        if key is not None:
            await pilot.press(key)
            if wait:
                await settle(app, pilot)
            else:
                await pilot.pause()
        yield app, pilot


#: Fast settings for the simulator: motion 50x faster than real time, status at 20 Hz, short watchdogs.
FAST = {"poll_interval": 0.05, "lost_ok_timeout": 0.3, "silence_timeout": 0.6}


@pytest.fixture
def make_connection():
    """Open connections and close them at the end of the test."""
    opened: list[GrblConnection] = []

    def make(url: str, **kwargs) -> GrblConnection:
        options = dict(FAST) if url.startswith("sim://") else {}
        options.update(kwargs)
        conn = GrblConnection(url, **options).open()
        opened.append(conn)
        return conn

    yield make
    for conn in opened:
        conn.close()


# -- the workshop ---------------------------------------------------------------------------------------------------

def environment(home: Path) -> dict[str, str]:
    env = dict(os.environ, CHAOS_STATION_HOME=str(home), TERM="dumb")
    env.pop("CHAOS_STATION_CONFIG", None)
    env.pop("CHAOS_STATION_DATABASE", None)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    return env


def run(command: str, folder: Path, *, answers: str | None = None, timeout: float = 600):
    """``command`` in a shell in ``folder`` with the station home ``folder/home``; one that outlives ``timeout``
    seconds is stopped as ``kill`` stops it (SIGTERM: the station shuts its simulation pools down) and fails."""
    process = subprocess.Popen(["bash", "-c", command], cwd=folder, env=environment(folder / "home"),
                               stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               start_new_session=True)
    try:
        out, err = process.communicate(answers or "", timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGTERM)
        try:
            out, err = process.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            out, err = process.communicate()
        pytest.fail(f"`{command}` did not finish within {timeout:g} s; it said:\n{err[-2000:]}")
    return subprocess.CompletedProcess(process.args, process.returncode, out, err)


#: The workshop's record of its own commands (:func:`prepare`), in the workshop folder.
PREPARED = "prepared.json"


def prepare(folder: Path, command: str) -> None:
    """Run ``command`` in the workshop ``folder``; it must succeed. How it ran is kept in the folder (:data:`PREPARED`):
    an example of a ``--help`` that is one of these commands is judged on this run (:func:`prepared`)."""
    done = run(command, folder)
    tail = "\n".join(done.stderr.strip().splitlines()[-5:])
    assert done.returncode == 0, f"preparing the workshop: `{command}` exited {done.returncode}:\n{tail}"
    record = folder / PREPARED
    ran = json.loads(record.read_text()) if record.exists() else {}
    ran[command] = {"returncode": done.returncode, "stdout": done.stdout, "stderr": done.stderr}
    record.write_text(json.dumps(ran))


def prepared(workshop: Path) -> dict[str, subprocess.CompletedProcess]:
    """The commands the workshop ran to prepare itself, and how each ran (see :func:`prepare`)."""
    ran = json.loads((workshop / PREPARED).read_text())
    return {command: subprocess.CompletedProcess(command, r["returncode"], r["stdout"], r["stderr"])
            for command, r in ran.items()}


def write_camera_images(folder: Path) -> None:
    """What a maker's camera gives: views of the printed ChArUco board (shots/), a frame of SIMPLE's layout.json
    placed as its guide draws it (frame.png) and a photo of the run (run3.jpg); rendered by the camera twin for a
    camera 1 m above the table."""
    # deferred: the camera renderer and the guide builder load only where a workshop is made (once per run), not
    # for every test file that takes a fixture from this module
    from PIL import Image

    from calibration.evaluate import board_views
    from design.contraption import load_scenario
    from design.contraption.layout_io import read_layout
    from drivers.sim.camera_render import render
    from drivers.sim.camera_scene import CameraModel, PlaneScene, RenderOptions, TagItem
    from projector.build import build_guide

    scenario = load_scenario(folder / "examples" / "scenarios" / "simple.toml")
    guide = build_guide(scenario, read_layout(folder / "layout.json", scenario).x)
    u0, v0, u1, v1 = guide.extent_mm
    camera = CameraModel.looking_down(target_mm=((u0 + u1) / 2, (v0 + v1) / 2), height_mm=1000.0)
    tags = [TagItem(t.id, t.center_mm, t.size_mm) for t in guide.reference_tags]
    tags += [TagItem(view.tag_id, view.tag_center_mm, view.tag_size_mm, view.tag_heading_deg, view.tag_height_mm)
             for part in guide.parts for view in part.tag_views()]
    frame, _ = render(PlaneScene(tags=tuple(tags)), camera,
                      RenderOptions(blur_px=0.8, noise=2.0, jpeg_quality=90, supersample=2, seed=3))
    Image.fromarray(frame).save(folder / "frame.png")
    Image.fromarray(frame).save(folder / "run3.jpg", quality=85)
    (folder / "shots").mkdir()
    views = board_views(8, camera.camera_matrix, camera.dist_coeffs, camera.image_size, seed=21,
                        options=RenderOptions(blur_px=0.7, noise=2.0, supersample=1, seed=21))
    for name, image in views:
        Image.fromarray(image).save(folder / "shots" / f"{name}.jpg", quality=92)


def write_ballrun_layout(folder: Path) -> None:
    """ballrun-layout.json: the layout BALLRUN's scenario names ``success``, as a layout file."""
    from design.contraption import load_scenario  # deferred, as in write_camera_images

    scenario = load_scenario(folder / "examples" / "scenarios" / "ballrun.toml")
    values = dict(zip(scenario.design_space.names, map(float, scenario.layout("success"))))
    (folder / "ballrun-layout.json").write_text(json.dumps({"parameters": values}, indent=2) + "\n")


def make_workshop(folder: Path) -> None:
    shutil.copytree(REPO / "examples", folder / "examples")
    prepare(folder, "station optimize examples/scenarios/simple.toml --budget 40 --seed 1 --out layout.json")
    write_ballrun_layout(folder)
    prepare(folder, "station guide simple layout.json --json > guide.json")
    write_camera_images(folder)
    prepare(folder, "station calibrate camera --images shots/ --out desk.json")
    prepare(folder, "station calibrate camera --images shots/ --name desk")
    for trial in ("simple success --outcome last_stops=yes --time last_topples=1.4",
                  "simple success --outcome first_topples=no",
                  "simple failure --outcome ball_hits_domino=no",
                  "ballrun success --outcome ball_stops=yes",
                  "ballrun failure --outcome ball_in_goblet=no"):
        prepare(folder, f"station trial log {trial} --predict 0")
    prepare(folder, "station calibrate sim simple --out simple-physics.toml")
    prepare(folder, "station check simple layout.json --guide guide.json --out check.json --predict 0")
    prepare(folder, "station trial export --out trials.json")
    prepare(folder, "station plot spirograph --set d=2.5 --size 150 --out spiro.gcode")
    prepare(folder, "station jigs causalityswitch_ball success --out switch-jigs --material mdf_3mm --sheet 300x200")
    # a laser test card, burned and photographed on the twins (what a maker's laser and phone give)
    prepare(folder, "station lasertest card --profile laser --material plywood_3mm --out card")
    prepare(folder, "station lasertest render --card card/card.json --out card/frame.png")
    if shutil.which("openssl"):
        subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", "station.key", "-out",
                        "station.pem", "-days", "2", "-subj", "/CN=localhost"], cwd=folder, check=True,
                       capture_output=True)


@contextmanager
def locked(path: Path):
    """An exclusive lock on ``path`` across processes (pytest-xdist's workers share the base temporary folder)."""
    with open(path, "w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def run_folder(tmp_path_factory) -> Path:
    """This test run's base temporary folder, shared by its pytest-xdist workers (each has a folder in it)."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


def made_once(tmp_path_factory, name: str, make) -> Path:
    """The folder ``name`` of this test run, made by ``make(folder)`` for every pytest-xdist worker at once: the
    first worker that asks makes it, the others wait for it under a lock (a module- or session-scoped fixture alone
    is made once per worker, so twice on two cores). Read-only to its users: a test that writes copies it first."""
    shared = run_folder(tmp_path_factory)
    folder = shared / name
    with locked(shared / f"{name}.lock"):
        if not (folder / "ready").exists():
            shutil.rmtree(folder, ignore_errors=True)
            folder.mkdir(parents=True)
            make(folder)
            (folder / "ready").write_text("")
    return folder


@pytest.fixture(scope="session")
def workshop(tmp_path_factory) -> Path:
    """The prepared workshop, made once for every worker of the run (tests/station/test_cli_examples.py's examples and
    tests/station/test_schemas.py's outputs start from it). Read-only: a test that writes copies it first."""
    return made_once(tmp_path_factory, "cli-examples-workshop", make_workshop)
