"""Every example of every ``station ... --help``, run as written (tests/station/test_cli_help.py only parses them).

Each example runs in a shell (its quotes, pipes and redirections as a reader types them) with this checkout's
``station`` on the PATH, in its own copy of a prepared workshop: a working folder and a station home
(``CHAOS_STATION_HOME``) holding what the examples name and what the station's earlier commands leave behind.
The workshop is made once by those commands (``station optimize`` writes layout.json, ``station calibrate sim``
the physics profile, ``station trial log`` the trials, ...), on the station's simulated devices; only what a maker
brings from outside the station is made here: the camera's images (rendered by the camera twin), a photo, the
TLS certificate, and BALLRUN's layout file from the layout its scenario names (an optimization that finds one
takes minutes; ``station optimize ballrun`` is itself an example, marked slow).

An example runs when it exits 0, prints no traceback and writes the files it names (``--out``, ``--pdf``,
``> FILE``...); ``station assemble`` logs its trial. Interactive ones get the answers a maker types (:data:`ANSWERS`);
``station serve`` runs until it says where to open it, then is stopped as Ctrl+C stops it. An example that needs
hardware a fresh machine lacks is skipped with its reason (:data:`HARDWARE`); the long ones are marked slow
(:data:`SLOW`, ``pytest -m slow``).
"""

from __future__ import annotations

import fcntl
import json
import os
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path

import pytest
from PIL import Image

from station.cli import build_parser

from .test_cli_help import examples_of

REPO = Path(__file__).resolve().parents[2]

#: Examples that cannot run on a fresh machine, and why.
HARDWARE = {
    "station calibrate camera --capture 15 --camera 0 --out desk.json --json":
        "grabs 15 frames of the printed board from camera 0, a real camera moved around by hand",
    "station calibrate projector":
        "the station's own camera and projector: a fresh machine's are simulated twins that do not see each other "
        "(the example with sim://camera?projector=wall links a simulated pair)",
    "station calibrate projector --camera 0 --projector display:1 --plane plane.json":
        "a real camera (0) and a second screen (display:1)",
}

#: Examples that run longer than the default suite allows (run with ``pytest -m slow``).
SLOW = {
    "station optimize ballrun --settings thesis --workers 2 --out ballrun-layout.json",  # minutes: BALLRUN's budget
    "station robustness ballrun ballrun-layout.json --plot rho.png --json",  # 2048 + 100 BALLRUN simulations
    "station compare simple --runs 3 --budget 60 --eval 128 --local 10",
    "station compare causalityswitch_ball --seed 10 --runs 5 --plot curves.png --json",
    "station loop simple --world 'sim://world?seed=1'",  # optimizations and calibrations: minutes
    "station loop ballrun --world 'sim://world?seed=3&place_mm=3' --attempts 8 --loops 3 --json",
    "station loop causalityswitch_ball --world 'sim://world?seed=2&ruler_mm=1' --jigs",  # CAUSALITYSWITCH's budgets
    "station assemble causalityswitch_ball success --world 'sim://world?seed=2' --jigs",  # its tolerance map: ~40 s
}

#: What a maker types into an interactive example: skip the guide's steps, Enter once placed, run as placed (a:
#: whatever the check says), then (a real table) say that each event happened, or (a simulated world) Enter to run
#: it; and log the trial.
ANSWERS = {
    "station assemble ballrun ballrun-layout.json --project": "s\n\na\n" + "y\n" * 8 + "y\n",
    "station assemble simple success --world 'sim://world?seed=3' --physics simple-physics.toml --sheet guide.pdf":
        "s\n\na\n\ny\n",
    "station assemble causalityswitch_ball success --world 'sim://world?seed=2' --jigs": "s\n\na\n\ny\n",
}

#: Options whose value is a file (or folder) the example writes (``--sheet`` too, when it names a PDF).
OUTPUTS = ("--out", "--pdf", "--svg", "--render", "--plot", "--overlay")

