"""The station's GRBL driver against the real firmware: gnea/grbl 1.1h built for this computer with grbl-sim, behind a
pty from socat. It needs a C compiler, make, socat and stdbuf, and the sources of both projects (nothing is
downloaded):

    python -m bench.grbl_firmware --grbl PATH/TO/grbl --grbl-sim PATH/TO/grbl-sim [--cache DIR]

Each PATH is a checkout or a bare git repository (its HEAD is used). The build goes to a cache folder
(``$XDG_CACHE_HOME/chaos-station/grbl-sim/<hash of the sources>``, or ``--cache``) and is reused while the sources
stay the same; each scenario runs a fresh firmware with an EEPROM of its own in a temporary folder. It prints what
the firmware and the driver did: connecting with several status report masks (``$10``) and checking that the mask is
unchanged after a job, a small job, a soft-limit alarm in a job and outside one (GRBL answers nothing until a reset)
and how the driver recovers, and a machine with homing locked at power-up. Without the tools or sources it says what
is missing and exits with 2.

grbl-sim reads its serial input through stdio (``getchar``), which keeps the rest of a line in its buffer until
another byte arrives: ``stdbuf -i0`` makes it read byte by byte. It runs the firmware's main loop and its simulated
timers in two threads: on a loaded computer the stepper interrupt drains the segment buffer the main loop fills,
GRBL ends the cycle with blocks left in its planner, and a ``G4`` waits for them for ever (a stall no AVR shows);
``--time-factor`` below 1 (``-t``, default 0.25) runs the simulated hardware slower than the wall clock so that
the main loop keeps up more often, and a guard sends a cycle start (``~``) when GRBL stands Idle with lines still
unanswered (on an AVR that never happens; each such restart is counted and printed). grbl-sim's pins all read as
set (``Pn:PXYZRHS``), so ``$H`` fails there (ALARM:8) and a probe always touches: the scenarios unlock with ``$X``
instead of homing.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import io
import os
import shutil
import signal
import subprocess
import sys
import tarfile
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import serial

from drivers.errors import DeviceStateError
from drivers.grbl import GrblConnection, Job, JobRunner

BUILD_FLAGS = "-g -O3 -fcommon"  # -fcommon: grbl-sim's headers define globals that newer compilers reject twice
TOOLS = ("make", "socat", "stdbuf")

#: A fast machine for the scenarios (grbl-sim runs motion in real time): 200 x 200 mm, soft limits on, homing on.
SETTINGS = {110: 1000.0, 111: 1000.0, 112: 500.0, 120: 50.0, 121: 50.0, 122: 50.0, 130: 200.0, 131: 200.0,
            132: 50.0, 22: 1, 20: 1, 32: 0}
SQUARE = ["G21", "G90", "G0 X5 Y5", "G1 X15 Y5 F800", "G1 X15 Y15", "G1 X5 Y15", "G1 X5 Y5", "G0 X0 Y0"]


def compiler() -> str | None:
    return os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")


def missing_tools() -> list[str]:
    missing = [tool for tool in TOOLS if shutil.which(tool) is None]
    return (["a C compiler (cc)"] if compiler() is None else []) + missing


def _tree(source: Path) -> bytes:
    """The files of ``source`` (a checkout or a bare git repository) as a tar archive."""
    if (source / "HEAD").is_file() and (source / "objects").is_dir():  # a bare repository
        return subprocess.run(["git", f"--git-dir={source}", "archive", "HEAD"], check=True,
                              capture_output=True).stdout
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w") as archive:
        archive.add(source, arcname=".", filter=lambda info: None if "/.git" in info.name else info)
    return buffer.getvalue()


def build(grbl: Path, grbl_sim: Path, cache: Path | None = None, log=print) -> Path:
    """grbl-sim's executable built from ``grbl`` (gnea/grbl: its ``grbl/`` folder) and ``grbl_sim`` (grbl/grbl-sim,
    which builds inside the firmware's folder), in the cache; built only when the sources changed."""
    trees = (_tree(grbl), _tree(grbl_sim))
    digest = hashlib.sha256(b"".join(trees) + BUILD_FLAGS.encode()).hexdigest()[:16]
    base = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "chaos-station" / "grbl-sim"
    folder = (cache or base) / digest
    exe = folder / "grbl" / "grbl-sim" / "grbl_sim.exe"
    if exe.is_file():
        log(f"grbl-sim: cached build {exe}")
        return exe
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    with tarfile.open(fileobj=io.BytesIO(trees[0])) as archive:
        archive.extractall(folder / "firmware", filter="data")
    if not (folder / "firmware" / "grbl" / "protocol.c").is_file():
        raise SystemExit(f"{grbl}: not a gnea/grbl checkout (no grbl/protocol.c)")
    shutil.move(folder / "firmware" / "grbl", folder / "grbl")
    with tarfile.open(fileobj=io.BytesIO(trees[1])) as archive:
        archive.extractall(folder / "grbl" / "grbl-sim", filter="data")
    if not (folder / "grbl" / "grbl-sim" / "simulator.c").is_file():
        raise SystemExit(f"{grbl_sim}: not a grbl-sim checkout (no simulator.c)")
    log(f"grbl-sim: building in {folder} (make FLAGS=\"{BUILD_FLAGS}\")")
    started = time.perf_counter()
    done = subprocess.run(["make", f"CC={compiler()}", f"FLAGS={BUILD_FLAGS}", "main"], cwd=exe.parent,
                          capture_output=True, text=True)
    if done.returncode != 0 or not exe.is_file():
        raise SystemExit(f"grbl-sim: the build failed:\n{done.stderr[-2000:]}")
    log(f"grbl-sim: built in {time.perf_counter() - started:.1f} s")
    return exe


