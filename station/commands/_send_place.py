"""``station send --place X,Y,ANGLE`` and ``--verify``: the job placed on the stock, and run on the GRBL twin at
virtual time before it is sent. The work is :func:`station.services.machine_sessions.load_job` (its placement) and
:meth:`~station.services.machine_sessions.MachineSessions.verify`; this module adds the options to ``station send``'s
parser and applies them (the underscore keeps it from being discovered as a command of its own)."""

from __future__ import annotations

import argparse
import sys

from station.errors import ServiceError, UsageError
from station.services.machine_sessions import parse_placement, refused_by_twin, verify_summary

__all__ = ["add_place_options", "verify_before_send"]


def placement(text: str):
    """argparse type of ``--place``."""
    try:
        return parse_placement(text)
    except ServiceError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def add_place_options(send) -> None:
    send.add_argument("--place", type=placement, metavar="X,Y,ANGLE",
                      help="send the job moved and turned: its work zero to X,Y (mm), turned ANGLE degrees "
                      "counter-clockwise about it (arcs turn with it; a job with G18/G19 arcs, G53, G10, G92 or "
                      "another G54-G59 system is refused); the pre-flight checks it where it lands")
    send.add_argument("--verify", action="store_true",
                      help="first run the job on the machine's GRBL twin at virtual time: the time with "
                      "acceleration (GRBL's planner), the laser dark on every travel, the job within the travel; "
                      "a job that fails is not sent")


def verify_before_send(args, job, profile, sessions, device: str) -> None:
    """With ``--verify``: the job on the twin of the machine ``device`` of ``sessions`` (its settings and work
    offset), the summary on stderr, the result kept as ``args.verified`` for ``--json``; a job the twin finds wrong
    is refused (exit 2) before anything is sent."""
    args.verified = None
    if not getattr(args, "verify", False):
        return
    try:
        done = sessions.verify(device, job.lines, title=job.name, profile=profile, laser=job.laser)
    except ServiceError as error:
        raise UsageError(f"--verify: {error}") from None
    args.verified = done
    refused = refused_by_twin(done, before_summary=True)
    if refused is not None:
        raise refused
    for line in verify_summary(done):
        print(f"station: {line}", file=sys.stderr)
    refused = refused_by_twin(done)
    if refused is not None:
        raise refused