SERVE = "station serve"
SERVE_PORT = 8000  # the port of every serve example (written, or station serve's default)


def every_parser(parser):
    """The parser and every (sub)command parser below it, groups too (``station calibrate``, ``station``)."""
    yield parser
    for action in parser._actions:
        if hasattr(action, "choices") and isinstance(action.choices, dict):
            for sub in action.choices.values():
                yield from every_parser(sub)


def all_examples() -> list[str]:
    """Every distinct example line of every ``--help``, in the order the help texts give them."""
    seen: dict[str, None] = {}
    for parser in every_parser(build_parser()):
        for example in examples_of(parser):
            seen.setdefault(example, None)
    return list(seen)


EXAMPLES = all_examples()


def outputs_of(example: str) -> list[str]:
    """The files an example says it writes: the values of :data:`OUTPUTS` and the targets of ``>``."""
    words = shlex.split(example)
    return [value for word, value in zip(words, words[1:])
            if word in (*OUTPUTS, ">") or (word == "--sheet" and value.endswith(".pdf"))]


def marks(example: str):
    if example in HARDWARE:
        return pytest.mark.skip(reason=f"needs hardware: {HARDWARE[example]}")
    return [pytest.mark.slow] if example in SLOW else []


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


def prepare(folder: Path, command: str) -> None:
    done = run(command, folder)
    tail = "\n".join(done.stderr.strip().splitlines()[-5:])
    assert done.returncode == 0, f"preparing the workshop: `{command}` exited {done.returncode}:\n{tail}"


def write_camera_images(folder: Path) -> None:
    """What a maker's camera gives: views of the printed ChArUco board (shots/), a frame of SIMPLE's layout.json
    placed as its guide draws it (frame.png) and a photo of the run (run3.jpg); rendered by the camera twin for a
    camera 1 m above the table."""
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
    from design.contraption import load_scenario

    scenario = load_scenario(folder / "examples" / "scenarios" / "ballrun.toml")
    values = dict(zip(scenario.design_space.names, map(float, scenario.layout("success"))))
    (folder / "ballrun-layout.json").write_text(json.dumps({"parameters": values}, indent=2) + "\n")


def make_workshop(folder: Path) -> None:
    folder.mkdir(parents=True)
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
    (folder / "ready").write_text("")


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


@pytest.fixture(scope="session")
def workshop(tmp_path_factory) -> Path:
    """The prepared workshop, made once for every worker of the run."""
    shared = run_folder(tmp_path_factory)
    folder = shared / "cli-examples-workshop"
    with locked(shared / "cli-examples-workshop.lock"):
        if not (folder / "ready").exists():
            shutil.rmtree(folder, ignore_errors=True)
            make_workshop(folder)
    return folder


# -- the examples ---------------------------------------------------------------------------------------------------

def test_the_examples_are_found():
    assert len(EXAMPLES) >= 50
    assert any(e.startswith("printf ") and "| station assemble" in e for e in EXAMPLES)  # a piped one
    assert "station calibrate sim simple --out simple-physics.toml" in EXAMPLES  # a group's (calibrate) too


def test_every_table_names_an_example():
    # a renamed example leaves no stale entry behind (it would be run, or skipped, under its old name)
    stale = [e for e in (*HARDWARE, *SLOW, *ANSWERS) if e not in EXAMPLES]
    assert not stale, f"not an example of any --help: {stale}"


@pytest.mark.parametrize("example", [pytest.param(e, marks=marks(e), id=e) for e in EXAMPLES
                                     if not e.startswith(SERVE)])