TIME_FACTOR = 0.25


@contextlib.contextmanager
def firmware(exe: Path, folder: Path | None = None, steps: Path | None = None,
             step_time: float = 0.005) -> Iterator[str]:
    """GRBL switched on behind a pty, with the EEPROM kept in ``folder`` (a fresh one in a temporary folder by
    default); yields the pty's path. ``steps``: a file where grbl-sim writes the machine's position every
    ``step_time`` simulated seconds while a block runs, and at each block's start and end (its own clock: what
    :mod:`bench.bench_job_estimate` times jobs with). The firmware and socat are stopped at the end (grbl-sim spins a
    core while it runs)."""
    with tempfile.TemporaryDirectory(prefix="grbl-sim-") as scratch:
        folder = folder or Path(scratch)
        link = Path(scratch) / "tty"
        record = f"-r {step_time:g} -s {steps}" if steps is not None else "-s /dev/null"
        command = f"stdbuf -i0 -o0 {exe} -n -t {TIME_FACTOR:g} {record} -b /dev/null"
        process = subprocess.Popen(["socat", f"PTY,raw,echo=0,link={link}", f"EXEC:'{command}',pty,raw,echo=0"],
                                   cwd=folder, start_new_session=True, stdout=subprocess.DEVNULL,
                                   stderr=subprocess.DEVNULL)
        try:
            deadline = time.monotonic() + 10.0
            while not link.exists():
                if time.monotonic() > deadline or process.poll() is not None:
                    raise SystemExit("grbl-sim: socat made no pty")
                time.sleep(0.05)
            yield str(link)
        finally:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(process.pid, signal.SIGTERM)  # socat and the firmware it runs
            process.wait(5.0)


def configure(port: str, settings: dict[int, float]) -> None:
    """Write ``settings`` as a maker would with a terminal, before the station connects (a fresh EEPROM is restored
    to GRBL's defaults at the first start: error:7 and a dump of the settings before the banner)."""
    with serial.Serial(port, 115200, timeout=0.1) as link:

        def read_until(ends: tuple[bytes, ...], seconds: float, what: str) -> bytes:
            data = b""
            deadline = time.monotonic() + seconds
            while not any(end in data for end in ends):
                if time.monotonic() > deadline:
                    raise SystemExit(f"grbl-sim: no reply to {what} (got {data[-200:]!r})")
                data += link.read(4096)
            return data

        # GRBL waits a simulated second before it reads: a slower simulation takes longer in wall time
        read_until((b"['$' for help]\r\n",), max(15.0, 4.0 / TIME_FACTOR), "switching on")
        time.sleep(0.3)
        link.read(65536)
        for key, value in settings.items():
            link.write(f"${key}={value:g}\n".encode())
            reply = read_until((b"ok\r\n", b"error:"), 5.0, f"${key}={value:g}")
            if b"ok" not in reply:
                raise SystemExit(f"grbl-sim: ${key}={value:g} -> {reply!r}")
        link.write(b"\x18")  # settings in force; a reset keeps the state
        read_until((b"['$' for help]\r\n",), max(5.0, 2.0 / TIME_FACTOR), "a reset")


