"""The twin's time estimate (``station send --verify``) against the real GRBL firmware, on three jobs: a pen plot,
a laser cut and a raster engraving.

    python -m bench.bench_job_estimate --grbl PATH/TO/grbl --grbl-sim PATH/TO/grbl-sim [--cache DIR]

Each job runs twice: on the station's twin at virtual time (:func:`station.services.job_verify.verify_job`: the
blocks the twin executed, timed by GRBL's planner in :mod:`drivers.grbl.planner`) and on gnea/grbl 1.1h built
with grbl-sim (:mod:`bench.grbl_firmware`), streamed by the station's driver, both machines with the same settings
(the profile's ``$11``, ``$100``-``$132``, no homing). The firmware's time is read from grbl-sim's step record (its
simulated clock, every 5 ms while a block runs, at each block's start and end): the time blocks ran, not the wall
time (grbl-sim runs slower than the wall clock, and its host-side stalls, see :mod:`bench.grbl_firmware`, add idle
time no AVR has). Dwells (``G4``) take their programmed time on both and are added to both. It prints, per job, the
firmware's time, the estimate, the same planner on the G-code as read before it runs (the ETA) and the ratios; the
goal is an estimate within 5 % of the firmware.
"""

from __future__ import annotations

import argparse
import io
import sys
import tempfile
from pathlib import Path

import numpy as np

from bench import grbl_firmware
from cam.laser import OperationSettings, plan_laser_job, write_laser_gcode
from drivers.gcode import interpret
from drivers.grbl import GrblConnection, Job, JobRunner
from drivers.profiles import load_profile
from drivers.sim.grbl.settings import DEFAULT_SETTINGS, SIM_PROFILES
from station.services.job_verify import verify_job

#: The settings both machines get: motion from the profile, no homing (grbl-sim's switches read as pressed).
MOTION_KEYS = (11, 12, 30, 31, 32, 100, 101, 102, 110, 111, 112, 120, 121, 122, 130, 131, 132)


def machine_settings(profile: str) -> dict[int, float]:
    settings = dict(DEFAULT_SETTINGS)
    settings.update(SIM_PROFILES[profile])
    chosen = {key: float(settings[key]) for key in MOTION_KEYS}
    chosen.update({20: 0.0, 22: 0.0})
    return chosen


def plot_lines() -> list[str]:
    """A spirograph star plotted on the pen plotter (``station plot``'s writer: servo pen with dwells)."""
    from design.machines import get_machine
    from station.services.machines import plot_job

    model = get_machine("spirograph")
    points = np.asarray(model.sample(model.validate({}), n=1500, spacing="arclength"), dtype=float)
    text, *_ = plot_job([points], load_profile("plotter"), 60.0, 0.05)
    return text.splitlines()


def _circle(cx: float, cy: float, r: float, n: int = 72) -> np.ndarray:
    t = np.linspace(0, 2 * np.pi, n + 1)
    return np.column_stack([cx + r * np.cos(t), cy + r * np.sin(t)])


def _square(x: float, y: float, size: float) -> np.ndarray:
    return np.array([[x, y], [x + size, y], [x + size, y + size], [x, y + size], [x, y]], dtype=float)


def cut_lines() -> list[str]:
    """Parts cut out on the laser: holes and outlines (circles as 72-gons), labels engraved."""
    engrave = OperationSettings(power=0.3, feed=3000.0, passes=1)
    cut = OperationSettings(power=1.0, feed=900.0, passes=1)
    strokes = [np.array([[22.0, 22.0], [32.0, 26.0], [42.0, 22.0]])]
    groups = [([_circle(25, 32, 4), _circle(38, 32, 4)], _square(15, 15, 35))]
    job = plan_laser_job(strokes, groups, engrave, cut, 1000.0)
    out = io.StringIO()
    write_laser_gcode(job, out, (0.0, 0.0, 400.0, 400.0))
    return out.getvalue().splitlines()


def raster_lines(width: float = 20.0, height: float = 6.0, pixel: float = 0.4, feed: float = 3000.0) -> list[str]:
    """A grey-level raster engraved line by line, both ways, one ``G1 X.. S..`` per pixel (M4: power follows
    speed)."""
    lines = ["; chaos-station laser job: raster", "G21", "G90", "M4 S0", "G0 X20 Y20", f"F{feed:g}"]
    columns = int(round(width / pixel))
    rows = int(round(height / pixel))
    for row in range(rows):
        y = 20 + row * pixel
        order = range(columns) if row % 2 == 0 else range(columns - 1, -1, -1)
        x0 = 20.0 if row % 2 == 0 else 20.0 + width
        lines.append(f"G0 X{x0:.3f} Y{y:.3f}")
        for column in order:
            shade = 0.5 + 0.5 * np.sin(column / 6.0) * np.cos(row / 5.0)
            x = 20 + (column + 1) * pixel if row % 2 == 0 else 20 + column * pixel
            lines.append(f"G1 X{x:.3f} S{int(1000 * shade)}")
    lines += ["M5 S0", "G0 X0 Y0"]
    return lines


def line_lines() -> list[str]:
    """One 100 mm feed move from rest to rest: 2.05 s exactly at 3000 mm/min and 1000 mm/s^2 (0.05 s to reach
    50 mm/s over 1.25 mm, the same to stop): what grbl-sim's own clock gives for it says how far to trust it."""
    return ["; chaos-station laser job: one line", "G21", "G90", "M4 S0", "G0 X10 Y10", "G4 P0",
            "G1 X110 Y10 S100 F3000", "M5 S0"]


