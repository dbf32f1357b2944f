"""Shared pieces of the trial-log tests: scenario texts, a CLI runner, a real PostgreSQL server."""

from __future__ import annotations

import json
import shutil
import tempfile
import uuid
from pathlib import Path

import pytest

from station.cli import main

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "scenarios"


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    """``station ARGV`` in this process: (exit code, stdout, stderr)."""
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def log_json(capsys, *argv: str) -> int:
    """``station trial log ARGV --json --predict 0`` that must succeed; the new trial's id."""
    code, out, err = run_cli(capsys, "trial", "log", *argv, "--json", "--predict", "0")
    assert code == 0, err
    return json.loads(out)["id"]


@pytest.fixture(scope="module")
def pg_server():
    """One real PostgreSQL server for the module (pgserver: PostgreSQL in a wheel, a dev dependency; 0.6-4 s to
    initialize and start, by the machine's load). Stopped and deleted at the module's end.

    Its folder is a new one in the system's temporary folder, not pytest's: run as root, pgserver runs the server
    as a user of its own and opens every parent folder to it, which pytest's own private folder does not keep.
    """
    pgserver = pytest.importorskip("pgserver", reason="pgserver (dev dependency) runs the PostgreSQL tests")
    import psycopg

    folder = Path(tempfile.mkdtemp(prefix="chaos-station-pg-"))
    server = pgserver.get_server(folder / "data", cleanup_mode="delete")
    # a throw-away server: no fsync (CREATE DATABASE and the shutdown checkpoint took seconds of disk flushes)
    with psycopg.connect(server.get_uri(), autocommit=True) as admin:
        for setting in ("fsync = off", "synchronous_commit = off", "full_page_writes = off"):
            admin.execute(f"ALTER SYSTEM SET {setting}")
        admin.execute("SELECT pg_reload_conf()")
    yield server
    server.cleanup()
    shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture
def pg_url(pg_server):
    """A new, empty database on the module's server, as a postgresql:// URL."""
    import psycopg

    name = f"t_{uuid.uuid4().hex[:12]}"
    with psycopg.connect(pg_server.get_uri(), autocommit=True) as admin:
        admin.execute(f"CREATE DATABASE {name}")
    return pg_server.get_uri(database=name)
