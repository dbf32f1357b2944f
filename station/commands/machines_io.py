"""``station plot``, ``station ports``, ``station send``: from a drawing-machine pattern to G-code to a GRBL machine.

``station plot`` takes a pattern (a drawing machine with parameters, or the JSON of ``station pattern --json``),
scales and centres it on the paper of a machine profile, simplifies the polyline within a tolerance and writes G-code.
``station send`` streams a G-code file to a GRBL controller (real port or ``sim://grbl?...``) with pre-flight,
dry run (check mode), frame, resume from a line, and a progress bar.
"""

from __future__ import annotations

import argparse
import dataclasses
import signal
import sys
import threading
from pathlib import Path
from typing import Any

import numpy as np

from station.cli_util import (
    NON_NEGATIVE,
    POSITIVE,
    check_output_file,
    design_parameters,
    emit_json,
    load_design,
    number,
    parse_assignments,
)
from station.commands._send_place import add_place_options, verify_before_send
from station.errors import ServiceError, UsageError
from station.progress_view import ProgressView
from station.services import plot as plot_service
from station.services.machine_sessions import (
    BAUD_RATES,
    FINAL_STATES,
    INTERRUPTED,
    HandledSignals,
    JobMode,
    JobProgress,
    JobResult,
    MachineSessions,
    SendPolicy,
    job_history,
    job_layer_marks,
    layer_at,
    list_ports,
    load_job,
    machine_profile,
    refusal,
)
from station.services.machines import job_seconds, machine_name, pattern_points, read_pattern, sample_pattern
from station.services.machines import plot_job as _plot_job
from station.services.reporting import Progress

DEFAULT_POINTS = 4096


