"""``station send --place X,Y,ANGLE`` and ``--verify``: the job placed on the stock, and run on the GRBL twin at
virtual time before it is sent. The work is :mod:`cam.place` and :mod:`station.services.job_verify`;
this module adds the options to ``station send``'s parser and applies them (the underscore keeps it from being
discovered as a command of its own)."""

from __future__ import annotations

import argparse
import sys

from cam.place import Placement, place_lines
from drivers.errors import JobRefused
from drivers.gcode import GcodeError
from drivers.grbl import Job
from station.errors import ServiceError, UsageError

__all__ = ["add_place_options", "placed_job", "verify_before_send"]


def placement(text: str) -> Placement:
    """argparse type of ``--place``."""
    try:
        return Placement.parse(text)
    except GcodeError as error:
        raise argparse.ArgumentTypeError(str(error).replace("placement: ", "")) from None


def add_place_options(send) -> None:
    send.add_argument("--place", type=placement, metavar="X,Y,ANGLE",
                      help="send the job moved and turned: its work zero to X,Y (mm), turned ANGLE degrees "
                      "counter-clockwise about it (arcs turn with it; a job with G18/G19 arcs, G53, G10, G92 or "
                      "another G54-G59 system is refused); the pre-flight checks it where it lands")
    send.add_argument("--verify", action="store_true",
                      help="first run the job on the machine's GRBL twin at virtual time: the time with "
                      "acceleration (GRBL's planner), the laser dark on every travel, the job within the travel; "
                      "a job that fails is not sent")


def placed_job(args, job: Job) -> Job:
    """``job`` at ``--place`` (itself without it); a job that cannot be placed is one line naming its line."""
    if getattr(args, "place", None) is None:
        return job
    try:
        lines = place_lines(job.lines, args.place)
    except GcodeError as error:
        raise UsageError(f"--place: job {job.name!r}: {error}") from None
    return Job(job.name, lines, laser=job.laser, pen_up=job.pen_up)


def verify_before_send(args, job: Job, profile, conn) -> None:
    """With ``--verify``: the job on the twin of the machine behind ``conn`` (its settings and work offset), the
    summary on stderr, the result kept as ``args.verified`` for ``--json``; a job the twin finds wrong is refused
    (:class:`JobRefused`, exit 2) before anything is sent."""
    from station.services.job_verify import verify_job, verify_summary

    args.verified = None
    if not getattr(args, "verify", False):
        return
    settings = {key: float(value) for key, value in conn.settings.items() if isinstance(key, int)}
    try:
        done = verify_job(job.lines, name=job.name, profile=profile, laser=job.laser or conn.laser_mode,
                          settings=settings, work_offset=conn.work_offset())
    except ServiceError as error:
        raise UsageError(f"--verify: {error}") from None
    args.verified = done
    if done.state != "done" and done.blocks == 0:  # refused before it moved: the refusal's one line says why
        raise JobRefused(f"--verify: job {job.name!r} fails on the twin: {done.message}")
    for line in verify_summary(done):
        print(f"station: {line}", file=sys.stderr)
    if not done.ok:
        if done.state not in ("done",):
            raise JobRefused(f"--verify: job {job.name!r} fails on the twin: {done.message}")
        why = (f"the laser is on during {len(done.lit_travels)} travel(s), the first at line "
               f"{done.lit_travels[0][0]} ({done.lit_travels[0][1]})" if done.lit_travels
               else "it leaves the machine's travel" if not done.within_travel
               else f"the twin raised ALARM:{done.alarms[0]}")
        raise JobRefused(f"--verify: job {job.name!r} refused: {why}; not sent")