def test_the_example_runs_as_written(example, workshop, tmp_path):
    folder = tmp_path / "workshop"
    shutil.copytree(workshop, folder, symlinks=True)
    done = run(example, folder, answers=ANSWERS.get(example), timeout=4 * 3600 if example in SLOW else 900)
    tail = "\n".join((done.stderr.strip() or done.stdout.strip()).splitlines()[-8:])
    assert done.returncode == 0, f"`{example}` exited {done.returncode}:\n{tail}"
    assert "Traceback" not in done.stderr + done.stdout, f"`{example}` printed a traceback:\n{done.stderr}"
    missing = [name for name in outputs_of(example) if not (folder / name).exists()]
    assert not missing, f"`{example}` did not write {missing}"
    if "station assemble" in example:  # the walk ends by logging the attempt; "nothing logged" is not a run
        assert "logged trial #" in done.stdout, f"`{example}` logged no trial:\n{done.stdout[-2000:]}"


@pytest.mark.parametrize("command", ["station optimize ballrun --physics simple-physics.toml --budget 10 --out x.json",
                                     "station predict ballrun ballrun-layout.json --physics simple-physics.toml"])
def test_a_profile_for_another_contraption_is_refused_as_such(command, workshop, tmp_path):
    # The examples' SIMPLE profile shares BALLRUN's material names (wood, steel) but not its parts: it is refused
    # for being SIMPLE's, not for a value outside one of BALLRUN's ranges.
    folder = tmp_path / "workshop"
    shutil.copytree(workshop, folder, symlinks=True)
    done = run(command, folder)
    assert done.returncode == 2
    assert done.stderr.strip() == (
        "station: error: simple-physics.toml: profile.scenarios: a profile for another contraption (SIMPLE); "
        "expected one fitted on BALLRUN's trials (`station calibrate sim --out`)")


def port_in_use(port: int) -> bool:
    with socket.socket() as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind(("0.0.0.0", port))
        except OSError:
            return True
    return False


@pytest.mark.parametrize("example", [pytest.param(e, id=e) for e in EXAMPLES if e.startswith(SERVE)])
def test_the_serve_example_serves(example, workshop, tmp_path, tmp_path_factory):
    # The server runs until stopped: it runs as written until it says where to open it, then gets Ctrl+C's SIGTERM.
    # Every serve example listens on one port: one at a time, across workers.
    if "--cert" in example and not (workshop / "station.pem").exists():
        pytest.skip("no openssl on this machine to make the example's certificate")
    folder = tmp_path / "workshop"
    shutil.copytree(workshop, folder, symlinks=True)
    with locked(run_folder(tmp_path_factory) / "cli-examples-serve.lock"):
        if port_in_use(SERVE_PORT):
            pytest.skip(f"port {SERVE_PORT}, the example's, is in use by another program on this machine")
        server = subprocess.Popen(["bash", "-c", f"exec {example}"], cwd=folder, env=environment(folder / "home"),
                                  stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                  text=True)
        lines: list[str] = []

        def read() -> None:
            for line in server.stdout:
                lines.append(line)

        reader = threading.Thread(target=read, daemon=True)
        reader.start()
        try:
            deadline = time.monotonic() + 60
            while time.monotonic() < deadline and reader.is_alive():
                if any(line.startswith("station serve: open ") for line in list(lines)):
                    break
                time.sleep(0.05)
            assert any(line.startswith("station serve: open ") for line in list(lines)), \
                f"`{example}` never said where to open it:\n{''.join(lines)}"
        finally:
            server.send_signal(signal.SIGTERM)
            try:
                server.wait(timeout=60)
            except subprocess.TimeoutExpired:
                server.kill()
                server.wait()
            reader.join(timeout=5)
    said = "".join(lines)
    assert server.returncode == 0, f"`{example}` stopped with {server.returncode}:\n{said}"
    assert "Traceback" not in said, f"`{example}` printed a traceback:\n{said}"


def test_examples_of_takes_a_piped_example():
    class Parser:
        epilog = "examples:\n  printf 'y\\n' | station assemble simple success\n  station trial list"

    assert examples_of(Parser()) == ["printf 'y\\n' | station assemble simple success", "station trial list"]