def register(subparsers) -> None:
    plot = subparsers.add_parser(
        "plot",
        help="write a plot job (G-code): patterns and SVGs, one pen per layer",
        description="Sample MACHINE's pattern (or read --pattern FILE.json from `station pattern --json`), scale and "
        "centre it on the profile's paper, simplify the polyline within the tolerance and write G-code for a GRBL "
        "pen plotter (pen up/down from the profile) or laser (M4 power, dark G0 travels). Several patterns "
        "(--design repeated, or a --compose file) and SVG files (--svg: each SVG layer, or stroke colour with "
        "--by color, a plot layer; hidden layers are not drawn) make a plot of layers, one pen each: vpype merges, "
        "re-seams and sorts each layer's paths (--no-sort keeps them as drawn), and the job pauses between layers "
        "(the profile's [pen] change lines, M0 by default) with a message saying which pen to put in; "
        "`station send` waits there for Enter.",
        epilog="examples: station plot spirograph --set d=2.5 --size 150 --out spiro.gcode\n"
        "          station pattern hoot_nanny --json > hn.json && station plot --pattern hn.json "
        "--profile plotter --out hn.gcode\n"
        "          station plot --svg examples/plots/frame.svg --out frame.gcode --preview frame.png\n"
        "          station plot --compose examples/plots/three-pens.toml --out three.gcode --preview three.png",
    )
    plot.add_argument("machine", nargs="?", help="drawing machine name (see `station machines`)")
    plot.add_argument("--design", action="append", default=[], metavar="FILE.json",
                      help='start from a design file: what `station pattern --json` prints, or {"params": {...}}; '
                      "repeated: one layer per design")
    plot.add_argument("--set", action="append", metavar="NAME=VALUE", default=[],
                      help="a parameter value (repeatable, wins)")
    plot.add_argument("--pattern", metavar="FILE.json", help="a pattern written by `station pattern --json`")
    plot.add_argument("--compose", metavar="FILE.toml",
                      help="a composition: [[patterns]], [[svg]] and [[layers]] (pens); see docs/guide/plotting.md")
    plot.add_argument("--svg", action="append", default=[], metavar="FILE.svg",
                      help="an SVG drawing to plot, centred on the paper at its own size (repeatable)")
    plot.add_argument("--by", choices=("layer", "color"), default="layer",
                      help="an SVG's plot layers: its layers (default) or its stroke colours")
    plot.add_argument("--no-sort", action="store_true",
                      help="keep each layer's paths as drawn (no vpype linemerge, reloop, linesort)")
    plot.add_argument("--seed", type=int, default=0, metavar="N", help="seed of the seams reloop moves (0)")
    plot.add_argument("--preview", metavar="FILE.png",
                      help="also draw the plot: layers in their pens' colours, travel in grey, time per layer")
    plot.add_argument("--profile", default="plotter",
                      help="machine profile TOML, or a built-in: plotter (default), laser")
    plot.add_argument("--size", type=POSITIVE, metavar="MM",
                      help="largest side of the drawing (default: fit the paper)")
    plot.add_argument("--tolerance", type=NON_NEGATIVE, metavar="MM",
                      help="simplification tolerance (default: profile's)")
    plot.add_argument("--points", type=int, default=DEFAULT_POINTS, help="samples of the pattern (default 4096)")
    plot.add_argument("--power", type=number(0, 1, above=True, why="a fraction of the maximum"), default=0.3,
                      help="laser power as a fraction of max (laser profiles)")
    plot.add_argument("--out", metavar="JOB.gcode", help="output file (default: standard output)")
    plot.add_argument("--json", action="store_true", help="print a JSON summary on stdout (needs --out)")
    plot.set_defaults(func=run_plot)

    ports = subparsers.add_parser(
        "ports",
        help="list serial ports and GRBL controllers",
        description="List serial ports (each probed for a GRBL banner) and the simulated GRBL machines.",
        epilog="examples:\n  station ports\n  station ports --no-probe --json",
    )
    ports.add_argument("--no-probe", action="store_true", help="do not open the ports to look for GRBL")
    ports.add_argument("--baud", type=baud_rate, default=115200, metavar="RATE",
                       help="baud rate to probe at (default 115200, GRBL 1.1's; a standard rate such as 9600)")
    ports.add_argument("--json", action="store_true",
                       help="print the ports as JSON (url, description, hwid, grbl version, simulated)")
    ports.set_defaults(func=run_ports)

    send = subparsers.add_parser(
        "send",
        help="stream a G-code job to a GRBL machine",
        description="Stream JOB.gcode to a GRBL 1.1 controller by character counting, after a pre-flight check "
        "against the machine's travel: with homing ($22=1) the machine space of GRBL's soft limits, without homing "
        "the job's size and the way from the head to it against $130-$132. Laser jobs need laser mode ($32=1) and "
        "always end with M5 S0; on a machine without homing, a laser job is offered its frame first when run from a "
        "terminal. Ctrl-C, kill -INT or kill abort the job (soft reset, laser off) and end it as interrupted with the "
        "line to resume from (exit 130), even when started with SIGINT ignored. At a program pause (M0: a multi-pen "
        "plot's pen change) it says which pen to put in and waits for Enter (a line on standard input; at its end the "
        "job is stopped there).",
        epilog='examples:\n  station send spiro.gcode --port "sim://grbl?profile=plotter&time_scale=0.01"\n'
        "  station send switch-jigs/jigs.gcode --profile laser --port 'sim://grbl?profile=laser&clock=virtual' "
        "--place 20,30,5 --verify",
    )
    send.add_argument("job", metavar="JOB.gcode", help="the G-code file to stream (from `station plot` or "
                      "`station fabricate`)")
    send.add_argument("--port", help="port URL (default: the profile's port)")
    send.add_argument("--profile", default=None, help="machine profile TOML or built-in name (plotter, laser)")
    send.add_argument("--baud", type=baud_rate, default=None, metavar="RATE",
                      help="baud rate (default: the profile's, else 115200)")
    send.add_argument("--laser", action="store_true", help="treat as a laser job (also implied by a laser profile)")
    send.add_argument("--dry-run", action="store_true", help="check mode ($C): parse every line, move nothing")
    send.add_argument("--frame", action="store_true",
                      help="only trace the job's bounding box (pen up, or laser at the profile's frame power)")
    send.add_argument("--from-line", type=int, default=1, metavar="N", help="resume from line N (1-based)")
    send.add_argument("--from-layer", type=int, default=None, metavar="N",
                      help="start at layer N of a multi-pen plot (its pen change first): where `station jobs` says "
                      "an unfinished plot stood")
    send.add_argument("--json", action="store_true",
                      help="print the result as JSON (state, message, lines confirmed, resume line, laser off), "
                      "also when interrupted; no progress bar")
    add_place_options(send)
    send.set_defaults(func=run_send)