@contextlib.contextmanager
def stall_guard(conn: GrblConnection) -> Iterator[list[float]]:
    """Send a cycle start when GRBL stands Idle for 0.5 s with lines unanswered (grbl-sim's stall, see the module
    docstring); yields the list of times it did."""
    restarts: list[float] = []
    stop = threading.Event()

    def watch() -> None:
        since = None
        while not stop.wait(0.1):
            status = conn.status
            stalled = status is not None and status.state == "Idle" and conn.pending_count > 0
            since = (since or time.monotonic()) if stalled else None
            if since is not None and time.monotonic() - since >= 0.5:
                restarts.append(time.monotonic())
                with contextlib.suppress(Exception):
                    conn.cycle_start()
                since = None

    thread = threading.Thread(target=watch, daemon=True)
    thread.start()
    try:
        yield restarts
    finally:
        stop.set()
        thread.join(1.0)


def mask_of(conn: GrblConnection) -> int:
    return next(int(r.value) for r in conn.command("$$") if getattr(r, "key", None) == 10)


def scenario_masks(exe: Path) -> None:
    print("connect and a small job under each status report mask ($10 set by the maker; the driver keeps it):")
    for mask in (1, 2, 0, 3):
        with firmware(exe) as port:
            configure(port, {**SETTINGS, 10: mask})
            with GrblConnection(port) as conn:
                status = conn.fresh_status()
                if status.state == "Alarm":
                    conn.command("$X")  # homing is on and grbl-sim cannot home: unlock where it stands (0, 0, 0)
                conn.command("G10 L2 P1 X-50 Y-50")  # work zero: machine (-50, -50)
                status = conn.fresh_status()
                started = time.perf_counter()
                with stall_guard(conn) as restarts:
                    result = JobRunner(conn, Job("square", SQUARE)).run()
                elapsed = time.perf_counter() - started
                after = conn.fresh_status() or conn.status
                if result.state != "done":
                    print(f"  ({result.message})")
                print(f"  $10={mask}: report {'MPos' if mask & 1 else 'WPos'}{'+Bf' if mask & 2 else ''}: mpos "
                      f"{status.mpos} wpos {status.wpos}; job {result.state} in {elapsed:.1f} s "
                      f"(grbl-sim stalls restarted: {len(restarts)}) "
                      f"({result.lines_acked}/{result.lines_total} lines); at the end wpos {after.wpos} mpos "
                      f"{after.mpos}; $10 after: {mask_of(conn)}; writes of $10 by the driver: "
                      f"{sum(1 for _, d, t in conn.log if d == 'out' and t.startswith('$10='))}")


def scenario_soft_limit(exe: Path) -> None:
    print("soft limit in a job (the pre-flight read 200 mm of travel; GRBL's soft limits then see 30 mm):")
    with firmware(exe) as port:
        configure(port, SETTINGS)
        with GrblConnection(port) as conn:
            conn.command("$X")
            conn.command("G10 L2 P1 X-50 Y-50")
            travel = conn.settings[130]

            def shrink(progress) -> None:
                if progress.stage == "running" and conn.settings[130] == travel:
                    conn.command("$130=30")  # machine X -30..0: the job's X 10 (machine -40) is outside
                    conn.settings[130] = 30.0

            started = time.monotonic()
            with stall_guard(conn):
                result = JobRunner(conn, Job("square", SQUARE), on_progress=shrink).run()
            took = time.monotonic() - started
            print(f"  {result.state}: {result.message}  (laser off: {result.laser_off}; {took:.1f} s)")
            events = [(t - started, d, x) for t, d, x in conn.log
                      if t >= started and (x.startswith(("ALARM", "[MSG", "Grbl", "$X", "<soft")) or "reset" in x)]
            for t, direction, text in events:
                print(f"    {t:6.2f} s {direction:4s} {text}")
            status = conn.fresh_status()
            offsets = [r for r in conn.command("$#") if getattr(r, "kind", "") == "G54"]
            print(f"  after: state {status.state}, '?' answered, $# answered ({offsets[0].kind}:{offsets[0].text}), "
                  f"position lost: {conn.position_lost}")
            conn.command(f"$130={travel:g}")
    print("soft limit outside a job (a console line): the connection resets GRBL by itself:")
    with firmware(exe) as port:
        configure(port, SETTINGS)
        with GrblConnection(port) as conn:
            conn.command("$X")
            started = time.monotonic()
            try:
                conn.command("G0 X50")  # machine X 50 > 0
            except DeviceStateError as error:
                print(f"  G0 X50 -> {str(error)[:110]}...")
            reset = conn.wait_for(lambda: not conn.alarm_locked, 10.0)
            print(f"  reset by the driver: {reset} after {time.monotonic() - started:.2f} s; state "
                  f"{conn.fresh_status().state}; $X: {[r.text for r in conn.command('$X')]}; state "
                  f"{conn.fresh_status().state}; position lost: {conn.position_lost}")


