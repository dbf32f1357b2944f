"""``station jobs``: the history of machine jobs (plots, laser cuts, frames, dry runs) and where to resume them."""

from __future__ import annotations

from station.cli_util import emit_json
from station.errors import UsageError
from station.services.machine_sessions import JobRecord, local_time, recent_jobs


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "jobs",
        help="the history of machine jobs: how each ended and where to resume",
        description="List the latest jobs streamed to a GRBL machine (from the Machines screen or `station send`), "
        "newest first: kind (run, frame, dry run), device, state, lines confirmed, and for every job that did not "
        "finish (stopped, aborted, error, position lost, interrupted) the line to resume it from "
        "(`station send JOB --from-line N`). A job whose station was killed shows as interrupted.",
        epilog="example: station jobs --limit 5",
    )
    parser.add_argument("--limit", type=int, default=20, metavar="N", help="how many jobs (default 20)")
    parser.add_argument("--json", action="store_true", help="print the jobs as JSON")
    parser.set_defaults(func=run_jobs)


def describe(record: JobRecord, device_width: int = 24, title_width: int = 32) -> str:
    """One line for a job: ``#12  2026-12-01 16:20  run  plotter  star.gcode  done  197/197``.

    The device (a port URL) and the title (a file path) are never cut: their columns are at least as wide as
    given, and a longer value widens its own line. An unfinished job ends with where to resume it.
    """
    when = local_time(record.created_at)
    line = (f"#{record.id:<4} {when}  {record.kind:<7} {record.device:<{device_width}} "
            f"{record.title:<{title_width}} {record.status:<13} {record.lines_acked}/{record.lines_total}")
    hint = record.resume_hint()
    if hint:
        line += f"  {hint}"
    return line


def run_jobs(args) -> int:
    if not 1 <= args.limit <= 10_000:
        raise UsageError(f"--limit must be an integer in [1, 10000], got {args.limit}")
    database, records = recent_jobs(args.limit)
    if args.json:
        emit_json({"database": str(database), "jobs": [r.to_dict() for r in records]})
        return 0
    if not records:
        print(f"no jobs yet (database {database})")
        return 0
    # columns as wide as the longest port URL and title listed, so that none is cut
    device_width = max(len(r.device) for r in records)
    title_width = max(len(r.title) for r in records)
    for record in records:
        print(describe(record, device_width, title_width))
    return 0