def baud_rate(text: str) -> int:
    """A standard serial baud rate (argparse type of ``--baud``)."""
    try:
        value = int(text)
    except ValueError:
        value = None
    if value not in BAUD_RATES:
        raise argparse.ArgumentTypeError(
            f"expected a standard baud rate such as 115200 (GRBL 1.1) or 9600, got {text!r}")
    return value


# ----------------------------------------------------------------------------------------------------------- plot


def _profile(name: str | None, default: str = "plotter"):
    return machine_profile(name, default)


def pattern_polylines(args) -> tuple[list[np.ndarray], dict[str, Any]]:
    """The pattern as polylines plus a description, from ``MACHINE --set`` or ``--pattern FILE.json``."""
    if args.pattern and args.machine:
        raise UsageError("give either MACHINE (with --set) or --pattern FILE.json, not both")
    if args.pattern:
        if args.set or args.design:
            raise UsageError("--set and --design apply to MACHINE, not to --pattern FILE.json")
        # a bad file is a FileFormatError naming the file first, as for --design (not a usage error)
        points, description = read_pattern(args.pattern)
        return [points], description
    if not args.machine:
        raise UsageError("give a drawing MACHINE (see `station machines`) or --pattern FILE.json")
    if args.points < 16:
        raise UsageError(f"--points must be at least 16, got {args.points}")
    name = machine_name(args.machine)
    points, params = sample_pattern(name, design_parameters(args, name), args.points)
    return [points], {"machine": name, "params": params}


def plot_job(polylines, profile, size: float | None, tolerance: float | None, power: float = 0.3):
    """:func:`station.services.machines.plot_job`, its refusals naming the CLI's flags (``--tolerance``...)."""
    try:
        return _plot_job(polylines, profile, size, tolerance, power)
    except ServiceError as error:
        if error.field in ("tolerance", "size", "power"):
            raise UsageError(f"--{error}") from None
        raise


def _layered(args) -> bool:
    """Whether the plot is one of layers: several designs, a composition, an SVG."""
    return bool(args.compose or args.svg or len(args.design) > 1)


def run_plot(args) -> int:
    profile = _profile(args.profile)
    if args.json and args.out is None:
        raise UsageError("--json prints a summary and needs --out for the G-code")
    if args.out is not None:
        check_output_file(args.out, {".gcode", ".nc", ".ngc", ".txt"}, "--out")
    if args.preview is not None:
        check_output_file(args.preview, {".png"}, "--preview")
    if _layered(args):
        return _run_layered_plot(args, profile)
    args.design = args.design[0] if args.design else None  # one design: the pattern plot
    polylines, description = pattern_polylines(args)
    text, fitted, simplified, options = plot_job(polylines, profile, args.size, args.tolerance, args.power)
    if args.out is not None:
        Path(args.out).write_text(text, encoding="utf-8")
    else:
        sys.stdout.write(text)
    if args.preview is not None:
        layer = plot_service.PlotLayer(description["machine"] or "pattern", "pen", plot_service.PALETTE[1][1],
                                       polylines=list(simplified))
        paper, box = plot_service.drawable_box(profile)
        document = plot_service.PlotDocument([layer], paper, box)
        result = plot_service.PlotResult(text, document, options, plot_service.summarize(text, document, profile))
        plot_service.write_preview_png(result, args.preview)
    stacked = np.concatenate(fitted)
    length = float(sum(np.linalg.norm(np.diff(p, axis=0), axis=1).sum() for p in simplified))
    summary = {
        "machine": description["machine"],
        "params": description["params"],
        "profile": profile.name,
        "out": args.out,
        "points_in": int(sum(len(p) for p in fitted)),
        "points_out": int(sum(len(p) for p in simplified)),
        "tolerance_mm": profile.plot.tolerance if args.tolerance is None else args.tolerance,
        "extent_mm": [float(v) for v in (*stacked.min(axis=0), *stacked.max(axis=0))],
        "draw_length_mm": length,
        "draw_time_s": job_seconds(text, profile),
        "lines": text.count("\n"),
    }
    if args.json:
        emit_json(summary)
    print(
        f"plot: {summary['points_in']} -> {summary['points_out']} points (tolerance {summary['tolerance_mm']:g} mm), "
        f"{length:.0f} mm of drawing at F{options.draw_feed:g}, about {summary['draw_time_s'] / 60:.1f} min (GRBL's "
        "planner)"
        + (f"; wrote {args.out}" if args.out is not None else "")
        + (f" and {args.preview}" if args.preview is not None else ""),
        file=sys.stderr,
    )
    return 0