def scenario_power_up(exe: Path) -> None:
    print("power-up with homing ($22=1): GRBL locks until $H; the pre-flight says how to go on:")
    with tempfile.TemporaryDirectory(prefix="grbl-eeprom-") as eeprom:
        with firmware(exe, Path(eeprom)) as port:
            configure(port, SETTINGS)
        with firmware(exe, Path(eeprom)) as port, GrblConnection(port, banner_timeout=8.0) as conn:  # switched on
            # again (grbl-sim waits a simulated second before it reads: 4 s at -t 0.25)
            status = conn.fresh_status()
            result = JobRunner(conn, Job("square", SQUARE)).run()
            print(f"  state at connect: {status.state}; job {result.state}: {result.message}")
            conn.command("$X")  # grbl-sim cannot home: unlocked at machine 0, G54 at 0
            with stall_guard(conn):
                result = JobRunner(conn, Job("square", SQUARE)).run()
            print(f"  unlocked ($X) at machine 0 with G54 at 0: job {result.state}: {result.message}")


def scenario_throughput(exe: Path) -> None:
    """Streaming in check mode as :mod:`bench.bench_grbl_stream` measures it (the station's streamer and a dry run
    against a bare character-counting loop; grbl-sim's serial input is no real wire: it reads bytes faster than
    115200 baud, so the loop on the same firmware is the figure to compare with)."""
    from bench import bench_grbl_stream

    print("streaming in check mode:")
    with firmware(exe) as port:
        configure(port, {})  # switched on and settled
        bench_grbl_stream.measure("gnea/grbl 1.1h (grbl-sim)", port, bench_grbl_stream.job_lines())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.grbl_firmware", description=__doc__.split("\n\n")[0])
    parser.add_argument("--grbl", type=Path, required=True, help="gnea/grbl: a checkout or a bare git repository")
    parser.add_argument("--grbl-sim", type=Path, required=True, help="grbl/grbl-sim: a checkout or a bare repository")
    parser.add_argument("--cache", type=Path, help="where builds are kept (default: the user's cache folder)")
    parser.add_argument("--time-factor", type=float, default=TIME_FACTOR, metavar="T",
                        help=f"grbl-sim's -t: simulated seconds per wall second (default {TIME_FACTOR:g})")
    args = parser.parse_args(argv)
    globals()["TIME_FACTOR"] = args.time_factor
    missing = missing_tools()
    if missing:
        print(f"grbl firmware bench: needs {', '.join(missing)} (e.g. apt-get install build-essential socat)",
              file=sys.stderr)
        return 2
    for option, path in (("--grbl", args.grbl), ("--grbl-sim", args.grbl_sim)):
        if not path.is_dir():
            print(f"grbl firmware bench: {option}: no such folder: {path}", file=sys.stderr)
            return 2
    exe = build(args.grbl, args.grbl_sim, args.cache)
    scenario_masks(exe)
    scenario_soft_limit(exe)
    scenario_power_up(exe)
    scenario_throughput(exe)
    return 0


if __name__ == "__main__":
    sys.exit(main())
