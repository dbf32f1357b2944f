"""Every example of every ``station ... --help``, run as written (tests/station/test_cli_help.py only parses them).

Each example runs in a shell (its quotes, pipes and redirections as a reader types them) with this checkout's
``station`` on the PATH, in its own copy of a prepared workshop: a working folder and a station home
(``CHAOS_STATION_HOME``) holding what the examples name and what the station's earlier commands leave behind.
The workshop (``workshop`` in tests/conftest.py, shared with the formats' tests) is made once per test run by
those commands (``station optimize`` writes layout.json, ``station calibrate sim`` the physics profile, ``station
trial log`` the trials, ...), on the station's simulated devices; only what a maker brings from outside the station
is made there by the tests: the camera's images (rendered by the camera twin), a photo, the TLS certificate, and
BALLRUN's layout file from the layout its scenario names (an optimization that finds one takes minutes; ``station
optimize ballrun`` is itself an example, marked slow).

An example that is one of the workshop's own commands (``station optimize ... --out layout.json``, ``station
lasertest render ...``) is judged on the run that prepared the workshop, not run a second time. An example runs
when it exits 0, prints no traceback and writes the files it names (``--out``, ``--pdf``, ``> FILE``...);
``station assemble`` logs its trial. Interactive ones get the answers a maker types (:data:`ANSWERS`); ``station
serve`` runs until it says where to open it, then is stopped as Ctrl+C stops it. An example that needs hardware a
fresh machine lacks is skipped with its reason (:data:`HARDWARE`); the long ones are marked slow (:data:`SLOW`,
``pytest -m slow``).
"""

from __future__ import annotations

import shlex
import shutil
import signal
import socket
import subprocess
import threading
import time

import pytest

from station.cli import build_parser

from ..conftest import environment, locked, prepared, run, run_folder
from .test_cli_help import examples_of

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
    # builds every machine's candidate database first; tests/station/commands/test_sketch.py runs the same command
    # on one machine
    "station retrieve examples/sketches/trefoil-sector.json --top 5 --out retrieval",
    # the full-size projector's Gray-code patterns; tests/calibration/test_projector_map.py maps a small linked pair
    # through the same command
    "station calibrate projector --camera 'sim://camera?projector=wall' "
    "--projector 'sim://projector?name=wall&area=-300,-190,300,190'",
}

#: What a maker types into an interactive example: skip the guide's steps, Enter once placed, run as placed (a:
#: whatever the check says), then (a real table) say that each event happened, or (a simulated world) Enter to run
#: it; and log the trial.
ANSWERS = {
    "station assemble ballrun ballrun-layout.json --project": "s\n\na\n" + "y\n" * 8 + "y\n",
    "station assemble simple success --world 'sim://world?seed=3' --physics simple-physics.toml --sheet guide.pdf":
        "s\n\na\n\ny\n",
    "station assemble causalityswitch_ball success --world 'sim://world?seed=2' --jigs": "s\n\na\n\ny\n",
    "station assemble simple success --world 'sim://world?seed=3' --jigs --camera sim://camera "
    "--camera 'sim://camera?view=side&height=700&tilt=-20'": "s\n\na\n\ny\n",
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
    done = prepared(workshop).get(example)
    if done is not None:  # the workshop ran this very command to prepare itself: that run is the example's
        folder = workshop
    else:
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