def plot_composition(args) -> plot_service.Composition:
    """What ``station plot`` was asked to draw as layers: the --compose file's sources, then MACHINE with each
    --design (or --pattern), then each --svg."""
    if args.pattern and args.machine:
        raise UsageError("give either MACHINE (with --set) or --pattern FILE.json, not both")
    if args.design and not args.machine:
        raise UsageError("--design needs the MACHINE it is a design of")
    composition = (plot_service.load_composition(args.compose, load_design) if args.compose
                   else plot_service.Composition())
    if args.points < 16:
        raise UsageError(f"--points must be at least 16, got {args.points}")
    if args.machine:
        name = machine_name(args.machine)
        for design in args.design or [None]:
            params = load_design(design, name) if design else {}
            params.update(parse_assignments(args.set))
            label = Path(design).stem if design else name
            composition.sources.append(plot_service.PatternSource(name, params, size=args.size, points=args.points,
                                                                  label=label))
    elif args.pattern:
        one = argparse.Namespace(**{**vars(args), "design": None})
        (points,), description = pattern_polylines(one)
        composition.sources.append(plot_service.PatternSource(
            description["machine"] or "pattern", description["params"], size=args.size,
            label=Path(args.pattern).stem, polyline=points))
    elif args.set:
        raise UsageError("--set applies to MACHINE; give the drawing MACHINE too")
    for svg in args.svg:
        composition.sources.append(plot_service.SvgSource(Path(svg), by=args.by))
    return composition


def _run_layered_plot(args, profile) -> int:
    composition = plot_composition(args)
    try:
        result = plot_service.plot(composition, profile, sample=pattern_points, sort=not args.no_sort,
                                   tolerance=args.tolerance, power=args.power, seed=args.seed)
    except ServiceError as error:
        if error.field in ("tolerance", "power"):
            raise UsageError(f"--{error}") from None
        raise
    if args.out is not None:
        Path(args.out).write_text(result.gcode, encoding="utf-8")
    else:
        sys.stdout.write(result.gcode)
    if args.preview is not None:
        plot_service.write_preview_png(result, args.preview)
    pauses = sum(1 for layer in result.layers if layer.pause_line is not None)
    if args.json:
        emit_json({"profile": profile.name, "out": args.out, "preview": args.preview, "sorted": not args.no_sort,
                   "layers": [layer.to_dict() for layer in result.layers], "pen_changes": pauses,
                   "travel_mm": result.travel_mm, "time_s": result.time_s, "lines": result.gcode.count("\n")})
    for layer in result.layers:
        pause = f", pen change at line {layer.pause_line}" if layer.pause_line is not None else ""
        print(f"  layer {layer.number} {layer.name!r}: pen {layer.pen!r} {layer.color}, {layer.paths} paths, "
              f"{layer.draw_mm:.0f} mm drawn, {layer.travel_mm:.0f} mm travel, about "
              f"{plot_service.format_minutes(layer.time_s)}{pause}", file=sys.stderr)
    wrote = [name for name in (args.out, args.preview) if name is not None]
    count = len(result.layers)
    print(f"plot: {count} layer{'s' * (count != 1)}, {pauses} pen change{'s' * (pauses != 1)}, "
          f"{result.travel_mm:.0f} mm travel, about "
          f"{plot_service.format_minutes(result.time_s)} (estimate)" + (f"; wrote {' and '.join(wrote)}" if wrote
                                                                          else ""), file=sys.stderr)
    return 0