def firmware_motion_seconds(steps: Path) -> float:
    """Simulated seconds blocks ran, from grbl-sim's step record: the time from each block's start line to its last
    line, without the idle time between one block's end and the next one's start (dwells, syncs, stalls)."""
    return firmware_motion(steps)[0]


def firmware_motion(steps: Path) -> tuple[float, int]:
    """:func:`firmware_motion_seconds` and how many times the machine stood still between blocks (the job's syncs,
    and grbl-sim's stalls: a block after either starts from rest)."""
    sections: list[list[tuple[float, tuple[int, ...]]]] = []
    before: list[tuple[float, tuple[int, ...]]] = []
    for raw in steps.read_text().splitlines():
        if raw.startswith("#"):
            sections.append([])
            continue
        parts = raw.replace(",", " ").split()
        if len(parts) < 4:
            continue
        sample = (float(parts[0]), tuple(int(v) for v in parts[1:4]))
        (sections[-1] if sections else before).append(sample)
    total, stops = 0.0, 0
    previous_last = before[-1] if before else None
    for section in sections:
        if not section:
            continue
        if previous_last is not None:
            total += section[0][0] - previous_last[0]
        for index, (a, b) in enumerate(zip(section, section[1:])):
            last = index == len(section) - 2
            if last and a[1] == b[1] and len(section) > 2:
                stops += 1
                continue  # this block ended at a; b is the next block's start after an idle time
            total += b[0] - a[0]
        previous_last = section[-1]
    return total, stops


def run_on_firmware(exe: Path, lines: list[str], settings: dict[int, float], laser: bool,
                    pen_up: tuple[str, ...]) -> tuple[float, int, int, str]:
    """(motion seconds, stops between blocks, cycle restarts, how the job ended) of ``lines`` on the real
    firmware."""
    with tempfile.TemporaryDirectory(prefix="job-estimate-") as folder:
        steps = Path(folder) / "steps.txt"
        with grbl_firmware.firmware(exe, steps=steps) as port:
            grbl_firmware.configure(port, settings)
            # a slow simulation reads the serial line at its own (simulated) baud rate: the replies take longer in
            # wall time, and the driver's watchdogs must wait as long
            slow = 1.0 / grbl_firmware.TIME_FACTOR
            with GrblConnection(port, poll_interval=0.05 * slow, silence_timeout=0.7 * slow,
                                lost_ok_timeout=1.5 * slow, banner_timeout=3.0 * slow,
                                reply_timeout=10.0 * slow) as conn, grbl_firmware.stall_guard(conn) as restarts:
                result = JobRunner(conn, Job("bench", lines, laser=laser, pen_up=pen_up)).run()
        seconds, stops = firmware_motion(steps)
        return seconds, stops, len(restarts), f"{result.state}: {result.message}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.bench_job_estimate", description=__doc__.split("\n\n")[0])
    parser.add_argument("--grbl", type=Path, required=True, help="gnea/grbl: a checkout or a bare git repository")
    parser.add_argument("--grbl-sim", type=Path, required=True, help="grbl/grbl-sim: a checkout or a bare repository")
    parser.add_argument("--cache", type=Path, help="where builds are kept (default: the user's cache folder)")
    parser.add_argument("--time-factor", type=float, default=grbl_firmware.TIME_FACTOR, metavar="T",
                        help="grbl-sim's -t: simulated seconds per wall second")
    parser.add_argument("--jobs", default="plot,cut,raster",
                        help="which jobs, of plot, cut, raster and line (default plot,cut,raster)")
    args = parser.parse_args(argv)
    grbl_firmware.TIME_FACTOR = args.time_factor
    missing = grbl_firmware.missing_tools()
    if missing:
        print(f"job estimate bench: needs {', '.join(missing)}", file=sys.stderr)
        return 2
    exe = grbl_firmware.build(args.grbl, args.grbl_sim, args.cache)
    jobs = {"plot": (plot_lines, "plotter"), "cut": (cut_lines, "laser"), "raster": (raster_lines, "laser"),
            "line": (line_lines, "laser")}
    print(f"{'job':8s} {'lines':>6s} {'blocks':>6s} {'dwell s':>8s} {'firmware s':>10s} {'estimate s':>10s} "
          f"{'ratio':>6s} {'G-code s':>10s} {'ratio':>6s} {'stops':>9s} {'restarts':>8s}")
    for key in args.jobs.split(","):
        make, kind = jobs[key]
        lines = make()
        profile = load_profile(kind)
        settings = machine_settings(kind)
        pen_up = tuple(profile.pen.up_commands()) if profile.pen else ("M5",)
        verified = verify_job(lines, name=key, profile=profile, settings=settings)
        if verified.state != "done":
            print(f"{key}: the twin did not run it: {verified.message}")
            continue
        dwell = float(interpret(lines).dwell.sum())
        motion, stops, restarts, ended = run_on_firmware(exe, lines, settings, profile.is_laser, pen_up)
        firmware = motion + dwell
        # stops: the firmware's (after the first block) against the twin's blocks from rest after the first
        print(f"{key:8s} {len(lines):6d} {verified.blocks:6d} {dwell:8.2f} {firmware:10.2f} "
              f"{verified.estimate_s:10.2f} {verified.estimate_s / firmware:6.3f} {verified.preflight_s:10.2f} "
              f"{verified.preflight_s / firmware:6.3f} {f'{stops}/{verified.from_rest - 1}':>9s} {restarts:8d}",
              flush=True)
        if not ended.startswith("done"):
            print(f"  firmware job: {ended}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