# ----------------------------------------------------------------------------------------------------------- ports


def run_ports(args) -> int:
    ports = list_ports(probe_ports=not args.no_probe, baud=args.baud)
    if args.json:
        emit_json([dataclasses.asdict(p) for p in ports])
        return 0
    if not ports:
        print("no serial ports")
        return 1
    for port in ports:
        grbl = f"GRBL {port.grbl}" if port.grbl else ("not probed" if args.no_probe else "no GRBL banner")
        kind = "simulated" if port.simulated else "serial"
        print(f"{port.url:40s} {kind:9s} {grbl:16s} {port.description}")
    return 0


# ----------------------------------------------------------------------------------------------------------- send


def format_duration(seconds: float) -> str:
    """``m:ss``, or ``h:mm:ss`` from an hour on."""
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


def progress_text(progress: JobProgress) -> str:
    """``42.0% 84/200 lines  ETA 1:05  running``; a job that ended shows its state without an ETA."""
    text = f"{progress.fraction * 100:5.1f}% {progress.lines_acked}/{progress.lines_total} lines"
    if progress.state in FINAL_STATES:
        return f"{text}  {progress.state}"
    eta = "--:--" if progress.eta is None else format_duration(progress.eta)
    return f"{text}  ETA {eta}  {progress.state}"


#: Job states that write no plain progress line: a refused job says why in one line of its own.
QUIET_STATES = ("idle", "preflight", "refused", "position_lost")


class SendProgress:
    """Progress of a job on stderr, drawn by :class:`station.progress_view.ProgressView`.

    On a terminal, one rich bar for the whole job (its state in the text beside it, so a hold or the end does not
    start a new bar). Anywhere else (a file, a pipe, a CI log) a plain line ``send: <progress_text>`` at every tenth
    of the job and every change of state, so the log reads as lines, not one long line of carriage returns.
    """

    def __init__(self, stream=None, tty: bool | None = None) -> None:
        self.view = ProgressView(stream, describe=lambda progress: progress.message, prefix="send: ", tty=tty,
                                 quiet_stages=QUIET_STATES)

    def __call__(self, progress: JobProgress) -> None:
        # the view starts a bar (or a run of tenths) per stage: one stage for the job on a terminal, its state
        # elsewhere (a plain line marks each change of state)
        stage = "job" if self.view.tty else progress.state
        self.view(Progress(stage, progress.fraction, 1.0, progress_text(progress)))

    def close(self, clear: bool = False) -> None:
        """End the bar (``clear``: remove it, e.g. before a refusal's one line)."""
        self.view.close(clear=clear)


def _interactive() -> bool:
    """Someone at a terminal can answer a question (stdin and stderr are terminals)."""
    return bool(sys.stdin and sys.stdin.isatty() and sys.stderr.isatty())


def _ask(question: str, default: bool) -> bool:
    """Ask a yes/no question on stderr; Enter takes ``default``, end of input means no."""
    sys.stderr.write(f"{question} [{'Y/n' if default else 'y/N'}] ")
    sys.stderr.flush()
    answer = sys.stdin.readline()
    if not answer:
        sys.stderr.write("\n")
        return False
    answer = answer.strip().lower()
    return default if not answer else answer in ("y", "yes")


class SendSignals(HandledSignals):
    """SIGINT (Ctrl-C, ``kill -INT``) and SIGTERM (``kill``) while ``station send`` runs, handled by the command.

    Installed even when the process started with SIGINT ignored: a background job of a script gets SIGINT ignored
    from its shell, Python then keeps it so, and ``kill -INT`` would let a laser job burn to its end. While a job
    streams a signal only asks the send to stop (:meth:`MachineSessions.interrupt`: soft reset, laser off, the
    history written, the result printed); at any other time it raises KeyboardInterrupt, as Python's own handler
    does. Off the main thread (where no handler can be set) nothing is installed.
    """

    def __init__(self, sessions: MachineSessions) -> None:
        super().__init__()
        self.sessions = sessions

    def _handle(self, signum, frame) -> None:
        if not self.sessions.sending:
            raise KeyboardInterrupt
        self.sessions.interrupt("SIGINT (Ctrl-C)" if signum == signal.SIGINT else signal.Signals(signum).name)


class TerminalPolicy(SendPolicy):
    """``station send``'s answers: the frame of a laser job on a machine without homing offered at a terminal (a tip
    elsewhere; never with ``--json``), a pen change announced on stderr and resumed by a line on standard input (at
    its end nobody is there to change the pen: the job is stopped there)."""

    def __init__(self, path: Path, *, ask: bool, bar: SendProgress | None, stream=None) -> None:
        self.path = path
        self.ask = ask
        self.bar = bar
        self.stream = stream
        self.framing = False  # the frame was asked for and has not ended well yet
        self.declined = False  # the job was not started after its frame

    def progress(self, progress) -> None:
        if self.bar is not None:
            self.bar(progress)

    def frame_first(self, job) -> bool:
        if not self.ask:
            return False
        if not _interactive():
            print(f"station: tip: this machine has no homing ($22=0): the job runs where work zero is set; "
                  f"`station send {self.path} --frame` traces its bounding box at frame power first", file=sys.stderr)
            return False
        self.framing = _ask("No homing ($22=0): trace the job's frame first (laser at frame power)?", default=True)
        return self.framing

    def start_after_frame(self, job) -> bool:
        if self.bar is not None:
            self.bar.close()
            self.bar = SendProgress()
        self.framing = False
        self.declined = not _ask(f"Frame done. Start the laser job {self.path.name}?", default=False)
        return not self.declined

    def paused(self, message: str, resume, stop) -> None:
        print(f"station: {message}: press Enter to resume (Ctrl-C aborts)", file=sys.stderr, flush=True)

        def wait_for_enter() -> None:
            stream = self.stream if self.stream is not None else sys.stdin
            if stream is not None and stream.readline():
                resume()
            else:
                print("station: standard input closed at the pen change: nobody to put the pen in; job stopped",
                      file=sys.stderr)
                stop()

        threading.Thread(target=wait_for_enter, name="pen-change", daemon=True).start()

    def warn(self, message: str) -> None:
        print(f"station: warning: {message}", file=sys.stderr)


def _layer_tip(marks, result: JobResult) -> str:
    """``, or --from-layer 2 to start layer 2/3 "star" again`` for an unfinished multi-pen plot, else ``""``."""
    if not marks or result.resume_line is None:
        return ""
    mark = layer_at(marks, result.resume_line - 1)
    if mark is None:
        return ""
    return f', or --from-layer {mark.number} to start layer {mark.number}/{mark.count} "{mark.name}" again'


def _warn_history(error: Exception) -> None:
    print(f"station: warning: job history not written ({error})", file=sys.stderr)


def run_send(args) -> int:
    profile = machine_profile(args.profile) if args.profile else None
    path = Path(args.job)
    try:
        job = load_job(path, profile=profile, laser=args.laser, place=getattr(args, "place", None))
    except ServiceError as error:
        raise UsageError(f"--place: {error}" if error.field == "place" else str(error)) from None
    if args.from_line < 1 or args.from_line > len(job.lines):
        raise UsageError(f"--from-line must be between 1 and {len(job.lines)} (lines in {path.name}), "
                         f"got {args.from_line}")
    marks = job_layer_marks(job.lines)
    if args.from_layer is not None:
        if args.from_line != 1:
            raise UsageError("give --from-line or --from-layer, not both")
        if not marks:
            raise UsageError(f"job {str(path)!r}: --from-layer needs a plot of layers (`station plot` with several "
                             "patterns or an SVG writes them); this job has none")
        if not 1 <= args.from_layer <= len(marks):
            raise UsageError(f"--from-layer must be between 1 and {len(marks)} (layers in {path.name}), "
                             f"got {args.from_layer}")
        args.from_line = marks[args.from_layer - 1].line + 1
    url = args.port or (profile.port if profile else None)
    if not url:
        raise UsageError("give --port URL (e.g. /dev/ttyUSB0 or sim://grbl?profile=plotter) or --profile")
    baud = args.baud or (profile.baud if profile else 115200)
    mode = JobMode.FRAME if args.frame else JobMode.DRY if args.dry_run else JobMode.RUN
    bar = None if args.json else SendProgress()
    policy = TerminalPolicy(path, ask=not args.json, bar=bar)
    with job_history(_warn_history) as history:
        sessions = MachineSessions(history, source="station send")
        with SendSignals(sessions), sessions.session(url, url, baud):
            verify_before_send(args, job, profile, sessions, url)
            entry = sessions.add(url, job, str(path))
            if args.from_layer is not None and not args.frame:
                mark = marks[args.from_layer - 1]
                print(f"station: starting at {mark.label}" + (": the machine pauses for its pen first"
                      if mark.pause is not None else f': pen "{mark.pen}" must be in'), file=sys.stderr)
            try:
                result = sessions.send(url, entry, mode, from_line=args.from_line, profile=profile, policy=policy,
                                       report=policy.progress)
            except ServiceError as error:
                if error.field == "job":  # nothing to frame
                    raise UsageError(str(error)) from None
                raise
        if policy.bar is not None:
            if result.state in ("refused", "position_lost"):
                policy.bar.close(clear=True)  # the error's one line says it all
            else:
                policy.bar.close()
    if policy.declined:
        print(f"station: {path.name} not started", file=sys.stderr)
        return 0
    if policy.framing:  # the frame ended badly: the result is the frame's, the job was not started
        if result.state == INTERRUPTED:
            print(f"station: frame {result.message}; {path.name} not started", file=sys.stderr)
            return 130
        print(result.message, file=sys.stderr)
        if result.state == "refused":
            raise refusal(result)
        return 1
    document = {
        "job": str(path), "port": url, "state": result.state, "message": result.message,
        "lines_total": result.lines_total, "lines_acked": result.lines_acked, "elapsed_s": result.elapsed,
        "resume_line": result.resume_line, "errors": result.errors, "laser_off": result.laser_off,
        "dry_run": args.dry_run, "frame": args.frame,
        **({"verify": args.verified.to_dict()} if getattr(args, "verified", None) else {}),
    }
    if marks:
        stood = layer_at(marks, result.resume_line - 1) if result.resume_line else None
        document["layers"] = len(marks)
        document["layer"] = stood.to_dict() if stood is not None else None
    if args.json:
        emit_json(document)
    if result.state == INTERRUPTED:
        # on stderr with --json too: whoever pressed Ctrl-C reads there whether the laser is off
        go_on = (f" (the same command with --from-line {result.resume_line}{_layer_tip(marks, result)})"
                 if result.resume_line is not None and mode is JobMode.RUN else "")
        print(f"station: {result.message}{go_on}", file=sys.stderr)
        return 130
    if not args.json and result.state not in ("refused", "position_lost"):  # those are raised: one line
        tip = _layer_tip(marks, result)
        print(result.message + (f" ({tip.lstrip(', ')})" if tip and mode is JobMode.RUN else ""), file=sys.stderr)
        for _, text in result.errors:
            print(f"  {text}", file=sys.stderr)
    error = refusal(result)
    if error is not None:
        raise error
    return 0 if result.state == "done" else 1
